"""Motor calibration: from amplitude (what a law asks for) to drive level (what a motor gets).

Per tactor: ``start`` (the dead zone of an ERM: the smallest drive that spins it),
``gain`` and ``ceiling``. Amplitude 0 is off; above 0 the drive is
``start + (ceiling - start) * amplitude * gain``, clamped to [0, ceiling] (and [0, 1]).
So every non-zero amplitude spins the motor, and no amplitude drives it past the
comfortable maximum found by ``tactorbelt calibrate``.

A calibration is stored as a small TOML file (:meth:`Calibration.save`,
:meth:`Calibration.load`)::

    format = "tactorbelt-calibration"
    version = 1
    belt = "serial:/dev/ttyACM0"      # optional, informative

    [[tactor]]
    index = 0                          # optional; when given, 0, 1, ... in order
    angle_deg = 30.0                   # optional, informative
    start = 0.22
    gain = 1.0                         # optional, default 1.0
    ceiling = 0.85
    channel = 3                        # optional: output channel (audio belts)
    response = [[100.0, 1.6], [250.0, 1.0], [400.0, 1.3]]
                                       # optional: output gain by carrier Hz (audio belts)

``channel`` and ``response`` matter only to belts driven through a sound card
(:mod:`tactorbelt.devices.audio`): which output channel is this tactor, and the gain
that evens out its frequency response, as ``[hz, gain]`` points interpolated on a
log-frequency axis at the carrier frequency. Other belts ignore them, and they take no
part in :meth:`Calibration.apply` (so they do not make a calibration non-identity).

Measured timing, written by ``tactorbelt validate onsets --calibration FILE``
(docs/validation.md), all optional: at the top ``validated`` (the date, ISO 8601) and
``validation_method`` (the sensor and estimator); per tactor ``latency_ms`` (command to
10 % of the steady vibration), ``rise_ms`` (10 to 90 %), ``fall_ms`` (90 to 10 % after
the stop) and the spread of each over pulses (``latency_sd_ms``, ``rise_sd_ms``,
``fall_sd_ms``). They take no part in :meth:`Calibration.apply` either;
:meth:`Calibration.skin_latency` gives a tactor set's skin-onset offset from them. Files
without them load as before::

    validated = "2025-03-01T10:12:00+01:00"
    validation_method = "audio:USB?channel=0: rectified moving mean, 4 ms"

    [[tactor]]
    start = 0.22
    ceiling = 0.85
    latency_ms = 15.2
    latency_sd_ms = 0.4
    rise_ms = 103.6
    rise_sd_ms = 1.1
    fall_ms = 54.9
    fall_sd_ms = 0.8

Pure: NumPy and the standard library; pydantic when a file is read (its model:
:func:`_file_model`), tomli-w when one is saved.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import math
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from functools import cache, cached_property
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError
from .._registry import check_option

__all__ = ["FORMAT", "SHAPING_KEYS", "TIMING_KEYS", "Calibration", "TactorCalibration",
           "response_gain", "update_timing"]

#: The ``format`` key of a calibration file.
FORMAT: Final = "tactorbelt-calibration"
#: The version of the file format written by :meth:`Calibration.save`.
VERSION: Final = 1

#: The per-tactor timing keys (milliseconds) ``tactorbelt validate onsets`` measures.
TIMING_KEYS: Final = ("latency_ms", "latency_sd_ms", "rise_ms", "rise_sd_ms", "fall_ms",
                      "fall_sd_ms")
#: The largest timing a file may hold (ms): a minute is no motor's response.
_MAX_TIMING_MS: Final = 60_000.0

#: The per-tactor shaping keys (milliseconds) ``tactorbelt validate onsets --tune`` fits:
#: the time constants of the motor's speed rising, coasting down and braking
#: (:class:`~tactorbelt.devices.erm.Shaper`).
SHAPING_KEYS: Final = ("rise_tau_ms", "fall_tau_ms", "brake_tau_ms")
#: The highest output channel a calibration may name (``channel``).
MAX_CHANNEL: Final = 255


def _check_response(points: Sequence[Sequence[float]]) -> None:
    """Raise ConfigError unless ``points`` are [hz, gain] pairs, hz increasing."""
    last = 0.0
    for p in points:
        ok = (isinstance(p, Sequence) and len(p) == 2
              and all(isinstance(v, int | float) and not isinstance(v, bool) for v in p))
        if not ok or not all(math.isfinite(v) for v in p):
            raise ConfigError(f"a response point must be [hz, gain] (two numbers), got {p!r}")
        hz, gain = float(p[0]), float(p[1])
        if hz <= last:
            raise ConfigError(f"response frequencies must be positive and increasing, got "
                              f"{hz:g} Hz after {last:g} Hz")
        if not 0.0 < gain <= 10.0:
            raise ConfigError(f"a response gain must be in (0, 10], got {gain:g} at {hz:g} Hz")
        last = hz


def _check_timing(name: str, value: object) -> str | None:
    """Why ``value`` is not a valid ``name`` (a timing key), or None. A latency may be
    negative (an onset stamped after the device changed its outputs); the rest may not."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return f"must be a finite number of milliseconds, got {value!r}"
    low = -_MAX_TIMING_MS if name == "latency_ms" else 0.0
    if name in SHAPING_KEYS and not float(value) > 0.0:
        return f"must be a positive number of milliseconds, got {value!r}"
    if not low <= float(value) <= _MAX_TIMING_MS:
        return f"must be in [{low:g}, {_MAX_TIMING_MS:g}] ms, got {value!r}"
    return None


