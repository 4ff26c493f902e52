"""The accuracy model's tests of the condition, its contrasts per target count, the RT
model's Satterthwaite tests, and how summary.json and the report present them (issue 39).

Agreement with R (emmeans, anova, pbkrtest, lmerTest) is in tests/test_stats_lme4.py;
here: the definitions, the contract of summary.json, the report's words, and what a
user relies on (the same seed gives the same bootstrap; the headline test changes with
the study's size as documented).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from support.synthetic import synthesize_store
from tactorbelt.analysis.models.contrasts import condition_contrasts
from tactorbelt.analysis.models.fit import (
    HEADLINE_TEST,
    PB_MAX_PARTICIPANTS,
    fit_model,
    model_frame,
)
from tactorbelt.analysis.models.glmm import ModelSpec, RandomTerm, fit_glmm
from tactorbelt.analysis.models.lrt import (
    condition_terms,
    likelihood_ratio,
    null_spec,
    parametric_bootstrap,
    pb_p_value,
    wald_condition,
)
from tactorbelt.analysis.models.satterthwaite import richardson_hessian, richardson_jacobian
from tactorbelt.analysis.summary import summarize
from tactorbelt.analysis.tables.load import load_stores
from tactorbelt.analysis.tables.tables import prepare_trials

COUNTS = [12, 24, 36]


@pytest.fixture(scope="module")
def resolution_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("resolution") / "res.sqlite"
    synthesize_store(path, 4, repetitions=2, seed=6, samples=False, timeout_rate=0.02,
                     participant_sd=0.6, slope_sd=0.3, target_sd=0.3, targets=COUNTS)
    return path


@pytest.fixture(scope="module")
def resolution_summary(resolution_store: Path) -> dict:
    summary = summarize(load_stores([resolution_store]), seed=4, pb_sims=9)
    return {"summary": summary, "json": json.loads(json.dumps(summary.to_json(),
                                                              allow_nan=False))}


def test_pbkrtest_p_counts_ratios_above_the_observed_among_the_positive() -> None:
    """pbkrtest 0.5: p = (1 + #{LRT* > LRT}) / (1 + #{LRT* > 0}); ratios at or below 0
    (a refit no better than the null) leave both counts."""
    p, npos, extreme = pb_p_value(2.0, np.array([1.0, 3.0, 0.0, -0.1, 2.0, 5.0, np.nan]))
    assert (npos, extreme) == (4, 2) and p == pytest.approx(3 / 5)
    assert pb_p_value(10.0, np.array([1.0, 2.0]))[0] == pytest.approx(1 / 3)


def test_condition_terms_and_the_null_model() -> None:
    names = ["(Intercept)", "conditionstatic", "on_tactor", "factor(n_targets)24",
             "conditionstatic:on_tactor", "conditionstatic:factor(n_targets)24",
             "on_tactor:factor(n_targets)24", "conditionstatic:on_tactor:factor(n_targets)24"]
    assert condition_terms(names) == [n for n in names if "condition" in n]
    spec = ModelSpec("correct", ("condition", "on_tactor", "factor(n_targets)"),
                     (RandomTerm("participant", ("condition",)), RandomTerm("target")))
    spec0 = null_spec(spec)
    assert spec0.fixed == ("on_tactor", "factor(n_targets)")
    assert spec0.random == spec.random  # the random slope stays
    assert spec0.formula() == ("correct ~ on_tactor * factor(n_targets) + "
                               "(1 + condition | participant) + (1 | target)")


def test_tests_of_one_study(resolution_store: Path) -> None:
    """The three tests of one resolution study: the LRT is 2 (log L - log L0) on the
    number of condition terms; the bootstrap is reproducible from its seed and its
    simulated ratios are not below 0 (each refit starts from the null refit)."""
    frame = model_frame(prepare_trials(load_stores([resolution_store]).trials))
    fit, _ = fit_model(frame)
    fit0 = fit_glmm(frame, null_spec(fit.spec), se=False)
    lr = likelihood_ratio(fit, fit0)
    k = len(condition_terms(list(fit.fixed_effects)))
    assert lr["df"] == k == 6  # condition x on_tactor x factor(n_targets), 3 counts
    assert lr["statistic"] == pytest.approx(2 * (fit.loglik - fit0.loglik))
    assert lr["p"] == pytest.approx(stats.chi2.sf(lr["statistic"], k))
    f = lr["f_reference"]  # the headline: LRT / k on F(k, participants - 1)
    assert (f["df1"], f["df2"]) == (k, 3)
    assert f["p"] == pytest.approx(stats.f.sf(lr["statistic"] / k, k, 3)) and f["p"] > lr["p"]
    w = wald_condition(fit)
    idx = [list(fit.fixed_effects).index(t) for t in w["terms"]]
    b = np.array([fit.fixed_effects[t].estimate for t in w["terms"]])
    assert w["statistic"] == pytest.approx(b @ np.linalg.solve(fit.vcov[np.ix_(idx, idx)], b))
    a = parametric_bootstrap(frame, fit, fit0, n_sim=6, seed=11)
    again = parametric_bootstrap(frame, fit, fit0, n_sim=6, seed=11)
    assert np.array_equal(a.ref, again.ref) and a.p == again.p
    assert np.all(a.ref > -1e-6) and a.n_sim == 6
    assert a.p == pb_p_value(a.statistic, a.ref)[0]


def test_contrasts_are_the_model_s_estimates_at_between_tactor_targets(
        resolution_store: Path) -> None:
    """At the reference count the dynamic - static contrast is minus conditionstatic
    (on_tactor = 0 is the reference too); the probability scale is the difference of
    the back-transformed linear predictors; Holm is statsmodels' over the counts."""
    from scipy.special import expit
    from statsmodels.stats.multitest import multipletests

    frame = model_frame(prepare_trials(load_stores([resolution_store]).trials))
    fit, _ = fit_model(frame)
    cs = condition_contrasts(fit, frame)
    assert [c["by"] for c in cs] == [{"n_targets": n, "on_tactor": 0} for n in COUNTS]
    fe = fit.fixed_effects["conditionstatic"]
    assert cs[0]["estimate"] == pytest.approx(-fe.estimate)
    assert cs[0]["se"] == pytest.approx(fe.se)
    inter = fit.fixed_effects["(Intercept)"].estimate
    assert cs[0]["probability"]["dynamic"] == pytest.approx(expit(inter))
    assert cs[0]["probability"]["static"] == pytest.approx(expit(inter + fe.estimate))
    p = [c["p"] for c in cs]
    assert [c["p_adjusted"] for c in cs] == pytest.approx(multipletests(p, method="holm")[1])
    assert all(c["z"] == pytest.approx(c["estimate"] / c["se"]) for c in cs)


def test_summary_json_carries_the_contract(resolution_summary: dict) -> None:
    """summary.json: mixed_model.formula with factor(n_targets), lme4's term names,
    mixed_model.tests (Wald, LRT, parametric bootstrap), contrasts per count, and the
    RT model's Satterthwaite df, t, p."""
    j = resolution_summary["json"]
    m = j["mixed_model"]
    assert "condition * on_tactor * factor(n_targets)" in m["formula"]
    assert {"factor(n_targets)24", "conditionstatic:factor(n_targets)36"} <= set(
        m["fixed_effects"])
    tests = {t["method"]: t for t in m["tests"]}
    assert set(tests) == {"Wald", "LRT", "parametric bootstrap"}
    assert all(t["term"] == "condition" for t in m["tests"])
    assert tests["LRT"]["df"] == tests["Wald"]["df"] == 6
    pb = tests["parametric bootstrap"]
    assert pb["n_sim"] == 9 and pb["computed"] and 0 < pb["p"] <= 1
    assert pb["statistic"] == tests["LRT"]["statistic"]
    head = m["headline_test"]
    assert head["method"] == "LRT" and head["reference"] == "F(6, 3)"
    assert head["p"] == tests["LRT"]["f_reference"]["p"]
    assert j["tests"][-1]["key"] == "mixed_model"
    assert j["tests"][-1]["p_value"] == head["p"]
    cs = j["contrasts"]
    assert [c["by"]["n_targets"] for c in cs] == COUNTS
    for c in cs:
        assert c["contrast"] == "dynamic - static" and c["scale"] == "log-odds"
        assert c["adjust"] == "holm" and c["p_adjusted"] >= c["p"]
        assert set(c) >= {"estimate", "se", "z", "p", "p_adjusted", "by"}
    rt = j["rt_mixed_model"]["fixed_effects"]["conditionstatic"]
    assert rt["df"] > 0 and rt["t"] == pytest.approx(rt["z"])
    assert rt["p"] == pytest.approx(2 * stats.t.sf(abs(rt["t"]), rt["df"]))
    assert "Satterthwaite" in j["rt_mixed_model"]["p_method"]


def test_report_says_which_test_and_adjustment_made_each_number(resolution_summary: dict
                                                                ) -> None:
    from tactorbelt.analysis.report.html import render_html

    html = render_html(resolution_summary["summary"], {})
    contrasts = html.index("Dynamic against static at each target count")
    assert contrasts < html.index("Results by cell")  # the resolution section leads with it
    assert "Holm" in html[contrasts:contrasts + 4000]
    assert "probability scale" in html and "regrid" in html
    assert "Tests of the condition" in html
    assert "parametric-bootstrap reference (pbkrtest" in html
    assert "F reference (headline)" in html and "nominal 5 %" in html
    assert "Satterthwaite" in html


def test_the_headline_test_is_the_f_referred_likelihood_ratio_at_every_size(
        resolution_store: Path) -> None:
    j = summarize(load_stores([resolution_store]), seed=4, pb_sims=0).to_json()
    m = j["mixed_model"]
    assert m["headline_test"]["method"] == "LRT"
    pb = next(t for t in m["tests"] if t["method"] == "parametric bootstrap")
    assert pb["computed"] is False and pb["p"] is None  # --bootstrap-sims 0
    lrt = next(t for t in m["tests"] if t["method"] == "LRT")
    assert j["tests"][-1]["p_value"] == lrt["f_reference"]["p"]
    assert j["tests"][-1]["details"]["headline_test"] == HEADLINE_TEST
    assert PB_MAX_PARTICIPANTS == 16


def test_richardson_derivatives_are_exact_on_smooth_functions() -> None:
    def f(x: np.ndarray) -> float:
        return float(math.exp(x[0]) * x[1] ** 2 + math.sin(x[0] * x[1]))

    x = np.array([0.3, 1.7])
    a, b = x
    hess = richardson_hessian(f, x)
    want = np.array([
        [math.exp(a) * b**2 - b**2 * math.sin(a * b),
         2 * math.exp(a) * b + math.cos(a * b) - a * b * math.sin(a * b)],
        [0.0, 2 * math.exp(a) - a**2 * math.sin(a * b)]])
    want[1, 0] = want[0, 1]
    assert hess == pytest.approx(want, rel=1e-7)
    jac = richardson_jacobian(lambda v: np.array([v[0] * v[1], v[0] ** 3]), x)
    assert jac == pytest.approx(np.array([[b, a], [3 * a**2, 0.0]]), rel=1e-9, abs=1e-12)


def test_analyze_bootstrap_sims_option(resolution_store: Path, tmp_path: Path) -> None:
    from tactorbelt.cli import main

    out = tmp_path / "o"
    main(["analyze", str(resolution_store), "-o", str(out), "--bootstrap-sims", "4"])
    doc = json.loads((out / "summary.json").read_text())
    pb = next(t for t in doc["mixed_model"]["tests"] if t["method"] == "parametric bootstrap")
    assert pb["n_sim"] == 4
    assert isinstance(pd.DataFrame(doc["contrasts"]), pd.DataFrame)
