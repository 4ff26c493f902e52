"""Power for effect sizes the user names (``tactorbelt power --odds-ratio``).

The simulated trials follow the named effect sizes, each simulated study is analysed
by the report's own accuracy model (the same function, formula and Wald test), and
the power answers the planning question: large effects are found, no effect is found
about as often as the test's false-positive rate in one direction.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from support.cli import tactorbelt
from support.power_trials import no_effect, trials_of
from tactorbelt._errors import ConfigError
from tactorbelt.analysis.models.fit import fit_model
from tactorbelt.experiment.study import Study, paper_study, template_toml
from tactorbelt.power.glmm import (
    NamedEffect,
    headline_statistics,
    simulate_frame,
    simulate_glmm_studies,
)


def test_the_paper_design_is_its_test_trials() -> None:
    d = trials_of(paper_study())
    assert d.n == 240 and d.n_targets == 24
    assert sorted(set(d.condition.tolist())) == ["dynamic", "static"]
    assert int(d.on_tactor.sum()) == 6 * 10  # 6 on-tactor targets x 5 reps x 2 blocks


def test_simulated_trials_have_the_named_accuracies() -> None:
    eff = NamedEffect(2.0, accuracy=0.4, on_tactor_accuracy=0.95, participant_sd=0.0,
                      slope_sd=0.0, target_sd=0.0)
    frame = simulate_frame(trials_of(paper_study()), eff, 200,
                           np.random.default_rng(3))
    between = frame["on_tactor"] == 0
    for cond, p in (("static", 0.4), ("dynamic", eff.dynamic_accuracy())):
        sel = frame.loc[between & (frame["condition"] == cond), "correct"]
        se = math.sqrt(p * (1 - p) / len(sel))
        assert abs(sel.mean() - p) < 4 * se, (cond, sel.mean(), p)
    on = frame.loc[~between, "correct"]
    assert abs(on.mean() - 0.95) < 4 * math.sqrt(0.95 * 0.05 / len(on))
    assert eff.dynamic_accuracy() == pytest.approx(0.4 * 2 / (0.6 + 0.4 * 2))


def test_the_report_model_recovers_the_named_odds_ratio() -> None:
    eff = NamedEffect(1.8, accuracy=0.5, participant_sd=0.6, slope_sd=0.2, target_sd=0.3)
    frame = simulate_frame(trials_of(paper_study()), eff, 30,
                           np.random.default_rng(11))
    fit, js = fit_model(frame)
    fe = fit.fixed_effects["conditionstatic"]
    assert abs(fe.estimate - eff.headline) < 3 * fe.se, (fe.estimate, fe.se, eff.headline)
    assert "condition * on_tactor" in js["formula"]


def test_large_effects_are_found_and_no_effect_rarely() -> None:
    """The headline is the likelihood ratio referred to F(k, participants - 1): a large
    effect is found, no effect about as rarely as alpha / 2 in the named direction."""
    design = trials_of(paper_study())
    big = simulate_glmm_studies(design, NamedEffect(4.0), 6, range(6), seed=2)
    assert all(o.found(0.05) for o in big)
    null = simulate_glmm_studies(design, no_effect(), 6, range(12), seed=3)
    assert sum(o.found(0.05) for o in null) <= 2
    # OR < 1 names "static better": found in that direction
    reverse = simulate_glmm_studies(design, NamedEffect(1 / 4.0), 6, range(3), seed=2)
    assert all(o.found(0.05) for o in reverse)
    assert all(np.mean(o.static_acc) > np.mean(o.dynamic_acc) for o in reverse)


def test_power_uses_the_likelihood_ratio_referred_to_f() -> None:
    from scipy import stats

    design = trials_of(paper_study())
    frame = simulate_frame(design, NamedEffect(2.0), 5, np.random.default_rng([5, 5, 0]))
    res = headline_statistics(frame)
    assert res.p == pytest.approx(stats.f.sf(res.lrt / 2, 2, 4))  # 2 condition terms
    assert res.lrt_p == pytest.approx(stats.chi2.sf(res.lrt, 2)) and res.p > res.lrt_p
    (out,) = simulate_glmm_studies(design, NamedEffect(2.0), 5, [0], seed=5)
    assert out.p_value == pytest.approx(res.p)
    assert out.direction_ok == (res.estimate < 0)


def test_null_effect_is_an_odds_ratio_of_one() -> None:
    eff = no_effect(accuracy=0.6)
    assert eff.odds_ratio == 1.0 and eff.headline == 0.0 and eff.accuracy == 0.6
    assert eff.dynamic_accuracy() == pytest.approx(0.6)


@pytest.mark.parametrize("kwargs, message", [
    ({"odds_ratio": 1.0}, "no effect"),
    ({"odds_ratio": -2.0}, "above 0"),
    ({"odds_ratio": 2.0, "accuracy": 1.0}, "accuracy must be a proportion"),
    ({"odds_ratio": 2.0, "target_sd": -1.0}, "target sd must be between 0 and 5"),
])
def test_bad_effect_sizes_are_refused(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        NamedEffect(**kwargs)


def test_a_factorial_study_needs_the_count_named() -> None:
    study = Study.from_toml(template_toml("resolution"))
    with pytest.raises(ConfigError, match="dynamic vs static at N"):
        trials_of(study)
    d = trials_of(study, 36)
    assert d.n_targets == 36 and np.unique(d.target_deg).size == 36
    assert d.n == 36 * 2 * 2  # static and dynamic blocks of 36, 2 repetitions each
    every = trials_of(study, all_counts=True)
    assert every.counts is not None and every.n == (12 + 24 + 36 + 48) * 2 * 2
    frame = simulate_frame(every, NamedEffect(2.0), 3, np.random.default_rng(0))
    assert sorted(frame["n_targets"].unique().tolist()) == [12, 24, 36, 48]


def test_power_command_with_named_effect(tmp_path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "p"
    proc = tactorbelt("power", "--odds-ratio", "3", "--participants", "3,6", "--sims", "4",
                      "--jobs", "1", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "GLMM" in proc.stdout and "likelihood ratio" in proc.stdout
    doc = json.loads((out / "power.json").read_text())
    assert "headline" in doc["test"] and doc["effect_sizes"]["odds_ratio"] == 3.0
    assert [r["n_participants"] for r in doc["rows"]] == [3, 6]
    assert (out / "power.png").stat().st_size > 0


def test_power_command_bad_named_effect(tmp_path) -> None:  # type: ignore[no-untyped-def]
    res = tmp_path / "res.toml"
    res.write_text(template_toml("resolution"), encoding="utf-8")
    proc = tactorbelt("power", "--study", str(res), "--odds-ratio", "2", "--effect",
                      "interaction", "--sims", "2", "-o", str(tmp_path / "o"))
    assert proc.returncode == 2 and "error: --odds-ratio plans for the condition" in proc.stderr
    proc = tactorbelt("power", "--odds-ratio", "2", "--participants", "2,4", "--sims", "2",
                      "-o", str(tmp_path / "o2"))
    assert proc.returncode == 2 and "at least 3 participants" in proc.stderr
    proc = tactorbelt("power", "--odds-ratio", "2", "--accuracy", "1.5", "--sims", "2",
                      "-o", str(tmp_path / "o3"))
    assert proc.returncode == 2 and "--accuracy" in proc.stderr


def test_a_fit_whose_warm_start_diverges_still_converges() -> None:
    """This simulated study made the PIRLS warm start diverge (a singular system) in the
    optimiser's first stage; it must fit, and agree with lme4::glmer (R 4.2.2, lme4
    1.1.31 on the same data: conditionstatic 1.7468, SE 0.2770)."""
    frame = simulate_frame(trials_of(paper_study()), NamedEffect(0.25), 6,
                           np.random.default_rng([2, 6, 2]))
    fit, js = fit_model(frame)
    fe = fit.fixed_effects["conditionstatic"]
    assert fe.estimate == pytest.approx(1.7468, rel=0.01)
    assert fe.se == pytest.approx(0.2770, rel=0.05)
    assert js["converged"]
