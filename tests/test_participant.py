"""The model participant's perception: published figures, bias, ideal observer, cues."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from support.observers import noiseless
from tactorbelt import ConfigError
from tactorbelt.geometry import Layout, TargetSet, wrap
from tactorbelt.laws import amplitudes
from tactorbelt.participant import (
    ModelParams,
    Spread,
    draw_participant,
    perceive,
    perceive_vibration,
    sense_cues,
)
from tactorbelt.participant.perception import (
    _CUE_FIELDS,
    KIND_FUNNELLED,
    KIND_NONE,
    KIND_SINGLE,
    Percepts,
    _perceive_many,
    _perceive_one,
    _sense_many,
    _sites,
    bias_deg,
    localisation_sd_deg,
)
from tactorbelt.participant.timing import decision_s, one_decision_s
from tactorbelt.stimuli import make_stimulus

T_S = np.arange(300) / 1000.0  # a 0.3 s window at 1 kHz


def steady(amps: np.ndarray, n: int = T_S.size) -> np.ndarray:
    """Vibration that holds the given per-tactor amplitudes over the window."""
    return np.broadcast_to(np.asarray(amps, dtype=float), (n, len(amps))).copy()


def erm(t_s: np.ndarray, amps: np.ndarray, tau_s: float = 0.045) -> np.ndarray:
    """A simple ERM: speed follows the drive through a first-order lag; vibration = speed^2."""
    speed = np.zeros_like(amps)
    k = 1.0 - np.exp(-np.diff(t_s, prepend=0.0)[1] / tau_s)
    acc = np.zeros(amps.shape[1])
    for i in range(amps.shape[0]):  # a test helper; 1,000 steps
        acc = acc + k * (amps[i] - acc)
        speed[i] = acc
    return speed**2


# -- published localisation figures (Cholewiak, Brill & Schwab 2004) --------------------

@pytest.mark.parametrize(("n_tactors", "published"), [(6, 0.97), (8, 0.92), (12, 0.74)])
def test_single_tactor_localisation_matches_cholewiak(n_tactors: int, published: float) -> None:
    layout = Layout.from_angles([k * 360.0 / n_tactors for k in range(n_tactors)])
    targets = layout.angles  # the observer names one of the tactors
    reps = 3000
    vib = np.stack([steady(np.eye(n_tactors)[k]) for k in range(n_tactors)])
    cues = sense_cues(T_S, vib, layout).take(np.repeat(np.arange(n_tactors), reps))
    pc = perceive(cues, layout, targets, ModelParams(), np.random.default_rng(1))
    truth = np.repeat(targets, reps)
    accuracy = float(np.mean(np.abs(wrap(pc.response_deg - truth)) < 1e-6))
    assert accuracy == pytest.approx(published, abs=0.05)


def test_localisation_is_best_at_navel_and_spine() -> None:
    layout = Layout.from_angles([k * 30.0 for k in range(12)])
    reps = 3000
    vib = np.stack([steady(np.eye(12)[k]) for k in range(12)])
    pc = perceive(sense_cues(T_S, vib, layout).take(np.repeat(np.arange(12), reps)), layout,
                  layout.angles, ModelParams(), np.random.default_rng(2))
    ok = (pc.response_deg == np.repeat(layout.angles, reps)).reshape(12, reps).mean(axis=1)
    assert ok[0] > ok[3] and ok[6] > ok[3] and ok[0] > ok[9] and ok[6] > ok[9]


def test_bias_at_oblique_directions_points_to_the_midline() -> None:
    layout = Layout.from_angles([k * 45.0 for k in range(8)])
    reps = 4000
    vib = np.stack([steady(np.eye(8)[k]) for k in range(8)])
    pc = perceive(sense_cues(T_S, vib, layout).take(np.repeat(np.arange(8), reps)), layout,
                  layout.angles, ModelParams(), np.random.default_rng(3))
    signed = wrap(pc.site_deg - np.repeat(layout.angles, reps)).reshape(8, reps).mean(axis=1)
    # 45 and 315 lean to the navel (0), 135 and 225 to the spine (180), by up to ~10 deg
    assert signed[1] < -5 and signed[7] > 5
    assert signed[3] > 5 and signed[5] < -5
    assert np.all(np.abs(signed) < 11)
    # none at the midline and the flanks
    assert np.all(np.abs(signed[[0, 2, 4, 6]]) < 1.0)


def test_answers_err_towards_the_midline() -> None:
    """With 12 tactors, a stimulus at 30 deg is mistaken for 0 more often than for 60."""
    layout = Layout.from_angles([k * 30.0 for k in range(12)])
    reps = 6000
    vib = steady(np.eye(12)[1])[None]
    pc = perceive(sense_cues(T_S, vib, layout).take(np.zeros(reps, dtype=int)), layout,
                  layout.angles, ModelParams(), np.random.default_rng(4))
    assert np.mean(pc.response_deg == 0.0) > 2 * np.mean(pc.response_deg == 60.0)


# -- the ideal observer perceives the energy law where it is rendered ------------------

@pytest.mark.parametrize("layout", [Layout.even(6), Layout.even(8),
                                    Layout.from_angles([10, 80, 170, 200, 290])])
def test_ideal_observer_feels_energy_law_where_rendered(layout: Layout) -> None:
    rng = np.random.default_rng(5)
    x = rng.uniform(0, 360, 200)
    amps = amplitudes(layout, x, "energy")  # (200, N), steady state
    vib = np.repeat(amps[:, None, :], 50, axis=1)
    ideal = noiseless().replace(detect_amplitude=0.0)  # feels any vibration
    pc = perceive(sense_cues(T_S[:50], vib, layout, ideal), layout, TargetSet.even(24), ideal,
                  np.random.default_rng(6))
    assert np.max(np.abs(wrap(pc.perceived_deg - x))) < 1e-9


def test_ideal_observer_feels_paper_law_quarter_point_displaced() -> None:
    """It perceives what is rendered, not the target: the paper's law at a quarter point
    is felt nearer the near tactor once the weights are squared amplitudes."""
    layout = Layout.even(6)
    ideal = noiseless()
    amps = amplitudes(layout, 45.0, "paper")
    pc = perceive_vibration(T_S, steady(amps), layout, TargetSet.even(24), ideal)
    w = amps**2
    expected = 30.0 + 60.0 * w[1] / (w[0] + w[1])
    assert pc.perceived_deg[0] == pytest.approx(expected, abs=1e-9)
    assert abs(pc.perceived_deg[0] - 45.0) > 1.0


def test_gamma_sets_the_weights() -> None:
    layout = Layout.even(6)
    amps = amplitudes(layout, 60.0 - 10.0, "linear")
    for gamma in (1.0, 2.0, 3.0):
        p = noiseless(ModelParams(gamma=gamma))
        pc = perceive_vibration(T_S, steady(amps), layout, TargetSet.even(24), p)
        w = amps**gamma
        assert pc.perceived_deg[0] == pytest.approx(30 + 60 * w[1] / (w[0] + w[1]), abs=1e-9)


# -- cues ------------------------------------------------------------------------------

def test_dynamic_cue_reads_the_dwell_times() -> None:
    layout = Layout.even(6)
    stim = make_stimulus(layout, 45.0, "dynamic")  # 600 ms on 30 deg, 200 ms on 90 deg
    t = np.arange(1000) / 1000.0
    cues = sense_cues(t, stim.amplitudes(t), layout)
    assert cues.pair[0] == 0
    # each dwell plus the part of the two 100 ms transits where its tactor dominates
    assert 0.62 <= cues.dwell_a_s[0] <= 0.70
    assert 0.22 <= cues.dwell_b_s[0] <= 0.30
    assert cues.dwell_a_s[0] - cues.dwell_b_s[0] == pytest.approx(0.4, abs=0.002)
    static = sense_cues(t, make_stimulus(layout, 45.0, "static").amplitudes(t), layout)
    assert static.dwell_b_s[0] == 0.0  # no motion: no dynamic cue


def test_dynamic_cue_is_used_only_for_moving_stimuli() -> None:
    layout = Layout.even(6)
    t = np.arange(900) / 1000.0
    targets = TargetSet.even(24)
    p = ModelParams()
    for mode, used in (("static", False), ("dynamic", True)):
        stim = make_stimulus(layout, 60.0, mode)
        pc = perceive_vibration(t, erm(t, stim.amplitudes(t)), layout, targets, p)
        assert bool(pc.dynamic_cue[0]) is used
        assert pc.kind[0] == KIND_FUNNELLED or pc.two_points[0]


def test_dynamic_beats_static_between_tactors_with_a_simple_erm() -> None:
    layout = Layout.even(6)
    targets = TargetSet.even(24)
    p = ModelParams()
    between = [x for x in targets.angles if not layout.is_on_tactor(x)]
    acc = {}
    for mode, dur in (("static", p.observe_static_s), ("dynamic", p.observe_dynamic_s)):
        t = np.arange(round(dur * 1000)) / 1000.0
        vib = np.stack([erm(t, make_stimulus(layout, x, mode).amplitudes(t)) for x in between])
        reps = 400
        cues = sense_cues(t, vib, layout, p).take(np.repeat(np.arange(len(between)), reps))
        pc = perceive(cues, layout, targets, p, np.random.default_rng(7))
        acc[mode] = np.mean(pc.response_deg == np.repeat(between, reps))
    assert acc["dynamic"] > acc["static"] + 0.15


def test_single_and_silent_tactors() -> None:
    layout = Layout.even(6)
    targets = TargetSet.even(24)
    p = noiseless()
    on = perceive_vibration(T_S, steady(np.eye(6)[2]), layout, targets, p)
    assert on.kind[0] == KIND_SINGLE and on.response_deg[0] == 150.0
    off = perceive_vibration(T_S, np.zeros((T_S.size, 6)), layout, targets, p,
                             np.random.default_rng(8))
    assert off.kind[0] == KIND_NONE and off.guessed[0]
    assert off.response_deg[0] in targets.angles


def test_two_point_percepts_answer_at_the_stronger_tactor() -> None:
    layout = Layout.even(6)
    p = noiseless().replace(p_two_points=1.0)
    amps = amplitudes(layout, 45.0, "paper")
    pc = perceive_vibration(T_S, steady(amps), layout, TargetSet.even(24), p)
    assert pc.two_points[0] and pc.response_deg[0] == 30.0


def test_lapses_answer_at_random() -> None:
    layout = Layout.even(6)
    p = noiseless().replace(lapse=1.0)
    vib = np.repeat(steady(np.eye(6)[0])[None], 2000, axis=0)
    pc = perceive_vibration(T_S, vib, layout, TargetSet.even(24), p, np.random.default_rng(9))
    assert pc.guessed.all()
    counts = np.bincount(pc.response_index, minlength=24)
    assert counts.min() > 40  # roughly uniform over the 24 targets


def test_perception_is_reproducible_with_a_seed() -> None:
    layout = Layout.even(6)
    vib = np.stack([steady(amplitudes(layout, x, "paper")) for x in np.arange(0, 360, 15.0)])
    cues = sense_cues(T_S, vib, layout).take(np.tile(np.arange(24), 20))
    a = perceive(cues, layout, TargetSet.even(24), ModelParams(), np.random.default_rng(11))
    b = perceive(cues, layout, TargetSet.even(24), ModelParams(), np.random.default_rng(11))
    assert np.array_equal(a.response_deg, b.response_deg)
    assert np.array_equal(a.site_deg, b.site_deg)


# -- parameters ------------------------------------------------------------------------

@pytest.mark.parametrize("change", [
    {"gamma": 0.0}, {"lapse": 1.5}, {"p_two_points": -0.1}, {"weber_amplitude": float("nan")},
    {"loc_sd_min_deg": 20.0}, {"dominance_margin": 0.5}, {"movement_s": 0.0},
])
def test_bad_parameters_are_refused(change: dict[str, float]) -> None:
    with pytest.raises(ConfigError, match="ModelParams"):
        ModelParams().replace(**change)


def test_unknown_parameter_is_refused() -> None:
    with pytest.raises(ConfigError, match="unknown model parameter 'gama'"):
        ModelParams().replace(gama=2.0)


def test_individual_observers_vary_around_the_typical_one() -> None:
    rng = np.random.default_rng(12)
    people = [draw_participant(rng) for _ in range(400)]
    wa = np.array([p.weber_amplitude for p in people])
    assert np.median(wa) == pytest.approx(ModelParams().weber_amplitude, rel=0.1)
    assert wa.std() > 0.02
    assert all(p.gamma == 2.0 and p.observe_dynamic_s == 0.9 for p in people)
    same = draw_participant(np.random.default_rng(1), spread=Spread(0, 0, 0, 0))
    assert same == ModelParams()


def test_sense_cues_checks_shapes() -> None:
    layout = Layout.even(6)
    with pytest.raises(ConfigError, match="shape"):
        sense_cues(T_S, np.zeros((T_S.size, 5)), layout)
    with pytest.raises(ConfigError, match="sample times"):
        sense_cues(T_S[:10], np.zeros((T_S.size, 6)), layout)
    with pytest.raises(ConfigError, match="increasing"):
        sense_cues(np.zeros(3), np.zeros((3, 6)), layout)


# -- one trial at a time: the same numbers as a batch ------------------------------------


def _window(rng: np.random.Generator, n: int, kind: int) -> np.ndarray:
    """A vibration window of a few shapes: silent, one tactor, a pair, a moving pair."""
    v = np.zeros((n, 6))
    a = int(rng.integers(0, 6))
    b = (a + 1) % 6
    if kind >= 1:
        v[:, a] = rng.uniform(0.0, 1.0) * (1.0 - np.exp(-np.arange(n) / 40.0))
    if kind >= 2:
        v[:, b] = rng.uniform(0.0, 1.0) * (1.0 - np.exp(-np.arange(n) / 40.0))
    if kind >= 3:
        swing = 0.5 + 0.5 * np.sin(np.arange(n) / rng.uniform(20.0, 200.0))
        v[:, a] *= swing
        v[:, b] *= 1.0 - swing
    return v * (rng.random((n, 6)) < 0.98)  # a few dropped samples


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 900), kind=st.integers(0, 3))
def test_one_window_gives_the_cues_of_the_batch_path(seed: int, n: int, kind: int) -> None:
    """The one-window path (the pair's columns only) and the batch path give the same
    numbers, bit for bit."""
    rng = np.random.default_rng(seed)
    layout = Layout.even(6)
    p = ModelParams()
    t = np.arange(n) / 1000.0
    v = _window(rng, n, kind)
    one = sense_cues(t, v, layout, p)
    w = v[None] ** p.gamma
    dt = np.full(n, 1e-3) if n == 1 else np.append(np.diff(t), np.diff(t)[-1])
    total = float(dt.sum())
    w_mean = np.einsum("knj,n->kj", w, dt) / total
    cw, _ = layout.neighbour_indices()
    many = _sense_many(v[None], w, w_mean, one.pair, cw[one.pair], dt, total, p)
    for f in _CUE_FIELDS:
        a, b = np.asarray(getattr(one, f)), np.asarray(getattr(many, f))
        assert a.shape == b.shape == (1,) and a.tolist() == b.tolist(), f


@pytest.mark.parametrize("layout", [Layout.even(6), Layout.from_angles([0, 50, 110, 180,
                                                                         250, 300])])
def test_the_sites_made_once_are_those_of_each_trial(layout: Layout) -> None:
    """The candidate sites, their SDs and the centre terms one trial's percept reads
    from the cache are, bit for bit, what the observer's functions give for them."""
    p = ModelParams(loc_sd_min_deg=3.0, midline_bias_deg=6.0)
    s = _sites(layout, p)
    mids = layout.angles + layout.gaps_deg() / 2.0
    for (sites, sd, log_sd), want in ((s.single, layout.angles), (s.pair, mids)):
        want_sd = np.maximum(localisation_sd_deg(want, p), 1e-9)
        assert sites.tolist() == want.tolist() and sd.tolist() == want_sd.tolist()
        assert log_sd.tolist() == np.log(want_sd).tolist()
    assert len(s.centre) == 2 * layout.n
    for c in [*layout.angles.tolist(), *mids.tolist()]:
        assert s.centre[c] == (float(bias_deg(c, p)),
                               max(float(localisation_sd_deg(c, p)), 0.0))
    assert _sites(Layout(tuple(layout.angles_deg)), ModelParams(loc_sd_min_deg=3.0,
                  midline_bias_deg=6.0)) is s  # equal layouts and observers share it
    assert _sites(layout, ModelParams()) is not s


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 900), kind=st.integers(0, 3),
       params=st.sampled_from([ModelParams(), ModelParams(lapse=0.5, p_two_points=0.9),
                               ModelParams(loc_sd_min_deg=3.0, midline_bias_deg=6.0)]),
       layout=st.sampled_from([Layout.even(6), Layout.from_angles([0, 50, 110, 180, 250,
                                                                   300])]))
