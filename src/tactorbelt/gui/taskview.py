"""The secondary task in the experiment window: its sounds, its glyphs, its button.

:class:`TaskPresenter` is the window's part of a running task (``[tasks.NAME]``):

- auditory items: each announced item's sound (:mod:`tactorbelt.tasks.sounds`) is
  scheduled on the task audio output (:mod:`tactorbelt.tasks.audio`) for its onset, so
  it sounds at its onset whatever the window is drawing;
- visual items: the glyph (a letter, or ``a+b``) is shown from its onset for
  ``stimulus_s``, as two identical copies left and right of the ellipse at the height
  of its centre: symmetric, so it cues neither side, nor front or back. The window
  polls on the sampling ticks (10 ms); it draws a frame at the tick nearest each
  glyph's onset and end (the first poll at or after onset - half a tick; not only at
  its 60 Hz frame deadlines), so a glyph appears within half a tick of its onset, and
  :attr:`TaskPresenter.glyph_frames` keeps when each glyph was first drawn;
- responses: the button of ``spec.response`` (``key:NAME`` a pygame key name,
  ``joystick:K`` button K of the participant's stick, ``mouse:left|middle|right``) is a
  press, timestamped with the runner's clock at the poll that took it from SDL's queue
  (the sampling tick: within 10 ms after the press);
- the participant's instructions for a practice run, the single-task baseline and a
  block with the task (:func:`instructions`, :func:`block_lines`);
- feedback during the practice run only (:class:`PracticeCoach`): right after a press,
  "Right: that was a match" or "Not a match: no press needed"; when a match's time is
  over without a press, "Missed: that was a match"; and a summary on the next screen
  ("In the practice you caught 4 of 5 matches ..."). The window uses ``item.target``
  for this (the participant's button decides; the model participant never sees it).

I/O: pygame (events), the task audio output; imports tactorbelt.tasks.
"""

from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

from .._errors import ConfigError
from ..tasks.audio import TaskAudio, open_task_audio
from ..tasks.kinds import task_kind
from ..tasks.sounds import SoundBank

if TYPE_CHECKING:
    from ..clock import Clock
    from ..experiment.study import Study, TaskSpec
    from ..tasks.schedule import TaskItem

__all__ = ["EXPERIMENTER_KEYS", "PracticeCoach", "Response", "TaskPresenter", "block_lines",
           "check_responses", "instructions", "parse_response"]

#: How long a practice feedback line stays (ns).
FEEDBACK_NS: Final = 900_000_000
#: Keys the experimenter uses in the window: a task's response may not be one of them.
EXPERIMENTER_KEYS: Final = ("p", "r", "escape", "tab", "f1", "f12")
_MOUSE_BUTTONS: Final = {"left": 1, "middle": 2, "right": 3}


@dataclass(frozen=True)
class Response:
    """A task's response button: ``device`` (key, joystick, mouse) and its code (a
    pygame key code, a joystick button index, a pygame mouse button number)."""

    device: str
    code: int
    text: str

    def words(self) -> str:
        """The button in the participant's words."""
        if self.device == "key":
            name = self.text.split(":", 1)[1]
            return f"the {name.upper() if len(name) == 1 else name} key"
        if self.device == "joystick":
            return f"joystick button {self.code}"
        return f"the {self.text.split(':', 1)[1]} mouse button"


def parse_response(text: str) -> Response:
    """``key:j``, ``joystick:1`` or ``mouse:right`` as a :class:`Response`.

    Raises:
        ConfigError: an unknown key name, or a key the experimenter uses in the window.
    """
    device, _, value = text.strip().lower().partition(":")
    if device == "key":
        import pygame

        if value in EXPERIMENTER_KEYS:
            raise ConfigError(
                f"the task response {text!r} is one of the experimenter's keys in the "
                f"window ({', '.join(EXPERIMENTER_KEYS)}); give the task another key, "
                "e.g. \"key:j\"")
        try:
            with warnings.catch_warnings(action="ignore"):  # the key table needs no SDL init
                code = int(pygame.key.key_code(value))
        except ValueError:
            raise ConfigError(f"the task response {text!r} names no key pygame knows "
                              "(key names as pygame.key.name gives them: a, j, left "
                              "shift, ...)") from None
        return Response("key", code, text)
    if device == "joystick" and value.isdigit():
        return Response("joystick", int(value), text)
    if device == "mouse" and value in _MOUSE_BUTTONS:
        return Response("mouse", _MOUSE_BUTTONS[value], text)
    raise ConfigError(f"unknown task response {text!r}: key:NAME, joystick:K or "
                      "mouse:left|middle|right")


