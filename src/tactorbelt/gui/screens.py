"""The screens of the experiment window: what each kind of screen shows.

One function per kind of screen fills a :class:`~tactorbelt.gui.render.View` from the
window's state (read only, a :class:`~tactorbelt.gui.controller.WindowController`): the
trial (training with its highlight and feedback, the test), the task alone, the waiting
screens (instructions, block start, a task's instructions, break, end, ``show_wait``'s
text), pause, and the experimenter overlay. :func:`compose` puts one frame's view together,
:func:`draw` draws it (:class:`~tactorbelt.gui.render.Renderer`, or the NASA-TLX's
:class:`~tactorbelt.gui.tlx.TlxScreen`), and :func:`screen_kind` names it
(:data:`SCREEN_KINDS`, :data:`TASK_SCREEN_KINDS`) for screenshots and ``on_frame``.

Nothing here changes the window's state; the task presenter advances its glyphs and its
practice feedback to the time of the frame, as it did before the split. The
participant's words for each input are the input kind's (:mod:`tactorbelt.inputs.kinds`).

Pure text and layout (with the stimuli and the task presenter); :func:`compose` and
:func:`draw` import tactorbelt.gui.render (pygame) on use.
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
from collections.abc import Callable, Container
from typing import TYPE_CHECKING, Any

from ..stimuli import make_stimulus
from ..tasks.kinds import task_kind
from .taskview import block_lines
from .taskview import instructions as task_instructions

if TYPE_CHECKING:
    from .controller import ShownTrial, WindowController
    from .render import Renderer, View
    from .tlx import TlxScreen

__all__ = [
    "SCREEN_KINDS",
    "TASK_SCREEN_KINDS",
    "WAIT_KINDS",
    "TactorLevels",
    "compose",
    "draw",
    "overlay_lines",
    "screen_kind",
    "screenshot_kind",
    "with_overlay",
    "with_pause",
]

#: Kinds of screen passed to ``on_frame`` and saved by ``screenshot_dir``.
SCREEN_KINDS = ("instructions", "block", "training", "feedback", "test", "overlay", "break",
                "pause", "end")
#: Kinds of screen of a study with secondary tasks or the NASA-TLX: a task's instructions,
#: the task alone (practice, baseline), the TLX sliders.
TASK_SCREEN_KINDS = ("task", "task_alone", "tlx")
#: Waiting screens (the participant goes on from them).
WAIT_KINDS = ("instructions", "block", "break", "end", "task")

Modal = tuple[str | None, list[str]]


def cursor_position(s: WindowController) -> tuple[float, float] | None:
    """Where the cursor is drawn: the live input's state, else the last sample."""
    live = s.live
    if live is not None:
        x, y, _ = live.state
        return (x, y)
    if not s.task_alone and s.current is not None and s.last_sample is not None:
        return (s.last_sample.x, s.last_sample.y)
    return (0.0, 0.0)


# ----------------------------------------------------------------------------------------
# one frame
def compose(s: WindowController, now_ns: int, levels: TactorLevels) -> View:
    """What to draw at ``now_ns``."""
    from .render import View

    v = View(targets_deg=s.targets_deg, on_tactor=s.on_tactor,
             tactors_deg=s.tactors_deg, home_radius=s.home_radius)
    v.cursor = cursor_position(s)
    go_on, move = s.input.go_on, s.input.move
    cur = None if s.task_alone else s.current
    _status(v, s, cur)
    if cur is not None and s.screen == "trial":
        trial(v, s, cur)
    v.glyph = s.tasks.glyph_at(now_ns)
    if s.task_alone and s.screen == "trial":
        task_alone(v, s, now_ns)
    modal = MODALS.get(s.screen)
    v.modal_title, v.modal_lines = modal(s, go_on, move) if modal is not None else (None, [])
    if s.user_paused or s.device_paused:
        v.modal_title, v.modal_lines = pause(s)
    if s.overlay:
        v = with_overlay(v, s, now_ns, levels)
    if s.banner is not None and now_ns <= s.banner_until_ns:
        v.banner = s.banner
    elif s.device_paused:
        v.banner = None
    v.screen = s.screen
    return v


def draw(surface: Any, renderer: Renderer, view: View, tlx: TlxScreen | None) -> None:
    """Draw ``view`` on ``surface``; the NASA-TLX's sliders instead while they are up
    (and no pause covers them)."""
    if tlx is not None and view.modal_title is None:
        from .render import COLORS

        tlx.draw(surface, renderer, COLORS)
    else:
        renderer.draw(surface, view)


def screen_kind(s: WindowController, view: View) -> str:
    """The kind of screen a view shows (for screenshots and ``on_frame``)."""
    if (s.user_paused or s.device_paused) and s.screen not in WAIT_KINDS:
        return "pause"
    if s.screen in WAIT_KINDS or s.screen in ("tlx", "wait"):
        return s.screen
    if s.task_alone:
        return "task_alone"
    cur = s.current
    if cur is not None and cur.trial.block == "training":
        return "feedback" if view.chosen_deg is not None else "training"
    return "test"