def test_one_trial_is_perceived_as_in_a_batch(seed: int, n: int, kind: int,
                                              params: ModelParams, layout: Layout) -> None:
    """The one-trial path (scalars, with the sites of its layout and observer made once)
    and the batch path give the same numbers, bit for bit, from the same cues and
    draws."""
    rng = np.random.default_rng(seed)
    cues = sense_cues(np.arange(n) / 1000.0, _window(rng, n, kind), layout, params)
    tgt = TargetSet.even(24).angles
    z, u, g = rng.standard_normal((3, 1)), rng.random((2, 1)), rng.integers(0, 24, size=1)
    cw, _ = layout.neighbour_indices()
    one = _perceive_one(cues, _sites(layout, params), tgt, params,
                        z[:, 0].tolist(), u[:, 0].tolist(), int(g[0]))
    many = _perceive_many(cues, layout.angles, cw, layout.gaps_deg(), tgt, params, z, u, g)
    for f in Percepts.__dataclass_fields__:
        a, b = np.asarray(getattr(one, f)), np.asarray(getattr(many, f))
        assert a.shape == b.shape == (1,) and a.tolist() == b.tolist(), f


@given(seed=st.integers(0, 2**32 - 1), kind=st.integers(0, 3),
       n_targets=st.sampled_from([1, 2, 6, 7, 24, 25, 48, 360]))