def instructions(spec: TaskSpec, phase: str, go_on: str) -> tuple[str, list[str]]:
    """The title and lines of the screen before a practice or baseline run."""
    kind = task_kind(spec.kind)
    n_items = spec.practice if phase == "practice" else spec.baseline
    rule = kind.rule(spec, parse_response(spec.response).words())
    minutes = n_items * spec.interval_s
    length = f"{n_items} items, about {minutes:.0f} s" if minutes < 90 else \
        f"{n_items} items, about {minutes / 60:.0f} min"
    if phase == "practice":
        title = f"Practice: {kind.title(spec)}"
        lines = [*rule, "",
                 "During some blocks you will do this task while you locate the",
                 f"vibrations. First practise it alone ({length}); no vibrations now.", ""]
    else:
        title = f"The task alone: {kind.title(spec)}"
        lines = [*rule, "",
                 f"Now the task alone once more ({length}): do it as well as you can.", ""]
    return title, [*lines, f"When you are ready, {go_on}."]


def block_lines(spec: TaskSpec) -> list[str]:
    """Lines for the start screen of a block with the task."""
    kind = task_kind(spec.kind)
    return [f"During this block, also do the task: {kind.title(spec)}.",
            *kind.rule(spec, parse_response(spec.response).words())]


def check_responses(study: Study) -> None:
    """Every active task's response parses and is no experimenter key, and an auditory
    sum's beeps end before the next item (ConfigError)."""
    for name, spec in study.tasks.items():
        if not spec.active:
            continue
        parse_response(spec.response)
        problem = task_kind(spec.kind).check_timing(name, spec)
        if problem is not None:
            raise ConfigError(problem)


class PracticeCoach:
    """Feedback during a practice run (see the module doc). ``interval_ns``: an item's
    time to answer (its onset to the next item's)."""

    def __init__(self, interval_ns: int, go_word: str = "a match",
                 go_plural: str = "matches") -> None:
        self.interval_ns = interval_ns
        self.go_word = go_word
        self.go_plural = go_plural
        #: (onset_ns, target, answered)
        self._items: list[list[Any]] = []
        self._judged = 0
        self.text: str | None = None
        self._until = 0
        self.hits = self.misses = self.false_alarms = self.go = 0

    def item(self, onset_ns: int, target: bool) -> None:
        self._items.append([onset_ns, bool(target), False])
        self.go += bool(target)

    def _say(self, text: str, now_ns: int) -> None:
        self.text = text
        self._until = now_ns + FEEDBACK_NS

    def press(self, t_ns: int) -> None:
        """A press at ``t_ns``: judged against the item whose time it falls in."""
        for it in reversed(self._items):
            onset, target, answered = it
            if onset <= t_ns < onset + self.interval_ns:
                if answered:
                    return
                it[2] = True
                if target:
                    self.hits += 1
                    self._say(f"Right: that was {self.go_word}", t_ns)
                else:
                    self.false_alarms += 1
                    self._say(f"Not {self.go_word}: no press needed", t_ns)
                return

    def tick(self, now_ns: int) -> None:
        """Items whose time is over: a match without a press is a miss."""
        items = self._items
        while self._judged < len(items) and items[self._judged][0] + self.interval_ns <= now_ns:
            onset, target, answered = items[self._judged]
            if target and not answered:
                self.misses += 1
                self._say(f"Missed: that was {self.go_word}", now_ns)
            self._judged += 1
        if self.text is not None and now_ns >= self._until:
            self.text = None

    def summary(self) -> str:
        """One line on how the practice went."""
        pressed = (f"pressed {self.false_alarms} time{'s' if self.false_alarms != 1 else ''}"
                   " when there was none" if self.false_alarms else "never pressed wrongly")
        return (f"In the practice you caught {self.hits} of {self.go} {self.go_plural} "
                f"and {pressed}.")


