"""Per-wearer perceptual calibration: equal-feeling tactors and phantom points where meant.

Two adaptive parts, each a set of 2AFC tracks whose next stimulus QUEST+ chooses (the
maintained ``questplus`` package, Watson 2017; function ``norm_cdf_2``):

1. **Intensity matching**: each tactor k against the reference tactor r. Two intervals,
   the reference at ``reference_amplitude`` and tactor k at ``reference_amplitude * 2**x``
   (in random order); "which was stronger?". x (log2 amplitude ratio) is the stimulus;
   the PSE is the x that feels as strong as the reference, and tactor k's gain is
   ``2**PSE`` (relative to the reference, whose gain is 1).
2. **Phantom location**, after the gains are applied: for each adjacent pair (a, b)
   and each marked point m (a fraction of the gap, by default the quarter points 0.25
   and 0.75), a static point rendered at fraction x of the gap; "was it nearer tactor a
   or tactor b than the marked point?" (in the window: left or right of the mark). The
   PSE is the rendered fraction felt at the mark, so the pair's warp maps m -> PSE
   (made strictly monotone by :func:`tactorbelt.wearer.isotonic`).

Each track starts from a normal prior on its PSE centred on "no correction" (as strong
as the reference; felt where rendered) and stops after ``max_trials`` or, after
``min_trials``, once the posterior SD of its PSE is at most ``precision`` (in the
track's units). Afterwards every track is fitted (:func:`fit_psychometric`): a
cumulative normal with a fixed lapse, ``P(second / b side) = lapse + (1 - 2 lapse) *
Phi((x - pse) / sd)``, its likelihood times the same prior maximised over (pse, log sd)
by Nelder-Mead from the QUEST+ estimate; the fitted PSE (clipped to the stimulus range)
is what the profile uses.

Who answers is a :class:`Respondent`: the model participant
(:class:`tactorbelt.inputs.model.ModelRespondent`, from the vibration it feels), a person
at the keyboard (:class:`KeyboardRespondent`), or a simulated observer in the tests.

:func:`profile_for_session` is what the runner calls before a session of a study that
requires a profile. Choosing and opening a respondent for ``calibrate perceptual`` (a
window, the model, the keyboard) is use-case wiring: :mod:`tactorbelt.app.wearer`.

Library (I/O through the belt and the respondent): NumPy, SciPy, questplus (imported
when a track is made), the kernel, the devices and the player; never inputs, gui or the
experiment layer.
"""

from __future__ import annotations

import datetime
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError
from ..wearer import PairWarp, WearerProfile, isotonic
from .motor import CalibrationQuit, ConstantFrame

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..geometry import Layout

__all__ = ["CalibrationSettings", "Fit", "Interval", "KeyboardRespondent",
           "PerceptualResult", "Respondent", "Track", "fit_psychometric",
           "profile_for_session", "run_perceptual_calibration"]

#: Lapse rate assumed by QUEST+ and the fit (both ends: ``norm_cdf_2``).
LAPSE: Final = 0.02


# -- the psychometric function and its fit ---------------------------------------------------

@dataclass(frozen=True)
class Fit:
    """A maximum-likelihood psychometric fit.

    Attributes:
        pse: point of subjective equality (50 % point), clipped to the stimulus range.
        sd: spread of the cumulative normal (from 50 % to about 84 %), stimulus units.
        slope: the function's slope at the PSE, ``(1 - 2 lapse) / (sd * sqrt(2 pi))``
            (proportion per stimulus unit).
        n: trials.
    """

    pse: float
    sd: float
    slope: float
    n: int


