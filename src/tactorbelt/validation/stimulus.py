"""``tactorbelt validate stimulus``: the felt stimulus against the intended one.

:func:`validate_stimulus` plays a study's stimuli on an open belt as a session does (a
:class:`~tactorbelt.player.Player`, the study's law, falloff, period and transit on the
belt's layout), senses every tactor over each playback, and compares what was felt with
what was meant:

- **felt**: each tactor's sensed envelope minus its baseline (the median of the 0.1 s
  before the onset), over the tactor's steady amplitude at full level;
- **intended**: the law's amplitude of the tactor over time (the perturbation with it;
  zero after the stop) through the tactor's measured static response: before the
  stimuli, every tactor is held at amplitudes 0.05, 0.10, ... 1.0 until it settles and
  its steady amplitude at each, over the one at full level, is the response
  (interpolated linearly). So a belt without dynamics (an instant motor) has no error:
  what remains is the motor's lag, which drive shaping addresses; the static shape of
  the response is the calibration's business (``tactorbelt calibrate``);
- per tactor, the RMS of felt minus intended from the onset to ``off_s`` after the stop;
  its **onset error**, when the felt envelope first reaches 10 % of the intended
  maximum minus when the intended one does (the onset validator's threshold), and its
  **offset error**, when it last is at or above it, minus the intended (ms);
- per target, the RMS over its driven tactors (those the law drives); overall, over
  every target's.

The onset of a playback is the device-true one where the belt reports it
(``Player.device_onset``, as a session stores it), else the player's; its end, for a
streamed play, when the player's stop took effect (``PlayerStats.stopped_ns``: a busy
computer sends a first frame or a stop late, and the device plays what it got), for a
rendered one the onset plus the duration, as the device times it. On a shaped belt both
are the pre-roll after the commands (``Belt.preroll_ns``), as a session stores them.

How each tactor is sensed depends on what the sensor declares
(:attr:`~tactorbelt.validation.sensors.Sensor.separates_tactors`):

- **directly**: a sensor with a signal per tactor (the sim belt's model, a sound card with
  one input channel per tactor) senses every tactor over one playback of the stimulus;
- **per-tactor replay**: a sensor that mixes the tactors (the board's IMU, one input
  channel) cannot tell them apart while two vibrate. Each tactor's drive is independent
  of the others' (its own motor, its own shaper), so its felt envelope is the same
  whether the others play or not: the stimulus is played once per tactor it drives,
  every other tactor held off (streamed: :class:`_Only`), and the one signal of each
  play is that tactor's envelope. Its static response is measured alone too. A tactor
  the stimulus never drives is not played: it is reported ``silent`` (felt nothing,
  error 0), not as whatever the sensor picked up from the others. The replays are
  streamed (a device renders whole stimuli only; ``session_plays`` says how a session
  plays it), with the shaper's preview on a shaped belt as a rendered stimulus has it.

:func:`run_stimulus` is the whole command: open, validate, write ``stimulus.json`` and
``stimulus.png``. Imports NumPy and tactorbelt's devices; matplotlib only for the figure.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError
from ..clock import WallClock
from .envelope import LOW
from .run import BASELINE_S, ONSET_TIMEOUT_S, check_output, making, write_json
from .sensors import Sensor

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.study import Study
    from ..geometry import Layout
    from ..player import Player
    from ..stimuli import Stimulus

__all__ = ["RESPONSE_LEVELS", "StimulusValidation", "run_stimulus", "validate_stimulus"]

RESULTS: Final = "stimulus.json"
FIGURE: Final = "stimulus.png"
FORMAT: Final = "tactorbelt-stimulus-validation"
#: The amplitudes the static response is measured at.
RESPONSE_LEVELS: Final = tuple(round(0.05 * i, 2) for i in range(1, 21))
#: Each response level is held this long (s); its steady amplitude is the median of the
#: last fifth.
HOLD_S: Final = 0.4
#: A streamed play whose player skipped more than this fraction of its frames (a busy
#: computer: the device holds a level until the next frame, so the stimulus comes late
#: and in steps) is played again, up to :data:`MAX_TRIES` plays in all; the one that
#: skipped least is measured.
MAX_SKIPPED: Final = 0.01
MAX_TRIES: Final = 3
#: How the tactors were told apart (stimulus.json's ``isolation``).
DIRECT: Final = "none: the sensor senses each tactor apart"
REPLAY: Final = "per-tactor replay"
STREAMED: Final = "streamed"
RENDERED: Final = "rendered on the device"

FloatArray = NDArray[np.float64]


@dataclass
class _Trace:
    """One tactor's playback: sample times (ms from the onset), felt and intended."""

    t_ms: FloatArray
    felt: FloatArray
    intended: FloatArray