def _ms(value: Any) -> float | None:
    return None if value is None else float(value)


def _with_keys(t: TactorCalibration, values: Mapping[str, Any],
               keys: Sequence[str]) -> TactorCalibration:
    """``t`` with the ``keys`` (timing or shaping) of ``values`` (a missing key: None)."""
    changed: dict[str, Any] = {k: _ms(values.get(k)) for k in keys}
    return replace(t, **changed)


def _toml_value(key: str, v: Any) -> str:
    """A value of a ``[[tactor]]`` row as TOML: floats as Python writes them."""
    if key == "channel":
        return str(int(v))
    if key == "response":
        return "[" + ", ".join(f"[{float(h)!r}, {float(g)!r}]" for h, g in v) + "]"
    return repr(float(v))


def response_gain(points: Sequence[tuple[float, float]], hz: float) -> float:
    """The gain of a frequency response at ``hz`` (1.0 with no points): linear in
    log-frequency between points, the end values beyond them."""
    if not points:
        return 1.0
    f = np.log([p[0] for p in points])
    g = np.array([p[1] for p in points], dtype=float)
    return float(np.interp(math.log(hz), f, g))


@dataclass(frozen=True)
class TactorCalibration:
    """Calibration of one tactor: start level, gain and ceiling, each in [0, 1] (gain > 0);
    for audio belts optionally its output ``channel`` and frequency ``response``
    (``((hz, gain), ...)``, frequencies increasing); optionally its measured timing in ms
    (:data:`TIMING_KEYS`, from ``tactorbelt validate onsets``; None: not measured)."""

    start: float = 0.0
    gain: float = 1.0
    ceiling: float = 1.0
    channel: int | None = None
    response: tuple[tuple[float, float], ...] = ()
    latency_ms: float | None = None
    latency_sd_ms: float | None = None
    rise_ms: float | None = None
    rise_sd_ms: float | None = None
    fall_ms: float | None = None
    fall_sd_ms: float | None = None
    rise_tau_ms: float | None = None
    fall_tau_ms: float | None = None
    brake_tau_ms: float | None = None

    def __post_init__(self) -> None:
        for name in (*TIMING_KEYS, *SHAPING_KEYS):
            problem = _check_timing(name, getattr(self, name))
            if problem:
                raise ConfigError(f"calibration {name} {problem}")
        if self.channel is not None and not (
                isinstance(self.channel, int) and 0 <= self.channel <= MAX_CHANNEL):
            raise ConfigError(f"calibration channel must be an integer in 0..{MAX_CHANNEL}, "
                              f"got {self.channel!r}")
        _check_response(self.response)
        for name in ("start", "ceiling"):
            v = getattr(self, name)
            if not (0.0 <= float(v) <= 1.0):
                raise ConfigError(f"calibration {name} must be in [0, 1], got {v!r}")
        if not (0.0 < float(self.gain) <= 10.0):
            raise ConfigError(f"calibration gain must be in (0, 10], got {self.gain!r}")
        if self.start > self.ceiling:
            raise ConfigError(
                f"calibration start ({self.start}) must not exceed ceiling ({self.ceiling})"
            )


