"""``tactorbelt analyze DB [DB ...] [-o DIRECTORY] [--seed S] [--rt-from skin|command]
[--fixef-prior normal:SD[,SD]]``.

The analysis report. Without ``--seed`` the analysis seed is derived from the stores;
without ``--rt-from`` the RTs count from the skin onset when every analyzed trial has
one, else from the command (docs/analysis.md).

Imports the analysis (pandas, SciPy, statsmodels, matplotlib) only when the command
runs. Errors are raised as tactorbelt errors; ``tactorbelt.cli.main`` prints them.
"""

from __future__ import annotations

import os
from pathlib import Path

import click

from ._options import number, output_option, seed_option

__all__ = ["analyze"]


@click.command("analyze")
@click.argument("db", nargs=-1, required=True)
@output_option("directory", "Directory for report.html, summary.json, per_target.csv and "
               "the PNGs [default: the directory of the first DB].")
@seed_option("Seed of the bootstrap intervals and of the sample trajectories shown "
             "[default: the smallest seed of the stored sessions, so the same stores "
             "always give the same report, the demo's included].")
@click.option("--engine", type=click.Choice(["tactorbelt", "lme4"]), default="tactorbelt",
              show_default=True,
              help="Who fits the mixed models: tactorbelt's Laplace GLMM, or R's lme4 through "
                   "Rscript (needs 'apt install r-base-core r-cran-lme4').")
@click.option("--site", "sites", multiple=True, metavar="NAME",
              help="Only the sessions of this site (repeat for several).")
@click.option("--bootstrap-sims", "pb_sims", type=number(int, 0, 100_000), default=None,
              help="Simulations of the accuracy model's parametric bootstrap of the "
                   "condition, computed up to 16 participants beside the headline test "
                   "[default: 100; 0: skip it].")
@click.option("--rt-from", "rt_from", type=click.Choice(["skin", "command"]), default=None,
              help="Count response times from the onset at the skin (the stored onset plus "
                   "the measured latency of the tactors that start the stimulus: 'tactorbelt "
                   "validate onsets') or from the command (the stored onset) [default: skin "
                   "when every analyzed trial has a skin onset, else command].")
@click.option("--fixef-prior", "fixef_prior", metavar="normal:SD[,SD]", default=None,
              help="Fit the accuracy model with a normal prior on its fixed effects, as "
                   "blme::bglmer(fixef.prior = normal(sd = ...)) with bglmer's default "
                   "covariance prior: normal:SD (every fixed effect) or normal:SD0,SD "
                   "(intercept, the rest; bglmer's default is normal:10,2.5). For cells at "
                   "0 or 100 %, where maximum likelihood has no finite estimates "
                   "(docs/analysis.md, 'Separation').")
@click.option("--include-running", is_flag=True,
              help="From a shared store (postgresql://), also the sessions that are not "
                   "complete yet.")
def analyze(db: tuple[str, ...], out: Path | None, seed: int | None, engine: str,
            sites: tuple[str, ...], include_running: bool, pb_sims: int | None,
            rt_from: str | None, fixef_prior: str | None) -> None:
    """Analyze one or more session stores and write the report.

    DB is a store written by 'tactorbelt run' or 'tactorbelt demo' (several may be
    given: their sessions are pooled). Writes report.html (self-contained), summary.json,
    per_target.csv and the figures, then prints the headline numbers and where the report is.
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..analysis.report.analyze import analyze as run_analysis
    from ..analysis.report.analyze import print_summary_table as _print

    first = Path(db[0]) if "://" not in db[0] else Path(".")
    out_dir = out if out is not None else (first.parent if str(first.parent) else Path("."))
    err = Console(stderr=True)
    with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                  console=err, transient=True, disable=not err.is_terminal) as bar:
        task = bar.add_task("analyzing", total=6)

        def progress(what: str, done: int, total: int) -> None:
            bar.update(task, description=what, completed=done, total=total)

        summary = run_analysis(list(db), out_dir, seed=seed, progress=progress,
                               engine=engine, sites=list(sites) or None,
                               include_running=include_running, pb_sims=pb_sims,
                               rt_from=rt_from, fixef_prior=fixef_prior)
    out_console = Console()
    _print(summary, out_console)
    for note in summary.notes:
        out_console.print(f"note: {note}", highlight=False, markup=False)
    out_console.print(f"report: {(out_dir / 'report.html').resolve()}", highlight=False,
                      markup=False, soft_wrap=True)