@dataclass
class StimulusValidation:
    """The results of :func:`validate_stimulus` (``to_dict`` is stimulus.json)."""

    belt: str
    sensor: str
    drive: str
    condition: str
    duration_s: float
    targets: list[dict[str, Any]]
    #: per tactor its steady amplitude at each response level (None: not played)
    response: list[list[float] | None]
    traces: dict[int, dict[int, _Trace]]
    rms_error: float
    between_tactor_rms_error: float | None
    isolation: str = DIRECT
    plays: int = 0
    onset_reference: str = "host"
    #: how the measured plays went, and how a session plays the stimulus on this belt
    #: (``streamed`` or ``rendered on the device``)
    played: str = STREAMED
    session_plays: str = STREAMED
    #: frames the player skipped in the plays measured (a streamed play on a busy
    #: computer), and the plays made again because it skipped too many
    missed_frames: int = 0
    replayed_late: int = 0
    #: why the run stopped before its last target (the belt or the sensor failed: the
    #: targets measured until then are kept), or None
    stopped: str | None = None

    @property
    def how_sensed(self) -> str:
        """How the tactors were told apart, in words (the console and the figure)."""
        if self.isolation == DIRECT:
            return "each tactor sensed directly"
        return (f"the sensor mixes the tactors: each played alone ({self.isolation}, "
                f"{self.plays} plays)")

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": 1, "belt": self.belt, "sensor": self.sensor,
                "drive": self.drive, "condition": self.condition,
                "duration_s": self.duration_s, "rms_error": self.rms_error,
                "between_tactor_rms_error": self.between_tactor_rms_error,
                "isolation": self.isolation, "plays": self.plays,
                "played": self.played, "session_plays": self.session_plays,
                "missed_frames": self.missed_frames, "replayed_late": self.replayed_late,
                "max_skipped": MAX_SKIPPED,
                "onset_reference": self.onset_reference,
                "threshold": LOW, "response_levels": list(RESPONSE_LEVELS),
                "response": self.response, "targets": self.targets,
                "stopped": self.stopped}