@dataclass(frozen=True)
class Calibration:
    """Calibration of every tactor of a belt (index k is tactor k).

    ``validated`` (an ISO 8601 date) and ``validation_method`` say when and how the
    tactors' timing was measured (``tactorbelt validate onsets``); None when it was not.
    """

    tactors: tuple[TactorCalibration, ...]
    validated: str | None = None
    validation_method: str | None = None

    def __post_init__(self) -> None:
        if not self.tactors:
            raise ConfigError("a calibration needs at least one tactor")
        for name in ("validated", "validation_method"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, str):
                raise ConfigError(f"calibration {name} must be text, got {v!r}")

    @classmethod
    def identity(cls, n: int) -> Calibration:
        """No dead zone, unit gain, full ceiling: drive level equals amplitude."""
        return cls(tuple(TactorCalibration() for _ in range(n)))

    @property
    def n(self) -> int:
        return len(self.tactors)

    @property
    def is_identity(self) -> bool:
        """True when :meth:`apply` changes nothing (``channel`` and ``response`` aside)."""
        return all((t.start, t.gain, t.ceiling) == (0.0, 1.0, 1.0) for t in self.tactors)

    @property
    def channels(self) -> tuple[int, ...] | None:
        """The output channel of each tactor, or None when the file names none.

        Raises:
            ConfigError: only some tactors name a channel, or two name the same one.
        """
        given = [t.channel for t in self.tactors]
        if all(c is None for c in given):
            return None
        if any(c is None for c in given):
            missing = [k for k, c in enumerate(given) if c is None]
            raise ConfigError(f"calibration: tactor {missing[0]} has no channel; give every "
                              "tactor a channel, or none")
        chans = tuple(int(c) for c in given if c is not None)
        if len(set(chans)) != len(chans):
            raise ConfigError(f"calibration: two tactors name the same channel: {list(chans)}")
        return chans

    @property
    def has_timing(self) -> bool:
        """True when some tactor has a measured latency (``validate onsets``)."""
        return any(t.latency_ms is not None for t in self.tactors)

    def with_timing(self, timings: Sequence[Mapping[str, float | None] | None],
                    validated: str, method: str) -> Calibration:
        """This calibration with each tactor's timing replaced (``timings[k]``: the
        :data:`TIMING_KEYS` of tactor k, None to leave a tactor as it is), dated
        ``validated`` by ``method``. :meth:`apply` is unchanged.

        Raises:
            ConfigError: not one entry per tactor, an unknown key, a value out of range.
        """
        if len(timings) != self.n:
            raise ConfigError(f"expected the timing of {self.n} tactors, got {len(timings)}")
        rows = []
        for k, (t, timing) in enumerate(zip(self.tactors, timings, strict=True)):
            for key in sorted(timing or ()):
                check_option(f"timing key of tactor {k}:", key, TIMING_KEYS)
            rows.append(t if timing is None else _with_keys(t, timing, TIMING_KEYS))
        return replace(self, tactors=tuple(rows), validated=str(validated),
                       validation_method=str(method))

    def shaping_taus(self) -> tuple[tuple[float, ...], tuple[float, ...],
                                    tuple[float, ...]] | None:
        """The fitted time constants of every tactor (s): rise, fall, brake (a brake
        not fitted: the rise's), or None unless every tactor has its rise and fall."""
        ts = self.tactors
        if any(t.rise_tau_ms is None or t.fall_tau_ms is None for t in ts):
            return None
        rise = tuple(float(t.rise_tau_ms or 0.0) / 1e3 for t in ts)
        fall = tuple(float(t.fall_tau_ms or 0.0) / 1e3 for t in ts)
        brake = tuple(float(t.brake_tau_ms if t.brake_tau_ms is not None else
                            t.rise_tau_ms or 0.0) / 1e3 for t in ts)
        return rise, fall, brake

    def with_shaping(self, taus: Sequence[Mapping[str, float] | None]) -> Calibration:
        """This calibration with each tactor's :data:`SHAPING_KEYS` from ``taus[k]``
        (None: leave the tactor as it is). :meth:`apply` is unchanged."""
        if len(taus) != self.n:
            raise ConfigError(f"expected the time constants of {self.n} tactors, got "
                              f"{len(taus)}")
        rows = [t if tau is None else _with_keys(t, tau, SHAPING_KEYS)
                for t, tau in zip(self.tactors, taus, strict=True)]
        return replace(self, tactors=tuple(rows))

    def skin_latency(self, tactors: Iterable[int]) -> tuple[float, float]:
        """The skin-onset offset of a stimulus on ``tactors``: ``(ms, sd_ms)``.

        ``ms`` is the mean of the tactors' ``latency_ms`` (command to 10 % of the steady
        vibration, as ``tactorbelt validate onsets`` measured it); add it to a trial's
        stored onset to get when the skin was stimulated. ``sd_ms`` is how far one onset
        may be from that, pulse to pulse: the root of the tactors' mean variance
        (``latency_sd_ms**2``) plus the variance of their latencies about the mean (the
        onsets of a set of tactors spread by both). It is not the error of the mean.

        Raises:
            ConfigError: no tactor given, a tactor not on this belt, or a tactor without
                a measured latency (the message says how to measure it).
        """
        ks = sorted({int(k) for k in tactors})
        if not ks:
            raise ConfigError("skin_latency needs at least one tactor")
        bad = [k for k in ks if not 0 <= k < self.n]
        if bad:
            raise ConfigError(f"tactor {bad[0]} is not on this {self.n}-tactor calibration")
        missing = [k for k in ks if self.tactors[k].latency_ms is None]
        if missing:
            raise ConfigError(f"tactor {missing[0]} has no measured latency in the calibration; "
                              "measure it with 'tactorbelt validate onsets --calibration FILE'")
        lat = np.array([self.tactors[k].latency_ms for k in ks], dtype=float)
        sd = np.array([self.tactors[k].latency_sd_ms or 0.0 for k in ks], dtype=float)
        mean = float(lat.mean())
        spread = float(np.sqrt(np.mean(sd**2) + np.mean((lat - mean) ** 2)))
        return mean, spread

    @cached_property
    def _identity(self) -> bool:
        return self.is_identity

    @cached_property
    def _arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                               NDArray[np.float64]]:
        """start, gain, ceiling and ceiling - start of every tactor (read-only)."""
        start = np.array([t.start for t in self.tactors], dtype=float)
        gain = np.array([t.gain for t in self.tactors], dtype=float)
        ceiling = np.array([t.ceiling for t in self.tactors], dtype=float)
        span = ceiling - start
        for arr in (start, gain, ceiling, span):
            arr.setflags(write=False)
        return start, gain, ceiling, span

    def apply(self, amplitudes: ArrayLike) -> NDArray[np.float64]:
        """Map amplitudes (last axis = tactors) to drive levels in [0, 1].

        Amplitude 0 (or below) gives 0; any positive amplitude gives at least ``start``
        and at most ``ceiling``.
        """
        a = np.asarray(amplitudes, dtype=float)
        if a.ndim == 0 or a.shape[-1] != self.n:
            got = 1 if a.ndim == 0 else a.shape[-1]
            raise ConfigError(f"expected {self.n} amplitudes (one per tactor), got {got}")
        if self._identity:  # start 0, gain 1, ceiling 1: x below is a itself where a > 0
            return np.asarray(np.where(a > 0.0, np.minimum(a, 1.0), 0.0))
        start, gain, ceiling, span = self._arrays
        # np.clip(x, 0, ceiling) as two ufuncs, without np.clip's Python layers (a third of
        # a streamed frame's cost): where a > 0, x >= start >= 0 is never -0.0 or below 0,
        # so the result is the same bit for bit (tests/test_calibration.py)
        drive = np.minimum(np.maximum(start + span * a * gain, 0.0), ceiling)
        return np.asarray(np.where(a > 0.0, drive, 0.0))

    def to_list(self) -> list[dict[str, Any]]:
        """Each tactor's keys that are set (not None, not empty), in the order of its fields;
        ``response`` as lists."""
        rows = [{k: v for k, v in asdict(t).items() if v is not None and v != ()}
                for t in self.tactors]
        for row in rows:
            if "response" in row:
                row["response"] = [list(p) for p in row["response"]]
        return rows

    # -- files ----------------------------------------------------------------------
    def to_toml(self, belt: str | None = None,
                angles_deg: Sequence[float] | None = None, created: str | None = None) -> str:
        """The calibration as TOML text (see the module docstring for the format).

        Args:
            belt: the belt URL, recorded for the reader's information.
            angles_deg: tactor angles, recorded for the reader's information.
            created: when the calibration was made, recorded for the reader.
        """
        import tomli_w

        if angles_deg is not None and len(angles_deg) != self.n:
            raise ConfigError(f"expected {self.n} tactor angles, got {len(angles_deg)}")
        lines = [
            "# tactorbelt motor calibration, one [[tactor]] table per tactor (index k = tactor k)",
            "# drive = start + (ceiling - start) * amplitude * gain, clamped to [0, ceiling];"
            " amplitude 0 = off",
            f'format = "{FORMAT}"',
            f"version = {VERSION}",
        ]
        top = {"belt": belt, "created": created, "validated": self.validated,
               "validation_method": self.validation_method}
        for key, value in top.items():
            if value:
                lines.append(tomli_w.dumps({key: str(value)}).strip())
        for k, row in enumerate(self.to_list()):  # to_list's keys, in its order
            lines += ["", "[[tactor]]", f"index = {k}"]
            if angles_deg is not None:
                lines.append(f"angle_deg = {float(angles_deg[k])!r}")
            lines += [f"{key} = {_toml_value(key, v)}" for key, v in row.items()]
        return "\n".join(lines) + "\n"

    def save(self, path: str | Path, belt: str | None = None,
             angles_deg: Sequence[float] | None = None, created: str | None = None) -> Path:
        """Write the calibration to a TOML file (parent directories are created).

        Atomic: the text goes to a temporary file beside it, which then replaces the
        file, so a reader (or a crash) never sees half a calibration.

        Returns:
            The path written.

        Raises:
            ConfigError: the file cannot be written (the message names it).
        """
        p = Path(path)
        text = self.to_toml(belt, angles_deg, created)
        tmp: str | None = None
        try:
            if p.parent != Path(""):
                p.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp",
                                       dir=p.parent if p.parent != Path("") else ".")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
            if p.exists():  # keep the file's permissions
                os.chmod(tmp, p.stat().st_mode & 0o7777)
            else:
                umask = os.umask(0)
                os.umask(umask)
                os.chmod(tmp, 0o666 & ~umask)
            os.replace(tmp, p)
            tmp = None
        except OSError as exc:
            raise ConfigError(f"cannot write calibration file {str(p)!r}: {exc.strerror}") from None
        finally:
            if tmp is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
        return p

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration TOML file.

        Raises:
            ConfigError: the file is missing or unreadable, is not valid TOML, or a
                field is missing or out of range; the message names the file and the
                field (``cal.toml: tactor[2].start: ...``).
        """
        from .._files import read_user_text

        p = Path(path)
        text = read_user_text(p, "calibration file")
        return cls.from_toml(text, source=str(p))

    @classmethod
    def from_toml(cls, text: str, source: str = "<calibration>") -> Calibration:
        """Parse calibration TOML text; errors name ``source`` and the field."""
        from .._files import read_toml

        return cls.from_mapping(read_toml(text, source), source)

    @classmethod
    def from_mapping(cls, doc: Mapping[str, Any], source: str = "<calibration>") -> Calibration:
        """Build a calibration from a parsed document (the TOML structure), validated by
        its file model (:func:`_file_model`)."""
        from .._files.model import parse

        f = parse(_file_model(), doc, source, missing={
            "tactor": "missing: add one [[tactor]] table per tactor",
            "start": "missing (a number in [0, 1])", "ceiling": "missing (a number in [0, 1])"})
        return cls(tuple(TactorCalibration(
            **row.model_dump(exclude={"index", "angle_deg", "response"}),
            response=tuple((float(h), float(g)) for h, g in row.response)) for row in f.tactor),
                   validated=f.validated, validation_method=f.validation_method)


@cache
def _file_model() -> Any:
    """The pydantic model of a calibration file (built when a file is first read)."""
    from typing import Annotated

    from pydantic import Field, create_model, model_validator

    from .._files.model import FileModel, checked, number

    def fixed(want: object, message: str) -> Any:
        def check(v: Any) -> Any:
            if v is not None and v != want:
                raise ValueError(message.format(v=v))
            return v
        return Annotated[Any, checked(check)]

    def a_text(v: Any) -> str | None:
        if isinstance(v, _dt.date | _dt.time):  # a TOML date or date-time
            v = v.isoformat()
        if v is not None and not isinstance(v, str):
            raise ValueError(f"must be text (or a TOML date), got {v!r}")
        return v

    def a_channel(v: Any) -> int | None:
        if v is not None and (isinstance(v, bool) or not isinstance(v, int)
                              or not 0 <= v <= MAX_CHANNEL):
            raise ValueError(f"must be an integer in 0..{MAX_CHANNEL}, got {v!r}")
        return v

    def a_response(v: Any) -> list[Any]:
        if not isinstance(v, list):
            raise ValueError(f"must be a list of [hz, gain] points, got {v!r}")
        _check_response(v)
        return v

    def timing(name: str) -> Any:
        def check(v: Any) -> float | None:
            problem = _check_timing(name, v)
            if problem:
                raise ValueError(problem)
            return _ms(v)
        return Annotated[float | None, checked(check)]

    def a_rows(v: Any) -> Any:
        if not isinstance(v, list) or not v:
            raise ValueError("must be a non-empty array of tables ([[tactor]])")
        for k, row in enumerate(v):
            if not isinstance(row, Mapping):
                raise ValueError(f"@[{k}]@ must be a table with start, gain and ceiling")
            if "index" in row and (isinstance(row["index"], bool) or row["index"] != k):
                raise ValueError(f"@[{k}].index@ must be {k} (tables in tactor order), got "
                                 f"{row['index']!r}")
        return v

    Unit = Annotated[float, number(0.0, 1.0)]
    Txt = Annotated[str | None, checked(a_text)]

    class Levels(FileModel):
        index: Any = None
        angle_deg: Any = None
        start: Unit
        gain: Annotated[float, number(0.0, 10.0, low_open=True)] = 1.0
        ceiling: Unit
        channel: Annotated[int | None, checked(a_channel)] = None
        response: Annotated[list[Any], checked(a_response)] = Field(default_factory=list)

        @model_validator(mode="after")
        def _order(self) -> Levels:
            if self.start > self.ceiling:
                raise ValueError(f"@start@ start ({self.start:g}) must not exceed ceiling "
                                 f"({self.ceiling:g})")
            return self

    # a [[tactor]] table: the levels, then the timing keys
    timings: dict[str, Any] = {k: (timing(k), None) for k in (*TIMING_KEYS, *SHAPING_KEYS)}
    Row = create_model("Row", __base__=Levels, **timings)

    class File(FileModel):
        format: fixed(FORMAT, f"must be {FORMAT!r}, got {{v!r}}") = None  # type: ignore[valid-type]
        version: fixed(VERSION, f"unsupported version {{v!r}}; allowed: {VERSION}") = None  # type: ignore[valid-type]
        belt: Any = None
        created: Any = None
        validated: Txt = None
        validation_method: Txt = None
        tactor: Annotated[list[Row], checked(a_rows)]  # type: ignore[valid-type]

    return File


def update_timing(path: str | Path, n: int,
                  timings: Sequence[Mapping[str, float | None] | None], validated: str,
                  method: str, belt: str | None = None,
                  angles_deg: Sequence[float] | None = None,
                  shaping: Sequence[Mapping[str, float] | None] | None = None) -> Calibration:
    """Write measured timings into the calibration file ``path``, in place, atomically.

    An existing file keeps everything else (start, gain, ceiling, channel, response, and
    its ``belt``, ``created`` and ``angle_deg`` notes); a missing file is created with an
    identity calibration of ``n`` tactors (``belt`` and ``angles_deg`` noted).
    ``shaping``: each tactor's fitted time constants (:data:`SHAPING_KEYS`), written too.

    Returns:
        The calibration written.

    Raises:
        ConfigError: the file is not a calibration, has another number of tactors than
            ``n``, or cannot be written.
    """
    from .._files import read_toml, read_user_text

    p = Path(path)
    created: str | None = None
    if p.exists():
        doc = read_toml(read_user_text(p, "calibration file"), str(p))
        cal = Calibration.from_mapping(doc, str(p))
        belt = str(doc["belt"]) if doc.get("belt") else belt
        created = str(doc["created"]) if doc.get("created") else None
        noted = [r.get("angle_deg") for r in doc["tactor"]]  # one table per tactor (checked)
        if all(isinstance(a, int | float) for a in noted):
            angles_deg = [float(a) for a in noted]
        if cal.n != n:
            raise ConfigError(f"calibration file {str(p)!r} has {cal.n} tactors but the belt "
                              f"has {n}")
    else:
        cal = Calibration.identity(n)
    if angles_deg is not None and len(angles_deg) != n:
        angles_deg = None
    new = cal.with_timing(timings, validated, method)
    if shaping is not None:
        new = new.with_shaping(shaping)
    new.save(p, belt=belt, angles_deg=angles_deg, created=created)
    return new
