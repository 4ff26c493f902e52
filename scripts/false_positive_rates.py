"""False-positive rates of the accuracy model's condition tests, by simulation.

Studies with **no condition effect** are simulated from the report's accuracy GLMM
(:func:`tactorbelt.power.glmm.simulate_frame` with the ``tactorbelt power
--odds-ratio`` defaults: static = dynamic between-tactor accuracy 0.5, on-tactor 0.9,
SDs 0.5 (participant), 0.3 (condition slope), 0.3 (target), log-odds) and analysed as
the report analyses them (:func:`tactorbelt.analysis.models.fit.fit_model`: the maximal
model simplified while singular). Per study:

- ``wald_z``: Wald z of ``conditionstatic`` (the old headline), two-sided;
  ``wald_z_one_sided``: the same, found in the direction ``tactorbelt power`` names
  (dynamic better), whose nominal rate is alpha / 2;
- ``wald_chi2``: the Wald chi-square over every condition term;
- ``lrt``: the likelihood ratio against the model without the condition terms;
- ``lrt_f``: the same ratio / k referred to ``F(k, participants - 1)`` (the report's
  headline; computed from ``lrt_stat`` when the table is made);
- ``pb``: its parametric bootstrap (pbkrtest's p) with ``--pb-sims`` simulations,
  on the first ``--pb-studies`` studies of each size.

A test *finds* an effect when ``p <= alpha``: with ``n_sim + 1`` a multiple of
``1 / alpha`` (39 at 0.05) the bootstrap's level is then exactly alpha when its
reference distribution is right, so its rate measures only how wrong the null fit's
reference distribution is.

Every study draws from ``numpy.random.default_rng([seed, n, i])`` (its bootstrap from
``[seed, n, i, 1]``); results are appended to ``--out`` as JSON lines, one per study,
and a rerun skips the studies already there, so the run can be stopped and resumed.
``--table`` prints the Markdown table of docs/analysis.md from that file.

Usage::

    python scripts/false_positive_rates.py --sizes 4,8,16 --studies 400 \\
        --pb-studies 150 --pb-sims 39 --out fp-paper.jsonl
    python scripts/false_positive_rates.py --design resolution --out fp-res.jsonl ...
    python scripts/false_positive_rates.py --start 80 --pb-studies 0 --out fp-more.jsonl
    python scripts/false_positive_rates.py --table --out fp-paper.jsonl fp-more.jsonl
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from tactorbelt.analysis.models.fit import fit_model
from tactorbelt.analysis.models.glmm import fit_glmm
from tactorbelt.analysis.models.lrt import (
    f_reference,
    likelihood_ratio,
    null_spec,
    parametric_bootstrap,
    wald_condition,
)
from tactorbelt.experiment.study import Study, paper_study, template_toml
from tactorbelt.power.design import TrialDesign
from tactorbelt.power.glmm import simulate_frame
from tactorbelt.power.outcomes import binomial_ci

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.power_trials import no_effect, trials_of

TESTS = ("wald_z", "wald_z_one_sided", "wald_chi2", "lrt", "lrt_f", "pb", "wald_z_max",
         "wald_chi2_max", "lrt_max", "pb_max")
LABELS = {"wald_z": "Wald z, `conditionstatic` (two-sided)",
          "wald_z_one_sided": "Wald z, one-sided (nominal alpha/2)",
          "wald_chi2": "Wald chi-square, all condition terms",
          "lrt": "likelihood ratio (chi-square)",
          "lrt_f": "likelihood ratio / k, F(k, participants - 1) (the headline)",
          "pb": "parametric bootstrap of the LRT",
          "wald_z_max": "slope kept: Wald z, `conditionstatic`",
          "wald_chi2_max": "slope kept: Wald chi-square",
          "lrt_max": "slope kept: likelihood ratio (chi-square)",
          "pb_max": "slope kept: parametric bootstrap"}


def design_of(name: str) -> TrialDesign:
    if name == "paper":
        return trials_of(paper_study())
    return trials_of(Study.from_toml(template_toml("resolution")), all_counts=True)


def one_study(design: TrialDesign, n: int, i: int, seed: int, pb_sims: int,
              keep_slopes: bool = False) -> dict[str, object]:
    rng = np.random.default_rng([seed, n, i])
    frame = simulate_frame(design, no_effect(), n, rng)
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit, js = fit_model(frame)
        fit0 = fit_glmm(frame, null_spec(fit.spec), se=False)
    fe = fit.fixed_effects["conditionstatic"]
    wald = wald_condition(fit)
    lr = likelihood_ratio(fit, fit0)
    out: dict[str, object] = {
        "n": n, "i": i, "formula": fit.spec.formula(), "singular": fit.singular,
        "wald_z": fe.p, "z": fe.z, "wald_chi2": wald["p"], "lrt": lr["p"],
        "lrt_stat": lr["statistic"], "df": lr["df"],
    }
    if pb_sims:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pb = parametric_bootstrap(frame, fit, fit0, n_sim=pb_sims, seed=[seed, n, i, 1])
        out.update({"pb": pb.p, "pb_sims": pb.n_sim, "pb_positive": pb.n_positive,
                    "pb_failed": pb.failed})
    if keep_slopes:
        # the same tests with the condition slope kept even when its variance is at 0
        if "(1 + condition | participant)" in fit.spec.formula():
            out.update({f"{k}_max": out.get(k) for k in ("wald_z", "z", "wald_chi2", "lrt",
                                                          "pb")})
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fm, _ = fit_model(frame, keep_slopes=True)
                fm0 = fit_glmm(frame, null_spec(fm.spec), se=False)
                fem = fm.fixed_effects["conditionstatic"]
                out.update({"wald_z_max": fem.p, "z_max": fem.z,
                            "wald_chi2_max": wald_condition(fm)["p"],
                            "lrt_max": likelihood_ratio(fm, fm0)["p"]})
                if pb_sims:
                    pbm = parametric_bootstrap(frame, fm, fm0, n_sim=pb_sims,
                                               seed=[seed, n, i, 1])
                    out["pb_max"] = pbm.p
    out["cpu_s"] = time.process_time() - t0
    return out


def found(rec: dict[str, Any], test: str, alpha: float) -> bool | None:
    if test == "wald_z_one_sided":
        p, z = rec.get("wald_z"), rec.get("z")
        if p is None or z is None or not math.isfinite(float(p)):
            return None
        return float(p) <= alpha and float(z) < 0  # dynamic better
    if test == "lrt_f":
        stat, df = rec.get("lrt_stat"), rec.get("df")
        if stat is None or df is None:
            return None
        p_f = f_reference(float(stat), int(df), int(rec["n"]))["p"]
        return bool(p_f <= alpha)
    p = rec.get(test)
    if p is None or not math.isfinite(float(p)):
        return None
    return float(p) <= alpha


def table(path: list[Path], alpha: float) -> str:
    recs = [json.loads(line) for p in path for line in p.read_text().splitlines()
            if line.strip()]
    sizes = sorted({int(r["n"]) for r in recs})
    head = "| test | " + " | ".join(f"{n} participants" for n in sizes) + " |"
    lines = [head, "|---|" + "---|" * len(sizes)]
    for test in TESTS:
        cells = []
        for n in sizes:
            hits = [h for h in (found(r, test, alpha) for r in recs if int(r["n"]) == n)
                    if h is not None]
            if not hits:
                cells.append("-")
                continue
            k = int(sum(hits))
            lo, hi = binomial_ci(k, len(hits))
            cells.append(f"{100 * k / len(hits):.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] "
                         f"({k}/{len(hits)})")
        if any(c != "-" for c in cells):
            lines.append(f"| {LABELS[test]} | " + " | ".join(cells) + " |")
    cpu = {n: np.mean([float(r["cpu_s"]) for r in recs if int(r["n"]) == n and "pb" in r] or
                      [math.nan]) for n in sizes}
    lines.append("")
    lines.append("CPU seconds per study with the bootstrap: " + ", ".join(
        f"{n}: {v:.0f}" for n, v in cpu.items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", choices=("paper", "resolution"), default="paper")
    ap.add_argument("--sizes", default="4,8,16")
    ap.add_argument("--studies", type=int, default=400)
    ap.add_argument("--start", type=int, default=0,
                    help="first study index (to split a run across processes and files)")
    ap.add_argument("--pb-studies", type=int, default=150)
    ap.add_argument("--pb-sims", type=int, default=39)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep-slopes", action="store_true",
                    help="also the tests with the condition slope kept when the report's "
                         "rule drops it (fields *_max)")
    ap.add_argument("--alpha", type=float, default=0.05)
    ap.add_argument("--out", type=Path, default=Path("false-positives.jsonl"))
    ap.add_argument("--table", action="store_true", help="print the table of --out and stop")
    ap.add_argument("more", nargs="*", type=Path,
                    help="with --table: more result files to pool with --out")
    a = ap.parse_args(argv)
    if a.table:
        print(table([a.out, *a.more], a.alpha))
        return 0
    design = design_of(a.design)
    done = set()
    if a.out.exists():
        done = {(int(r["n"]), int(r["i"])) for r in
                (json.loads(x) for x in a.out.read_text().splitlines() if x.strip())}
    sizes = [int(s) for s in a.sizes.split(",")]
    # interleave the sizes so that a stopped run has some of each
    for i in range(a.start, a.studies):
        for n in sizes:
            if (n, i) in done:
                continue
            pb = a.pb_sims if i < a.pb_studies else 0
            rec = one_study(design, n, i, a.seed, pb, a.keep_slopes)
            rec["design"] = a.design
            with a.out.open("a") as fh:
                fh.write(json.dumps(rec) + "\n")
            print(f"n={n} i={i} lrt p={rec['lrt']:.3f} pb p={rec.get('pb', float('nan')):.3f} "
                  f"cpu {rec['cpu_s']:.1f} s", file=sys.stderr, flush=True)
    print(table([a.out], a.alpha))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