def test_one_trial_takes_the_draws_of_a_batch_of_one(seed: int, kind: int,
                                                     n_targets: int) -> None:
    """perceive() of one trial draws its guess without a size; the answer and the
    generator's state after it are those of the batch path's draws of size 1."""
    layout, p = Layout.even(6), ModelParams(lapse=0.5)
    cues = sense_cues(np.arange(300) / 1000.0, _window(np.random.default_rng(seed), 300,
                                                       kind), layout, p)
    tgt = TargetSet.even(n_targets).angles
    got_rng, want_rng = np.random.default_rng(seed), np.random.default_rng(seed)
    got = perceive(cues, layout, tgt, p, got_rng)
    z, u = want_rng.standard_normal((3, 1)), want_rng.random((2, 1))
    g = want_rng.integers(0, tgt.size, size=1)
    cw, _ = layout.neighbour_indices()
    want = _perceive_many(cues, layout.angles, cw, layout.gaps_deg(), tgt, p, z, u, g)
    for f in Percepts.__dataclass_fields__:
        assert np.asarray(getattr(got, f)).tolist() == np.asarray(getattr(want, f)).tolist(), f
    assert got_rng.bit_generator.state == want_rng.bit_generator.state


@given(seed=st.integers(0, 2**32 - 1), n_targets=st.sampled_from([1, 2, 6, 24, 25]),
       params=st.sampled_from([ModelParams(), ModelParams(exgauss_sigma_s=0.4,
                                                          nondecision_s=0.0)]))
