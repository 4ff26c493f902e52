"""Statistics cross-checked against direct SciPy and statsmodels calls."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from support.analysis import HAND_TRIALS, _rows, hand_store
from support.synthetic import (
    create_store,
    insert_session,
    insert_trials,
    synthesize_store,
)
from tactorbelt.analysis.models.fit import mixed_model
from tactorbelt.analysis.summary import summarize
from tactorbelt.analysis.tables.classical import (
    fisher_accuracy,
    mann_whitney_rt,
    matched_pairs_rank_biserial,
    wilcoxon_paired,
)
from tactorbelt.analysis.tables.load import load_stores
from tactorbelt.analysis.tables.tables import prepare_trials


@pytest.fixture
def hand(tmp_path: Path) -> Path:
    return hand_store(tmp_path / "hand.sqlite")


@pytest.fixture(scope="module")
def several(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("several") / "s.sqlite"
    synthesize_store(path, 6, repetitions=2, seed=3, samples=False, timeout_rate=0.05)
    return path


def test_fisher_matches_scipy_and_bootstrap_is_reproducible() -> None:
    rng = np.random.default_rng(0)
    r = fisher_accuracy(10, 30, 22, 30, rng, n_boot=4000)
    ref = stats.fisher_exact([[22, 8], [10, 20]])
    assert r.p_value == pytest.approx(ref.pvalue)
    assert r.effect == pytest.approx(22 / 30 - 10 / 30)
    assert r.details["sample_odds_ratio"] == pytest.approx((22 * 20) / (8 * 10))
    # the conditional MLE and exact interval R's fisher.test reports for this table
    assert r.details["odds_ratio"] == pytest.approx(5.327244, rel=1e-5)
    assert r.details["odds_ratio_ci95"] == pytest.approx([1.603346, 19.44574], rel=1e-4)
    assert r.ci_low < r.effect < r.ci_high
    # the binomial-draw bootstrap equals resampling trials: compare with a naive one
    g = np.random.default_rng(1)
    s = np.r_[np.ones(10), np.zeros(20)]
    d = np.r_[np.ones(22), np.zeros(8)]
    naive = (g.choice(d, (4000, 30)).mean(1) - g.choice(s, (4000, 30)).mean(1))
    lo, hi = np.percentile(naive, [2.5, 97.5])
    assert r.ci_low == pytest.approx(lo, abs=0.04) and r.ci_high == pytest.approx(hi, abs=0.04)
    again = fisher_accuracy(10, 30, 22, 30, np.random.default_rng(0), n_boot=4000)
    assert (again.ci_low, again.ci_high) == (r.ci_low, r.ci_high)


def test_fisher_zero_cell_reports_odds_ratio_undefined_not_nan() -> None:
    r = fisher_accuracy(5, 5, 5, 5, np.random.default_rng(0))
    assert r.computed and r.p_value == pytest.approx(1.0)
    assert r.details["odds_ratio"] is None and "undefined" in r.details["odds_ratio_note"]
    json.dumps(r.to_dict(), allow_nan=False)


def test_fisher_one_condition_says_why() -> None:
    r = fisher_accuracy(3, 10, 0, 0, np.random.default_rng(0))
    assert not r.computed and "dynamic" in (r.reason or "")


def test_mann_whitney_matches_scipy_with_rank_biserial() -> None:
    s = np.array([1.0, 1.2, 1.4, 1.1, np.nan])
    d = np.array([1.5, 1.6, 1.7, 1.8, 1.3, 1.9])
    r = mann_whitney_rt(s, d, np.random.default_rng(0))
    ref = stats.mannwhitneyu(d, s[:4], alternative="two-sided")
    assert r.p_value == pytest.approx(ref.pvalue)
    assert r.statistic == pytest.approx(ref.statistic)
    diff = np.subtract.outer(d, s[:4])
    assert r.effect == pytest.approx((diff > 0).mean() - (diff < 0).mean())
    assert r.ci_low <= np.median(d) - np.median(s[:4]) <= r.ci_high


def test_mann_whitney_all_equal_says_why() -> None:
    r = mann_whitney_rt(np.ones(4), np.ones(3), np.random.default_rng(0))
    assert not r.computed and "equal" in (r.reason or "")


def test_wilcoxon_matches_scipy_and_rank_biserial() -> None:
    s = np.array([0.40, 0.50, 0.45, 0.60, 0.30, 0.55, 0.52])
    d = np.array([0.70, 0.65, 0.40, 0.80, 0.62, 0.75, 0.51])
    r = wilcoxon_paired(s, d, np.random.default_rng(0), key="k", what="accuracy")
    ref = stats.wilcoxon(d, s)
    assert r.p_value == pytest.approx(ref.pvalue)
    assert r.statistic == pytest.approx(ref.statistic)
    n = len(s)
    t_minus = ref.statistic  # smaller rank sum (no ties, no zeros): negative differences
    assert r.effect == pytest.approx(1 - 2 * 2 * t_minus / (n * (n + 1)))
    assert matched_pairs_rank_biserial(d - s) == pytest.approx(r.effect)
    assert r.ci_low <= (d - s).mean() <= r.ci_high


def test_wilcoxon_says_why_when_it_cannot_run() -> None:
    rng = np.random.default_rng(0)
    one = wilcoxon_paired(np.array([0.5]), np.array([0.7]), rng, key="k", what="accuracy")
    assert not one.computed and "at least 2" in (one.reason or "")
    same = wilcoxon_paired(np.array([0.5, 0.6]), np.array([0.5, 0.6]), rng, key="k",
                           what="accuracy")
    assert not same.computed and "zero" in (same.reason or "")


def test_summarize_one_participant_uses_fisher_and_mann_whitney(hand: Path) -> None:
    summary = summarize(load_stores([hand]), seed=1)
    t = summary.between_accuracy_test
    assert t.test == "Fisher's exact test"
    # static between: 1 of 5 (timeout counts as incorrect); dynamic between: 4 of 6
    assert t.p_value == pytest.approx(stats.fisher_exact([[4, 2], [1, 4]]).pvalue)
    rt = summary.test("between_rt")
    assert rt is not None
    ref = stats.mannwhitneyu([1.5, 1.6, 1.7, 1.8, 1.3, 1.9], [1.0, 1.2, 1.4, 1.1])
    assert rt.p_value == pytest.approx(ref.pvalue)
    mm = summary.test("mixed_model")
    assert mm is not None and not mm.computed and "at least 3 participants" in (mm.reason or "")
    assert summary.counts["aborted"] == 1 and summary.counts["timeout"] == 1
    assert summary.counts["training_trials"] == 1
    j = summary.to_json()
    json.dumps(j, allow_nan=False)
    assert j["conditions"]["static"]["between_tactor"]["accuracy"] == pytest.approx(0.2)
    assert j["between_accuracy_test"]["p_value"] == pytest.approx(t.p_value)


def _per_participant_between(path: Path) -> pd.DataFrame:
    import sqlite3

    con = sqlite3.connect(path)
    df = pd.read_sql_query(
        "SELECT s.participant, t.condition, "
        "AVG(CASE WHEN t.status = 'done' AND t.correct = 1 THEN 1.0 ELSE 0.0 END) AS acc "
        "FROM trials t JOIN sessions s USING(session_id) WHERE t.block = 'test' AND "
        "t.status IN ('done', 'timeout') AND t.on_tactor = 0 GROUP BY 1, 2", con)
    rts = pd.read_sql_query(
        "SELECT s.participant, t.condition, t.rt_s FROM trials t JOIN sessions s "
        "USING(session_id) WHERE t.block = 'test' AND t.status = 'done' AND t.on_tactor = 0",
        con)
    con.close()
    med = rts.groupby(["participant", "condition"])["rt_s"].median().rename("rt")
    return df.set_index(["participant", "condition"]).join(med).unstack("condition")


def test_summarize_several_participants_matches_scipy_wilcoxon(several: Path) -> None:
    summary = summarize(load_stores([several]), seed=0)
    w = _per_participant_between(several)
    acc = summary.between_accuracy_test
    assert acc.test == "Wilcoxon signed-rank test"
    ref = stats.wilcoxon(w[("acc", "dynamic")], w[("acc", "static")])
    assert acc.p_value == pytest.approx(ref.pvalue)
    assert acc.statistic == pytest.approx(ref.statistic)
    rt = summary.test("between_rt")
    assert rt is not None
    ref_rt = stats.wilcoxon(w[("rt", "dynamic")], w[("rt", "static")])
    assert rt.p_value == pytest.approx(ref_rt.pvalue)
    d = (w[("acc", "dynamic")] - w[("acc", "static")]).to_numpy()
    assert acc.effect == pytest.approx(matched_pairs_rank_biserial(d))
    assert acc.details["mean_difference"] == pytest.approx(d.mean())


def test_mixed_model_is_the_laplace_glmm_headed_by_the_f_referred_lrt(several: Path) -> None:
    """The headline test of the condition is the likelihood ratio referred to
    F(k, participants - 1) (docs/analysis.md); the coefficients keep their Wald z; with 6
    participants the parametric bootstrap is beside it."""
    tr = prepare_trials(load_stores([several]).trials)
    r = mixed_model(tr, pb_sims=9, seed=1)
    assert r.computed
    m = r.details["model"]
    assert m["engine"] == "tactorbelt-laplace" and m["ci_method"] == "Wald"
    assert list(m["fixed_effects"]) == ["(Intercept)", "conditionstatic", "on_tactor",
                                        "conditionstatic:on_tactor"]
    fe = m["fixed_effects"]["conditionstatic"]
    assert fe["p"] == pytest.approx(2 * stats.norm.sf(abs(fe["estimate"] / fe["se"])))
    # one target count, no load: the effect is conditionstatic (static - dynamic)
    assert r.effect == pytest.approx(fe["estimate"]) and r.effect < 0
    assert r.ci_low == pytest.approx(fe["estimate"] - 1.959964 * fe["se"])
    tests = {t["method"]: t for t in m["tests"]}
    assert m["headline_test"]["method"] == "LRT" and m["headline_test"]["reference"] == (
        "F(2, 5)")
    assert r.p_value == tests["LRT"]["f_reference"]["p"]
    assert r.p_value == pytest.approx(stats.f.sf(tests["LRT"]["statistic"] / 2, 2, 5))
    assert tests["parametric bootstrap"]["n_sim"] == 9
    assert r.statistic == pytest.approx(tests["LRT"]["statistic"])
    assert tests["LRT"]["df"] == 2  # conditionstatic and conditionstatic:on_tactor
    assert "F(k, participants - 1)" in r.test and "nominal 5 %" in r.details["why"]
    assert [c["by"] for c in r.details["contrasts"]] == [{"n_targets": 24, "on_tactor": 0}]


def test_mixed_model_says_why_with_one_condition(tmp_path: Path) -> None:
    path = tmp_path / "static_only.sqlite"
    conn = create_store(path)
    for p in ("A", "B", "C"):
        sid = insert_session(conn, participant=p, started_at=f"2026-01-01T10:00:0{ord(p) % 10}")
        insert_trials(conn, _rows(sid, [t for t in HAND_TRIALS if t[1] == "static"]))
    conn.close()
    summary = summarize(load_stores([path]))
    mm = summary.test("mixed_model")
    assert mm is not None and not mm.computed and "both conditions" in (mm.reason or "")
    acc = summary.between_accuracy_test
    assert not acc.computed and "in both conditions" in (acc.reason or "")
    j = summary.to_json()
    json.dumps(j, allow_nan=False)
    assert j["conditions"]["dynamic"]["between_tactor"]["accuracy"] is None
    assert j["conditions"]["dynamic"]["between_tactor"]["note"] == "no counted test trials"
