"""The experiment window: a view of a running session and the participant's input.

:class:`ExperimentWindow` is a :class:`~tactorbelt.experiment.runner.SessionObserver`.
The runner owns the trial logic and the timing; the window only shows the state it is
told about, turns keys into commands, and feeds the joystick or mouse cursor.

Threads: everything runs in the **main thread**. :func:`run_with_window` opens the
window (pygame is initialised and pumped only there) and calls
:func:`~tactorbelt.experiment.runner.run_session` in the same thread. The runner calls
:meth:`ExperimentWindow.poll` at every 10 ms sampling step (and while it waits: the
home zone, the inter-trial interval, a pause); ``poll`` handles the pending events and
draws a frame when one is due (60 Hz by default, so a frame falls on every first poll
after a 16.7 ms frame deadline). A frame costs about a millisecond (cached static
layer), well inside the 10 ms between two samples, so drawing never moves a sampling
deadline. The joystick and mouse sources pump SDL's events in their ``read``, so each
sample holds the stick's state at that instant. Blocking hooks (instructions, block
start, breaks) run their own loop of events and frames until the participant goes on.

Screens: instructions, block start, trial (training: the target is highlighted while
its stimulus plays, then feedback; test: no feedback), break, pause, end.

Keys (experimenter): P pause (motors off at once) / resume, R resume, Esc twice or
Ctrl-Q abort (the session is saved and can be resumed), F1 or Tab the overlay
(tactor positions, live amplitudes, trial, block, condition), F12 a screenshot.
Participant: Space, Enter, a joystick button or (mouse input) a click to go on.

I/O: imports pygame (after :func:`tactorbelt.inputs.joystick.prepare_sdl`), the
runner's observer types, inputs and tactorbelt.gui.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import logging
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError, TactorbeltError
from ..clock import Deadlines
from ..inputs import make_cursor
from ..inputs.base import CursorSample, CursorSource
from ..inputs.joystick import JoystickConfig, LiveCursor, prepare_sdl

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.runner import Command, SessionInfo, SessionResult
    from ..experiment.schedule import ScheduledTrial
    from ..experiment.store import Store
    from ..experiment.study import Study, TaskSpec
    from ..experiment.trial import TrialResult, TrialState
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem
    from .render import View
    from .tlx import TlxScreen

__all__ = ["SCREEN_KINDS", "TASK_SCREEN_KINDS", "ExperimentWindow", "run_with_window"]

#: Kinds of screen passed to ``on_frame`` and saved by ``screenshot_dir``.
SCREEN_KINDS = ("instructions", "block", "training", "feedback", "test", "overlay", "break",
                "pause", "end")
#: Kinds of screen of a study with secondary tasks or the NASA-TLX: a task's instructions,
#: the task alone (practice, baseline), the TLX sliders.
TASK_SCREEN_KINDS = ("task", "task_alone", "tlx")
#: Waiting screens (the participant goes on from them).
WAIT_KINDS = ("instructions", "block", "break", "end", "task")

#: Two presses of Esc within this many seconds abort the session.
ESC_WINDOW_S = 2.0
#: Frames per second of the waiting screens on the wall clock (they wait on events in
#: between: a key, a button or a stick move wakes them at once).
IDLE_FPS = 10.0
#: Frames per second of the NASA-TLX screen on the wall clock (a held stick repeats).
TLX_FPS = 30.0

FrameHook = Callable[["ExperimentWindow", str], None]

log = logging.getLogger("tactorbelt.gui")


@dataclass
class _Trial:
    """What the window knows about the trial in progress."""

    trial: ScheduledTrial
    phase: str = "home"  # home, stimulus, response, timeout, iti, aborted
    onset_ns: int | None = None


class ExperimentWindow:
    """The pygame window of a session; pass it to ``run_session`` as ``observer``.

    Create it in the main thread; it opens the display at once.

    Args:
        study: the study (targets, layout, response rule).
        clock: the runner's clock (waiting screens pace their frames on it).
        belt: the belt, optional: stopped at once on pause and abort (the runner stops
            it too, at the same poll), and its live ``levels`` feed the overlay when it
            has them (the sim belt); without it the overlay computes the amplitudes
            from the stimulus.
        input_kind: ``joystick``, ``mouse``, ``model`` or ``scripted`` (words on screen,
            and whether the participant can press to go on).
        participant: the participant id (overlay only).
        fullscreen: open full screen at the desktop's size.
        size: the window size when not full screen.
        fps: frames per second (drawn at the first poll after each frame deadline).
        screenshot_dir: save a PNG of each kind of screen (:data:`SCREEN_KINDS`) there,
            the first time it is drawn (``window-<kind>.png``).
        auto_continue_s: go on from waiting screens (instructions, block start, break,
            end) after this many seconds of the clock; None waits for the participant.
        on_frame: called as ``on_frame(window, kind)`` after each frame (tests post
            events from here).
    """

    def __init__(
        self,
        study: Study,
        clock: Clock,
        *,
        belt: Belt | None = None,
        input_kind: str = "joystick",
        participant: str = "",
        fullscreen: bool = False,
        size: tuple[int, int] = (1280, 800),
        fps: float = 60.0,
        screenshot_dir: str | Path | None = None,
        auto_continue_s: float | None = None,
        on_frame: FrameHook | None = None,
    ) -> None:
        if not (math.isfinite(fps) and 1.0 <= fps <= 1000.0):
            raise ConfigError(f"fps must be in [1, 1000], got {fps!r}")
        if auto_continue_s is not None and not (auto_continue_s >= 0):
            raise ConfigError(f"auto_continue_s must be >= 0 seconds, got {auto_continue_s!r}")
        prepare_sdl()
        import pygame

        from .render import Renderer

        self._pg = pygame
        self.study = study
        self.belt = belt
        self.clock = clock
        self.input_kind = input_kind
        self.participant = participant
        self.fps = float(fps)
        self.auto_continue_s = auto_continue_s
        self.on_frame = on_frame
        self.screenshot_dir = Path(screenshot_dir) if screenshot_dir is not None else None
        self.saved: dict[str, Path] = {}
        if self.screenshot_dir is not None:
            try:
                self.screenshot_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ConfigError(
                    f"cannot create the screenshot folder {self.screenshot_dir}: {exc.strerror}"
                ) from None

        try:
            pygame.display.init()
            pygame.font.init()
            pygame.joystick.init()
            if fullscreen:
                sizes = pygame.display.get_desktop_sizes()
                full = sizes[0] if sizes else size
                self.surface = pygame.display.set_mode(full, pygame.FULLSCREEN)
            else:
                self.surface = pygame.display.set_mode(size, pygame.RESIZABLE)
        except pygame.error as exc:
            with contextlib.suppress(Exception):
                pygame.display.quit()
            raise ConfigError(
                f"cannot open the experiment window ({exc}); run with --headless, or "
                "check DISPLAY / WAYLAND_DISPLAY"
            ) from None
        pygame.display.set_caption(f"tactorbelt: {study.name}")
        if input_kind == "joystick":
            pygame.mouse.set_visible(False)  # the participant looks at the cursor only
        self.renderer = Renderer(self.surface.get_size())

        layout = study.layout_obj()
        self._layout = layout
        self._n_targets = 0
        self._targets: tuple[float, ...] = ()
        self._on_tactor: tuple[bool, ...] = ()
        self._schedule: list[ScheduledTrial] = []
        self._show_targets(study.targets.count if study.design is None
                           else study.target_counts()[0])
        self._tactors = layout.angles_deg
        self._home_radius = float(study.response.home_radius)

        self.cursor: CursorSource | None = None
        # session state (set by the observer hooks)
        self.info: SessionInfo | None = None
        self.n_total = study.n_trials()
        self.n_done = 0
        self.block: str | None = None
        self.condition: str | None = None
        self._test_blocks_seen = 0
        self.current: _Trial | None = None
        self.last_sample: CursorSample | None = None
        self.last_result: TrialResult | None = None
        self.end_status: str | None = None
        self._sample_times: collections.deque[int] = collections.deque(maxlen=256)
        # what is on screen
        self.screen = "trial"
        self._wait_text: tuple[str, list[str]] | None = None  # show_wait's
        self.overlay = False
        # commands
        self.user_paused = False
        self.device_paused = False
        self.abort_requested = False
        self._pause_sent = False
        self._continue = False
        self._esc_ns: int | None = None
        self._banner: str | None = None
        self._banner_until_ns = 0
        self._frames = Deadlines(clock, self.fps)
        self.frames = 0
        self._stimuli: dict[tuple[Any, ...], Any] = {}
        from ..experiment.runner import Command

        self._Command = Command
        # secondary tasks and the NASA-TLX
        from .taskview import TaskPresenter

        self.tasks = TaskPresenter(clock,
                                   tick_ns=round(1e9 / study.session.sample_rate_hz))
        #: a practice or baseline run is on: the task alone, no trial on screen
        self.task_alone = False
        self._task_intro: tuple[str, list[str]] | None = None
        self._intros_shown: set[tuple[str, str]] = set()
        self._block_task: tuple[str, TaskSpec] | None = None
        self._block_note: str | None = None
        self._tlx: TlxScreen | None = None
        try:
            self._open_task_audio()
        except BaseException:
            self.close()
            raise

    def _open_task_audio(self) -> None:
        """Check the tasks' buttons; open the sound output now when a task is auditory
        (a sound card that cannot be opened stops the run before the session starts)."""
        from .taskview import check_responses

        check_responses(self.study)
        if any(t.active and t.modality == "auditory" for t in self.study.tasks.values()):
            from ..tasks.audio import DEVICE_ENV, open_task_audio

            self.tasks.audio = open_task_audio(self.clock)
            belt = self.belt
            if (belt is not None and belt.uses_sound_output
                    and self.tasks.audio.plays_sound and not os.environ.get(DEVICE_ENV)):
                log.warning("the task sounds play on SDL's default output: make sure it is "
                            "not the sound card that drives the tactors of %s (name the "
                            "headphones' output in $%s)", belt.url, DEVICE_ENV)

    # ------------------------------------------------------------------------------------
    # cursor
    def attach_cursor(self, cursor: CursorSource) -> None:
        """Use ``cursor``: live sources (joystick, mouse) are fed by this window."""
        self.cursor = cursor
        live = cursor.live_input()
        if live is not None:
            live.geometry = self.renderer.geometry
            live.attach_refresh(self._refresh_live)

    def _refresh_live(self) -> None:
        """Pump SDL's events and re-read the device (from ``read``, main thread only).

        Hot-plug events are taken from the queue here, so a stick unplugged between two
        samples reads as the centre at the very next sample (nothing is acquired) and
        the next ``poll`` pauses the session.
        """
        pg = self._pg
        pg.event.pump()
        live = self._live
        if live is not None:
            for ev in pg.event.get((pg.JOYDEVICEADDED, pg.JOYDEVICEREMOVED)):
                live.handle_event(ev)
            live.update()

    @property
    def _live(self) -> LiveCursor | None:
        return self.cursor.live_input() if self.cursor is not None else None

    # ------------------------------------------------------------------------------------
    # SessionObserver hooks (called by the runner, in this thread)
    def _show_targets(self, n: int) -> None:
        """Draw the candidate targets of a block of ``n`` targets (at k*360/n)."""
        if n <= 0 or n == self._n_targets:
            return
        from ..geometry import TargetSet

        targets = TargetSet.even(n)
        self._n_targets = n
        self._targets = targets.angles_deg
        self._on_tactor = tuple(bool(b) for b in targets.on_tactor(self._layout))

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
        self._block_task = None
        self._block_note = None
        if 0 <= nxt < len(self._schedule):
            t = self._schedule[nxt]
            self._show_targets(t.n_targets)
            spec = self.study.tasks.get(t.load) if block == "test" else None
            if spec is not None and spec.active:
                self._block_task = (t.load, spec)
                self._block_note = self._practice_note()
        if block == "test":
            self._test_blocks_seen += 1
            self._wait_screen("block")

    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None:
        phase = str(getattr(state, "value", state))
        if phase == "wait_home" or self.current is None or self.current.trial is not trial:
            self.current = _Trial(trial)
            self._show_targets(trial.n_targets)
            self.block = trial.block
            self.condition = trial.condition
            if phase == "wait_home":
                self.last_sample = None
                self._sample_times.clear()
        cur = self.current
        if phase == "wait_home":
            cur.phase = "home"
        elif phase == "stimulus":
            cur.phase = "stimulus"
            cur.onset_ns = int(now_ns)
        else:
            cur.phase = phase

    def on_sample(self, sample: CursorSample) -> None:
        self.last_sample = sample
        cur = self.current
        if cur is not None and cur.phase == "stimulus":
            self._sample_times.append(sample.t_ns)

    def on_trial_done(self, result: TrialResult) -> None:
        self.last_result = result
        if result.status in ("done", "timeout"):
            self.n_done += 1

    def on_break(self, n_done: int, n_total: int) -> None:
        self.n_done = n_done
        self.n_total = n_total
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
        """A task run starts (practice and baseline: its instructions first, once) or
        ends (silence, no glyph)."""
        if name is None or spec is None or phase is None:
            self.tasks.end()
            self.task_alone = False
            return
        self.tasks.start(name, spec, phase)
        self.task_alone = phase in ("practice", "baseline")
        if phase in ("practice", "baseline") and (name, phase) not in self._intros_shown:
            from .taskview import instructions

            self._intros_shown.add((name, phase))
            go_on, _ = self._input_words()
            n = spec.practice if phase == "practice" else spec.baseline
            assert self.tasks.response is not None
            title, lines = instructions(name, spec, phase, n, self.tasks.response.words(),
                                        go_on)
            note = self._practice_note()
            self._task_intro = (title, [note, "", *lines] if note else lines)
            try:
                self._wait_screen("task")
            finally:
                self._task_intro = None
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
        from .tlx import TlxForm, TlxScreen

        form = TlxForm()
        tests = sorted({t.block_index for t in self._schedule if t.block == "test"})
        k = tests.index(info.block_index) + 1 if info.block_index in tests else \
            self._test_blocks_seen
        n = max(len(tests), k)
        sub = (f"Test block {k} of {n} is over. Rate it: mark each scale where it fits "
               "best.")
        self._tlx = TlxScreen(form, "How was that block?", sub,
                              stick=self.input_kind == "joystick")
        pg = self._pg
        visible = bool(pg.mouse.get_visible())
        pg.mouse.set_visible(True)
        prev = self.screen
        try:
            self._idle("tlx", lambda: form.done and not (self.user_paused
                                                        or self.device_paused),
                       fps=TLX_FPS)
        finally:
            self._tlx = None
            self.screen = prev
            self._continue = False
            self._frames = Deadlines(self.clock, self.fps)
            pg.mouse.set_visible(visible)
        return form.result() if form.done and not self.abort_requested else None

    # ------------------------------------------------------------------------------------
    # commands
    def _command(self) -> Command | None:
        Command = self._Command
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
        self._banner = None
        self._motors_off()
        self._silence()

    # ------------------------------------------------------------------------------------
    # events
    def _handle_events(self, now_ns: int, first: Any = None) -> None:
        pg = self._pg
        live = self._live
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
            elif t == pg.MOUSEBUTTONDOWN and self.input_kind == "mouse":
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
                self._show_banner("Press Esc again to abort (the session is saved and can "
                                  "be resumed)", now_ns)
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
            self._save_frame(f"manual-{self.frames}")

    def _show_banner(self, text: str, now_ns: int, seconds: float = ESC_WINDOW_S) -> None:
        self._banner = text
        self._banner_until_ns = now_ns + round(seconds * 1e9)

    def _relayout(self) -> None:
        surface = self._pg.display.get_surface()
        if surface is not None:
            self.surface = surface
        self.renderer.resize(self.surface.get_size(), overlay=self.overlay)
        live = self._live
        if live is not None:
            live.geometry = self.renderer.geometry

    # ------------------------------------------------------------------------------------
    # the loop
    def step(self, now_ns: int, event: Any = None) -> None:
        """Handle pending events (``event`` first), and draw a frame if one is due (or a
        task glyph appeared or ended since the last frame)."""
        self._handle_events(now_ns, event)
        tlx = self._tlx
        live = self._live
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

    def _wait_screen(self, kind: str) -> None:
        """Show a waiting screen until the participant goes on (or an abort)."""
        prev = self.screen
        try:
            self._idle(kind, lambda: self._continue and not (self.user_paused
                                                            or self.device_paused))
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
            self._wait_text = None
            self.screen = "trial" if self.screen == "wait" else self.screen
            return self.abort_requested
        self._wait_text = (title, list(lines))
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
        self._banner = None  # "Press Esc again" belongs to the session, not its end
        self._esc_ns = None
        self._idle("end", lambda: self._continue)

    # ------------------------------------------------------------------------------------
    # drawing
    def _kind(self, view: View) -> str:
        """The kind of screen a view shows (for screenshots and ``on_frame``)."""
        if (self.user_paused or self.device_paused) and self.screen not in WAIT_KINDS:
            return "pause"
        if self.screen in WAIT_KINDS or self.screen in ("tlx", "wait"):
            return self.screen
        if self.task_alone:
            return "task_alone"
        cur = self.current
        if cur is not None and cur.trial.block == "training":
            return "feedback" if view.chosen_deg is not None else "training"
        return "test"

    def draw(self, now_ns: int | None = None) -> str:
        """Draw one frame now; return its kind."""
        now = self.clock.now_ns() if now_ns is None else now_ns
        view = self.view(now)
        tlx = self._tlx
        if tlx is not None and view.modal_title is None:
            from .render import COLORS

            tlx.draw(self.surface, self.renderer, COLORS)
        else:
            self.renderer.draw(self.surface, view)
        self._pg.display.flip()
        self.tasks.drawn(now)
        self.frames += 1
        kind = self._kind(view)
        if self.screenshot_dir is not None:
            self._screenshots(kind, view)
        if self.on_frame is not None:
            self.on_frame(self, kind)
        return kind

    def _cursor_pos(self) -> tuple[float, float] | None:
        live = self._live
        if live is not None:
            x, y, _ = live.state
            return (x, y)
        if self.task_alone:
            return (0.0, 0.0)
        if self.current is not None and self.last_sample is not None:
            return (self.last_sample.x, self.last_sample.y)
        return (0.0, 0.0)

    def _input_words(self) -> tuple[str, str]:
        """(how to go on, how to answer) in the participant's words."""
        if self.input_kind == "mouse":
            return "click or press Space", "Move the mouse"
        if self.input_kind == "joystick":
            return "press the trigger or Space", "Push the joystick"
        return "press Space (or wait a moment)", "Move the cursor"

    def view(self, now_ns: int) -> View:
        """What to draw now."""
        from .render import View

        v = View(targets_deg=self._targets, on_tactor=self._on_tactor,
                 tactors_deg=self._tactors, home_radius=self._home_radius)
        v.cursor = self._cursor_pos()
        go_on, move = self._input_words()
        cur = None if self.task_alone else self.current
        block = cur.trial.block if cur is not None else self.block
        # status line (participant-facing)
        if block == "training":
            v.status_left = "Training"
        elif block == "test":
            k = max(self._test_blocks_seen, 1)
            n = len(self.info.condition_order) if self.info is not None else k
            v.status_left = f"Test block {k} of {max(n, k)}"
        if cur is not None:
            v.status_right = f"Trial {cur.trial.trial_index + 1} of {self.n_total}"
        # the trial
        if cur is not None and self.screen == "trial":
            phase = cur.phase
            training = cur.trial.block == "training"
            x, y = v.cursor if v.cursor is not None else (0.0, 0.0)
            at_home = x * x + y * y <= self._home_radius ** 2
            if phase == "home":
                v.home_state = "ok" if at_home else "wait"
                v.prompt = "" if at_home else "Return to the centre"
            elif phase == "stimulus":
                if training:
                    v.highlight_deg = cur.trial.target_deg
                    v.prompt = "Move to the highlighted target"
                else:
                    v.prompt = "Move to where you feel the vibration"
            elif phase in ("response", "timeout", "iti"):
                r = self.last_result
                if training and r is not None and r.trial is cur.trial:
                    v.highlight_deg = cur.trial.target_deg
                    if r.status == "done" and r.response_target_deg is not None:
                        v.chosen_deg = r.response_target_deg
                        v.chosen_correct = bool(r.correct)
                        v.prompt = ("Correct" if r.correct else
                                    "Not quite: the highlighted target was the answer")
                    else:
                        v.prompt = "Too slow: no answer"
                v.home_state = "idle" if at_home else "wait"
        # the secondary task
        v.glyph = self.tasks.glyph_at(now_ns)
        task_phase = self.tasks.phase
        if self.task_alone and self.screen == "trial":
            v.status_left = "Practice" if task_phase == "practice" else "The task alone"
            button = self.tasks.response
            spec = self.tasks.spec
            if button is not None and spec is not None:
                from ..tasks.kinds import task_kind

                v.prompt = task_kind(spec.kind).prompt(spec, button.words())
            said = self.tasks.feedback(now_ns)
            if said is not None:
                v.prompt = said
        # modal screens
        v.modal_title, v.modal_lines = self._modal_for(go_on, move)
        if self.user_paused or self.device_paused:
            v.modal_title, v.modal_lines = self._pause_text()
        # experimenter overlay
        v.overlay = self.overlay
        if self.overlay:
            v.overlay_lines = self._overlay_lines(now_ns)
            v.levels = self._levels(now_ns)
        if self._banner is not None and now_ns <= self._banner_until_ns:
            v.banner = self._banner
        elif self.device_paused:
            v.banner = None
        v.screen = self.screen
        return v

    def _modal_for(self, go_on: str, move: str) -> tuple[str | None, list[str]]:
        s = self.screen
        if s == "instructions":
            lines = [
                "You will feel a vibration around your waist. Show where it is.",
                "The ellipse is your torso seen from above; the top is your front.",
                f"{move} from the centre to the target where you feel it,",
                "then back to the centre.",
                "",
            ]
            if self._training_left():
                lines += ["First, training: the target lights up while you feel it,",
                          "and you see whether your answer was right.",
                          "Then the test, without feedback.", ""]
            if self.info is not None and self.info.resumed:
                lines += [f"Resuming: {self.info.n_done} of {self.info.n_total} trials "
                          "already done.", ""]
            lines.append(f"When you are ready, {go_on}.")
            return "Instructions", lines
        if s == "block":
            k = self._test_blocks_seen
            n = len(self.info.condition_order) if self.info is not None else k
            extra: list[str] = []
            if self._block_task is not None:
                from .taskview import block_lines, parse_response

                name, spec = self._block_task
                extra = [*block_lines(name, spec, parse_response(spec.response).words()), ""]
                if self._block_note:
                    extra = [self._block_note, "", *extra]
            return f"Test block {k} of {max(n, k)}", [
                "No feedback from now on: answer as well as you can.", "", *extra,
                f"When you are ready, {go_on}."]
        if s == "task" and self._task_intro is not None:
            return self._task_intro
        if s == "wait" and self._wait_text is not None:
            return self._wait_text
        if s == "break":
            return "Break", [f"{self.n_done} of {self.n_total} trials done.",
                             "Take a rest.", "", f"When you are ready, {go_on}."]
        if s == "end":
            status = self.end_status or "complete"
            if status == "complete":
                return "Thank you!", ["The session is complete.", "",
                                      "Press Space or Esc to close."]
            return "Session stopped", [
                f"{self.n_done} of {self.n_total} trials done; the session is saved.",
                "The experimenter can resume it later (--resume).", "",
                "Press Space or Esc to close."]
        return None, []

    def _training_left(self) -> bool:
        """Whether training trials remain (a resumed session may be past them)."""
        if self.study.training.passes <= 0:
            return False
        if self.info is None or not self.info.resumed:
            return True
        return self.study.n_training_trials() > self.info.n_done

    def _pause_text(self) -> tuple[str, list[str]]:
        if self.device_paused:
            live = self._live
            want = live.describe_wanted() if live is not None else "the joystick"
            lines = [f"Waiting for {want}: plug it back in.",
                     "The session goes on by itself when it is back."]
            problem = live.problem if live is not None else None
            if problem:
                lines.append(str(problem))
            lines += ["", "Esc twice: stop the session (saved, can be resumed)."]
            return "Joystick disconnected", lines
        return "Paused", ["The motors are off.", "",
                          "P or R: resume    Esc twice or Ctrl-Q: stop (saved, resumable)"]

    def _overlay_lines(self, now_ns: int) -> list[str]:
        lines = []
        info = self.info
        sid = f"session {info.session_id}" if info is not None else "no session yet"
        lines.append(f"participant {self.participant or '?'}  {sid}  done "
                     f"{self.n_done}/{self.n_total}")
        cur = self.current
        if cur is not None:
            t = cur.trial
            lines.append(f"trial {t.trial_index + 1} (index {t.trial_index})  block "
                         f"{t.block_name} ({t.block})  condition {t.condition}  rep "
                         f"{t.repetition}")
            where = "on-tactor" if t.on_tactor else "between-tactor"
            dt = (f"  t {(now_ns - cur.onset_ns) / 1e9:5.2f} s" if cur.onset_ns is not None
                  and cur.phase == "stimulus" else "")
            lines.append(f"target {t.target_deg:g} deg ({where})  state {cur.phase}{dt}")
        r = self.last_result
        if r is not None:
            if r.status == "done":
                lines.append(f"last: answer {r.response_target_deg:g} deg ("
                             f"{'correct' if r.correct else 'wrong'}), RT {r.rt_s:.3f} s")
            else:
                lines.append(f"last: {r.status}"
                             + (f" ({r.abort_reason})" if r.abort_reason else ""))
        tasks = self.tasks
        if tasks.running and tasks.spec is not None:
            audio = tasks.audio
            late = len(audio.late) if audio is not None else 0
            shown = [(item, onset) for item, onset in tasks.items[-4:] if onset <= now_ns]
            last = ""
            if shown:
                item, _ = shown[-1]
                last = f", last item {item.stimulus}{' (go)' if item.target else ''}"
            lines.append(f"task {tasks.name} ({tasks.phase}): {len(tasks.items)} items so far"
                         f"{last}, response {tasks.spec.response}"
                         + (f", {late} sounds late" if late else ""))
        live = self._live
        x, y = self._cursor_pos() or (0.0, 0.0)
        name = live.name if live is not None else None
        raw = live.raw_axes if live is not None else None
        desc = f"input {self.input_kind}" + (f" '{name}'" if name else "")
        if raw is not None:
            desc += f"  raw ({raw[0]:+.2f}, {raw[1]:+.2f})"
        lines.append(f"{desc}  cursor ({x:+.2f}, {y:+.2f})")
        times = list(self._sample_times)
        if len(times) >= 3:
            period = 1e9 / self.study.session.sample_rate_hz
            err = max(abs((b - a) - period) for a, b in itertools.pairwise(times))
            lines.append(f"samples this trial {len(times)}, worst interval error "
                         f"{err / 1e6:.2f} ms")
        lines.append("P pause  R resume  Esc Esc / Ctrl-Q abort  F1/Tab overlay  F12 shot")
        return lines

    def _levels(self, now_ns: int) -> Any:
        """Live amplitude per tactor: the belt's levels when it has them, else computed."""
        lv = self.belt.levels if self.belt is not None else None
        if lv is not None:
            return lv
        cur = self.current
        if cur is None or cur.phase != "stimulus" or cur.onset_ns is None:
            return [0.0] * len(self._tactors)
        sp = self.study.trial_stimulus(cur.trial.block_name)
        key = (cur.trial.target_deg, cur.trial.condition, sp.law, sp.falloff_deg,
               sp.period_s, sp.transit_s)
        stim = self._stimuli.get(key)
        if stim is None:
            from ..stimuli import make_stimulus

            stim = make_stimulus(self._layout, cur.trial.target_deg, cur.trial.condition,
                                 sp.law, sp.falloff_deg, sp.period_s, sp.transit_s)
            self._stimuli[key] = stim
        return stim.amplitudes((now_ns - cur.onset_ns) / 1e9)

    # ------------------------------------------------------------------------------------
    # screenshots
    def _save_frame(self, kind: str, surface: Any = None) -> Path | None:
        folder = self.screenshot_dir or Path.cwd()
        path = folder / f"window-{kind}.png"
        try:
            self._pg.image.save(surface if surface is not None else self.surface, str(path))
        except (self._pg.error, OSError) as exc:
            raise TactorbeltError(f"cannot save the screenshot {path}: {exc}") from None
        self.saved[kind] = path
        return path

    def _screenshots(self, kind: str, view: View) -> None:
        if kind in self.saved:
            return
        x, y = view.cursor if view.cursor is not None else (0.0, 0.0)
        moving = math.hypot(x, y) >= 0.5
        if kind in ("training", "test") and not moving:
            return
        cur = self.current
        if (kind == "test" and cur is not None and cur.trial.on_tactor
                and not all(self._on_tactor)):
            return  # show a between-tactor trial: two tactors at work in the overlay
        if kind == "test" and self.overlay:
            kind = "overlay"
            if kind in self.saved:
                return
        self._save_frame(kind)
        if kind == "test":
            # the overlay and the pause screen over the same trial, drawn off screen
            self._extra("overlay", view, overlay=True)
            self._extra("pause", view, pause=True)

    def _extra(self, kind: str, view: View, overlay: bool = False, pause: bool = False) -> None:
        if kind in self.saved:
            return
        import copy

        v = copy.copy(view)
        if overlay:
            now = self.clock.now_ns()
            v.overlay = True
            v.overlay_lines = self._overlay_lines(now)
            v.levels = self._levels(now)
        if pause:
            v.modal_title, v.modal_lines = "Paused", [
                "The motors are off.", "",
                "P or R: resume    Esc twice or Ctrl-Q: stop (saved, resumable)"]
        surf = self._pg.Surface(self.surface.get_size())
        self.renderer.draw(surf, v)
        self._save_frame(kind, surf)

    def save_screen(self, kind: str) -> Path | None:
        """Draw a waiting screen (``break``, ``instructions``, ...) off screen and save it."""
        prev = self.screen
        self.screen = kind
        try:
            v = self.view(self.clock.now_ns())
            surf = self._pg.Surface(self.surface.get_size())
            self.renderer.draw(surf, v)
            return self._save_frame(kind, surf)
        finally:
            self.screen = prev

    def close(self) -> None:
        """Close the window (motors off and the task sound output closed first)."""
        self._motors_off()
        with contextlib.suppress(Exception):
            self.tasks.close()
        live = self._live
        if live is not None:
            live.attach_refresh(None)
        with contextlib.suppress(Exception):
            self._pg.display.quit()


