"""The accuracy model at the ceiling: cells at 0 or 100 % (docs/analysis.md, "Separation").

Localisation data put whole design cells at 100 % (a static target on a tactor). The
datasets here are drawn from a GLMM as the model participant's studies look (3 to 6
participants, 24 targets, 1 or 2 repetitions) with one or two cells forced to 100 % or
0 %. Asserted, without R: every one fits; separation names the cells and exactly the
fixed effects whose likelihood has no finite maximum; the report shows them as not
estimable and the Wald test as not valid; the penalised fit (``--fixef-prior``) is
finite. With R (skipped with the reason without it): the estimable fixed effects equal
glmer's on the same data, the penalised fit equals ``blme::bglmer`` (or, where bglmer
reports that it did not converge, reaches at least as high a penalised likelihood), and
the lme4 engine keeps every message R gives, a list of them included.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from support.r_reference import lme4_available
from tactorbelt.analysis.models.fit import fit_model, mixed_model, model_spec
from tactorbelt.analysis.models.glmm import FixefPrior, GlmmData, fit_glmm
from tactorbelt.analysis.models.lme4 import _FLATTEN, fit_lme4
from tactorbelt.analysis.models.separation import detect_separation

EST_REL, EST_FLOOR_SE, SE_REL = 0.02, 0.02, 0.05


def test_a_condition_at_100_percent_gives_no_wald_z_and_valid_json() -> None:
    """Every static trial correct on a 6-target belt (every target on a tactor, so the
    condition is the only term): the condition's coefficient is infinite, its Wald z is
    null and marked not valid, and the details are JSON without NaN (summary.json is
    written with allow_nan=False; a NaN z once made analyze exit 1 here)."""
    frame = ceiling_frame(seed=5, participants=3, counts=(6,), ceiling=("static",))
    tr = frame.assign(is_correct=frame["correct"].astype(bool), counted=True,
                      target_deg=frame["target"].astype(float), rt=frame["rt_s"], block="test")
    res = mixed_model(tr, pb_sims=0)
    m = res.details["model"]
    assert m["separation"]["terms"] == ["conditionstatic"]
    wz = res.details["wald_z_conditionstatic"]
    assert wz["valid"] is False and wz["z"] is None and wz["p"] is None
    json.dumps(res.details, allow_nan=False)


def ceiling_frame(seed: int, participants: int = 4, repetitions: int = 1,
                  counts: tuple[int, ...] = (24,), ceiling: tuple[str, ...] = ("dynamic",),
                  floor: tuple[str, ...] = ()) -> pd.DataFrame:
    """A model frame from a GLMM with every on-tactor trial of the ``ceiling``
    conditions correct and of the ``floor`` conditions wrong (cells at 100 % and 0 %)."""
    rng = np.random.default_rng(seed)
    rows = []
    p_int = rng.normal(0, 0.6, participants)
    p_slope = rng.normal(0, 0.4, participants)
    for n_t in counts:
        tg = np.arange(n_t) * 360.0 / n_t
        t_int = rng.normal(0, 0.3, n_t)
        for p in range(participants):
            for cond in ("dynamic", "static"):
                for _ in range(repetitions):
                    for k, deg in enumerate(tg):
                        on = int(deg % 60 == 0)
                        eta = (1.6 if on else (0.9 + p_slope[p] if cond == "dynamic" else 0.1)
                               ) + p_int[p] + t_int[k] - 0.02 * (n_t - 12)
                        y = int(rng.random() < 1 / (1 + np.exp(-eta)))
                        if on and cond in ceiling:
                            y = 1
                        if on and cond in floor:
                            y = 0
                        rows.append({"correct": y, "condition": cond, "on_tactor": on,
                                     "n_targets": n_t, "participant": f"P{p + 1:02d}",
                                     "target": f"{deg:g}", "rt_s": 1.0, "status": "done"})
    return pd.DataFrame(rows)


CASES = {
    "4 participants, 24 targets, dynamic on-tactor at 100 %":
        dict(seed=3, participants=4),
    "3 participants, 12 and 24 targets, dynamic on-tactor at 100 %":
        dict(seed=1, participants=3, counts=(12, 24)),
    "6 participants, 2 repetitions, both conditions on-tactor at 100 %":
        dict(seed=2, participants=6, repetitions=2, ceiling=("dynamic", "static")),
    "5 participants, static on-tactor at 0 %":
        dict(seed=4, participants=5, ceiling=(), floor=("static",)),
}


@pytest.fixture(scope="module", params=list(CASES))
def case(request: pytest.FixtureRequest) -> tuple[str, pd.DataFrame]:
    return request.param, ceiling_frame(**CASES[request.param])


def test_every_study_with_a_cell_at_0_or_100_percent_is_fitted(case) -> None:
    what, frame = case
    fit, js = fit_model(frame)
    assert js["fixed_effects"], what
    for name, fe in fit.fixed_effects.items():
        assert np.isfinite(fe.estimate), (what, name)


def test_separation_names_the_cells_and_the_infinite_terms() -> None:
    frame = ceiling_frame(seed=3, participants=4)
    spec, _ = model_spec(frame)
    sep = detect_separation(frame, spec)
    assert [(c["condition"], c["on_tactor"], c["accuracy"]) for c in sep.cells] == [
        ("dynamic", 1, 1.0)]
    # dynamic is the reference: its on-tactor cell is (Intercept) + on_tactor, so
    # on_tactor goes to +inf and the static interaction compensates with -inf
    assert sep.terms == ["on_tactor", "conditionstatic:on_tactor"]
    assert sep.direction == {"on_tactor": "+inf", "conditionstatic:on_tactor": "-inf"}
    # the fit agrees: those two are far out, the others are not
    fit, _ = fit_model(frame)
    assert abs(fit.fixed_effects["on_tactor"].estimate) > 10
    assert abs(fit.fixed_effects["conditionstatic"].estimate) < 5


def test_a_cell_at_0_percent_is_minus_infinity() -> None:
    frame = ceiling_frame(seed=4, participants=5, ceiling=(), floor=("static",))
    spec, _ = model_spec(frame)
    sep = detect_separation(frame, spec)
    assert [c["accuracy"] for c in sep.cells] == [0.0]
    assert sep.direction == {"conditionstatic:on_tactor": "-inf"}


def test_no_cell_at_the_bounds_no_separation() -> None:
    frame = ceiling_frame(seed=5, participants=4, ceiling=())
    spec, _ = model_spec(frame)
    g = frame.groupby(["condition", "on_tactor"])["correct"].mean()
    assert ((g > 0) & (g < 1)).all()
    sep = detect_separation(frame, spec)
    assert not sep.cells and not sep.terms and not sep.found


def test_report_shows_not_estimable_and_the_wald_test_not_valid() -> None:
    from tactorbelt.analysis.report.html import model_view

    frame = ceiling_frame(seed=3, participants=4)
    tr = frame.assign(is_correct=frame["correct"].astype(bool), counted=True,
                      target_deg=frame["target"].astype(float), rt=frame["rt_s"], block="test")
    res = mixed_model(tr, pb_sims=0)
    m = res.details["model"]
    assert m["separation"]["terms"] == ["on_tactor", "conditionstatic:on_tactor"]
    assert m["fixed_effects"]["on_tactor"]["estimable"] is False
    assert "estimable" not in m["fixed_effects"]["conditionstatic"]
    wald = next(t for t in m["tests"] if t["method"] == "Wald")
    lrt = next(t for t in m["tests"] if t["method"] == "LRT")
    assert wald["valid"] is False and lrt["valid"] is True and np.isfinite(lrt["statistic"])
    view = model_view(m)  # what the report's template shows of the model
    rows = {r["term"]: r for r in view["fixed"]}
    assert "not estimable (cell condition = dynamic, on_tactor = 1" in rows["on_tactor"]["note"]
    assert rows["conditionstatic"]["note"] is None
    # the not-estimable row has as many cells as the table's header
    assert view["fixed_blank"] + 2 == len(view["fixed_headers"])
    assert np.isfinite(rows["conditionstatic"]["estimate"])
    wald_row = next(t for t in view["tests"] if t["name"].startswith("Wald"))
    assert wald_row["invalid"] and "not valid: separation" in wald_row["extra"]
    # the penalised fit is beside it, finite, named as blme names it
    sens = m["sensitivity"]
    assert sens["computed"] and "normal(sd = c(10, 2.5))" in sens["fixef_prior"]["call"]
    assert all(np.isfinite(v["estimate"]) and v["se"] < 10
               for v in sens["fixed_effects"].values())
    shown = view["separation"]["sensitivity"]
    assert shown["computed"] and shown["call"] == sens["fixef_prior"]["call"]
    # the between-tactor effect does not involve the infinite terms: still estimable
    assert res.details.get("effect_estimable", True)


def test_fixef_prior_parses_as_blme_spreads_it() -> None:
    assert FixefPrior.parse("normal:10,2.5").sds(4).tolist() == [10, 2.5, 2.5, 2.5]
    assert FixefPrior.parse("normal:3").sds(3).tolist() == [3, 3, 3]
    assert FixefPrior.parse("normal:10,2.5").blme() == "normal(sd = c(10, 2.5))"
    assert FixefPrior.parse("normal:3").blme() == "normal(sd = 3)"
    for bad in ("t:3", "normal", "normal:", "normal:-1", "normal:1,2,3", "normal:a", "normal:inf"):
        with pytest.raises(ValueError, match="fixef-prior"):
            FixefPrior.parse(bad)


def test_analyze_fixef_prior_names_the_fit_and_refuses_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from support.synthetic import synthesize_store
    from tactorbelt.cli import main

    store = tmp_path / "s.sqlite"
    synthesize_store(store, 3, repetitions=1, seed=5, samples=False)
    try:
        main(["analyze", str(store), "-o", str(tmp_path / "o"), "--fixef-prior",
              "normal:10,2.5", "--bootstrap-sims", "0"])
    except SystemExit as exc:
        assert exc.code in (0, None)
    m = json.loads((tmp_path / "o" / "summary.json").read_text())["mixed_model"]
    assert m["fixef_prior"]["prior"] == "normal(sd = c(10, 2.5))"
    assert "bglmer" in m["criterion"]
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(store), "-o", str(tmp_path / "p"), "--fixef-prior", "cauchy:2.5"])
    assert exc.value.code == 2
    assert "normal:SD" in capsys.readouterr().err


# -- against R ---------------------------------------------------------------------------

WHY = lme4_available()
needs_r = pytest.mark.skipif(WHY is not None, reason=f"R with lme4 unavailable: {WHY}")


def _blme_missing() -> str | None:
    if WHY is not None:
        return WHY
    r = subprocess.run(["Rscript", "-e", "suppressPackageStartupMessages(library(blme))"],
                       capture_output=True, text=True, timeout=120)
    return None if r.returncode == 0 else "the R package blme is not installed"


def _clean(ref) -> bool:
    """glmer said nothing of convergence or identifiability (a singular fit is clean)."""
    return not [m for m in ref.messages if not m.startswith("lme4 ") and "singular" not in m]


@needs_r
def test_estimable_terms_equal_glmer_at_the_ceiling(case) -> None:
    what, frame = case
    ours, _ = fit_model(frame)
    ref = fit_lme4(frame, ours.spec)
    sep = detect_separation(frame, ours.spec, list(ours.fixed_effects))
    assert list(ours.fixed_effects) == list(ref.fixed_effects)
    bad = []
    for name, r in ref.fixed_effects.items():
        if name in sep.terms:
            continue
        o = ours.fixed_effects[name]
        if abs(o.estimate - r.estimate) > max(EST_REL * abs(r.estimate), EST_FLOOR_SE * r.se):
            bad.append(f"{name} estimate {o.estimate:.5f} vs glmer {r.estimate:.5f}")
        # glmer's Hessian is degenerate along the infinite terms: its SEs count only
        # where it says it converged
        if _clean(ref) and abs(o.se - r.se) > SE_REL * r.se:
            bad.append(f"{name} SE {o.se:.5f} vs glmer {r.se:.5f}")
    assert not bad, (what, bad, ref.messages)


@pytest.mark.skipif(_blme_missing() is not None, reason=f"{_blme_missing()}")
def test_penalised_fit_equals_bglmer(case) -> None:
    what, frame = case
    prior = FixefPrior()
    spec, _ = model_spec(frame)
    ours = fit_glmm(frame, spec, fixef_prior=prior)
    ref = fit_lme4(frame, spec, fixef_prior=prior)
    assert list(ours.fixed_effects) == list(ref.fixed_effects)
    if _clean(ref):
        for name, r in ref.fixed_effects.items():
            o = ours.fixed_effects[name]
            assert abs(o.estimate - r.estimate) <= max(EST_REL * abs(r.estimate),
                                                       EST_FLOOR_SE * r.se), (what, name)
            assert o.se == pytest.approx(r.se, rel=SE_REL), (what, name)
    # either way, ours is at least as good a posterior mode as bglmer's
    data = GlmmData(frame, spec)
    lap = data.laplace()
    lap.set_prior(prior)
    at_ours = lap.dev(np.r_[ours.theta, [f.estimate for f in ours.fixed_effects.values()]])
    at_ref = lap.dev(np.r_[ref.theta, [f.estimate for f in ref.fixed_effects.values()]])
    assert at_ours <= at_ref + 1e-4, (what, at_ours, at_ref, ref.messages)


@needs_r
def test_r_messages_in_a_list_are_all_kept(tmp_path: Path) -> None:
    """glmer keeps two convergence messages as a list; writeLines refused it."""
    script = tmp_path / "m.R"
    script.write_text(_FLATTEN + r"""
x <- list("Model failed to converge with max|grad| = 0.4", "Model is nearly unidentifiable")
writeLines(unique(c(flat_msgs(character(0)), flat_msgs(x), flat_msgs(NULL),
                    flat_msgs(list(simpleWarning("a warning"))))), commandArgs(TRUE)[1])
""")
    out = tmp_path / "messages.txt"
    subprocess.run(["Rscript", str(script), str(out)], check=True, timeout=120)
    assert out.read_text().splitlines() == [
        "Model failed to converge with max|grad| = 0.4", "Model is nearly unidentifiable",
        "a warning"]