def fit_psychometric(x: ArrayLike, r: ArrayLike, lo: float, hi: float,
                     start: tuple[float, float] | None = None,
                     prior: tuple[float, float] | None = None) -> Fit:
    """Maximum-likelihood fit of the psychometric function (module doc) to answers ``r``.

    Args:
        x, r: stimuli and answers (1 = "second" / "b side").
        lo, hi: the stimulus range: the PSE is searched in and clipped to it, the sd in
            ``[(hi - lo) / 200, 2 (hi - lo)]``.
        start: (pse, sd) to start from (the QUEST+ estimate); default the middle.
        prior: (mean, sd) of a normal prior on the PSE: the fit then maximises the
            likelihood times this prior (a penalised, maximum a posteriori fit). None:
            plain maximum likelihood.
    """
    from scipy.optimize import minimize
    from scipy.special import log_ndtr

    xa = np.asarray(x, dtype=float)
    ra = np.asarray(r, dtype=float)
    span = hi - lo
    sd_lo, sd_hi = span / 200.0, 2.0 * span
    p0 = start if start is not None else ((lo + hi) / 2.0, span / 4.0)

    def nll(theta: NDArray[np.float64]) -> float:
        mu = min(max(float(theta[0]), lo - span), hi + span)
        sd = min(max(math.exp(float(theta[1])), sd_lo), sd_hi)
        z = (xa - mu) / sd
        # log P(1) and log P(0) with the lapse, computed stably
        p1 = LAPSE + (1 - 2 * LAPSE) * np.exp(log_ndtr(z))
        p0_ = LAPSE + (1 - 2 * LAPSE) * np.exp(log_ndtr(-z))
        penalty = 0.0 if prior is None else 0.5 * ((mu - prior[0]) / prior[1]) ** 2
        return float(-(ra * np.log(p1) + (1 - ra) * np.log(p0_)).sum()) + penalty

    res = minimize(nll, np.array([p0[0], math.log(max(p0[1], sd_lo))]), method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 400})
    pse = min(max(float(res.x[0]), lo), hi)
    sd = min(max(math.exp(float(res.x[1])), sd_lo), sd_hi)
    return Fit(pse, sd, (1 - 2 * LAPSE) / (sd * math.sqrt(2 * math.pi)), int(xa.size))


# -- one adaptive track -----------------------------------------------------------------------

class Track:
    """One 2AFC staircase run by QUEST+ over a grid of stimuli.

    Args:
        stimuli: the stimulus values QUEST+ may choose.
        pse_grid, sd_grid: the parameter grid of its posterior.
        min_trials, max_trials, precision: the stop rule (see the module docstring).
    """

    def __init__(self, stimuli: ArrayLike, pse_grid: ArrayLike, sd_grid: ArrayLike, *,
                 min_trials: int, max_trials: int, precision: float,
                 prior: tuple[float, float] | None = None) -> None:
        import questplus

        self.stimuli = np.asarray(stimuli, dtype=float)
        self.min_trials, self.max_trials, self.precision = min_trials, max_trials, precision
        self.prior = prior
        grid = np.asarray(pse_grid, dtype=float)
        prior_arg = None
        if prior is not None:
            weights = np.exp(-0.5 * ((grid - prior[0]) / prior[1]) ** 2)
            prior_arg = {"mean": weights / weights.sum()}
        self._q = questplus.QuestPlus(
            stim_domain={"intensity": self.stimuli},
            param_domain={"mean": np.asarray(pse_grid, dtype=float),
                          "sd": np.asarray(sd_grid, dtype=float), "lapse_rate": [LAPSE]},
            outcome_domain={"response": [1, 0]},  # the function gives P(1)
            prior=prior_arg, func="norm_cdf_2", stim_scale="linear")
        self.x: list[float] = []
        self.r: list[int] = []

    @property
    def n(self) -> int:
        return len(self.x)

    def next(self) -> float:
        """The stimulus QUEST+ chooses next (minimum expected posterior entropy)."""
        return float(self._q.next_stim["intensity"])

    def update(self, x: float, r: int) -> None:
        self._q.update(stim={"intensity": float(x)}, outcome={"response": int(r)})
        self.x.append(float(x))
        self.r.append(int(r))

    def estimate(self) -> tuple[float, float, float]:
        """Posterior mean of the PSE and of the sd, and the PSE's posterior SD."""
        post = self._q.posterior
        marg = np.asarray(post.sum(dim=["sd", "lapse_rate"]).values, dtype=float)
        grid = np.asarray(post["mean"].values, dtype=float)
        mean = float((marg * grid).sum())
        sd_pse = math.sqrt(max(float((marg * (grid - mean) ** 2).sum()), 0.0))
        est = self._q.param_estimate
        return mean, float(est["sd"]), sd_pse

    @property
    def done(self) -> bool:
        if self.n >= self.max_trials:
            return True
        return self.n >= self.min_trials and self.estimate()[2] <= self.precision

    def fit(self) -> Fit:
        mean, sd, _ = self.estimate()
        return fit_psychometric(self.x, self.r, float(self.stimuli[0]), float(self.stimuli[-1]),
                                start=(mean, sd), prior=self.prior)


