"""The experiment window's controller: which screen is up, what the keys do, the waits.

:class:`WindowController` is the state machine of
:class:`~tactorbelt.gui.window.ExperimentWindow`, with no drawing in it: it takes the
runner's events into its state (a listener), answers its queries (the operator): turns
pygame's events into the runner's commands (pause, resume, abort:
:meth:`~WindowController.poll`), and runs the waiting screens
(``instructions``, ``block``, ``break``, ``task``, ``end``, the NASA-TLX's ``tlx``,
``show_wait``'s ``wait``) until the participant goes on, an abort, or
``auto_continue_s``. The keys are listed in :mod:`tactorbelt.gui.window`; a joystick
that goes away pauses the session until it is back.

A subclass draws: :meth:`~WindowController.draw` (a frame of the current state;
:mod:`tactorbelt.gui.screens` says what each screen shows),
:meth:`~WindowController._relayout` (a new size, the overlay toggled) and
:meth:`~WindowController._manual_shot` (F12).

I/O: reads pygame's events (main thread; pygame imported on construction).
"""

from __future__ import annotations

import abc
import collections
import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError
from ..clock import Deadlines
from ..experiment.listeners import Command, NullObserver
from ..geometry import TargetSet
from ..inputs.base import LiveCursor
from ..inputs.joystick import prepare_sdl
from ..inputs.kinds import input_kind as input_kind_of
from .taskview import TaskPresenter
from .tlx import TlxForm, TlxScreen

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.listeners import SessionInfo
    from ..experiment.schedule import ScheduledTrial
    from ..experiment.study import Study, TaskSpec
    from ..experiment.trial import TrialResult, TrialState
    from ..inputs.base import CursorSample, CursorSource
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem

__all__ = ["ESC_WINDOW_S", "IDLE_FPS", "TLX_FPS", "WindowController"]

#: Two presses of Esc within this many seconds abort the session.
ESC_WINDOW_S = 2.0
#: Frames per second of the waiting screens on the wall clock (they wait on events in
#: between: a key, a button or a stick move wakes them at once).
IDLE_FPS = 10.0
#: Frames per second of the NASA-TLX screen on the wall clock (a held stick repeats).
TLX_FPS = 30.0


@dataclass
class ShownTrial:
    """What the window knows about the trial in progress."""

    trial: ScheduledTrial
    phase: str = "home"  # home, stimulus, response, timeout, iti, aborted
    onset_ns: int | None = None


