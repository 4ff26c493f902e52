"""``tactorbelt study init FILE`` and ``tactorbelt study check FILE``.

Imports click and (when a command runs) tactorbelt.experiment.study / schedule.
"""

from __future__ import annotations

from pathlib import Path

import click

from ._options import seed_option

__all__ = ["study"]

TEMPLATE_NAMES = ("paper", "resolution", "load")


@click.group("study")
def study() -> None:
    """Write or check a study file (TOML)."""


@study.command("init")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--template", type=click.Choice(TEMPLATE_NAMES), default="paper",
              show_default=True,
              help="paper: the paper's protocol; resolution: 12/24/36/48 targets x "
                   "static/dynamic, Williams order; load: static/dynamic x no load/auditory "
                   "2-back, NASA-TLX after every block.")
@click.option("--force", is_flag=True, help="Overwrite FILE if it exists.")
def init(file: Path, template: str, force: bool) -> None:
    """Write a commented study file to FILE, for you to edit.

    paper: 6 tactors, 24 targets, paper law T = 15, period 1 s, transit 100 ms; a
    training block, then a static and a dynamic test block of 24 targets x 5
    repetitions. resolution: the factorial follow-up ([design]: 12, 24, 36, 48 targets
    x static, dynamic, 2 repetitions, Williams order). load: 24 targets, static,
    dynamic x no load, auditory 2-back (practice and a single-task baseline first),
    raw NASA-TLX after every test block.
    """
    from ..experiment.study import Study, template_toml

    if file.exists() and not force:
        raise click.UsageError(f"{file} exists; add --force to overwrite it")
    if not file.parent.exists():
        raise click.UsageError(f"directory {file.parent} does not exist")
    text = template_toml(template)
    try:
        file.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise click.UsageError(f"cannot write {file}: {exc.strerror}") from None
    s = Study.from_toml(text, path=file)
    click.echo(f"wrote {file}: {s.name}, {s.n_trials()} trials "
               f"({s.n_training_trials()} training, {s.n_test_trials()} test)")
    click.echo(f"check it with: tactorbelt study check {file}")


@study.command("check")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--participant", default="P01", show_default=True,
              help="Show the block order of this participant.")
@seed_option("Seed for design.order = random [default: the study's session.seed].")
def check(file: Path, participant: str, seed: int | None) -> None:
    """Validate FILE; print its cells, trials per cell, block order and duration."""
    from ..experiment.description import describe
    from ..experiment.runner import check_participant
    from ..experiment.study import load_study

    s = load_study(file)
    report = describe(s, check_participant(participant), seed)
    click.echo(f"{file}: ok")
    click.echo(report.to_text())
