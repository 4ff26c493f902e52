"""The mixed-model engine without R: R's coding, the simplification rule, the lme4 error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from support.r_reference import lme4_available
from tactorbelt.analysis.models import lme4 as lme4_mod
from tactorbelt.analysis.models.glmm import (
    ModelSpec,
    RandomTerm,
    fit_glmm,
    fit_simplified,
    fixed_design,
)


def _frame(seed: int = 3, participants: int = 6, sd: float = 0.8) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    p_int = rng.normal(0, sd, participants)
    for p in range(participants):
        for cond in ("static", "dynamic"):
            for t in range(12):
                on = int(t % 4 == 0)
                eta = p_int[p] + (2.0 if on else (1.0 if cond == "dynamic" else 0.0))
                for _ in range(4):
                    rows.append({"correct": int(rng.random() < 1 / (1 + np.exp(-eta))),
                                 "condition": cond, "on_tactor": on,
                                 "participant": f"P{p}", "target": str(t * 30)})
    return pd.DataFrame(rows)


def test_fixed_design_names_and_codes_terms_as_r() -> None:
    grid = pd.MultiIndex.from_product([["static", "dynamic"], [0, 1], ["none", "count"]],
                                      names=["condition", "on_tactor", "load"])
    df = grid.to_frame(index=False)
    x, names, dropped = fixed_design(df, ["condition", "on_tactor", "load"])
    assert names == ["(Intercept)", "conditionstatic", "on_tactor", "loadnone",
                     "conditionstatic:on_tactor", "conditionstatic:loadnone",
                     "on_tactor:loadnone", "conditionstatic:on_tactor:loadnone"]
    assert not dropped and x.shape == (8, 8)
    assert x[:, 1].tolist() == (df["condition"] == "static").astype(float).tolist()
    df["copy"] = df["on_tactor"]
    _, names, dropped = fixed_design(df, ["on_tactor", "copy"])
    assert names == ["(Intercept)", "on_tactor"] and dropped == ["copy", "on_tactor:copy"]


def test_glmm_recovers_a_participant_sd_and_reports_wald_statistics() -> None:
    df = _frame(participants=12, sd=1.0)
    spec = ModelSpec("correct", ("condition", "on_tactor"), (RandomTerm("participant"),))
    fit = fit_glmm(df, spec)
    fe = fit.fixed_effects["conditionstatic"]
    assert fe.estimate < 0 and fe.ci_low < fe.estimate < fe.ci_high
    assert fe.z == pytest.approx(fe.estimate / fe.se)
    assert 0.3 < fit.random_effects["participant"]["sd"]["(Intercept)"] < 2.0
    assert not fit.singular and fit.converged


def test_singular_fits_are_simplified_by_the_stated_rule() -> None:
    df = _frame(sd=0.0)  # no participant or target variation at all
    spec = ModelSpec("correct", ("condition", "on_tactor"),
                     (RandomTerm("participant", ("condition",)), RandomTerm("target")))
    fit, steps = fit_simplified(df, spec, fit_glmm)
    assert steps[0]["singular"] and "slope" in steps[0]["action"]
    # the participant intercept is never dropped; a zero target SD is
    assert fit.spec.random[0] == RandomTerm("participant")
    assert all("participant" in s["formula"] for s in steps)
    assert steps[-1]["formula"] == fit.spec.formula()


def test_lme4_engine_without_r_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lme4_mod.shutil, "which", lambda _name: None)
    assert lme4_available() is not None
    spec = ModelSpec("correct", ("condition",), (RandomTerm("participant"),))
    with pytest.raises(lme4_mod.Lme4Unavailable, match="apt install r-base-core r-cran-lme4"):
        lme4_mod.fit_lme4(_frame(), spec)


def test_analyze_engine_lme4_without_r_exits_2_with_the_install_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from support.synthetic import synthesize_store
    from tactorbelt.cli import main

    store = tmp_path / "s.sqlite"
    synthesize_store(store, 3, repetitions=1, seed=2, samples=False)
    monkeypatch.setattr(lme4_mod.shutil, "which", lambda _name: None)
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(store), "--out", str(tmp_path / "out"), "--engine", "lme4"])
    assert exc.value.code == 2
    assert "apt install r-base-core r-cran-lme4" in capsys.readouterr().err


def test_synthetic_participants_can_differ_as_people_do(tmp_path: Path) -> None:
    """The benchmark's synthetic store gives participants their own accuracy: the
    accuracy model estimates the SD it was made with; the default store (everyone
    alike) fits the participant SD at about 0."""
    from support.synthetic import synthesize_store
    from tactorbelt.analysis.models.fit import fit_model, model_frame
    from tactorbelt.analysis.tables.load import load_stores
    from tactorbelt.analysis.tables.tables import prepare_trials

    sds = {}
    for name, sd in (("alike", 0.0), ("varied", 0.8)):
        store = tmp_path / f"{name}.sqlite"
        synthesize_store(store, 30, repetitions=2, seed=4, samples=False, timeout_rate=0.0,
                         participant_sd=sd, target_sd=sd / 2)
        tr = prepare_trials(load_stores([store]).trials)
        fit, _ = fit_model(model_frame(tr))
        sds[name] = fit.random_effects["participant"]["sd"]["(Intercept)"]
    assert sds["alike"] < 0.2
    assert 0.5 < sds["varied"] < 1.2, sds


def test_target_count_is_a_factor_in_numeric_order_named_as_r() -> None:
    """factor(n_targets) is coded as R codes it: the smallest count the reference (6 before
    12, though "12" < "6" as text), columns named factor(n_targets)<count>."""
    from tactorbelt.analysis.models.fit import model_spec
    from tactorbelt.analysis.models.glmm import term_column, term_levels

    df = pd.DataFrame({"condition": ["static", "dynamic"] * 3,
                       "n_targets": [6, 6, 12, 12, 24, 24]})
    assert term_column("factor(n_targets)") == "n_targets"
    assert term_levels(df, "factor(n_targets)") == [6.0, 12.0, 24.0]
    x, names, _ = fixed_design(df, ["condition", "factor(n_targets)"])
    assert names == ["(Intercept)", "conditionstatic", "factor(n_targets)12",
                     "factor(n_targets)24", "conditionstatic:factor(n_targets)12",
                     "conditionstatic:factor(n_targets)24"]
    assert x[:, 2].tolist() == [0, 0, 1, 1, 0, 0]
    frame = _frame().assign(n_targets=24)
    assert model_spec(frame)[0].fixed == ("condition", "on_tactor")  # one count: no term
    frame.loc[frame["participant"] == "P0", "n_targets"] = 12
    spec, _ = model_spec(frame)
    assert spec.fixed == ("condition", "on_tactor", "factor(n_targets)")
    assert "condition * on_tactor * factor(n_targets)" in spec.formula()


@pytest.mark.parametrize("slopes", [(), ("condition",)])
def test_laplace_gradient_is_the_derivative_of_the_deviance(slopes: tuple[str, ...]) -> None:
    """The analytic gradient over (theta, beta) (the modes move with both) equals central
    differences of the Laplace deviance."""
    from tactorbelt.analysis.models.glmm import GlmmData, _central_grad

    df = _frame(participants=8, sd=0.8)
    spec = ModelSpec("correct", ("condition", "on_tactor"),
                     (RandomTerm("participant", slopes), RandomTerm("target")))
    lap = GlmmData(df, spec).laplace()
    rng = np.random.default_rng(4)
    par = np.r_[rng.uniform(0.2, 0.9, lap.n_theta), rng.normal(0, 0.5, lap.p)]
    lower = np.full(par.size, -np.inf)
    _, grad = lap.dev_and_grad(par, lower)
    num = _central_grad(lap.dev, par, lower)
    assert grad == pytest.approx(num, rel=1e-5, abs=1e-4)


def test_a_variance_at_zero_is_left_when_it_is_no_minimum() -> None:
    """The deviance is even in a variance component at 0, so its gradient there is 0; a
    simplified model started from a singular fit's 0 used to stay at that saddle (the
    participant SD of this study: 0 instead of glmer's 0.358, deviance 1761.3 instead of
    1735.5)."""
    from support.power_trials import no_effect, trials_of
    from tactorbelt.analysis.models.fit import fit_model
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.power.glmm import simulate_frame

    frame = simulate_frame(trials_of(paper_study()), no_effect(), 6,
                           np.random.default_rng([2, 6, 1_000_017]))
    fit, js = fit_model(frame)
    assert not fit.singular
    assert fit.random_effects["participant"]["sd"]["(Intercept)"] == pytest.approx(0.358,
                                                                                 abs=0.005)
    assert fit.deviance == pytest.approx(1735.526, abs=0.01)  # glmer: 1735.5258


def test_simulated_responses_follow_the_fit() -> None:
    """GlmmData.simulate draws new random effects from the fit (lme4's simulate): the
    simulated accuracy matches the model's, and a seed gives the same draws."""
    from tactorbelt.analysis.models.glmm import GlmmData

    df = _frame(participants=10)
    spec = ModelSpec("correct", ("condition", "on_tactor"), (RandomTerm("participant"),))
    fit = fit_glmm(df, spec)
    data = GlmmData(df, spec)
    a = data.simulate(fit, np.random.default_rng(1), 200)
    b = data.simulate(fit, np.random.default_rng(1), 200)
    assert a.shape == (200, len(df)) and np.array_equal(a, b)
    assert set(np.unique(a).tolist()) <= {0.0, 1.0}
    assert abs(a.mean() - df["correct"].mean()) < 0.03
