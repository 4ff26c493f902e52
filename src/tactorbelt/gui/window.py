"""The experiment window: a view of a running session and the participant's input.

:class:`ExperimentWindow` is a listener and the operator of a session (a
:class:`~tactorbelt.experiment.listeners.SessionObserver`).
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

The parts: :mod:`tactorbelt.gui.controller` (the state, the observer hooks, the keys
and the waits), :mod:`tactorbelt.gui.screens` (what each kind of screen shows), and
here the display (the pygame window, a frame drawn, screenshots) and the session's
entry points.

I/O: imports pygame (after :func:`tactorbelt.inputs.joystick.prepare_sdl`), the
runner's observer types, inputs and tactorbelt.gui.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError, TactorbeltError
from ..clock import Clock, SimClock, WallClock
from ..inputs import make_cursor
from ..inputs.base import CursorSource
from ..inputs.kinds import JoystickConfig, input_kind
from ..tasks.audio import DEVICE_ENV, open_task_audio
from . import screens
from .controller import WindowController
from .screens import SCREEN_KINDS, TASK_SCREEN_KINDS
from .taskview import check_responses

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..experiment.runner import SessionResult
    from ..experiment.store import Store
    from ..experiment.study import Study
    from .render import View

__all__ = ["SCREEN_KINDS", "TASK_SCREEN_KINDS", "ExperimentWindow", "SessionWindow",
           "run_with_window", "session_window"]

FrameHook = Callable[["ExperimentWindow", str], None]

log = logging.getLogger("tactorbelt.gui")


class ExperimentWindow(WindowController):
    """The pygame window of a session; pass it to ``run_session`` as ``observer``.

    Create it in the main thread; it opens the display at once. The state, the hooks,
    the keys and the waits are :class:`~tactorbelt.gui.controller.WindowController`'s;
    this class adds the display: frames drawn from :mod:`tactorbelt.gui.screens`, and
    screenshots.

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
        super().__init__(study, clock, belt=belt, input_kind=input_kind,
                         participant=participant, fps=fps, auto_continue_s=auto_continue_s)
        from .render import Renderer

        pygame = self._pg
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
        if self.input.stick:
            pygame.mouse.set_visible(False)  # the participant looks at the cursor only
        self.renderer = Renderer(self.surface.get_size())
        self.frames = 0
        self._levels = screens.TactorLevels()
        try:
            self._open_task_audio()
        except BaseException:
            self.close()
            raise

    def _open_task_audio(self) -> None:
        """Check the tasks' buttons; open the sound output now when a task is auditory
        (a sound card that cannot be opened stops the run before the session starts)."""
        check_responses(self.study)
        if any(t.active and t.modality == "auditory" for t in self.study.tasks.values()):
            self.tasks.audio = open_task_audio(self.clock)
            belt = self.belt
            if (belt is not None and belt.uses_sound_output
                    and self.tasks.audio.plays_sound and not os.environ.get(DEVICE_ENV)):
                log.warning("the task sounds play on SDL's default output: make sure it is "
                            "not the sound card that drives the tactors of %s (name the "
                            "headphones' output in $%s)", belt.url, DEVICE_ENV)

    def attach_cursor(self, cursor: CursorSource) -> None:
        """Use ``cursor``: live sources (joystick, mouse) are fed by this window."""
        self.cursor = cursor
        live = cursor.live_input()
        if live is not None:
            live.geometry = self.renderer.geometry
            live.attach_refresh(self._refresh_live)

    def _relayout(self) -> None:
        surface = self._pg.display.get_surface()
        if surface is not None:
            self.surface = surface
        self.renderer.resize(self.surface.get_size(), overlay=self.overlay)
        live = self.live
        if live is not None:
            live.geometry = self.renderer.geometry

    # ------------------------------------------------------------------------------------
    # drawing
    def view(self, now_ns: int) -> View:
        """What to draw now."""
        return screens.compose(self, now_ns, self._levels)

    def draw(self, now_ns: int | None = None) -> str:
        """Draw one frame now; return its kind."""
        now = self.clock.now_ns() if now_ns is None else now_ns
        view = self.view(now)
        screens.draw(self.surface, self.renderer, view, self._tlx)
        self._pg.display.flip()
        self.tasks.drawn(now)
        self.frames += 1
        kind = screens.screen_kind(self, view)
        if self.screenshot_dir is not None:
            self._screenshots(kind, view)
        if self.on_frame is not None:
            self.on_frame(self, kind)
        return kind

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

    def _manual_shot(self) -> None:
        self._save_frame(f"manual-{self.frames}")

    def _screenshots(self, kind: str, view: View) -> None:
        shot = screens.screenshot_kind(self, view, kind, self.saved)
        if shot is None:
            return
        self._save_frame(shot)
        if shot == "test":
            # the overlay and the pause screen over the same trial, drawn off screen
            if "overlay" not in self.saved:
                self._save_off_screen(
                    "overlay",
                    screens.with_overlay(view, self, self.clock.now_ns(), self._levels))
            if "pause" not in self.saved:
                self._save_off_screen("pause", screens.with_pause(view))

    def _save_off_screen(self, kind: str, view: View) -> Path | None:
        surf = self._pg.Surface(self.surface.get_size())
        self.renderer.draw(surf, view)
        return self._save_frame(kind, surf)

    def save_screen(self, kind: str) -> Path | None:
        """Draw a waiting screen (``break``, ``instructions``, ...) off screen and save it."""
        prev = self.screen
        self.screen = kind
        try:
            return self._save_off_screen(kind, self.view(self.clock.now_ns()))
        finally:
            self.screen = prev

    def close(self) -> None:
        """Close the window (motors off and the task sound output closed first)."""
        super().close()
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
    """
    if clock is None:
        clock = WallClock()
    kind = input_kind(input)
    if auto_continue_s is None and not kind.live:  # nobody presses a key
        auto_continue_s = 2.0
    window = ExperimentWindow(study, clock, belt=belt, input_kind=input,
                              participant=participant, fullscreen=fullscreen, size=size,
                              fps=fps, screenshot_dir=screenshot_dir,
                              auto_continue_s=auto_continue_s, on_frame=on_frame)
    try:
        if cursor is None and kind.display:  # the window makes and feeds it
            cursor = make_cursor(input, study=study, participant=participant,
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
        else:
            clock = WallClock() if realtime else SimClock()
    if auto_continue_s is None and (cursor is not None or not input_kind(cursor_kind).live):
        auto_continue_s = 2.0
    with session_window(study, input=cursor_kind, participant=participant, clock=clock,
                        belt=belt, fullscreen=fullscreen, screenshot_dir=screenshot_dir,
                        joystick=joystick, cursor=cursor, size=size, fps=fps,
                        auto_continue_s=auto_continue_s, on_frame=on_frame) as win:
        src = win.cursor
        if src is None:
            from ..experiment.recorder import SessionRecorder

            answers = SessionRecorder.schedule_for(study, participant, seed)[0]  # scripted's
            src = make_cursor(cursor_kind, study=study, belt=belt, clock=clock,
                              participant=participant, seed=seed, schedule=answers)
            win.window.attach_cursor(src)
        result: SessionResult = win.run(functools.partial(
            run_session, study, participant, belt, src, store, clock, seed=seed, resume=resume,
            limit=limit, observer=win.observer, progress=progress, study_toml=study_toml,
            input_name=cursor_kind))
        return result