# -- who answers --------------------------------------------------------------------------------

@dataclass(frozen=True)
class Interval:
    """One presentation: what was played, and when on the belt's clock.

    Attributes:
        frame: the amplitudes (one per tactor, after the gains) held for the interval.
        t0_ns, t1_ns: when it started and ended.
        tactor: the tactor (intensity trials; -1 otherwise).
        value: the trial's stimulus value (log2 ratio, or rendered fraction). Only a
            simulated observer in a test may read it; a respondent that stands for a
            person (the model participant, the keyboard) never does.
    """

    frame: NDArray[np.float64]
    t0_ns: int
    t1_ns: int
    tactor: int = -1
    value: float = math.nan


class Respondent(ABC):
    """Answers calibration trials (a person at the keyboard, the model participant)."""

    #: How it is named in the profile and the messages.
    name: str = "respondent"

    @abstractmethod
    def stronger(self, first: Interval, second: Interval) -> int:
        """1 when the second interval felt stronger, else 0."""

    @abstractmethod
    def side(self, interval: Interval, pair: tuple[int, int], marked_deg: float,
             layout: Layout) -> int:
        """1 when the point felt on tactor b's side of the marked point, 0 on a's."""

    def say(self, text: str) -> None:  # noqa: B027 - optional hook
        """A message for the person (the model ignores it)."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release what it holds (the window's respondent closes its window)."""


class KeyboardRespondent(Respondent):
    """A person answering with keys in the terminal: ``1``/``2`` (first or second was
    stronger) and ``a``/``b`` (nearer tactor a or tactor b than the marked point); ``q``
    quits (:class:`~tactorbelt.calibrate.CalibrationQuit`: nothing is written).
    ``read_key`` returns one key; ``say`` prints a prompt."""

    name = "keyboard"

    def __init__(self, read_key: Callable[[], str], say: Callable[[str], None]) -> None:
        self._read = read_key
        self._say = say
        self._asked = 0

    def say(self, text: str) -> None:
        self._say(text)

    def _ask(self, prompt: str, keys: dict[str, int]) -> int:
        self._asked += 1
        self._say(f"  [{self._asked}] {prompt}")
        while True:
            k = self._read().lower()
            if k == "q":
                raise CalibrationQuit("perceptual calibration abandoned (q); nothing was "
                                      "written")
            if k in keys:
                return keys[k]

    def stronger(self, first: Interval, second: Interval) -> int:
        return self._ask("which was stronger: [1] first or [2] second?", {"1": 0, "2": 1})

    def side(self, interval: Interval, pair: tuple[int, int], marked_deg: float,
             layout: Layout) -> int:
        a, b = pair
        return self._ask(f"nearer [a] tactor {a} ({layout.angles_deg[a]:g} deg) or [b] tactor "
                         f"{b} ({layout.angles_deg[b]:g} deg) than {marked_deg:g} deg?",
                         {"a": 0, "b": 1})


# -- the procedure ----------------------------------------------------------------------------