class _Only:
    """A stimulus with every tactor but ``tactor`` held off: a Playable the player streams
    (the device renders whole stimuli only), frame by frame as the stimulus's own."""

    def __init__(self, stimulus: Stimulus, tactor: int) -> None:
        self.layout: Layout = stimulus.layout
        self._stimulus = stimulus
        self._tactor = tactor

    def amplitudes(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        a = np.asarray(self._stimulus.amplitudes(t), dtype=float)
        out = np.zeros_like(a)
        out[..., self._tactor] = a[..., self._tactor]
        return out


def _steady(t: NDArray[np.int64], env: FloatArray, t0: int, t1: int) -> float:
    """The median of ``env`` over the last fifth of [t0, t1)."""
    sel = (t >= t1 - (t1 - t0) // 5) & (t < t1)
    return float(np.median(env[sel])) if sel.any() else float("nan")


def _staircase(belt: Belt, sensor: Sensor, clock: Clock, tactors: Sequence[int]
               ) -> dict[int, FloatArray]:
    """``tactors`` held together (every other one off) at each of
    :data:`RESPONSE_LEVELS`: each one's steady amplitude at each, minus its baseline."""
    n = belt.n_tactors
    hold = round(HOLD_S * 1e9)
    t0 = int(clock.now_ns())
    clock.sleep_until_ns(t0 + round(BASELINE_S * 1e9))
    marks = []
    frame = np.zeros(n)
    for level in RESPONSE_LEVELS:
        t_on = int(clock.now_ns())
        frame[list(tactors)] = level
        belt.set_amplitudes(frame)
        clock.sleep_until_ns(t_on + hold)
        marks.append((t_on, int(clock.now_ns())))
    belt.stop()
    out = {}
    for k in tactors:
        w = sensor.envelope(k, t0, int(clock.now_ns()))
        if w.problem is not None:
            raise DeviceError(f"tactor {k}: {w.problem} while its response was measured")
        base = float(np.median(w.env[w.t_ns < marks[0][0]]))
        steady = np.array([_steady(w.t_ns, w.env, a, b) - base for a, b in marks])
        if not (math.isfinite(steady[-1]) and steady[-1] > 0):
            raise DeviceError(f"the sensor saw no vibration of tactor {k} at full level")
        out[k] = steady
    sensor.forget_before(int(clock.now_ns()))
    return out


def _response(belt: Belt, sensor: Sensor, clock: Clock, tactors: Sequence[int],
              rest_ns: int) -> FloatArray:
    """The steady amplitude of each of ``tactors`` at each of :data:`RESPONSE_LEVELS`
    minus its baseline (rows: levels; columns: every tactor, NaN where not measured): all
    held together when the sensor senses them apart, else one after the other, each
    alone. Each staircase is followed by ``rest_ns`` off, so the motors have stopped
    before the next baseline."""
    out = np.full((len(RESPONSE_LEVELS), belt.n_tactors), np.nan)
    groups = [list(tactors)] if sensor.separates_tactors else [[k] for k in tactors]
    for group in groups:
        for k, steady in _staircase(belt, sensor, clock, group).items():
            out[:, k] = steady
        clock.sleep_until_ns(int(clock.now_ns()) + rest_ns)
    return out


def _crossing(t_ms: FloatArray, y: FloatArray, th: float, last: bool) -> float | None:
    hit = np.flatnonzero(y >= th)
    if hit.size == 0:
        return None
    return float(t_ms[hit[-1] if last else hit[0]])


def _driven(stimulus: Stimulus, duration_s: float) -> list[int]:
    """The tactors ``stimulus`` drives at any frame of a 1 kHz playback of ``duration_s``."""
    t = np.arange(max(1, round(duration_s * 1000.0))) / 1000.0
    return [int(k) for k in np.flatnonzero(stimulus.amplitudes(t).max(axis=0) > 0.0)]


@dataclass
class _Played:
    """One playback: its onset and end on the commands' clock, and the frames the player
    skipped (streamed on a busy computer: each shows the stimulus later)."""

    onset: int
    end: int
    missed: int = 0
    frames: int = 0

    @property
    def skipped(self) -> float:
        """The fraction of the frames due that the player skipped."""
        due = self.frames + self.missed
        return self.missed / due if due else 0.0


def _play(player: Player, clock: Clock, what: Any, duration_s: float, base_ns: int,
          off_ns: int) -> _Played:
    """Wait a baseline, play ``what`` for ``duration_s`` (motors off after), wait
    ``off_ns`` for the fall. The onset is the device's where the belt reports it (both
    with the pre-roll of a shaped belt, ``Player.device_onset``); the end
    of a streamed play is when its stop took effect (the computer may have sent its first
    frame or its stop late), of a rendered one the onset plus the duration."""
    clock.sleep_until_ns(int(clock.now_ns()) + base_ns)
    stats = player.play(what, duration_s)
    onset = int(stats.onset_ns if stats.onset_ns is not None else clock.now_ns())
    got = player.device_onset(timeout_s=ONSET_TIMEOUT_S)
    if got is not None:
        onset = got[0]
    end = (onset + round(duration_s * 1e9) if stats.stopped_ns is None
           else stats.stopped_ns)
    clock.sleep_until_ns(end + off_ns)
    return _Played(onset, end, int(stats.missed), int(stats.frames))


def _compare(sensor: Sensor, k: int, played: _Played, stim: Stimulus, base_ns: int,
             off_ns: int, full: float, grid: FloatArray, curve: FloatArray
             ) -> tuple[dict[str, Any], _Trace, FloatArray]:
    """Tactor ``k``'s felt envelope over ``played`` against its intended one: its row
    of stimulus.json, its trace and its squared errors."""
    onset, end = played.onset, played.end
    w = sensor.envelope(k, onset - base_ns, end + off_ns)
    if w.problem is not None:
        raise DeviceError(f"tactor {k}: {w.problem}")
    before = w.t_ns < onset
    base = float(np.median(w.env[before])) if before.any() else 0.0
    keep = w.t_ns >= onset
    t_ns = w.t_ns[keep]
    felt = (w.env[keep] - base) / full
    ticks = (t_ns - onset) // 1_000_000
    amp = stim.amplitudes(ticks / 1000.0)[:, k]
    amp = np.where(t_ns < end, amp, 0.0)
    intended = np.interp(amp, grid, curve)
    err = felt - intended
    peak = float(intended.max()) if intended.size else 0.0
    t_ms = (t_ns - onset) / 1e6
    row: dict[str, Any] = {"tactor": k, "rms_error": float(np.sqrt(np.mean(err ** 2))),
                           "onset_error_ms": None, "offset_error_ms": None,
                           "driven": peak > 0.0, "felt": "sensed"}
    if peak > 0.0:
        th = LOW * peak
        for key, last in (("onset_error_ms", False), ("offset_error_ms", True)):
            a, b = _crossing(t_ms, felt, th, last), _crossing(t_ms, intended, th, last)
            row[key] = None if a is None or b is None else round(a - b, 3)
    return row, _Trace(t_ms, felt, intended), err ** 2


def validate_stimulus(belt: Belt, sensor: Sensor, study: Study, targets: Sequence[int],
                      condition: str, *, duration_s: float = 2.0, off_s: float = 0.3,
                      progress: Callable[[int, int], None] | None = None,
                      ) -> StimulusValidation:
    """Play the stimulus of each of ``targets`` (numbered as the study numbers them) in
    ``condition`` for ``duration_s``, sensed by ``sensor``: directly, or once per driven
    tactor when the sensor mixes the tactors; see the module docstring. The motors are
    off when it returns or raises (Ctrl-C too). ``progress(done, total)`` counts plays.
    A DeviceError after the first target (the belt or the sensor lost) ends the run with
    the targets measured until then and the reason in ``stopped``.

    Raises:
        ConfigError: a target or condition the study does not have.
        DeviceError: the sensor saw nothing, or lost samples, before a target was done.
    """
    from ..geometry import TargetSet
    from ..player import Player
    from ..stimuli import make_stimulus

    if condition not in ("static", "dynamic"):
        raise ConfigError(f"condition must be static or dynamic, got {condition!r}")
    count = study.targets.count
    bad = [k for k in targets if not 0 <= int(k) < count]
    if bad:
        raise ConfigError(f"target {bad[0]} is not one of the study's {count} targets "
                          f"(0..{count - 1})")
    if not (math.isfinite(duration_s) and 0 < duration_s <= 60):
        raise ConfigError(f"duration must be in (0, 60] s, got {duration_s!r}")
    sp = study.stimulus
    angles = TargetSet.even(count).angles
    on_tactor = belt.layout.is_on_tactor(angles)
    stimuli = {int(k): make_stimulus(belt.layout, float(angles[int(k)]), condition, sp.law,
                                     sp.falloff_deg, sp.period_s, sp.transit_s)
               for k in targets}
    direct = sensor.separates_tactors
    driven = {k: _driven(s, duration_s) for k, s in stimuli.items()}
    needed = sorted({k for ks in driven.values() for k in ks})
    total = len(stimuli) if direct else sum(len(ks) for ks in driven.values())
    clock = belt.clock or WallClock()
    base_ns, off_ns = round(BASELINE_S * 1e9), round(off_s * 1e9)
    rows: list[dict[str, Any]] = []
    traces: dict[int, dict[int, _Trace]] = {}
    all_sq: list[FloatArray] = []
    between_sq: list[FloatArray] = []
    done = missed = extra = 0
    session = STREAMED
    stopped: str | None = None
    try:
        with Player(belt, clock) as player:
            if any(player.renders_on_device(s) for s in stimuli.values()):
                session = RENDERED
            sensor.start()
            response = _response(belt, sensor, clock,
                                 range(belt.n_tactors) if direct else needed, off_ns)
            full = response[-1]
            curve = np.vstack([np.zeros((1, belt.n_tactors)), response / full])
            grid = np.array((0.0, *RESPONSE_LEVELS))
            for target, stim in stimuli.items():
                try:
                    tactors: dict[int, dict[str, Any]] = {}
                    sq = []
                    traces[target] = {}
                    plays: list[tuple[Any, Sequence[int]]] = (
                        [(stim, range(belt.n_tactors))] if direct else
                        [(_Only(stim, k), (k,)) for k in driven[target]])
                    for what, which in plays:
                        tries: list[_Played] = []
                        while not tries or (tries[-1].skipped > MAX_SKIPPED
                                            and len(tries) < MAX_TRIES):
                            tries.append(_play(player, clock, what, duration_s, base_ns,
                                               off_ns))
                        played = min(tries, key=lambda p: p.skipped)
                        for k in which:
                            row, trace, err2 = _compare(sensor, k, played, stim, base_ns,
                                                        off_ns, float(full[k]), grid,
                                                        curve[:, k])
                            row["plays"], row["missed_frames"] = len(tries), played.missed
                            tactors[k], traces[target][k] = row, trace
                            if row["driven"]:
                                sq.append(err2)
                        sensor.forget_before(tries[-1].end + off_ns - base_ns)
                        missed += played.missed
                        extra += len(tries) - 1
                        done += 1
                        if progress is not None:
                            progress(done, total)
                    for k in range(belt.n_tactors):  # never played: silent
                        tactors.setdefault(k, {"tactor": k, "rms_error": 0.0,
                                               "onset_error_ms": None, "offset_error_ms": None,
                                               "driven": False, "felt": "silent", "plays": 0,
                                               "missed_frames": 0})
                    cat = np.concatenate(sq) if sq else np.zeros(1)
                    rows.append({"target": target, "target_deg": float(angles[target]),
                                 "on_tactor": bool(on_tactor[target]),
                                 "rms_error": float(np.sqrt(np.mean(cat))),
                                 "tactors": [tactors[k] for k in range(belt.n_tactors)]})
                    all_sq.append(cat)
                    if not on_tactor[target]:
                        between_sq.append(cat)
                except DeviceError as exc:  # the belt or the sensor lost
                    if not rows:
                        raise
                    # what was measured is kept: the targets done, and why it stopped
                    traces.pop(target, None)
                    stopped = f"target {target}: {exc}"
                    break
    finally:
        with contextlib.suppress(Exception):
            belt.stop()
    return StimulusValidation(
        belt=belt.url, sensor=sensor.url, drive=belt.drive, condition=condition,
        duration_s=duration_s, targets=rows,
        response=[[float(v) for v in col] if np.isfinite(col).all() else None
                  for col in response.T],
        traces=traces, rms_error=float(np.sqrt(np.mean(np.concatenate(all_sq)))),
        between_tactor_rms_error=(float(np.sqrt(np.mean(np.concatenate(between_sq))))
                                  if between_sq else None),
        isolation=DIRECT if direct else REPLAY, plays=total + extra, replayed_late=extra,
        played=session if direct else STREAMED, session_plays=session, missed_frames=missed,
        onset_reference=("device: Player.device_onset(), as a session stores it"
                         if belt.reports_onsets else "host: the player's onset"),
        stopped=stopped)


def run_stimulus(belt_url: str, out_dir: str | Path, *, targets: Sequence[int] | None,
                 condition: str, sense_url: str | None = None, drive: str | None = None,
                 study: Study | None = None, duration_s: float = 2.0, force: bool = False,
                 calibration_file: str | Path | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 on_open: Callable[[Belt, Sensor], None] | None = None,
                 ) -> tuple[StimulusValidation, dict[str, Path]]:
    """The whole ``tactorbelt validate stimulus``: open the belt (``drive``, else the
    study's ``[stimulus] drive`` as a session sets it, else the belt's; through the
    calibration file) and the sensor, play ``targets`` (None: every target of the study)
    of ``study`` (default: the paper's), write ``stimulus.json`` and ``stimulus.png``.

    Raises:
        ConfigError: a bad URL, target or setting; an existing stimulus.json without
            ``force``.
        DeviceError: the belt or the sensor cannot be used.
    """
    from ..devices import open_belt
    from ..devices.calibration import Calibration
    from ..experiment.study import paper_study
    from .sensors import open_sensor

    st = study if study is not None else paper_study()
    out, results = check_output(out_dir, RESULTS, force, sense_url)
    calibration = (Calibration.load(calibration_file) if calibration_file is not None
                   else None)
    ks = list(range(st.targets.count)) if targets is None else [int(k) for k in targets]
    with making(out):
        options: dict[str, Any] = {"calibration": calibration} if calibration else {}
        if belt_url.split(":", 1)[0].split("?", 1)[0] == "sim":
            options["layout"] = st.layout_obj()
        belt = open_belt(belt_url, **options)
        with belt, open_sensor(sense_url, belt) as sensor:
            how = drive if drive is not None else st.stimulus.drive  # as a session plays
            if how is not None:
                belt.set_drive(how)
            if on_open is not None:
                on_open(belt, sensor)
            result = validate_stimulus(belt, sensor, st, ks, condition,
                                       duration_s=duration_s, progress=progress)
    write_json(results, result.to_dict())
    return result, {"results": results, "figure": stimulus_figure(result, out / FIGURE)}


def stimulus_figure(result: StimulusValidation, path: str | Path) -> Path:
    """One panel per target: each driven tactor's felt envelope (solid) over its intended
    one (dashed), normalised to the tactor's steady amplitude at full level, against the
    time from the onset; the title gives the target's RMS error."""
    from ..figures import _pyplot, save_figure, tactor_colors

    plt = _pyplot()
    rows = result.targets
    n = max(1, len(rows))
    cols = 1 if n == 1 else (2 if n <= 4 else 4)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols + (4 if n == 1 else 0),
                                                   2.3 * nrows + 1.0),
                             sharex=True, sharey=True, squeeze=False)
    colors = tactor_colors(max(1, len(rows[0]["tactors"]) if rows else 1))
    for ax, row in zip(axes.ravel(), rows, strict=False):
        traces = result.traces[row["target"]]
        for t in row["tactors"]:
            if not t["driven"]:
                continue
            tr = traces[t["tactor"]]
            c = colors[t["tactor"]]
            ax.plot(tr.t_ms, tr.intended, color=c, lw=1.0, ls="--")
            ax.plot(tr.t_ms, tr.felt, color=c, lw=1.2, label=f"tactor {t['tactor']}")
        ax.axvline(result.duration_s * 1e3, color="grey", lw=0.8)
        ax.grid(alpha=0.25)
        where = "on a tactor" if row["on_tactor"] else "between tactors"
        ax.set_title(f"target {row['target']} ({row['target_deg']:g} deg, {where}): "
                     f"RMS {row['rms_error']:.3f}", fontsize=8, loc="left")
        ax.legend(fontsize=6, loc="upper right", frameon=False)
    for ax in axes.ravel()[len(rows):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("ms from the onset (grey: the stop)")
    for ax in axes[:, 0]:
        ax.set_ylabel("of full-level steady")
    between = ("" if result.between_tactor_rms_error is None else
               f", between tactors {result.between_tactor_rms_error:.3f}")
    fig.suptitle(f"Felt (solid) and intended (dashed) {result.condition} stimulus, drive "
                 f"{result.drive}: RMS error {result.rms_error:.3f}{between}\n"
                 f"belt {result.belt}, sensor {result.sensor}\n{result.how_sensed}"
                 + ("" if result.stopped is None else
                    f"\nstopped after target {result.targets[-1]['target']}: the belt or "
                    "the sensor failed (stimulus.json says why)"), fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
