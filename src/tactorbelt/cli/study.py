"""``tactorbelt study init FILE`` and ``tactorbelt study check FILE``.

Imports click and (when a command runs) tactorbelt.experiment.study / schedule.
"""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["study"]


@click.group("study")
def study() -> None:
    """Write or check a study file (TOML)."""


@study.command("init")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--force", is_flag=True, help="Overwrite FILE if it exists.")
def init(file: Path, force: bool) -> None:
    """Write the paper's protocol to FILE, with comments, for you to edit.

    6 tactors, 24 targets, paper law T = 15, period 1 s, transit 100 ms; a training
    block, then a static and a dynamic test block of 24 targets x 5 repetitions.
    """
    from ..experiment.study import PAPER_STUDY_TOML, paper_study

    if file.exists() and not force:
        raise click.UsageError(f"{file} exists; add --force to overwrite it")
    if not file.parent.exists():
        raise click.UsageError(f"directory {file.parent} does not exist")
    try:
        file.write_text(PAPER_STUDY_TOML, encoding="utf-8")
    except OSError as exc:
        raise click.UsageError(f"cannot write {file}: {exc.strerror}") from None
    s = paper_study()
    click.echo(f"wrote {file}: {s.name}, {s.n_trials()} trials "
               f"({s.n_training_trials()} training, {s.n_test_trials()} test)")
    click.echo(f"check it with: tactorbelt study check {file}")


def _minutes(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"


@study.command("check")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--participant", default="P01", show_default=True,
              help="Show the block order of this participant.")
def check(file: Path, participant: str) -> None:
    """Validate FILE and print its trial counts and an estimate of its duration."""
    from ..experiment.schedule import block_order, make_schedule
    from ..experiment.study import load_study

    s = load_study(file)
    layout = s.layout_obj()
    targets = s.target_set()
    on = int(targets.on_tactor(layout).sum())
    click.echo(f"{file}: ok")
    click.echo(f"  study       {s.name}")
    click.echo(f"  layout      {layout.n} tactors at "
               f"{', '.join(f'{a:g}' for a in layout.angles_deg)} deg")
    click.echo(f"  targets     {targets.m} ({on} on-tactor, {targets.m - on} between-tactor)")
    st = s.stimulus
    click.echo(f"  stimulus    law {st.law}, falloff {st.falloff_deg:g} deg, period "
               f"{st.period_s:g} s, transit {st.transit_s:g} s, at most "
               f"{st.max_presentation_s:g} s")
    r = s.response
    click.echo(f"  response    home {r.home_radius:g}, threshold {r.threshold:g}, dwell "
               f"{r.dwell_s:g} s, timeout {r.timeout_s:g} s")
    click.echo("  blocks")
    if s.n_training_trials():
        click.echo(f"    training  {s.n_training_trials():4d} trials "
                   f"({s.training.passes} pass(es) x {len(s.training.conditions)} "
                   f"condition(s) x {targets.m} targets, {s.training.order})")
    for b in s.test:
        click.echo(f"    {b.label:<9s} {b.repetitions * targets.m:4d} trials "
                   f"({b.condition}, {b.repetitions} repetitions x {targets.m} targets)")
    click.echo(f"  total       {s.n_trials()} trials ({s.n_test_trials()} test)")
    order = [s.test[i].label for i in block_order(s, participant)]
    click.echo(f"  order       {s.session.condition_order}; {participant}: "
               f"{' -> '.join(order)}")
    n = s.n_trials()
    brk = (n - 1) // s.session.break_every if s.session.break_every else 0
    click.echo(f"  breaks      {brk} (every {s.session.break_every} trials)"
               if brk else "  breaks      none")
    click.echo(f"  duration    about {_minutes(s.estimate_duration_s())} "
               f"(2 s per response + {s.session.iti_s:g} s ITI per trial + 1 min per break); "
               f"at most {_minutes(s.estimate_duration_s(response_s=s.response.timeout_s))}")
    make_schedule(s, participant)  # proves the schedule can be built
