"""The mixed models agree with R's lme4 (glmer, lmer), fitted through Rscript.

Three datasets made here: one participant and eight participants from the synthetic
store generator (seed 11; no participant or target variation, so the fits are
singular and get simplified), and eight participants drawn from a GLMM with
participant intercepts and condition slopes, target intercepts, an extra ``load``
factor and 100 test trials set to timeout.

Agreement asserted for every fixed effect: estimates within 1 % of glmer's, or within
an absolute floor of 2 % of glmer's SE for estimates near 0 (a relative criterion means
nothing at 0; 2 % of an SE is far below what any reader of the table can see); SEs
within 5 %. Skipped with the reason when Rscript or lme4 is missing (CI installs
``r-base-core r-cran-lme4``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tactorbelt.analysis.glmm import MixedModelFit, fit_glmm, fit_lmm, fit_simplified
from tactorbelt.analysis.lme4 import fit_lme4, lme4_available
from tactorbelt.analysis.load import load_stores
from tactorbelt.analysis.stats import model_frame, model_spec, summarize
from tactorbelt.analysis.synthetic import synthesize_store
from tactorbelt.analysis.tables import prepare_trials

WHY = lme4_available()
pytestmark = pytest.mark.skipif(WHY is not None, reason=f"R with lme4 unavailable: {WHY}")

EST_REL = 0.01
EST_FLOOR_SE = 0.02
SE_REL = 0.05


def _store_frame(path: Path, participants: int) -> pd.DataFrame:
    synthesize_store(path, participants, repetitions=5, seed=11, samples=False,
                     timeout_rate=0.02)
    return model_frame(prepare_trials(load_stores([path]).trials))


def _glmm_frame(seed: int = 11) -> pd.DataFrame:
    """8 participants x 2 conditions x 2 loads x 3 repetitions x 24 targets, from a GLMM."""
    rng = np.random.default_rng(seed)
    tg = np.arange(24) * 15.0
    on = (tg % 60 == 0).astype(int)
    p_int, p_slope, t_int = rng.normal(0, 0.7, 8), rng.normal(0, 0.5, 8), rng.normal(0, 0.4, 24)
    grid = pd.MultiIndex.from_product(
        [range(8), ["static", "dynamic"], ["none", "count"], range(3), range(24)],
        names=["p", "condition", "load", "rep", "t"]).to_frame(index=False)
    p, t = grid["p"].to_numpy(), grid["t"].to_numpy()
    dyn = (grid["condition"] == "dynamic").to_numpy()
    eta = (np.where(on[t] == 1, 2.2, np.where(dyn, 1.2 + p_slope[p], 0.0)) + p_int[p]
           + t_int[t] - 0.5 * (grid["load"] == "count").to_numpy())
    correct = (rng.random(len(grid)) < 1 / (1 + np.exp(-eta))).astype(int)
    rt = np.exp(rng.normal(np.log(np.where(dyn, 1.4, 1.2)) + 0.1 * p_int[p], 0.25))
    status = np.full(len(grid), "done", dtype=object)
    timeout = rng.choice(len(grid), 100, replace=False)
    status[timeout] = "timeout"
    correct[timeout] = 0
    rt[timeout] = np.nan
    return pd.DataFrame({
        "correct": correct, "condition": grid["condition"], "on_tactor": on[t],
        "load": grid["load"], "participant": [f"P{i + 1:02d}" for i in p],
        "target": [f"{v:g}" for v in tg[t]], "rt_s": rt, "status": status})


@pytest.fixture(scope="module")
def datasets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, pd.DataFrame]:
    d = tmp_path_factory.mktemp("lme4")
    return {"one participant": _store_frame(d / "one.sqlite", 1),
            "8 participants (synthetic store)": _store_frame(d / "eight.sqlite", 8),
            "8 participants, GLMM, load, 100 timeouts": _glmm_frame()}


def _agree(ours: MixedModelFit, ref: MixedModelFit, what: str) -> list[str]:
    assert list(ours.fixed_effects) == list(ref.fixed_effects), what
    bad = []
    for name, r in ref.fixed_effects.items():
        o = ours.fixed_effects[name]
        tol = max(EST_REL * abs(r.estimate), EST_FLOOR_SE * r.se)
        if abs(o.estimate - r.estimate) > tol:
            bad.append(f"{what}: {name} estimate {o.estimate:.6f} vs lme4 {r.estimate:.6f}")
        if abs(o.se - r.se) > SE_REL * r.se:
            bad.append(f"{what}: {name} SE {o.se:.6f} vs lme4 {r.se:.6f}")
    return bad


def test_glmm_agrees_with_glmer(datasets: dict[str, pd.DataFrame]) -> None:
    bad: list[str] = []
    for what, frame in datasets.items():
        spec, _ = model_spec(frame)
        ours, steps = fit_simplified(frame, spec, fit_glmm)
        ref = fit_lme4(frame, ours.spec)
        assert ours.singular == ref.singular, (what, steps, ref.theta)
        bad += _agree(ours, ref, what)
    assert not bad, "\n".join(bad)


def test_rt_lmm_agrees_with_lmer(datasets: dict[str, pd.DataFrame]) -> None:
    bad: list[str] = []
    for what, frame in datasets.items():
        done = frame.loc[frame["status"] == "done"]
        spec, _ = model_spec(done, "rt_s", "log")
        ours, _ = fit_simplified(done, spec, fit_lmm)
        ref = fit_lme4(done, ours.spec, family="gaussian")
        bad += _agree(ours, ref, "RT " + what)
        sd_o = ours.random_effects["Residual"]["sd"]["(Intercept)"]
        sd_r = ref.random_effects["Residual"]["sd"]["(Intercept)"]
        assert sd_o == pytest.approx(sd_r, rel=1e-3), what
    assert not bad, "\n".join(bad)


def test_analyze_engine_lme4_reports_the_same_fields(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    synthesize_store(path, 4, repetitions=2, seed=5, samples=False, timeout_rate=0.03)
    data = load_stores([path])
    ours = summarize(data, engine="tactorbelt").to_json()["mixed_model"]
    ref = summarize(data, engine="lme4").to_json()["mixed_model"]
    assert ours["engine"] == "tactorbelt-laplace" and ref["engine"] == "lme4"
    assert ours["formula"] == ref["formula"]
    assert list(ours["fixed_effects"]) == list(ref["fixed_effects"])
    for name, r in ref["fixed_effects"].items():
        assert set(r) == {"estimate", "se", "z", "p", "ci_low", "ci_high"}
        o = ours["fixed_effects"][name]
        assert abs(o["estimate"] - r["estimate"]) <= max(EST_REL * abs(r["estimate"]),
                                                        EST_FLOOR_SE * r["se"])
        assert o["se"] == pytest.approx(r["se"], rel=SE_REL)