class TaskPresenter:
    """The window's side of the running task (see the module doc).

    Args:
        clock: the runner's clock.
        tick_ns: the window's poll period (the runner's sampling period): glyphs
            change at the poll nearest their onset and end.
    """

    def __init__(self, clock: Clock, tick_ns: int) -> None:
        self.clock = clock
        #: the task sound output (None: opened on the first auditory task, a silent one
        #: on a simulated clock)
        self.audio: TaskAudio | None = None
        self._half_tick = max(int(tick_ns) // 2, 0)
        self.name: str | None = None
        self.spec: TaskSpec | None = None
        self.phase: str | None = None
        self.response: Response | None = None
        self._bank: SoundBank | None = None
        self._presses: list[int] = []
        #: visual items to show: (onset_ns, end_ns, glyph)
        self._glyphs: list[tuple[int, int, str]] = []
        self._drawn: tuple[int, int, str] | None = None
        #: per visual item shown: (onset_ns, the time of the first frame showing it)
        self.glyph_frames: list[tuple[int, int]] = []
        #: every item announced: (item, onset_ns)
        self.items: list[tuple[TaskItem, int]] = []
        #: the practice run's feedback (None outside practice); the last practice's
        #: summary line stays in :attr:`practice_summary`
        self.coach: PracticeCoach | None = None
        self._coach_of: str | None = None
        self.practice_summary: str | None = None

    # -- phases ----------------------------------------------------------------------------
    def start(self, name: str, spec: TaskSpec, phase: str) -> None:
        self.name, self.spec, self.phase = name, spec, phase
        self.response = parse_response(spec.response)
        self._presses.clear()
        if phase == "practice":
            if self.coach is None or self._coach_of != name:  # after a pause: the same
                self.coach = PracticeCoach(round(spec.interval_s * 1e9),
                                           *task_kind(spec.kind).go_words)
                self._coach_of = name
        else:
            self.coach = None
        if spec.modality == "auditory":
            self._sounds()

    def _sounds(self) -> tuple[TaskAudio, SoundBank]:
        """The sound output (opened now when there is none) and its sounds."""
        if self.audio is None:
            self.audio = open_task_audio(self.clock)
        if self._bank is None:
            self._bank = SoundBank(self.audio.rate)
        return self.audio, self._bank

    def end(self) -> None:
        """The task run ended (or paused): silence, no glyph, no button."""
        if self.coach is not None and self.phase == "practice":
            self.practice_summary = self.coach.summary()
        self.name = self.spec = self.phase = None
        self.response = None
        self._glyphs.clear()
        self._drawn = None
        if self.audio is not None:
            self.audio.stop()

    @property
    def running(self) -> bool:
        return self.spec is not None

    # -- items -----------------------------------------------------------------------------
    def item(self, item: TaskItem, onset_ns: int, spec: TaskSpec) -> None:
        """Schedule ``item``'s sound, or its glyph, for ``onset_ns``."""
        self.items.append((item, onset_ns))
        if self.coach is not None:
            self.coach.item(onset_ns, item.target)
        if spec.modality == "auditory":
            audio, bank = self._sounds()
            audio.schedule(bank.get(item.stimulus, spec.stimulus_s, task_kind(spec.kind).sound),
                           onset_ns, item.stimulus)
        else:
            end = onset_ns + round(spec.stimulus_s * 1e9)
            self._glyphs.append((onset_ns, end, item.stimulus))

    def _current(self, now_ns: int) -> tuple[int, int, str] | None:
        now_ns += self._half_tick  # the poll nearest the onset or end, not the first after
        g = self._glyphs
        while g and g[0][1] <= now_ns:
            g.pop(0)
        for entry in g:
            if entry[0] <= now_ns < entry[1]:
                return entry
        return None

    def glyph_at(self, now_ns: int) -> str | None:
        """The glyph to show at ``now_ns`` (None: none)."""
        cur = self._current(now_ns)
        return None if cur is None else cur[2]

    def frame_due(self, now_ns: int) -> bool:
        """Whether a glyph appeared or ended since the last frame drawn."""
        return self._current(now_ns) != self._drawn

    def drawn(self, now_ns: int) -> None:
        """A frame was drawn at ``now_ns`` (records glyph onsets as shown)."""
        cur = self._current(now_ns)
        if cur is not None and cur != self._drawn:
            self.glyph_frames.append((cur[0], now_ns))
        self._drawn = cur

    # -- responses -------------------------------------------------------------------------
    def on_event(self, ev: Any, now_ns: int, pg: Any, stick_id: int | None) -> bool:
        """A press of the task's button (recorded at ``now_ns``): True, the window must
        not also use it (to go on, say). Other events: False."""
        r = self.response
        if r is None:
            return False
        t = ev.type
        if r.device == "key":
            down, up, code = pg.KEYDOWN, pg.KEYUP, getattr(ev, "key", None)
        elif r.device == "joystick":
            down, up, code = pg.JOYBUTTONDOWN, pg.JOYBUTTONUP, getattr(ev, "button", None)
            if (t in (down, up) and stick_id is not None
                    and getattr(ev, "instance_id", stick_id) != stick_id):
                return False  # another stick's button
        else:
            down, up, code = (pg.MOUSEBUTTONDOWN, pg.MOUSEBUTTONUP,
                              getattr(ev, "button", None))
        if t not in (down, up) or code != r.code:
            return False
        if t == down:
            self._presses.append(int(now_ns))
            if self.coach is not None:
                self.coach.press(int(now_ns))
        return True  # its release is the task's too

    def feedback(self, now_ns: int) -> str | None:
        """The practice feedback line to show now (None: none)."""
        coach = self.coach
        if coach is None:
            return None
        coach.tick(now_ns)
        return coach.text

    def presses(self) -> list[int]:
        """The presses since the last call (ns, runner clock)."""
        out, self._presses = self._presses, []
        return out

    def close(self) -> None:
        if self.audio is not None:
            with contextlib.suppress(Exception):
                self.audio.close()