# ----------------------------------------------------------------------------------------
class SessionWindow:
    """The window of one session, as ``tactorbelt run`` uses it (a context manager).

    ``with session_window(study, input="joystick", clock=clock) as win:`` opens the
    window; ``win.cursor`` is the joystick or mouse source it feeds (None for the model
    or a scripted cursor, which the caller passes to the runner itself);
    ``win.observer`` goes to ``run_session(observer=...)``; ``win.run(fn)`` calls
    ``fn()`` (which runs the session) in this thread, the main thread, then shows the
    end screen, and returns ``fn``'s result. Leaving the block closes the window
    (motors off first, when the window has the belt).
    """

    def __init__(self, window: ExperimentWindow, cursor: CursorSource | None) -> None:
        self.window = window
        self.cursor = cursor

    @property
    def observer(self) -> ExperimentWindow:
        return self.window

    def run(self, fn: Callable[[], Any]) -> Any:
        """Run the session (``fn``) in this thread, then show the end screen."""
        result = fn()
        status = getattr(result, "status", None)
        self.window.show_end(status)
        w = self.window
        if w.screenshot_dir is not None and "break" not in w.saved:
            w.save_screen("break")
        return result

    def __enter__(self) -> SessionWindow:
        return self

    def __exit__(self, *exc: object) -> None:
        self.window.close()


