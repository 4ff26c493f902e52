"""``tactorbelt validate onsets``: pulse each tactor, sense it, measure its timing.

:func:`validate_onsets` drives an open belt and reads an open sensor
(:mod:`~tactorbelt.validation.sensors`); :func:`run_onsets` is the whole command as a
library function: it opens both, runs, writes ``validation.json`` and the figure, and
updates a calibration file.

The procedure (docs/validation.md): after a lead-in for the sensor's baseline, the
pulses go round the tactors (pulse 1 of every tactor at every level, then pulse 2, ...),
one motor on at a time, each on for ``on_s`` (long enough for the vibration to settle),
each tactor then resting ``off_s`` (long enough for it to stop), timed on the belt's
clock (``clock.sleep_until_ns``; a ``sim:virtual`` belt runs instantly). The command time
of a pulse is what the runner stores as a trial's onset: the clock time just before
``belt.set_amplitudes`` (as ``Player.start`` returns it), or ``belt.last_onset()`` where
the belt ``reports_onsets`` (the device-true onset). Each pulse is measured over its
window, from :data:`BASELINE_S` before its command to ``off_s`` after its stop
(:func:`~tactorbelt.validation.envelope.measure_pulse`), once the window is over, while
later pulses go on. A pulse whose samples were lost (the sensor reports lost input in its
window, or the belt an output underrun while it was on) is pulsed again, up to
``max_repeats`` times. A pulse the sensor does not see stops the run with
:class:`NoPulseError` naming the tactor and level.

Imports NumPy and tactorbelt's devices; matplotlib only for the figure.
"""

from __future__ import annotations

import bisect
import contextlib
import datetime as _dt
import json
import math
import textwrap
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from .._errors import ConfigError, DeviceError
from ..clock import WallClock
from .envelope import HIGH, LOW, PulseMeasure, TactorSummary, measure_pulse, summarise
from .sensors import Sensor

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["NoPulseError", "OnsetSettings", "OnsetValidation", "fit_shaping", "parse_levels",
           "run_onsets", "validate_onsets"]

#: The results file and the figure ``run_onsets`` writes.
RESULTS: Final = "validation.json"
FIGURE: Final = "onsets.png"
#: The format of validation.json.
FORMAT: Final = "tactorbelt-validation"
VERSION: Final = 1
#: The baseline before each command: this long, at most half the off-time (s).
BASELINE_S: Final = 0.1
#: ``last_onset`` waits this long for a device's report (s).
ONSET_TIMEOUT_S: Final = 0.5
#: The pause between pulses of different tactors when the sensor senses each tactor
#: apart (s); one that senses them together waits the whole off-time.
GAP_S: Final = 0.05


class NoPulseError(DeviceError):
    """The sensor did not see a pulse: names the tactor and the level."""

    def __init__(self, message: str, tactor: int, level: float) -> None:
        super().__init__(message)
        self.tactor = tactor
        self.level = level


def check_output(out_dir: str | Path, name: str, force: bool,
                 sense_url: str | None) -> tuple[Path, Path]:
    """``(directory, results file)`` of a validation run, checked before any device is
    opened: the directory is not a file, the results file is new unless ``force``, and
    a sensor URL names a sensor.

    Raises:
        ConfigError: any of these does not hold (a bad sensor URL: its own message).
    """
    from .sensors import resolve_sensor

    out = Path(out_dir)
    results = out / name
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output {str(out)!r} is a file, not a directory")
    if results.exists() and not force:
        raise ConfigError(f"{str(results)!r} exists: give another directory, or --force to "
                          "replace it")
    if sense_url is not None:
        resolve_sensor(sense_url)  # a bad URL fails before the belt is opened
    return out, results


@contextlib.contextmanager
def making(out: Path) -> Iterator[None]:
    """Create the output directory ``out`` before the pulses (fail early); an error,
    Ctrl-C or SIGTERM in the block leaves no empty directory behind."""
    made = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create output directory {str(out)!r}: {exc.strerror}"
                          ) from None
    try:
        yield
    except BaseException:
        if made:
            with contextlib.suppress(OSError):
                out.rmdir()
        raise


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as JSON at ``path`` through a temporary file beside it."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    tmp.replace(path)