def _status(v: View, s: WindowController, cur: ShownTrial | None) -> None:
    """The participant's status line: the block, the trial."""
    block = cur.trial.block if cur is not None else s.block
    if block == "training":
        v.status_left = "Training"
    elif block == "test":
        k = max(s.test_blocks_seen, 1)
        n = len(s.info.condition_order) if s.info is not None else k
        v.status_left = f"Test block {k} of {max(n, k)}"
    if cur is not None:
        v.status_right = f"Trial {cur.trial.trial_index + 1} of {s.n_total}"


# ----------------------------------------------------------------------------------------
# the trial screens: training, feedback, test; the task alone
def trial(v: View, s: WindowController, cur: ShownTrial) -> None:
    """The trial: home zone, the stimulus (training: its target highlighted), and in
    training the feedback on the answer."""
    phase = cur.phase
    training = cur.trial.block == "training"
    x, y = v.cursor if v.cursor is not None else (0.0, 0.0)
    at_home = x * x + y * y <= s.home_radius ** 2
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
        r = s.last_result
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


def task_alone(v: View, s: WindowController, now_ns: int) -> None:
    """A practice or baseline run of the task: its rule, then the practice feedback."""
    tasks = s.tasks
    v.status_left = "Practice" if tasks.phase == "practice" else "The task alone"
    button = tasks.response
    spec = tasks.spec
    if button is not None and spec is not None:
        v.prompt = task_kind(spec.kind).prompt(spec, button.words())
    said = tasks.feedback(now_ns)
    if said is not None:
        v.prompt = said


# ----------------------------------------------------------------------------------------
# the waiting screens (a box over the dimmed scene)
def instructions(s: WindowController, go_on: str, move: str) -> Modal:
    lines = [
        "You will feel a vibration around your waist. Show where it is.",
        "The ellipse is your torso seen from above; the top is your front.",
        f"{move} from the centre to the target where you feel it,",
        "then back to the centre.",
        "",
    ]
    if _training_left(s):
        lines += ["First, training: the target lights up while you feel it,",
                  "and you see whether your answer was right.",
                  "Then the test, without feedback.", ""]
    if s.info is not None and s.info.resumed:
        lines += [f"Resuming: {s.info.n_done} of {s.info.n_total} trials "
                  "already done.", ""]
    lines.append(f"When you are ready, {go_on}.")
    return "Instructions", lines


def _training_left(s: WindowController) -> bool:
    """Whether training trials remain (a resumed session may be past them)."""
    if s.study.training.passes <= 0:
        return False
    if s.info is None or not s.info.resumed:
        return True
    return s.study.n_training_trials() > s.info.n_done


def block(s: WindowController, go_on: str, move: str) -> Modal:
    k = s.test_blocks_seen
    n = len(s.info.condition_order) if s.info is not None else k
    extra: list[str] = []
    if s.block_task is not None:
        extra = [*block_lines(s.block_task[1]), ""]
        if s.block_note:
            extra = [s.block_note, "", *extra]
    return f"Test block {k} of {max(n, k)}", [
        "No feedback from now on: answer as well as you can.", "", *extra,
        f"When you are ready, {go_on}."]


def task(s: WindowController, go_on: str, move: str) -> Modal:
    """A task's instructions before its practice or baseline run."""
    if s.task_intro is None:
        return None, []
    _, spec, phase, note = s.task_intro
    title, lines = task_instructions(spec, phase, go_on)
    return title, [note, "", *lines] if note else lines


def wait(s: WindowController, go_on: str, move: str) -> Modal:
    """``show_wait``'s title and lines."""
    if s.wait_text is None:
        return None, []
    return s.wait_text


def break_(s: WindowController, go_on: str, move: str) -> Modal:
    return "Break", [f"{s.n_done} of {s.n_total} trials done.",
                     "Take a rest.", "", f"When you are ready, {go_on}."]


def end(s: WindowController, go_on: str, move: str) -> Modal:
    status = s.end_status or "complete"
    if status == "complete":
        return "Thank you!", ["The session is complete.", "",
                              "Press Space or Esc to close."]
    return "Session stopped", [
        f"{s.n_done} of {s.n_total} trials done; the session is saved.",
        "The experimenter can resume it later (--resume).", "",
        "Press Space or Esc to close."]


#: The box of each waiting screen: ``modal(state, go_on, move)``.
MODALS: dict[str, Callable[[WindowController, str, str], Modal]] = {
    "instructions": instructions, "block": block, "task": task, "wait": wait,
    "break": break_, "end": end,
}


def paused() -> tuple[str, list[str]]:
    """The experimenter's pause."""
    return "Paused", ["The motors are off.", "",
                      "P or R: resume    Esc twice or Ctrl-Q: stop (saved, resumable)"]


