"""The trial state machine: home zone, acquisition, dwell, timeout, abort (pure, no clock)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactorbelt import TactorbeltError
from tactorbelt.experiment.schedule import ScheduledTrial
from tactorbelt.experiment.trial import (
    ResponseRule,
    TrialMachine,
    TrialResult,
    TrialState,
    cursor_angle_deg,
)
from tactorbelt.geometry import TargetSet
from tactorbelt.inputs.base import CursorSample

MS = 1_000_000
TRIAL = ScheduledTrial(3, "test", 1, "dynamic", "dynamic", 1, 45.0, False)
TARGETS = TargetSet.even(24)


def _machine(**rule: int | float) -> TrialMachine:
    return TrialMachine(TRIAL, ResponseRule(**rule), TARGETS)  # type: ignore[arg-type]


def _point(angle_deg: float, r: float) -> tuple[float, float]:
    a = math.radians(angle_deg)
    return r * math.sin(a), r * math.cos(a)


@pytest.mark.parametrize(("x", "y", "deg"), [
    (0.0, 1.0, 0.0), (1.0, 0.0, 90.0), (0.0, -1.0, 180.0), (-1.0, 0.0, 270.0),
    (1.0, 1.0, 45.0), (-1.0, 1.0, 315.0),
])
def test_cursor_angle_is_clockwise_from_front(x: float, y: float, deg: float) -> None:
    assert cursor_angle_deg(x, y) == pytest.approx(deg, abs=1e-6)
    assert 0.0 <= cursor_angle_deg(x, y) < 360.0


def test_home_zone() -> None:
    m = _machine(home_radius=0.15)
    assert m.at_home(CursorSample(0, 0.1, 0.1))
    assert not m.at_home(CursorSample(0, 0.2, 0.0))


def test_acquisition_at_first_sample_beyond_threshold() -> None:
    m = _machine(threshold=0.9)
    m.start(1000 * MS)
    for k, r in enumerate([0.0, 0.3, 0.6, 0.89, 0.95, 1.0]):
        state = m.feed(1000 * MS + k * 10 * MS, *_point(47.0, r))
        if r <= 0.9:
            assert state is TrialState.STIMULUS
        else:
            break
    assert state is TrialState.RESPONSE
    res = m.result
    assert res.status == "done"
    assert res.acquired_ns == 1040 * MS  # the 0.95 sample
    assert res.onset_ns is not None
    assert res.rt_s == (res.acquired_ns - res.onset_ns) / 1e9 == pytest.approx(0.04)
    assert res.response_deg == pytest.approx(47.0)
    assert res.response_target_deg == 45.0
    assert res.correct is True
    assert res.n_samples == 5
    assert [row[0] for row in res.sample_rows()] == pytest.approx([0, 0.01, 0.02, 0.03, 0.04])


def test_wrong_answer_selects_nearest_target() -> None:
    m = _machine()
    m.start(0)
    m.feed(0, *_point(353.0, 1.0))
    assert m.result.response_target_deg == 0.0  # 353 is nearest to 0 (wraps)
    assert m.result.correct is False


def test_dwell_must_be_held() -> None:
    m = _machine(threshold=0.5, dwell_ns=30 * MS)
    m.start(0)
    seq = [0.6, 0.6, 0.4, 0.6, 0.6, 0.6, 0.6]  # dips back at 20 ms
    states = [m.feed(k * 10 * MS, *_point(90.0, r)) for k, r in enumerate(seq)]
    assert states[:-1] == [TrialState.STIMULUS] * 6
    assert states[-1] is TrialState.RESPONSE
    assert m.result.crossed_ns == 30 * MS
    assert m.result.acquired_ns == 60 * MS
    assert m.result.rt_s == pytest.approx(0.06)


def test_timeout() -> None:
    m = _machine(timeout_ns=100 * MS)
    m.start(0)
    for k in range(10):
        assert m.feed(k * 10 * MS, 0.0, 0.0) is TrialState.STIMULUS
    assert m.feed(100 * MS, 0.0, 0.0) is TrialState.TIMEOUT
    r = m.result
    assert r.status == "timeout"
    assert r.rt_s is None and r.response_deg is None and r.correct is None


def test_acquisition_on_the_timeout_sample_counts() -> None:
    m = _machine(timeout_ns=100 * MS)
    m.start(0)
    assert m.feed(100 * MS, 0.0, 1.0) is TrialState.RESPONSE


def test_stimulus_due_off_after_longest_presentation() -> None:
    m = _machine(max_presentation_ns=2000 * MS)
    assert not m.stimulus_due_off(5000 * MS)  # not started
    m.start(1000 * MS)
    assert not m.stimulus_due_off(2999 * MS)
    assert m.stimulus_due_off(3000 * MS)


def test_abort_clears_the_response() -> None:
    m = _machine()
    m.start(0)
    m.feed(0, 0.0, 0.2)
    r = m.abort("device error: gone")
    assert m.state is TrialState.ABORTED
    assert r.status == "aborted" and r.abort_reason == "device error: gone"
    assert r.rt_s is None and r.correct is None
    assert r.n_samples == 1


def test_abort_before_onset() -> None:
    m = _machine()
    r = m.abort("paused")
    assert r.onset_ns is None and r.n_samples == 0


def test_illegal_transitions() -> None:
    m = _machine()
    with pytest.raises(TactorbeltError, match="expected state stimulus"):
        m.feed(0, 0.0, 0.0)
    m.start(0)
    with pytest.raises(TactorbeltError, match="expected state wait_home"):
        m.start(0)


def test_rule_from_study() -> None:
    from tactorbelt.experiment.study import paper_study

    rule = ResponseRule.from_study(paper_study())
    assert rule.threshold == 0.9
    assert rule.timeout_ns == 10_000 * MS


@given(onset=st.one_of(st.none(), st.integers(-2**62, 2**62)),
       offsets=st.lists(st.integers(-2**60, 2**60), max_size=50))
def test_sample_times_are_the_exact_formula(onset: int | None, offsets: list[int]) -> None:
    """``sample_times_s`` (vectorised) is ``(t - onset) / 1e9`` per sample, bit for bit,
    also where the difference is too large for an exact float."""
    res = TrialResult(trial=_machine().result.trial, onset_ns=onset)
    res.sample_t_ns = [(onset or 0) + d for d in offsets]
    expected = [(t - (onset or 0)) / 1e9 for t in res.sample_t_ns]
    got = res.sample_times_s()
    assert got == expected and all(type(v) is float for v in got)