class WindowController(NullObserver, abc.ABC):
    """The state of the experiment window and its event loop (see the module doc).

    Args:
        study: the study (targets, layout, tasks).
        clock: the runner's clock (waiting screens pace their frames on it).
        belt: stopped at once on pause, abort and a lost joystick; None: no belt.
        input_kind: ``joystick``, ``mouse``, ``model`` or ``scripted``.
        participant: the participant id.
        fps: frames per second of the trial screens, in [1, 1000].
        auto_continue_s: leave waiting screens after this many seconds of the clock;
            None waits for the participant.

    Raises:
        ConfigError: ``fps`` or ``auto_continue_s`` out of range.
    """

    def __init__(
        self,
        study: Study,
        clock: Clock,
        *,
        belt: Belt | None,
        input_kind: str,
        participant: str,
        fps: float,
        auto_continue_s: float | None,
    ) -> None:
        if not (math.isfinite(fps) and 1.0 <= fps <= 1000.0):
            raise ConfigError(f"fps must be in [1, 1000], got {fps!r}")
        if auto_continue_s is not None and not (auto_continue_s >= 0):
            raise ConfigError(f"auto_continue_s must be >= 0 seconds, got {auto_continue_s!r}")
        prepare_sdl()
        import pygame

        self._pg = pygame
        self.study = study
        self.belt = belt
        self.clock = clock
        self.input_kind = input_kind
        #: what the input kind declares (the window's words, a stick, a clicking mouse)
        self.input = input_kind_of(input_kind)
        self.participant = participant
        self.fps = float(fps)
        self.auto_continue_s = auto_continue_s

        # what a trial screen shows
        self.layout = study.layout_obj()
        self._n_targets = 0
        self.targets_deg: tuple[float, ...] = ()
        self.on_tactor: tuple[bool, ...] = ()
        self._schedule: list[ScheduledTrial] = []
        self._show_targets(study.targets.count if study.design is None
                           else study.target_counts()[0])
        self.tactors_deg = self.layout.angles_deg
        self.home_radius = float(study.response.home_radius)

        self.cursor: CursorSource | None = None
        # session state (set by the observer hooks)
        self.info: SessionInfo | None = None
        self.n_total = study.n_trials()
        self.n_done = 0
        self.block: str | None = None
        self.condition: str | None = None
        self.test_blocks_seen = 0
        self.current: ShownTrial | None = None
        self.last_sample: CursorSample | None = None
        self.last_result: TrialResult | None = None
        self.end_status: str | None = None
        #: sample times of the trial's stimulus phase (the overlay's interval check)
        self.sample_times: collections.deque[int] = collections.deque(maxlen=256)
        # what is on screen
        self.screen = "trial"
        self.wait_text: tuple[str, list[str]] | None = None  # show_wait's
        self.overlay = False
        self.banner: str | None = None
        self.banner_until_ns = 0
        # commands
        self.user_paused = False
        self.device_paused = False
        self.abort_requested = False
        self._pause_sent = False
        self._continue = False
        self._esc_ns: int | None = None
        self._frames = Deadlines(clock, self.fps)
        # secondary tasks and the NASA-TLX
        self.tasks = TaskPresenter(clock,
                                   tick_ns=round(1e9 / study.session.sample_rate_hz))
        #: a practice or baseline run is on: the task alone, no trial on screen
        self.task_alone = False
        #: the task instructions up: (task, spec, phase, how the last practice went)
        self.task_intro: tuple[str, TaskSpec, str, str | None] | None = None
        self._intros_shown: set[tuple[str, str]] = set()
        #: the task of the coming test block, and how the last practice went
        self.block_task: tuple[str, TaskSpec] | None = None
        self.block_note: str | None = None
        self._tlx: TlxScreen | None = None

    # ------------------------------------------------------------------------------------
    # the window's part
    @abc.abstractmethod
    def draw(self, now_ns: int | None = None) -> str:
        """Draw one frame of the current state now; return its kind."""

    @abc.abstractmethod
    def _relayout(self) -> None:
        """The window's size or the overlay changed: lay the scene out again."""

    @abc.abstractmethod
    def _manual_shot(self) -> None:
        """Save the frame on screen (F12)."""

    # ------------------------------------------------------------------------------------
    # cursor
    def _refresh_live(self) -> None:
        """Pump SDL's events and re-read the device (from ``read``, main thread only).

        Hot-plug events are taken from the queue here, so a stick unplugged between two
        samples reads as the centre at the very next sample (nothing is acquired) and
        the next ``poll`` pauses the session.
        """
        pg = self._pg
        pg.event.pump()
        live = self.live
        if live is not None:
            for ev in pg.event.get((pg.JOYDEVICEADDED, pg.JOYDEVICEREMOVED)):
                live.handle_event(ev)
            live.update()

    @property
    def live(self) -> LiveCursor | None:
        """The part of the cursor this window feeds (joystick, mouse), or None."""
        return self.cursor.live_input() if self.cursor is not None else None

    # ------------------------------------------------------------------------------------
    # listener and operator hooks (called by the runner, in this thread)
    def _show_targets(self, n: int) -> None:
        """Show the candidate targets of a block of ``n`` targets (at k*360/n)."""
        if n <= 0 or n == self._n_targets:
            return
        targets = TargetSet.even(n)
        self._n_targets = n
        self.targets_deg = targets.angles_deg
        self.on_tactor = tuple(bool(b) for b in targets.on_tactor(self.layout))

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        self.info = info
        self._schedule = list(schedule)
        if schedule:
            first = schedule[min(info.n_done, len(schedule) - 1)]
            self._show_targets(first.n_targets)
        self.n_total = info.n_total
        self.n_done = info.n_done
        self._wait_screen("instructions")

    def on_block_start(self, block: str, condition: str) -> None:
        self.block = block
        self.condition = condition
        # the block's first trial follows the current one: show its targets on the
        # block screen already
        nxt = self.current.trial.trial_index + 1 if self.current is not None else (
            self.info.n_done if self.info is not None else 0)
        self.block_task = None
        self.block_note = None
        if 0 <= nxt < len(self._schedule):
            t = self._schedule[nxt]
            self._show_targets(t.n_targets)
            spec = self.study.tasks.get(t.load) if block == "test" else None
            if spec is not None and spec.active:
                self.block_task = (t.load, spec)
                self.block_note = self._practice_note()
        if block == "test":
            self.test_blocks_seen += 1
            self._wait_screen("block")

    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None:
        phase = str(state)  # a StrEnum: its value
        if phase == "wait_home" or self.current is None or self.current.trial is not trial:
            self.current = ShownTrial(trial)
            self._show_targets(trial.n_targets)
            self.block = trial.block
            self.condition = trial.condition
            if phase == "wait_home":
                self.last_sample = None
                self.sample_times.clear()
        cur = self.current
        cur.phase = "home" if phase == "wait_home" else phase
        if phase == "stimulus":
            cur.onset_ns = int(now_ns)

    def on_sample(self, sample: CursorSample) -> None:
        self.last_sample = sample
        cur = self.current
        if cur is not None and cur.phase == "stimulus":
            self.sample_times.append(sample.t_ns)

    def on_trial_done(self, result: TrialResult) -> None:
        self.last_result = result
        if result.status in ("done", "timeout"):
            self.n_done += 1

    def on_break(self, n_done: int, n_total: int) -> None:
        self.n_done = n_done
        self.n_total = n_total

    def wait_break(self, n_done: int, n_total: int) -> None:
        self._wait_screen("break")

    def on_session_end(self, status: str) -> None:
        self.end_status = status
        self._motors_off()

    def poll(self, now_ns: int) -> Command | None:
        """Handle events, draw when a frame is due, and return a command for the runner."""
        self.step(now_ns)
        return self._command()

    # -- secondary tasks and workload ------------------------------------------------------
    def on_task_phase(self, name: str | None, spec: TaskSpec | None, phase: str | None
                      ) -> None:
        """A task run starts or ends (silence, no glyph)."""
        if name is None or spec is None or phase is None:
            self.tasks.end()
            self.task_alone = False
            return
        self.tasks.start(name, spec, phase)
        self.task_alone = phase in ("practice", "baseline")

    def wait_task_phase(self, name: str | None, spec: TaskSpec | None,
                        phase: str | None) -> None:
        """A practice or baseline run: its instructions first, once."""
        if name is None or spec is None or phase is None:
            return
        if phase in ("practice", "baseline") and (name, phase) not in self._intros_shown:
            self._intros_shown.add((name, phase))
            self.task_intro = (name, spec, phase, self._practice_note())
            try:
                self._wait_screen("task")
            finally:
                self.task_intro = None
        self.tasks.presses()  # presses on the instructions screen are not responses

    def _practice_note(self) -> str | None:
        """How the last practice went, once (the next screen after it says it)."""
        note, self.tasks.practice_summary = self.tasks.practice_summary, None
        return note

    def on_task_item(self, item: TaskItem, onset_ns: int, spec: TaskSpec) -> None:
        """Schedule the item's sound (auditory) or glyph (visual) for its onset."""
        self.tasks.item(item, onset_ns, spec)

    def task_presses(self, now_ns: int) -> list[int]:
        """Presses of the task's button since the last call (runner clock)."""
        return self.tasks.presses()

    def ask_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        """The NASA-TLX screen; the six ratings, or None when the session was aborted
        (or nobody answered within ``auto_continue_s``)."""
        form = TlxForm()
        tests = sorted({t.block_index for t in self._schedule if t.block == "test"})
        k = tests.index(info.block_index) + 1 if info.block_index in tests else \
            self.test_blocks_seen
        n = max(len(tests), k)
        sub = (f"Test block {k} of {n} is over. Rate it: mark each scale where it fits "
               "best.")
        self._tlx = TlxScreen(form, "How was that block?", sub,
                              stick=self.input.stick)
        pg = self._pg
        visible = bool(pg.mouse.get_visible())
        pg.mouse.set_visible(True)
        try:
            self._wait_screen("tlx", lambda: form.done, fps=TLX_FPS)
        finally:
            self._tlx = None
            pg.mouse.set_visible(visible)
        return form.result() if form.done and not self.abort_requested else None

    # ------------------------------------------------------------------------------------
    # commands
    def _command(self) -> Command | None:
        if self.abort_requested:
            return Command.ABORT
        want = self.user_paused or self.device_paused
        if want and not self._pause_sent:
            self._pause_sent = True
            return Command.PAUSE
        if not want and self._pause_sent:
            self._pause_sent = False
            return Command.RESUME
        return None

    def _silence(self) -> None:
        audio = self.tasks.audio
        if audio is not None:
            with contextlib.suppress(Exception):
                audio.stop()

    def _motors_off(self) -> None:
        if self.belt is not None:
            with contextlib.suppress(Exception):
                self.belt.stop()

    def pause(self) -> None:
        """Pause the session now (the experimenter's P): motors off and task sounds
        silent at once."""
        self.user_paused = True
        self._motors_off()
        self._silence()

    def resume(self) -> None:
        """Resume after :meth:`pause`."""
        self.user_paused = False

    def abort(self) -> None:
        """Abort the session (saved, resumable): motors off at once."""
        self.abort_requested = True
        self.banner = None
        self._motors_off()
        self._silence()

    # ------------------------------------------------------------------------------------
    # events
    def _handle_events(self, now_ns: int, first: Any = None) -> None:
        pg = self._pg
        live = self.live
        events = pg.event.get()
        if first is not None:
            events.insert(0, first)
        stick_id = live.instance_id if live is not None else None
        for ev in events:
            if live is not None:
                live.handle_event(ev)
            if self.tasks.on_event(ev, now_ns, pg, stick_id):
                continue  # the task's button: a response, nothing else
            if self._tlx is not None and self._tlx.handle_event(ev, stick_id):
                continue
            t = ev.type
            if t == pg.QUIT:
                self.abort()
            elif t == pg.KEYDOWN:
                self._on_key(ev, now_ns)
            elif t == pg.JOYBUTTONDOWN:
                own = live.instance_id if live is not None else None
                if own is None or getattr(ev, "instance_id", own) == own:
                    self._continue = True
            elif t == pg.MOUSEBUTTONDOWN and self.input.clicks:
                self._continue = True
            elif t in (pg.VIDEORESIZE, pg.WINDOWSIZECHANGED):
                self._relayout()
        if live is not None:
            live.update()
            connected = live.connected
            if not connected and not self.device_paused:
                self.device_paused = True
                self._motors_off()
            elif connected and self.device_paused:
                self.device_paused = False

    def _on_key(self, ev: Any, now_ns: int) -> None:
        pg = self._pg
        key = ev.key
        ctrl = bool(ev.mod & pg.KMOD_CTRL)
        if key in (pg.K_F1, pg.K_TAB):
            self.overlay = not self.overlay
            self._relayout()
        elif key == pg.K_q and ctrl:
            self.abort()
        elif key == pg.K_ESCAPE and self.screen == "end":
            self._continue = True
        elif key == pg.K_ESCAPE:
            if self._esc_ns is not None and now_ns - self._esc_ns <= ESC_WINDOW_S * 1e9:
                self.abort()
            else:
                self._esc_ns = now_ns
                self.banner = ("Press Esc again to abort (the session is saved and can be "
                               "resumed)")
                self.banner_until_ns = now_ns + round(ESC_WINDOW_S * 1e9)
        elif key == pg.K_p:
            if self.user_paused:
                self.resume()
            else:
                self.pause()
        elif key == pg.K_r:
            self.resume()
        elif key in (pg.K_SPACE, pg.K_RETURN, pg.K_KP_ENTER):
            self._continue = True
        elif key == pg.K_F12:
            self._manual_shot()

    # ------------------------------------------------------------------------------------
    # the loop
    def step(self, now_ns: int, event: Any = None) -> None:
        """Handle pending events (``event`` first), and draw a frame if one is due (or a
        task glyph appeared or ended since the last frame)."""
        self._handle_events(now_ns, event)
        tlx = self._tlx
        live = self.live
        if tlx is not None and live is not None:
            x, y, _ = live.state
            tlx.stick_at(x, y, now_ns)
        if self._frames.due(now_ns) is not None or self.tasks.frame_due(now_ns):
            self.draw(now_ns)

    def _idle(self, kind: str, done: Callable[[], bool], fps: float = IDLE_FPS) -> None:
        """Show the waiting screen ``kind`` until ``done()``, an abort, or
        ``auto_continue_s``. On the wall clock it waits on SDL's event queue between
        frames (``pygame.event.wait`` with a timeout): no spinning, and a signal is
        handled within a frame."""
        pg = self._pg
        self.screen = kind
        self._continue = False
        sim = bool(self.clock.simulated)
        self._frames = Deadlines(self.clock, self.fps if sim else min(self.fps, fps))
        start = self._frames.onset_ns
        limit = None if self.auto_continue_s is None else round(self.auto_continue_s * 1e9)
        event = None
        while True:
            now = self.clock.now_ns()
            self.step(now, event)
            event = None
            if self.abort_requested or done():
                return
            if limit is not None and now - start >= limit:
                return
            until = self._frames.deadline(self._frames.next_index)
            if limit is not None:
                until = min(until, start + limit)
            if sim:
                self.clock.sleep_until_ns(max(until, now + 1))
                continue
            ev = pg.event.wait(max(1, (until - self.clock.now_ns()) // 1_000_000))
            if ev.type != pg.NOEVENT:
                event = ev

    def _wait_screen(self, kind: str, done: Callable[[], bool] | None = None,
                     fps: float = IDLE_FPS) -> None:
        """Show a waiting screen until the participant goes on (or ``done()``), and no
        pause is on, or an abort."""
        prev = self.screen
        ready = done or (lambda: self._continue)
        try:
            self._idle(kind, lambda: ready() and not (self.user_paused or self.device_paused),
                       fps)
        finally:
            self.screen = prev
            self._continue = False
            self._frames = Deadlines(self.clock, self.fps)

    def show_wait(self, title: str | None, lines: list[str]) -> bool:
        """Show ``title`` and ``lines`` (screen kind ``wait``), handle the pending events
        and draw, once: call it again and again during a wait outside the runner's hooks
        (LSL's wait for a recorder); ``title`` None takes the screen down. Returns True
        when the experimenter stopped the session (Esc Esc, Ctrl-Q, closing the window)."""
        if title is None:
            self.wait_text = None
            self.screen = "trial" if self.screen == "wait" else self.screen
            return self.abort_requested
        self.wait_text = (title, list(lines))
        self.screen = "wait"
        now = self.clock.now_ns()
        self._handle_events(now)
        self.draw(now)
        return self.abort_requested

    def show_end(self, status: str | None = None) -> None:
        """The end screen: wait for the participant (or ``auto_continue_s``)."""
        if status is not None:
            self.end_status = status
        self.abort_requested = False  # Esc twice leaves the end screen
        self.banner = None  # "Press Esc again" belongs to the session, not its end
        self._esc_ns = None
        self._idle("end", lambda: self._continue)

    def close(self) -> None:
        """Motors off, the task sound output closed, the live cursor let go."""
        self._motors_off()
        with contextlib.suppress(Exception):
            self.tasks.close()
        live = self.live
        if live is not None:
            live.attach_refresh(None)