def session_window(
    study: Study,
    *,
    input: str = "joystick",
    participant: str = "",
    clock: Clock | None = None,
    belt: Belt | None = None,
    fullscreen: bool = False,
    screenshot_dir: str | Path | None = None,
    joystick: JoystickConfig | int | str | None = None,
    cursor: CursorSource | None = None,
    seed: int | None = None,
    size: tuple[int, int] = (1280, 800),
    fps: float = 60.0,
    auto_continue_s: float | None = None,
    on_frame: FrameHook | None = None,
) -> SessionWindow:
    """Open the experiment window for one session (call in the main thread).

    Args:
        study: the study.
        input: ``joystick`` or ``mouse`` (the window makes and feeds the source:
            ``win.cursor``), or ``model`` / ``scripted`` (the caller's source; the
            window shows the samples the runner reports).
        participant: shown in the experimenter overlay.
        clock: the runner's clock (default: the wall clock).
        belt: the belt, optional (motors off at the key press, live levels in the
            overlay).
        fullscreen, screenshot_dir, size, fps, auto_continue_s, on_frame: see
            :class:`ExperimentWindow`. ``auto_continue_s`` defaults to 2 s for
            ``model`` and ``scripted`` (nobody presses a key), else None (wait).
        joystick: which stick (index, name substring) or a full JoystickConfig.
        cursor: a ready source to show and feed (e.g. a JoystickCursor on a test
            backend) instead of the one ``input`` makes.
        seed: unused (the model participant is made by the caller with
            :func:`tactorbelt.inputs.make_cursor`).
    """
    if clock is None:
        from ..clock import WallClock

        clock = WallClock()
    if input not in ("joystick", "mouse", "model", "scripted"):
        raise ConfigError(f"unknown input {input!r}; allowed: joystick, mouse, model, scripted")
    if auto_continue_s is None and input in ("model", "scripted"):
        auto_continue_s = 2.0
    window = ExperimentWindow(study, clock, belt=belt, input_kind=input,
                              participant=participant, fullscreen=fullscreen, size=size,
                              fps=fps, screenshot_dir=screenshot_dir,
                              auto_continue_s=auto_continue_s, on_frame=on_frame)
    try:
        if cursor is None and input in ("joystick", "mouse"):
            cursor = make_cursor(input, study=study, participant=participant, seed=seed,
                                 geometry=window.renderer.geometry, joystick=joystick)
        if cursor is not None:
            window.attach_cursor(cursor)
    except BaseException:
        window.close()
        raise
    return SessionWindow(window, cursor)