def pause(s: WindowController) -> tuple[str, list[str]]:
    """The pause box: the experimenter's, or the joystick's gone."""
    if s.device_paused:
        live = s.live
        want = live.describe_wanted() if live is not None else "the joystick"
        lines = [f"Waiting for {want}: plug it back in.",
                 "The session goes on by itself when it is back."]
        problem = live.problem if live is not None else None
        if problem:
            lines.append(str(problem))
        lines += ["", "Esc twice: stop the session (saved, can be resumed)."]
        return "Joystick disconnected", lines
    return paused()


# ----------------------------------------------------------------------------------------
# the experimenter overlay
def overlay_lines(s: WindowController, now_ns: int) -> list[str]:
    """The overlay panel's text: participant, session, trial, last answer, task, input,
    sampling."""
    lines = []
    info = s.info
    sid = f"session {info.session_id}" if info is not None else "no session yet"
    lines.append(f"participant {s.participant or '?'}  {sid}  done "
                 f"{s.n_done}/{s.n_total}")
    cur = s.current
    if cur is not None:
        t = cur.trial
        lines.append(f"trial {t.trial_index + 1} (index {t.trial_index})  block "
                     f"{t.block_name} ({t.block})  condition {t.condition}  rep "
                     f"{t.repetition}")
        where = "on-tactor" if t.on_tactor else "between-tactor"
        dt = (f"  t {(now_ns - cur.onset_ns) / 1e9:5.2f} s" if cur.onset_ns is not None
              and cur.phase == "stimulus" else "")
        lines.append(f"target {t.target_deg:g} deg ({where})  state {cur.phase}{dt}")
    r = s.last_result
    if r is not None:
        if r.status == "done":
            lines.append(f"last: answer {r.response_target_deg:g} deg ("
                         f"{'correct' if r.correct else 'wrong'}), RT {r.rt_s:.3f} s")
        else:
            lines.append(f"last: {r.status}"
                         + (f" ({r.abort_reason})" if r.abort_reason else ""))
    tasks = s.tasks
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
    live = s.live
    x, y = cursor_position(s) or (0.0, 0.0)
    name = live.name if live is not None else None
    raw = live.raw_axes if live is not None else None
    desc = f"input {s.input_kind}" + (f" '{name}'" if name else "")
    if raw is not None:
        desc += f"  raw ({raw[0]:+.2f}, {raw[1]:+.2f})"
    lines.append(f"{desc}  cursor ({x:+.2f}, {y:+.2f})")
    times = list(s.sample_times)
    if len(times) >= 3:
        period = 1e9 / s.study.session.sample_rate_hz
        err = max(abs((b - a) - period) for a, b in itertools.pairwise(times))
        lines.append(f"samples this trial {len(times)}, worst interval error "
                     f"{err / 1e6:.2f} ms")
    lines.append("P pause  R resume  Esc Esc / Ctrl-Q abort  F1/Tab overlay  F12 shot")
    return lines


class TactorLevels:
    """Live amplitude per tactor for the overlay: the belt's ``levels`` when it has
    them (the sim belt), else computed from the trial's stimulus (kept per stimulus)."""

    def __init__(self) -> None:
        self._stimulus = functools.cache(make_stimulus)

    def __call__(self, s: WindowController, now_ns: int) -> Any:
        lv = s.belt.levels if s.belt is not None else None
        if lv is not None:
            return lv
        cur = s.current
        if cur is None or cur.phase != "stimulus" or cur.onset_ns is None:
            return [0.0] * len(s.tactors_deg)
        sp = s.study.trial_stimulus(cur.trial.block_name)
        stim = self._stimulus(s.layout, cur.trial.target_deg, cur.trial.condition, sp.law,
                              sp.falloff_deg, sp.period_s, sp.transit_s)
        return stim.amplitudes((now_ns - cur.onset_ns) / 1e9)


# ----------------------------------------------------------------------------------------
# screenshots: which frames show a kind of screen well
def screenshot_kind(s: WindowController, view: View, kind: str, saved: Container[str]
                    ) -> str | None:
    """The kind to save this frame as, or None: each kind once; a trial once the cursor
    moves; the test on a between-tactor trial (two tactors at work in the overlay), as
    ``overlay`` when the overlay is up."""
    if kind in saved:
        return None
    x, y = view.cursor if view.cursor is not None else (0.0, 0.0)
    moving = math.hypot(x, y) >= 0.5
    if kind in ("training", "test") and not moving:
        return None
    cur = s.current
    if (kind == "test" and cur is not None and cur.trial.on_tactor
            and not all(s.on_tactor)):
        return None
    if kind == "test" and s.overlay:
        kind = "overlay"
        if kind in saved:
            return None
    return kind


def with_overlay(view: View, s: WindowController, now_ns: int, levels: TactorLevels) -> View:
    """A copy of ``view`` with the experimenter overlay."""
    v = copy.copy(view)
    v.overlay = True
    v.overlay_lines = overlay_lines(s, now_ns)
    v.levels = levels(s, now_ns)
    return v


def with_pause(view: View) -> View:
    """A copy of ``view`` under the experimenter's pause."""
    v = copy.copy(view)
    v.modal_title, v.modal_lines = paused()
    return v
