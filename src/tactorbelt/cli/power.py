"""``tactorbelt power``: plan a study's size by simulating it with model participants.

Parse the options, call one library function (:func:`tactorbelt.power.study.run_power_study`),
print the result.

Imports click at import time; NumPy, the simulation, matplotlib and rich only when the
command runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import click

from ._options import number, output_option, seed_option
from .demo import progress_bar

__all__ = ["parse_sizes", "power"]


# -- power ---------------------------------------------------------------------------------

def parse_sizes(text: str) -> list[int]:
    """Parse ``4,8,12,16`` into study sizes (whole numbers >= 2, no repeats)."""
    sizes: list[int] = []
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        try:
            n = int(part)
        except ValueError:
            n = -1
        if n < 2 or n > 10_000:
            raise click.BadParameter(
                f"must be a comma-separated list of whole numbers of participants from 2 to "
                f"10000, e.g. 4,8,12,16; got {text!r}", param_hint="'--participants'")
        if n not in sizes:
            sizes.append(n)
    if not sizes:
        raise click.BadParameter("give at least one study size, e.g. 4,8,12,16",
                                 param_hint="'--participants'")
    return sorted(sizes)


@click.command("power")
@click.option("--participants", "sizes_text", default="4,8,12,16", show_default=True,
              help="Study sizes to simulate, comma-separated.")
@click.option("--sims", type=number(int, 1, 1_000_000), default=500, show_default=True,
              help="Simulated studies per size.")
@output_option("directory", "Directory for power.csv, power.json and power.png.",
               default=Path("power-output"))
@seed_option("Seed of the simulation (results do not depend on --jobs).", default=1)
@click.option("--jobs", type=number(int, 1, 256), default=None,
              help="Worker processes [default: the number of CPUs, at most 8].")
@click.option("--study", "study_file", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Study file to plan [default: the paper's protocol].")
@click.option("--alpha", type=number(float, 0, 1, lo_open=True, hi_open=True),
              default=0.05, show_default=True, help="Significance level of the test.")
@click.option("--effect", default=None, metavar="EFFECT",
              help="Effect to detect in a factorial study: 'dynamic vs static', 'dynamic "
                   "vs static at 36', 'interaction' (resolution x condition) or 'load' "
                   "(between-tactor accuracy without vs under load; 'load NAME': one "
                   "load).")
@click.option("--odds-ratio", type=number(float, 0, 1000, lo_open=True), default=None,
              help="Plan for the report's accuracy GLMM instead of model participants: the "
                   "dynamic-over-static odds ratio at between-tactor targets to find.")
@click.option("--accuracy", type=number(float, 0, 1, lo_open=True, hi_open=True),
              default=0.5, show_default=True,
              help="With --odds-ratio: static between-tactor accuracy.")
@click.option("--on-tactor-accuracy", type=number(float, 0, 1, lo_open=True, hi_open=True),
              default=0.9, show_default=True,
              help="With --odds-ratio: accuracy at on-tactor targets.")
@click.option("--participant-sd", type=number(float, 0, 5), default=0.5, show_default=True,
              help="With --odds-ratio: SD of the participant intercept (log-odds).")
@click.option("--slope-sd", type=number(float, 0, 5), default=0.3, show_default=True,
              help="With --odds-ratio: SD of the participant's condition slope (log-odds).")
@click.option("--target-sd", type=number(float, 0, 5), default=0.3, show_default=True,
              help="With --odds-ratio: SD of the target intercept (log-odds).")
def power(sizes_text: str, sims: int, out: Path, seed: int, jobs: int | None,
          study_file: Path | None, alpha: float, effect: str | None,
          odds_ratio: float | None, accuracy: float, on_tactor_accuracy: float,
          participant_sd: float, slope_sd: float, target_sd: float) -> None:
    """Plan a study's size by simulation with model participants.

    For each study size, simulates --sims studies of that many model participants
    (each an individual observer drawn around the typical one), runs the analysis'
    static-vs-dynamic test (paired Wilcoxon signed-rank on per-participant
    between-tactor accuracy), and counts the studies in which it finds the difference
    (p < alpha, dynamic higher). Writes power.csv, power.json and power.png (power vs
    participants with 95 % binomial intervals) to DIR and prints the table. For a
    factorial study, --effect names what to detect (default: dynamic vs static over
    every block).

    Trials are simulated directly from the model's perception (no runner, no store;
    the fast path gives the same accuracy as the full runner). The power is that of a
    study *if people behaved like the model* (docs/participant-model.md).

    With --odds-ratio, the effect sizes are yours instead: each study's trials are
    drawn from the report's accuracy GLMM with that odds ratio, accuracy and random-
    effect SDs, and analyzed with the same GLMM and headline test as the report (the
    likelihood ratio of the condition referred to F(k, participants - 1)); about 0.5 s a
    study of the paper's size: use fewer --sims for a first look.
    """
    from rich.console import Console
    from rich.table import Table

    from ..experiment.study import load_study, paper_study
    from ..power.study import run_power_study

    named = None
    if odds_ratio is not None:
        from ..power.glmm import NamedEffect

        named = NamedEffect(odds_ratio, accuracy, on_tactor_accuracy, participant_sd,
                            slope_sd, target_sd)
    sizes = parse_sizes(sizes_text)
    study = load_study(study_file) if study_file is not None else paper_study()
    err = Console(stderr=True)
    with progress_bar(err) as bar:
        task = bar.add_task("simulated studies", total=sims * len(sizes))
        result = run_power_study(study, sizes, sims, seed, out, jobs=jobs, alpha=alpha,
                                 advance=lambda k: bar.advance(task, k),
                                 study_label=str(study_file) if study_file else None,
                                 effect=effect, named=named)
    what = (f"'{result.effect}'" if named is not None
            else "the static-vs-dynamic test" if effect is None else f"'{effect}'")
    table = Table(title=f"Power of {what} (alpha {alpha:g}, "
                        f"{sims} simulated studies per size)",
                  caption=f"test: {result.test}")
    for col in ("participants", "power", "95 % CI", f"{result.pair[0]} acc.".replace("_", " "),
                f"{result.pair[1]} acc.".replace("_", " "), "median p"):
        table.add_column(col, justify="right")
    for r in result.rows:
        table.add_row(str(r.n_participants), f"{r.power:.2f}",
                      f"[{r.ci_low:.2f}, {r.ci_high:.2f}]", f"{r.static_acc:.1%}",
                      f"{r.dynamic_acc:.1%}",
                      "n/a" if not math.isfinite(r.median_p) else f"{r.median_p:.3g}")
    Console().print(table)
    for note in result.notes:
        err.print(f"note: {note}", highlight=False)
    click.echo(f"power: {result.plot.resolve()}")