def run_with_window(
    study: Study,
    participant: str,
    belt: Belt,
    cursor_kind: str,
    store: Store,
    *,
    clock: Clock | None = None,
    cursor: CursorSource | None = None,
    fullscreen: bool = False,
    screenshot_dir: str | Path | None = None,
    realtime: bool = True,
    seed: int | None = None,
    resume: bool = False,
    limit: int | None = None,
    joystick: JoystickConfig | int | str | None = None,
    study_toml: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    size: tuple[int, int] = (1280, 800),
    fps: float = 60.0,
    auto_continue_s: float | None = None,
    on_frame: FrameHook | None = None,
) -> SessionResult:
    """Run one session in the experiment window (main thread; returns when it closes).

    Args:
        study: the study.
        participant: the participant id.
        belt: an open belt with the study's layout (the caller closes it).
        cursor_kind: ``joystick``, ``mouse`` or ``model`` (or any name, e.g.
            ``scripted``, when ``cursor`` is given).
        store: an open, writable store.
        clock: the clock (default: the sim belt's own clock when it has one, else the
            wall clock; with ``realtime=False`` and no simulated belt clock, a SimClock).
        cursor: a ready cursor source (instead of the one ``cursor_kind`` makes).
        fullscreen: full screen at the desktop's size.
        screenshot_dir: save ``window-<kind>.png`` for each kind of screen there.
        realtime: pace the session on the wall clock (the model participant moves the
            cursor on screen at human speed).
        seed, resume, limit, study_toml, progress: passed to ``run_session``.
        joystick: which stick (index or name substring) or a full JoystickConfig.
        size, fps: window size and frame rate.
        auto_continue_s: leave waiting screens by themselves after this many seconds
            (default: 2 s for the model participant or a given cursor, else wait for
            the participant).
        on_frame: ``on_frame(window, kind)`` after each frame (tests).

    Returns:
        The runner's :class:`~tactorbelt.experiment.runner.SessionResult`.

    Raises:
        ConfigError: no display, an unknown input.
        DeviceError, StoreError: as ``run_session``.
    """
    from ..experiment.runner import run_session

    if clock is None:
        own = belt.clock
        if own is not None and (realtime or own.simulated):
            clock = own
        elif realtime:
            from ..clock import WallClock

            clock = WallClock()
        else:
            from ..clock import SimClock

            clock = SimClock()
    assert clock is not None
    if auto_continue_s is None and (cursor is not None or cursor_kind == "model"):
        auto_continue_s = 2.0
    with session_window(study, input=cursor_kind, participant=participant, clock=clock,
                        belt=belt, fullscreen=fullscreen, screenshot_dir=screenshot_dir,
                        joystick=joystick, cursor=cursor, size=size, fps=fps,
                        auto_continue_s=auto_continue_s, on_frame=on_frame) as win:
        src = win.cursor
        if src is None:
            from ..experiment.schedule import make_schedule

            answers = (make_schedule(study, participant,
                                     study.session.seed if seed is None else int(seed))
                       if cursor_kind == "scripted" else None)
            src = make_cursor(cursor_kind, study=study, belt=belt, clock=clock,
                              participant=participant, seed=seed, schedule=answers)
            win.window.attach_cursor(src)
        clk = clock

        def go() -> SessionResult:
            return run_session(study, participant, belt, src, store, clk, seed=seed,
                               resume=resume, limit=limit, observer=win.observer,
                               progress=progress, study_toml=study_toml,
                               input_name=cursor_kind)

        result: SessionResult = win.run(go)
        return result