@dataclass(frozen=True)
class CalibrationSettings:
    """The procedure's settings (defaults: at most 228 trials, about 9 minutes for a person
    with 6 tactors; docs/calibration-perceptual.md).

    Attributes:
        reference_tactor: the tactor the others are matched to.
        reference_amplitude: its amplitude (law units, before the motor calibration).
        intensity_trials, location_trials: (min, max) trials per track.
        intensity_precision: stop once the PSE's posterior SD is this (log2 units).
        location_precision: the same for location tracks (fraction of the gap).
        marks: the marked points of each pair (fractions of the gap).
        interval_s, gap_s, iti_s: presentation, pause between two intervals, and pause
            after a trial (on a simulated clock the clock just moves on).
        law, falloff_deg: the amplitude law of the phantom points (the study's).
        intensity: run the intensity part (False: all gains 1).
        intensity_prior_sd, location_prior_sd: SD of the normal prior on each track's
            PSE, centred on no correction (log2 units; fraction of the gap); None: a
            flat prior and a plain maximum-likelihood fit.
    """

    reference_tactor: int = 0
    reference_amplitude: float = 0.6
    intensity_trials: tuple[int, int] = (8, 12)
    location_trials: tuple[int, int] = (10, 14)
    intensity_precision: float = 0.08
    location_precision: float = 0.02
    marks: tuple[float, ...] = (0.25, 0.75)
    interval_s: float = 0.4
    gap_s: float = 0.4
    iti_s: float = 0.4
    law: str = "paper"
    falloff_deg: float = 15.0
    intensity: bool = True
    intensity_prior_sd: float | None = 0.5
    location_prior_sd: float | None = 0.1

    def __post_init__(self) -> None:
        for name in ("intensity_trials", "location_trials"):
            lo, hi = getattr(self, name)
            if not 1 <= lo <= hi:
                raise ConfigError(f"{name} must be (min, max) with 1 <= min <= max, "
                                  f"got {(lo, hi)!r}")
        if not all(0.0 < m < 1.0 for m in self.marks) or list(self.marks) != sorted(
                set(self.marks)):
            raise ConfigError(f"marks must be increasing fractions of the gap in (0, 1), "
                              f"got {self.marks!r}")
        if not 0.0 < self.reference_amplitude <= 1.0:
            raise ConfigError("reference_amplitude must be in (0, 1]")


#: The log2 amplitude ratios intensity matching may present (stimulus grid).
INTENSITY_STIMULI: Final = np.round(np.arange(-1.0, 1.0001, 0.1), 6)
#: The rendered fractions of a gap a location track may present.
LOCATION_STIMULI: Final = np.round(np.linspace(0.02, 0.98, 25), 6)


def intensity_track(settings: CalibrationSettings) -> Track:
    """An intensity track; its prior centres the PSE on 0 (as strong as the reference)."""
    lo, hi = settings.intensity_trials
    sd = settings.intensity_prior_sd
    return Track(INTENSITY_STIMULI, np.linspace(-1.0, 1.0, 41), np.geomspace(0.05, 1.0, 8),
                 min_trials=lo, max_trials=hi, precision=settings.intensity_precision,
                 prior=None if sd is None else (0.0, sd))


def location_track(settings: CalibrationSettings, mark: float | None = None) -> Track:
    """A location track for a marked point; its prior centres the PSE on the mark (felt
    where rendered) unless ``mark`` is None."""
    lo, hi = settings.location_trials
    sd = settings.location_prior_sd
    return Track(LOCATION_STIMULI, np.linspace(0.02, 0.98, 49), np.geomspace(0.02, 0.5, 8),
                 min_trials=lo, max_trials=hi, precision=settings.location_precision,
                 prior=None if sd is None or mark is None else (mark, sd))


@dataclass
class PerceptualResult:
    """The outcome: the profile, each track's fit, the trial count and the clock time."""

    profile: WearerProfile
    fits: list[dict[str, Any]] = field(default_factory=list)
    n_trials: int = 0
    duration_s: float = 0.0


