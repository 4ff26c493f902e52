"""The mixed-model engine without R: R's coding, the simplification rule, the lme4 error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tactorbelt.analysis import lme4 as lme4_mod
from tactorbelt.analysis.glmm import (
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
    assert lme4_mod.lme4_available() is not None
    spec = ModelSpec("correct", ("condition",), (RandomTerm("participant"),))
    with pytest.raises(lme4_mod.Lme4Unavailable, match="apt install r-base-core r-cran-lme4"):
        lme4_mod.fit_lme4(_frame(), spec)


def test_analyze_engine_lme4_without_r_exits_2_with_the_install_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from tactorbelt.analysis.synthetic import synthesize_store
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
    from tactorbelt.analysis.load import load_stores
    from tactorbelt.analysis.stats import fit_model, model_frame
    from tactorbelt.analysis.synthetic import synthesize_store
    from tactorbelt.analysis.tables import prepare_trials

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
