"""Benchmark: the accuracy model's contrasts, likelihood ratio and parametric bootstrap,
tactorbelt against R (lme4, emmeans, pbkrtest) on the same data.

1. A resolution study (12, 24, 36, 48 targets x static/dynamic, 2 repetitions: 480
   test trials a participant) of ``--participants`` synthetic participants who differ
   (SDs 0.5, 0.3, 0.3 log-odds: participant intercept, condition slope, target
   intercept; :func:`support.synthetic.synthesize_store`, cached): the
   report's accuracy model with its simplification rule, the contrasts per target
   count and the likelihood ratio (the null model fitted too). R on the same frame:
   ``glmer`` of the final model and of the null model, ``anova`` and emmeans'
   contrasts (``support.r_reference.r_condition_tests``; its time includes starting R
   and reading the CSV, ``r_*_fit_s`` is R's own clock for the fits and tests after
   that).
2. The parametric bootstrap with ``--pb-sims`` simulations on ``--pb-participants``
   participants of the same design: ours
   (:func:`tactorbelt.analysis.models.lrt.parametric_bootstrap`)
   and pbkrtest's ``PBmodcomp`` in R (R's own simulations), timed on ``--r-pb-sims``
   simulations and scaled to ``--pb-sims`` (``r_pb_<sims>_<n>_est_s``): glmer's
   ``refit`` of this model takes about a minute a simulation on 2 busy cores, so 500
   would take hours.

Prints one JSON object, e.g. ``{"resolution_1000_fit_contrasts_lrt_s": 80.1,
"r_resolution_1000_s": 900.0, "pb_500_20_s": 300.0, "r_pb_500_20_s": 1200.0, ...}``.
Without R (or ``--no-r``) the R figures are left out.

Usage: python benchmarks/bench_condition_tests.py [--participants 1000]
       [--pb-participants 20] [--pb-sims 500] [--no-r] [--cache DIR] [--keep]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # support.synthetic


def _frame(path: Path, participants: int, seed: int) -> object:
    from support.synthetic import synthesize_store
    from tactorbelt.analysis.models.fit import model_frame
    from tactorbelt.analysis.tables.load import load_stores
    from tactorbelt.analysis.tables.tables import prepare_trials

    if not path.exists():
        tmp = path.with_suffix(".partial")
        tmp.unlink(missing_ok=True)
        synthesize_store(tmp, participants, repetitions=2, seed=seed, samples=False,
                         participant_sd=0.5, slope_sd=0.3, target_sd=0.3,
                         targets=[12, 24, 36, 48])
        tmp.rename(path)
    return model_frame(prepare_trials(load_stores([path]).trials))


def main() -> int:
    os.environ.setdefault("MPLBACKEND", "Agg")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=1000)
    ap.add_argument("--pb-participants", type=int, default=20)
    ap.add_argument("--pb-sims", type=int, default=500)
    ap.add_argument("--r-pb-sims", type=int, default=10,
                    help="simulations of R's PBmodcomp, timed and scaled to --pb-sims "
                         "(glmer's refit of this model takes about a minute each)")
    ap.add_argument("--no-r", action="store_true", help="leave out R's times")
    ap.add_argument("--cache", type=Path,
                    default=Path(tempfile.gettempdir()) / "tactorbelt-bench-conditions")
    ap.add_argument("--keep", action="store_true", help="keep the stores for the next run")
    args = ap.parse_args()

    from support.r_reference import lme4_available, r_condition_tests
    from tactorbelt.analysis.models.contrasts import condition_contrasts
    from tactorbelt.analysis.models.fit import fit_model
    from tactorbelt.analysis.models.glmm import fit_glmm
    from tactorbelt.analysis.models.lrt import likelihood_ratio, null_spec, parametric_bootstrap

    warnings.simplefilter("ignore")
    use_r = not args.no_r and lme4_available() is None
    args.cache.mkdir(parents=True, exist_ok=True)
    result: dict[str, float | int | str] = {}
    n, k = args.participants, args.pb_participants
    stores = [args.cache / f"resolution_{n}.sqlite", args.cache / f"resolution_{k}.sqlite"]
    try:
        frame = _frame(stores[0], n, seed=0)
        result["trials"] = len(frame)  # type: ignore[arg-type]
        t0 = time.perf_counter()
        fit, js = fit_model(frame)  # type: ignore[arg-type]
        t_fit = time.perf_counter() - t0
        contrasts = condition_contrasts(fit, frame)  # type: ignore[arg-type]
        fit0 = fit_glmm(frame, null_spec(fit.spec), se=False)  # type: ignore[arg-type]
        lr = likelihood_ratio(fit, fit0)
        result[f"resolution_{n}_fit_s"] = round(t_fit, 1)
        result[f"resolution_{n}_fit_contrasts_lrt_s"] = round(time.perf_counter() - t0, 1)
        result["resolution_fits"] = len(js["simplification"])
        result["lrt"] = round(float(lr["statistic"]), 3)
        result["formula"] = fit.spec.formula()
        if use_r:
            t0 = time.perf_counter()
            ref = r_condition_tests(frame, fit.spec, null_spec(fit.spec),  # type: ignore[arg-type]
                                    contrasts=True, timeout_s=7200)
            result[f"r_resolution_{n}_s"] = round(time.perf_counter() - t0, 1)
            result["r_lrt"] = round(float(ref["lrt"]), 3)
            est = ref["contrasts"].query("scale == 'log-odds'")["estimate"].to_numpy()
            result["contrast_max_abs_diff"] = float(max(
                abs(c["estimate"] - e) for c, e in zip(contrasts, est, strict=True)))

        small = _frame(stores[1], k, seed=1)
        fit_s, _ = fit_model(small)  # type: ignore[arg-type]
        fit0_s = fit_glmm(small, null_spec(fit_s.spec), se=False)  # type: ignore[arg-type]
        t0 = time.perf_counter()
        pb = parametric_bootstrap(small, fit_s, fit0_s, n_sim=args.pb_sims, seed=0)  # type: ignore[arg-type]
        result[f"pb_{args.pb_sims}_{k}_s"] = round(time.perf_counter() - t0, 1)
        result["pb_p"] = pb.p
        if use_r:
            t0 = time.perf_counter()
            ref = r_condition_tests(small, fit_s.spec, null_spec(fit_s.spec),  # type: ignore[arg-type]
                                    n_sim=args.r_pb_sims, seed=0, timeout_s=7200)
            per_sim = float(ref["seconds_tests"]) / max(args.r_pb_sims, 1)
            result[f"r_pb_{args.r_pb_sims}_{k}_s"] = round(time.perf_counter() - t0, 1)
            result["r_pb_per_sim_s"] = round(per_sim, 2)
            result[f"r_pb_{args.pb_sims}_{k}_est_s"] = round(per_sim * args.pb_sims, 1)
            result["pb_per_sim_s"] = round(float(result[f"pb_{args.pb_sims}_{k}_s"])
                                           / args.pb_sims, 3)
    finally:
        if not args.keep:
            for s in stores:
                s.unlink(missing_ok=True)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