class _Presenter:
    """Holds a frame on the belt for a while: set once on a simulated clock, streamed by
    a Player on the wall clock (a hardware belt's heartbeat needs frames)."""

    def __init__(self, belt: Belt, clock: Clock) -> None:
        from ..player import Player

        self.belt, self.clock = belt, clock
        self.player = None if clock.simulated else Player(belt, clock=clock, device_render=False)

    def hold(self, frame: NDArray[np.float64], seconds: float) -> tuple[int, int]:
        t0 = self.clock.now_ns()
        if self.player is None:
            self.belt.set_amplitudes(frame)
            self.clock.sleep_until_ns(t0 + round(seconds * 1e9))
            self.belt.stop()
        else:
            self.player.play(ConstantFrame(self.belt.layout, frame).as_stimulus(), seconds)
        return t0, self.clock.now_ns()

    def wait(self, seconds: float) -> None:
        self.clock.sleep_until_ns(self.clock.now_ns() + round(seconds * 1e9))


def _rounds(tracks: Sequence[Track], rng: np.random.Generator) -> Iterator[int]:
    """Indices of the unfinished tracks, a round of trials at a time in a random order,
    until every track is done."""
    while todo := [i for i, t in enumerate(tracks) if not t.done]:
        rng.shuffle(todo)
        yield from todo


def run_perceptual_calibration(belt: Belt, clock: Clock, respondent: Respondent, *,
                               participant: str, settings: CalibrationSettings | None = None,
                               seed: int = 0, created: str = "") -> PerceptualResult:
    """Run both parts on ``belt`` with ``respondent`` answering; return the profile.

    Tracks of one part are interleaved (a random order in each round), so a person
    cannot follow one staircase. Motors are off at the end.
    """
    from ..stimuli import make_stimulus

    s = settings if settings is not None else CalibrationSettings()
    layout = belt.layout
    n = layout.n
    if not 0 <= s.reference_tactor < n:
        raise ConfigError(f"reference tactor {s.reference_tactor} is not on a {n}-tactor belt")
    rng = np.random.default_rng(seed)
    present = _Presenter(belt, clock)
    start_ns = clock.now_ns()
    fits: list[dict[str, Any]] = []
    n_trials = 0

    # -- part 1: intensity matching --------------------------------------------------------
    gains = [1.0] * n
    ref = s.reference_tactor
    others = [k for k in range(n) if k != ref]
    if s.intensity:
        respondent.say(f"part 1: intensity. Two vibrations each time; say which was stronger "
                       f"({len(others)} tactors against tactor {ref}).")
        tracks = [intensity_track(s) for _ in others]
        for i in _rounds(tracks, rng):
            k, x = others[i], tracks[i].next()
            ref_frame = np.zeros(n)
            ref_frame[ref] = s.reference_amplitude
            test_frame = np.zeros(n)
            test_frame[k] = min(1.0, s.reference_amplitude * 2.0 ** x)
            test_first = bool(rng.random() < 0.5)
            frames = [(test_frame, k), (ref_frame, ref)]
            if not test_first:
                frames.reverse()
            shown = []
            for j, (frame, tactor) in enumerate(frames):
                t0, t1 = present.hold(frame, s.interval_s)
                shown.append(Interval(frame, t0, t1, tactor, x))
                present.wait(s.gap_s if j == 0 else s.iti_s)
            second = respondent.stronger(shown[0], shown[1])
            tracks[i].update(x, second if test_first is False else 1 - second)
            n_trials += 1
        for k, tr in zip(others, tracks, strict=True):
            f = tr.fit()
            gains[k] = float(2.0 ** f.pse)
            fits.append({"part": "intensity", "tactor": k, "reference": ref, "pse_log2": f.pse,
                         "sd_log2": f.sd, "slope": f.slope, "trials": f.n,
                         "gain": gains[k]})
    gain_profile = WearerProfile(tuple(layout.angles_deg), tuple(gains),
                                 tuple(PairWarp() for _ in range(n)))

    # -- part 2: phantom location -----------------------------------------------------------
    respondent.say("part 2: location. A point between two tactors; say whether it was "
                   "nearer tactor a or tactor b than the marked point.")
    cw, _ = layout.neighbour_indices()
    gaps = layout.gaps_deg()
    keys = [(a, m) for a in range(n) for m in s.marks]
    ltracks = [location_track(s, m) for _, m in keys]
    for i in _rounds(ltracks, rng):
        a, m = keys[i]
        b = int(cw[a])
        x = ltracks[i].next()
        rendered = layout.angles_deg[a] + x * float(gaps[a])
        stim = make_stimulus(layout, rendered, "static", s.law, s.falloff_deg,
                             profile=gain_profile)
        frame = np.asarray(stim.amplitudes(0.0), dtype=float)
        t0, t1 = present.hold(frame, s.interval_s)
        marked = float((layout.angles_deg[a] + m * float(gaps[a])) % 360.0)
        r = respondent.side(Interval(frame, t0, t1, -1, x), (a, b), marked, layout)
        present.wait(s.iti_s)
        ltracks[i].update(x, r)
        n_trials += 1
    warps: list[PairWarp] = []
    for a in range(n):
        pses = []
        for j, m in enumerate(s.marks):
            f = ltracks[a * len(s.marks) + j].fit()
            pses.append(f.pse)
            fits.append({"part": "location", "pair": a, "mark": m, "pse": f.pse,
                         "pse_deg": f.pse * float(gaps[a]), "sd_deg": f.sd * float(gaps[a]),
                         "slope": f.slope, "trials": f.n})
        warps.append(PairWarp(tuple(s.marks), tuple(isotonic(pses))))
    belt.stop()
    profile = WearerProfile(tuple(layout.angles_deg), tuple(gains), tuple(warps),
                            participant=participant, law=s.law, falloff_deg=s.falloff_deg,
                            reference_tactor=ref, belt=belt.url, created=created,
                            fit=tuple(fits))
    return PerceptualResult(profile, fits, n_trials, (clock.now_ns() - start_ns) / 1e9)