def test_one_decision_time_is_the_draw_of_size_one(seed: int, n_targets: int,
                                                   params: ModelParams) -> None:
    """The model's per-trial decision time equals decision_s of one draw, bit for bit,
    and leaves the generator where decision_s leaves it (the floor included)."""
    got_rng, want_rng = np.random.default_rng(seed), np.random.default_rng(seed)
    for _ in range(20):
        got = one_decision_s(got_rng, n_targets, params)
        want = decision_s(want_rng, 1, n_targets, params)
        assert type(got) is float and got == float(want[0])
    assert got_rng.bit_generator.state == want_rng.bit_generator.state


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_window_with_a_non_finite_amplitude_is_refused(bad: float) -> None:
    layout = Layout.even(6)
    vib = np.full((50, 6), 0.2)
    vib[17, 3] = bad
    with pytest.raises(ConfigError, match="finite"):
        sense_cues(np.arange(50) / 1000.0, vib, layout)


@pytest.mark.parametrize("low, high", [(-0.3, 0.9), (0.1, 1.4), (-0.3, 1.4)])
def test_amplitudes_outside_0_1_are_felt_as_their_nearest_bound(low: float,
                                                                 high: float) -> None:
    """A sense function may return amplitudes a little outside [0, 1]: they are felt as
    0 and 1, exactly as the clipped window."""
    layout = Layout.even(6)
    rng = np.random.default_rng(4)
    vib = rng.uniform(low, high, (120, 6))
    t = np.arange(120) / 1000.0
    got, expected = sense_cues(t, vib, layout), sense_cues(t, np.clip(vib, 0.0, 1.0), layout)
    for name in ("pair", "w_a", "w_b", "felt_a", "felt_b", "dwell_a_s", "dwell_b_s",
                 "overlap", "duration_s"):
        np.testing.assert_array_equal(getattr(got, name), getattr(expected, name))
    assert float(got.w_a[0]) <= 1.0 and float(got.w_b[0]) <= 1.0
