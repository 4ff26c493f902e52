"""The accuracy model on studies with cells at 0 or 100 %, against glmer and bglmer.

    python scripts/ceiling_studies.py STORE [STORE ...] [--no-r]

For each store (a study.sqlite of `tactorbelt demo` or `run`): the report's accuracy
model fitted by tactorbelt's engine (does it fit?), the design cells at 0 or 100 % and
the fixed effects separation makes infinite; with R, glmer's fit of the same model
(are the estimable terms equal: estimates within 2 % or 2 % of an SE, SEs within 5 %
where glmer reports no convergence or identifiability message?) and bglmer's with
fixef.prior = normal(sd = c(10, 2.5)) (equal where bglmer converges; otherwise is our
posterior mode at least as high?). Prints one line per store and the totals
(docs/analysis.md, "Separation", reports the figures).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np


def _frame(store: str):  # type: ignore[no-untyped-def]
    from tactorbelt.analysis.models.fit import model_frame
    from tactorbelt.analysis.summary import rt_from_choice
    from tactorbelt.analysis.tables.load import load_stores
    from tactorbelt.analysis.tables.tables import prepare_trials

    data = load_stores([store])
    trials, _, _ = rt_from_choice(data.trials, None)
    return model_frame(prepare_trials(trials))


def _clean(fit) -> bool:  # type: ignore[no-untyped-def]
    return not [m for m in fit.messages if not m.startswith("lme4 ") and "singular" not in m]


def _equal(ours, ref, skip: set[str], se: bool) -> list[str]:  # type: ignore[no-untyped-def]
    bad = []
    for name, r in ref.fixed_effects.items():
        if name in skip:
            continue
        o = ours.fixed_effects[name]
        if abs(o.estimate - r.estimate) > max(0.02 * abs(r.estimate), 0.02 * r.se):
            bad.append(f"{name} {o.estimate:.4f} vs {r.estimate:.4f}")
        if se and abs(o.se - r.se) > 0.05 * r.se:
            bad.append(f"{name} SE {o.se:.4f} vs {r.se:.4f}")
    return bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stores", nargs="+")
    ap.add_argument("--no-r", action="store_true", help="tactorbelt's engine only")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    from tactorbelt.analysis.models.fit import fit_model
    from tactorbelt.analysis.models.glmm import FixefPrior, GlmmData, fit_glmm
    from tactorbelt.analysis.models.lme4 import fit_lme4
    from tactorbelt.analysis.models.separation import detect_separation

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from support.r_reference import lme4_available

    use_r = not args.no_r and lme4_available() is None
    prior = FixefPrior()
    tot = {"studies": 0, "fitted": 0, "with_cells": 0, "named": 0, "glmer_equal": 0,
           "glmer_compared": 0, "bglmer_equal": 0, "bglmer_converged": 0, "bglmer_not_worse": 0}
    for store in args.stores:
        frame = _frame(store)
        tot["studies"] += 1
        try:
            fit, _ = fit_model(frame)
        except Exception as exc:  # the measurement: say it and go on
            print(f"{store}: FAILED {type(exc).__name__}: {exc}")
            continue
        tot["fitted"] += 1
        sep = detect_separation(frame, fit.spec, list(fit.fixed_effects))
        line = f"{store}: fitted; {len(sep.cells)} cell(s) at 0/100 %, infinite: {sep.terms}"
        if sep.cells:
            tot["with_cells"] += 1
            tot["named"] += bool(sep.terms)
        if use_r:
            ref = fit_lme4(frame, fit.spec)
            bad = _equal(fit, ref, set(sep.terms), _clean(ref))
            tot["glmer_compared"] += 1
            tot["glmer_equal"] += not bad
            line += f"; glmer {bad if bad else 'equal'}" + ("" if _clean(ref) else
                                                                  " (glmer not clean)")
            ours_p = fit_glmm(frame, fit.spec, fixef_prior=prior)
            ref_p = fit_lme4(frame, fit.spec, fixef_prior=prior)
            lap = GlmmData(frame, fit.spec).laplace()
            lap.set_prior(prior)
            d_o = lap.dev(np.r_[ours_p.theta, [f.estimate for f in ours_p.fixed_effects.values()]])
            d_r = lap.dev(np.r_[ref_p.theta, [f.estimate for f in ref_p.fixed_effects.values()]])
            tot["bglmer_not_worse"] += d_o <= d_r + 1e-4
            if _clean(ref_p):
                tot["bglmer_converged"] += 1
                bad_p = _equal(ours_p, ref_p, set(), True)
                tot["bglmer_equal"] += not bad_p
                line += f"; bglmer {bad_p if bad_p else 'equal'}"
            else:
                line += (f"; bglmer did not converge (objective ours {d_o:.3f}, "
                         f"bglmer {d_r:.3f})")
        print(line, flush=True)
    print(" ".join(f"{k}={v}" for k, v in tot.items()))
    return 0 if tot["fitted"] == tot["studies"] else 1


if __name__ == "__main__":
    sys.exit(main())