def profile_for_session(study: Any, store: Any, belt: Belt, clock: Clock, participant: str,
                        respondent: Respondent | None, *, resume: bool,
                        seed: int = 0) -> WearerProfile | None:
    """The wearer profile a session renders with (the runner calls this before it creates
    the session, so a missing profile leaves no empty session behind, and records it
    with the session as its provenance).

    A study with ``[calibration] perceptual = true`` uses the participant's profile kept
    in ``store``; when there is none, the participant is calibrated now with
    ``respondent`` and the profile kept. A resumed session keeps the profile it started
    with. Other studies: None.

    Raises:
        ConfigError: the study requires a profile, none is kept, and nobody can answer
            the calibration here (a person's joystick or mouse); or the profile was
            measured on another layout.
    """
    if not study.calibration.perceptual:
        return None
    row = store.find_resumable(participant) if resume else None
    if row is not None:
        sid = int(row["session_id"])
        text = store.session_profile(sid)
        if text is not None:
            return WearerProfile.from_toml(text, source=f"{store.url} (session {sid})")
    text = store.wearer_profile(participant)
    if text is not None:
        profile = WearerProfile.from_toml(text, source=f"{store.url} ({participant})")
    elif respondent is None:
        raise ConfigError(
            f"the study requires a perceptual profile ([calibration] perceptual = true) and "
            f"{store.url} keeps none for {participant!r}; measure it first: tactorbelt "
            f"calibrate perceptual --participant {participant} --input keyboard --db "
            f"{store.url}")
    else:
        s = study.stimulus
        settings = CalibrationSettings(law=s.law, falloff_deg=float(s.falloff_deg))
        profile = run_perceptual_calibration(belt, clock, respondent, participant=participant,
                                             settings=settings, seed=seed,
                                             created=datetime.datetime.now(datetime.UTC).isoformat(
                                                 timespec="microseconds")).profile
        store.save_wearer_profile(participant, profile.to_toml())
    profile.check_layout(belt.layout, source=f"the wearer profile of {participant!r}")
    return profile
