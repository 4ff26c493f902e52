"""``tactorbelt demo``: the paper's study (or a study file) with model participants.

Parse the options, call one library function (:func:`tactorbelt.app.demo.run_model_study`),
print the result. ``tactorbelt power`` is :mod:`.power`.

Imports click at import time; NumPy, the runner, the analysis, matplotlib and rich only
when a command runs.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click

from ._options import number, output_option, seed_option

__all__ = ["demo", "progress_bar"]


def progress_bar(console: Any) -> Any:
    """A rich progress bar with counts and times (demo and power)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console)


# -- demo ----------------------------------------------------------------------------------

@click.command("demo")
@output_option("directory", "Directory for study.toml, study.sqlite, the report and its "
               "figures.", default=Path("demo-output"))
@click.option("--participants", type=number(int, 1, 999), default=1, show_default=True,
              help="Number of model participants (ids model-01, model-02, ...).")
@seed_option("Seed of the schedules, the model participants and the analysis.", default=1)
@click.option("--study", "study_file", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Study file to run [default: the paper's protocol].")
def demo(out: Path, participants: int, seed: int, study_file: Path | None) -> None:
    """Run the paper's study (or --study FILE) with model participants, then analyze it.

    Writes DIR/study.toml (the paper's protocol, as 'tactorbelt study init' writes it,
    or a copy of --study FILE), runs each model participant through a whole session
    (training, then the test blocks: 240 trials in the paper's protocol) on the
    simulated belt and a simulated clock, stores every trial and cursor sample in
    DIR/study.sqlite, and writes the analysis report: report.html, summary.json,
    per_target.csv and PNG figures. Then prints accuracy and median RT per condition
    and where the report is. Under a load (a [tasks.NAME] secondary task) the model
    participants also do the task and answer the NASA-TLX, and the report covers them.

    An existing DIR/study.sqlite is moved to DIR/study.previous.sqlite (replacing an
    older one), so the demo can be run again into the same directory.

    The participants are models: simulated observers whose results follow from the
    model's assumptions (docs/participant-model.md), not evidence about people.
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    from rich.console import Console

    from ..analysis.report.analyze import print_summary_table
    from ..app.demo import run_model_study

    err = Console(stderr=True)
    with progress_bar(err) as bar:
        tasks: dict[str, Any] = {}

        def progress(what: str, done: int, total: int) -> None:
            key = "analysis" if what.startswith("analysis") else "participants"
            if key not in tasks:
                tasks[key] = bar.add_task(what, total=total)
            bar.update(tasks[key], description=what, completed=done, total=max(total, 1))

        result = run_model_study(out, participants, seed, progress=progress,
                                 notify=lambda note: err.print(f"note: {note}",
                                                               highlight=False),
                                 study_file=study_file)
        if "analysis" in tasks:
            bar.update(tasks["analysis"], completed=bar.tasks[-1].total,
                       description="analysis")
    print_summary_table(result.summary, Console())
    for note in result.summary.notes:
        err.print(f"note: {note}", highlight=False)
    click.echo(f"store:  {result.store.resolve()}")
    click.echo(f"report: {result.report.resolve()}")