def parse_levels(text: str | Sequence[float]) -> tuple[float, ...]:
    """Levels from ``"0.5,1.0"`` (or numbers): each in (0, 1], no repeats, sorted.

    Raises:
        ConfigError: not numbers, out of range, none.
    """
    parts: list[Any] = ([p for p in text.replace(" ", "").split(",") if p]
                        if isinstance(text, str) else list(text))
    try:
        values = [float(p) for p in parts]
    except (TypeError, ValueError):
        raise ConfigError(f"levels must be numbers in (0, 1] separated by commas, "
                          f"got {text!r}") from None
    if not values:
        raise ConfigError("give at least one level in (0, 1]")
    bad = [v for v in values if not (math.isfinite(v) and 0.0 < v <= 1.0)]
    if bad:
        raise ConfigError(f"levels must be in (0, 1], got {bad[0]:g}")
    return tuple(sorted(set(values)))


@dataclass(frozen=True)
class OnsetSettings:
    """How the tactors are pulsed.

    Attributes:
        pulses: pulses per tactor at each level.
        levels: the amplitudes pulsed (through the belt's calibration), in (0, 1].
        on_s: how long each pulse is on (the vibration must settle: the steady amplitude
            is the median over its last fifth).
        off_s: how long a tactor rests after its pulse (its vibration must stop: the
            fall is measured in it, and the baseline of its next pulse is the last 0.1 s
            of it).
        max_repeats: a pulse whose samples were lost is pulsed again at most this often.
        lead_s: the sensor records this long before the first pulse.
    """

    pulses: int = 10
    levels: tuple[float, ...] = (1.0,)
    on_s: float = 0.3
    off_s: float = 0.3
    max_repeats: int = 5
    lead_s: float = 0.2

    def __post_init__(self) -> None:
        if isinstance(self.pulses, bool) or not isinstance(self.pulses, int) or self.pulses < 1:
            raise ConfigError(f"pulses must be a whole number of at least 1, got {self.pulses!r}")
        object.__setattr__(self, "levels", parse_levels(self.levels))
        for name in ("on_s", "off_s", "lead_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and 0 < v <= 3600):
                raise ConfigError(f"{name} must be a number of seconds in (0, 3600], got {v!r}")
        if not 0 <= int(self.max_repeats) <= 100:
            raise ConfigError(f"max_repeats must be in 0..100, got {self.max_repeats!r}")


@dataclass
class OnsetValidation:
    """The results of :func:`validate_onsets` (``to_dict`` is validation.json)."""

    belt: str
    belt_name: str
    sensor: str
    sensor_description: str
    method: str
    unit: str
    onset_reference: str
    settings: OnsetSettings
    tactors: list[TactorSummary]
    date: str
    angles_deg: tuple[float, ...]
    seconds: float
    repeats: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    onset_uncertainty_ms: float | None = None
    #: the belt's drive during the pulses (``plain`` or ``shaped``)
    drive: str = "plain"
    #: with ``--tune``: each tactor's fitted time constants (:func:`fit_shaping`) and the
    #: plain validation they were fitted from
    shaping: list[dict[str, Any]] | None = None
    plain: OnsetValidation | None = None
    #: why the run stopped before its last pulse (the belt or the sensor failed: the
    #: pulses measured before are kept), or None
    stopped: str | None = None

    def to_dict(self) -> dict[str, Any]:
        from importlib.metadata import PackageNotFoundError, version

        try:
            ours = version("tactorbelt")
        except PackageNotFoundError:  # pragma: no cover - a source tree
            ours = "unknown"
        return {
            "format": FORMAT, "version": VERSION, "kind": "onsets",
            "tactors": [t.to_dict() for t in self.tactors],
            "belt": self.belt, "belt_name": self.belt_name,
            "sensor": self.sensor, "sensor_description": self.sensor_description,
            "method": self.method, "unit": self.unit,
            "onset_reference": self.onset_reference,
            "onset_uncertainty_ms": self.onset_uncertainty_ms,
            "thresholds": {"onset": LOW, "top": HIGH},
            "date": self.date, "tactorbelt": ours,
            "settings": {**asdict(self.settings), "levels": list(self.settings.levels)},
            "angles_deg": list(self.angles_deg),
            "seconds": round(self.seconds, 3),
            "repeats": self.repeats, "warnings": self.warnings,
            "pulses": [p.to_dict() for t in self.tactors for p in t.pulses],
            "drive": self.drive, "stopped": self.stopped,
            **({} if self.shaping is None else {"shaping": self.shaping}),
            **({} if self.plain is None else {"plain": {
                "drive": self.plain.drive,
                "tactors": [t.to_dict() for t in self.plain.tactors],
                "pulses": [p.to_dict() for t in self.plain.tactors for p in t.pulses]}}),
        }

    def timings(self) -> list[dict[str, float | None] | None]:
        """Per tactor of the belt, the calibration file's timing keys (None: a tactor not
        validated)."""
        by = {t.tactor: t.timing() for t in self.tactors}
        return [by.get(k) for k in range(len(self.angles_deg))]


#: 10-90 % of an amplitude that grows with the square of a first-order speed: the rise
#: from rest lasts tau * ln((1 - sqrt(0.1)) / (1 - sqrt(0.9))), the coasting fall
#: tau * ln(sqrt(0.9) / sqrt(0.1)) (docs/validation.md, "Tuning the drive").
_RISE_PER_TAU: Final = math.log((1 - math.sqrt(LOW)) / (1 - math.sqrt(HIGH)))
_FALL_PER_TAU: Final = math.log(math.sqrt(HIGH) / math.sqrt(LOW))


def fit_shaping(result: OnsetValidation) -> list[dict[str, Any]]:
    """Each tactor's time constants from a plain validation: its rise and fall (the
    median over levels and pulses) through the motor model (amplitude ~ speed squared, a
    first-order speed), the brake's taken as the rise's (a plain pulse never brakes).

    Raises:
        ConfigError: the validation was not plain, or a tactor has no rise or fall.
    """
    if result.drive != "plain":
        raise ConfigError("the time constants are fitted from a plain validation")
    out = []
    for t in result.tactors:
        d = t.to_dict()
        rise, fall = d["rise_ms"], d["fall_ms"]
        if rise is None or fall is None or not (rise > 0 and fall > 0):
            raise ConfigError(f"tactor {t.tactor}: no rise or fall measured to fit its time "
                              "constants (raise --on and --off)")
        r = float(rise) / _RISE_PER_TAU
        out.append({"tactor": t.tactor, "rise_tau_ms": round(r, 3),
                    "fall_tau_ms": round(float(fall) / _FALL_PER_TAU, 3),
                    "brake_tau_ms": round(r, 3)})
    return out


@dataclass
class _Pulse:
    tactor: int
    level: float
    attempt: int
    t_on: int = 0
    t_off: int = 0


class _Dropouts:
    """The belt's dropout count noted at every command, to tell whether a window held one
    (an output underrun anywhere between the notes around it)."""

    def __init__(self, belt: Belt) -> None:
        self.belt = belt
        self.t: list[int] = []
        self.n: list[int] = []

    def note(self, t_ns: int) -> None:
        self.t.append(t_ns)
        self.n.append(self.belt.dropouts())

    def within(self, t0_ns: int, t1_ns: int) -> bool:
        i = max(0, bisect.bisect_right(self.t, t0_ns) - 1)
        j = bisect.bisect_left(self.t, t1_ns)
        now = self.belt.dropouts() if j >= len(self.n) else self.n[j]
        return bool(self.n) and now > self.n[i]

    def forget_before(self, t_ns: int) -> None:
        i = max(0, bisect.bisect_right(self.t, t_ns) - 2)
        del self.t[:i], self.n[:i]


def validate_onsets(belt: Belt, sensor: Sensor, settings: OnsetSettings | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    tactors: Sequence[int] | None = None) -> OnsetValidation:
    """Pulse ``tactors`` (default: all) of an open ``belt``, sensed by an open ``sensor``,
    and measure each (see the module docstring). The motors are off when it returns or
    raises (the last pulse is stopped; the caller's ``with belt`` does the rest).

    The pulses go round the tactors (pulse 1 of every tactor at every level, then pulse
    2, ...), one motor on at a time. Each tactor rests ``off_s`` after its pulse, and its
    window (from :data:`BASELINE_S` before its command to ``off_s`` after its stop) is
    measured when it is over. A sensor that senses every tactor on one signal
    (``separates_tactors`` False: one input channel, an IMU) also waits ``off_s`` after
    every pulse before the next, whichever tactor is next; one that senses each tactor
    apart (its model, one input channel per tactor) only :data:`GAP_S`.

    ``progress(done, total)`` is called after each pulse is measured.

    A DeviceError after the first pulse is measured (the belt or the sensor lost, input
    lost in every attempt at a pulse) ends the run with the pulses measured until then and
    the reason in ``stopped``.

    Raises:
        NoPulseError: the sensor saw no pulse on a tactor at a level.
        DeviceError: the sensor lost input in every attempt at a pulse, or stopped, before
            a pulse was measured.
    """
    s = settings or OnsetSettings()
    clock = belt.clock or WallClock()
    ks = list(range(belt.n_tactors)) if tactors is None else [int(k) for k in tactors]
    bad = [k for k in ks if not 0 <= k < belt.n_tactors]
    if bad:
        raise ConfigError(f"tactor {bad[0]} is not on belt {belt.url!r} "
                          f"({belt.n_tactors} tactors)")
    queue = [_Pulse(k, lv, 0) for _ in range(s.pulses) for lv in s.levels for k in ks]
    total = len(queue)
    on_ns, off_ns = round(s.on_s * 1e9), round(s.off_s * 1e9)
    base_ns = round(min(BASELINE_S, 0.5 * s.off_s) * 1e9)
    gap_ns = round(GAP_S * 1e9) if sensor.separates_tactors else off_ns
    device_onsets = belt.reports_onsets
    uncertainties: list[int] = []
    measured: list[PulseMeasure] = []
    repeats: list[dict[str, Any]] = []
    warned: dict[tuple[int, float, str], str] = {}
    dropouts = _Dropouts(belt)
    pending: list[_Pulse] = []
    wall0 = time.perf_counter()

    def measure(p: _Pulse) -> None:
        t_end = p.t_off + off_ns
        window = sensor.envelope(p.tactor, p.t_on - base_ns, t_end)
        problem = window.problem
        if problem is None and dropouts.within(p.t_on, p.t_off):  # while it was on
            problem = "the belt reported an output underrun"
        if problem is not None and p.attempt < s.max_repeats:
            repeats.append({"tactor": p.tactor, "level": p.level, "reason": problem})
            queue.insert(0, _Pulse(p.tactor, p.level, p.attempt + 1))
            return
        m: PulseMeasure | None
        try:
            m = measure_pulse(window.t_ns, window.env, p.t_on, p.t_off, tactor=p.tactor,
                              level=p.level)
        except ValueError:  # the sensor lost the window's start (a loaded machine)
            if problem is None:
                raise
            m = None
        if m is not None and not m.seen:
            raise NoPulseError(
                f"the sensor ({sensor.url}) saw no pulse on tactor {p.tactor} at level "
                f"{p.level:g}: its steady amplitude {m.amplitude:.3g} is not above the "
                f"baseline's noise ({m.noise:.3g}; {sensor.unit}). Is the sensor on that "
                "tactor and connected, and does the tactor vibrate at this level (an "
                "ERM's dead zone; see 'tactorbelt belt-test')?", p.tactor, p.level)
        if problem is not None or m is None:
            raise DeviceError(
                f"tactor {p.tactor} at level {p.level:g}: {problem} in each of "
                f"{p.attempt + 1} attempts (an overloaded machine? raise the sound "
                "card's latency, or JACK's period)")
        for bad_value, text in ((not m.settled, "was still changing at the end of the "
                                 "pulse: raise --on"),
                                (math.isnan(m.fall_ms), "had not fallen to 10 % within --off "
                                 "after the pulse: raise --off"),
                                (not m.stopped or math.isnan(m.latency_ms),
                                 "had not stopped before the pulse: raise --off")):
            if bad_value:
                warned.setdefault((p.tactor, p.level, text),
                                  f"tactor {p.tactor} at level {p.level:g}: the vibration "
                                  f"{text}")
        measured.append(m)
        if progress is not None:
            progress(len(measured), total)

    def measure_due(now_ns: int) -> None:
        for p in [p for p in pending if p.t_off + off_ns <= now_ns]:
            pending.remove(p)
            measure(p)

    free_at: dict[int, int] = {}  # when each tactor has rested after its last pulse
    if progress is not None:
        progress(0, total)
    sensor.start()
    t_next = int(clock.now_ns()) + round(s.lead_s * 1e9)
    stopped: str | None = None
    try:
        while queue or pending:
            if not queue:  # wait out the last windows
                clock.sleep_until_ns(max(p.t_off + off_ns for p in pending))
                measure_due(int(clock.now_ns()))
                continue
            p = queue.pop(0)
            frame = np.zeros(belt.n_tactors)
            frame[p.tactor] = p.level
            clock.sleep_until_ns(max(t_next, free_at.get(p.tactor, t_next)))
            try:
                p.t_on = int(clock.now_ns())
                dropouts.note(p.t_on)
                belt.set_amplitudes(frame)
                if device_onsets:
                    got = belt.last_onset(timeout_s=ONSET_TIMEOUT_S)
                    if got is not None:
                        p.t_on = int(got[0])
                        uncertainties.append(int(got[1]))
                measure_due(int(clock.now_ns()))  # while this pulse is on
                clock.sleep_until_ns(p.t_on + on_ns)
                p.t_off = int(clock.now_ns())
                belt.stop()
            except NoPulseError:
                raise
            except DeviceError as exc:  # the belt or the sensor lost
                if not measured:
                    raise
                # what was measured is kept: the pulses done (and those whose windows are
                # over, if the sensor still answers), and why it stopped
                with contextlib.suppress(DeviceError):
                    measure_due(int(clock.now_ns()))
                stopped = (f"the pulse of tactor {p.tactor} at level {p.level:g}, with "
                           f"{len(measured)} of {total} measured: {exc}")
                break
            dropouts.note(p.t_off)
            pending.append(p)
            free_at[p.tactor] = p.t_off + off_ns
            t_next = p.t_off + gap_ns
            oldest = min([q.t_on for q in pending] + [t_next]) - base_ns
            sensor.forget_before(oldest)
            dropouts.forget_before(oldest)
    finally:
        with contextlib.suppress(Exception):  # the with block closes it in any case
            belt.stop()
    return OnsetValidation(
        belt=belt.url, belt_name=belt.name, sensor=sensor.url,
        sensor_description=sensor.description, method=sensor.method, unit=sensor.unit,
        onset_reference=("device: belt.last_onset(), the device-true onset" if device_onsets
                         and uncertainties else
                         "host: the clock time just before the command (Player.start)"),
        settings=s, tactors=summarise(measured),
        date=_dt.datetime.now(_dt.UTC).astimezone().isoformat(timespec="seconds"),
        angles_deg=tuple(belt.tactor_angles_deg), seconds=time.perf_counter() - wall0,
        repeats=repeats, warnings=list(warned.values()),
        onset_uncertainty_ms=(float(np.median(uncertainties)) / 1e6 if uncertainties
                              else None), drive=belt.drive, stopped=stopped)


def run_onsets(belt_url: str, out_dir: str | Path, *, sense_url: str | None = None,
               settings: OnsetSettings | None = None, calibration_file: str | Path | None = None,
               force: bool = False, progress: Callable[[int, int], None] | None = None,
               on_open: Callable[[Belt, Sensor], None] | None = None,
               drive: str | None = None, tune: bool = False,
               ) -> tuple[OnsetValidation, dict[str, Path]]:
    """The whole ``tactorbelt validate onsets``: open the belt (through the calibration
    file when it exists) and the sensor, validate, write ``validation.json`` and
    ``onsets.png`` into ``out_dir``, and with ``calibration_file`` write the timings into
    it (in place, atomically; created when missing). ``on_open(belt, sensor)`` is called
    once both are open. ``drive``: play ``plain`` or ``shaped`` (None: the belt's
    default).

    ``tune``: validate plain, fit each tactor's time constants (:func:`fit_shaping`),
    write them into ``calibration_file`` (required), open the belt again through it and
    validate shaped; the result is the shaped validation, with the fitted constants and
    the plain validation (``shaping``, ``plain``).

    Returns:
        The results and the paths written (``results``, ``figure``, ``calibration``).

    Raises:
        ConfigError: a bad URL or setting, an existing validation.json without ``force``,
            a calibration file for another belt.
        DeviceError: the belt or the sensor cannot be used, or a pulse was not seen.
    """
    from ..devices import open_belt
    from ..devices.calibration import Calibration
    from .sensors import open_sensor

    out, results = check_output(out_dir, RESULTS, force, sense_url)
    if tune and calibration_file is None:
        raise ConfigError("--tune writes the fitted drive shaping into the calibration file: "
                          "give --calibration FILE")
    if tune and drive == "plain":
        raise ConfigError("--tune validates the shaped drive: leave out --drive plain")
    calibration = None
    if calibration_file is not None and Path(calibration_file).exists():
        calibration = Calibration.load(calibration_file)

    def once(cal: Any, how: str | None) -> OnsetValidation:
        belt = open_belt(belt_url, **({"calibration": cal} if cal else {}))
        with belt, open_sensor(sense_url, belt) as sensor:
            if tune and not belt.can_shape:
                raise ConfigError(f"belt {belt.url!r} cannot shape its drive: nothing to "
                                  "tune (docs/belts.md, 'Drive shaping')")
            if how is not None:
                belt.set_drive(how)
            if on_open is not None:
                on_open(belt, sensor)
            return validate_onsets(belt, sensor, settings, progress)

    with making(out):
        if tune:
            result = plain = once(calibration, "plain")
            if plain.stopped is None:  # else nothing to fit from: the plain run is kept
                shaping = fit_shaping(plain)
                by = {f["tactor"]: f for f in shaping}
                base = calibration or Calibration.identity(len(plain.angles_deg))
                tuned = base.with_shaping([by.get(k) for k in range(base.n)])
                result = once(tuned, "shaped")
                result.shaping, result.plain = shaping, plain
        else:
            result = once(calibration, drive)
    return _written(result, out, results, calibration_file)


def _written(result: OnsetValidation, out: Path, results: Path,
             calibration_file: str | Path | None) -> tuple[OnsetValidation, dict[str, Path]]:
    """Write validation.json and onsets.png of ``result`` into ``out``, and its timings
    (and fitted shaping) into ``calibration_file`` when given and the run was not stopped
    (a calibration holds complete measurements); return it and the paths written."""
    from ..devices.calibration import update_timing

    paths = {"results": results}
    write_json(results, result.to_dict())
    paths["figure"] = onset_figure(result, out / FIGURE)
    if calibration_file is not None and result.stopped is None:
        by = {f["tactor"]: f for f in result.shaping or []}
        update_timing(calibration_file, len(result.angles_deg), result.timings(),
                      result.date, f"{result.sensor}: {result.method}", belt=result.belt,
                      angles_deg=result.angles_deg,
                      shaping=[by.get(k) for k in range(len(result.angles_deg))]
                      if result.shaping is not None else None)
        paths["calibration"] = Path(calibration_file)
    return result, paths


def _fmt(mean: float | None, sd: float | None) -> str:
    if mean is None:
        return "n/a"
    return f"{mean:.1f}" + ("" if sd is None else f" ± {sd:.1f}") + " ms"


def onset_figure(result: OnsetValidation, path: str | Path) -> Path:
    """Draw ``result`` to a PNG at ``path``: one row per tactor; on the left every
    pulse's envelope (normalised: 0 the baseline, 1 the steady amplitude) against the
    time from its command, the 10 % onset (the latency) marked with a line and its spread
    over pulses, and the 10-90 % rise shaded; on the right the same pulses from their stop
    command, with the 90-10 % fall shaded. Imports matplotlib (Agg) when called."""
    from ..figures import _pyplot, save_figure, tactor_colors

    plt = _pyplot()
    from matplotlib.lines import Line2D

    rows = result.tactors
    n = max(1, len(rows))
    fig, axes = plt.subplots(n, 2, figsize=(10, 1.9 * n + 1.0), sharey=True, squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2]})
    colors = tactor_colors(len(result.angles_deg))
    levels = list(result.settings.levels)
    styles = ["-", "--", ":", "-."]
    span_on = result.settings.on_s * 1e3
    plain = {t.tactor: t for t in result.plain.tactors} if result.plain is not None else {}
    for ax_on, ax_off, summary in zip(axes[:, 0], axes[:, 1], rows, strict=False):
        d = summary.to_dict()
        color = colors[summary.tactor]
        before = plain.get(summary.tactor)
        for p in before.pulses if before is not None else ():  # --tune: the plain drive
            ax_on.plot(p.trace_ms, p.trace, color="grey", lw=0.6, alpha=0.35)
            if math.isfinite(p.off_ms):
                ax_off.plot(p.trace_ms - p.off_ms, p.trace, color="grey", lw=0.6, alpha=0.35)
        for p in summary.pulses:
            ls = styles[levels.index(p.level) % len(styles)] if p.level in levels else "-"
            ax_on.plot(p.trace_ms, p.trace, color=color, lw=0.7, alpha=0.45, ls=ls)
            if math.isfinite(p.off_ms):
                ax_off.plot(p.trace_ms - p.off_ms, p.trace, color=color, lw=0.7, alpha=0.45,
                            ls=ls)
        lat, lat_sd, rise = d["latency_ms"], d["latency_sd_ms"], d["rise_ms"]
        if lat is not None:
            ax_on.axvline(lat, color="black", lw=1.0)
            if lat_sd:
                ax_on.axvspan(lat - lat_sd, lat + lat_sd, color="black", alpha=0.12, lw=0)
            if rise is not None:
                ax_on.axvspan(lat, lat + rise, color=color, alpha=0.12, lw=0)
        stop, fall = d["stop_latency_ms"], d["fall_ms"]
        if stop is not None and fall is not None:
            ax_off.axvspan(stop, stop + fall, color=color, alpha=0.12, lw=0)
        for ax in (ax_on, ax_off):
            for y in (LOW, HIGH):
                ax.axhline(y, color="grey", lw=0.6, ls=":")
            ax.axvline(0.0, color="grey", lw=0.8)
            ax.grid(alpha=0.25)
        ax_on.set_xlim(-0.1 * span_on, span_on)
        ax_off.set_xlim(-0.1 * span_on, result.settings.off_s * 1e3)
        angle = result.angles_deg[summary.tactor]
        ax_on.set_title(f"tactor {summary.tactor} ({angle:g} deg): latency "
                        f"{_fmt(lat, lat_sd)}, rise 10-90 % {_fmt(rise, d['rise_sd_ms'])}",
                        fontsize=9, loc="left")
        ax_off.set_title(f"fall 90-10 % {_fmt(fall, d['fall_sd_ms'])}", fontsize=9,
                         loc="left")
        ax_on.set_ylabel("of steady")
    axes[-1, 0].set_xlabel("ms from the command (10 % onset: black line; 10-90 % rise: "
                           "shaded)")
    axes[-1, 1].set_xlabel("ms from the stop command (90-10 % fall: shaded)")
    for ax in axes[:, 0]:
        ax.set_ylim(-0.1, 1.2)
        ax.set_yticks(np.array([0.0, LOW, 0.5, HIGH, 1.0]))
    if len(levels) > 1:
        handles = [Line2D([], [], color="black", lw=0.9, ls=styles[i % len(styles)],
                          label=f"level {x:g}") for i, x in enumerate(levels)]
        axes[0, 1].legend(handles=handles, loc="upper right", fontsize=7, frameon=False)
    lv = ", ".join(f"{x:g}" for x in levels)
    drive = f"drive {result.drive}" + (" (grey: plain, before tuning)" if plain else "")
    stopped = ("" if result.stopped is None else "\n" + "\n".join(
        textwrap.wrap(f"stopped early, at {result.stopped}", 110)[:2]))
    counts = sorted({len(t.pulses) for t in result.tactors}) or [0]
    pulses = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    fig.suptitle(f"Onset validation of {result.belt} sensed by {result.sensor}, {drive}\n"
                 f"({pulses} pulses a tactor at levels {lv}; {result.date}){stopped}",
                 fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
