"""``tactorbelt export``: a store as CSV, BIDS, Parquet, a tidy table for R and JASP, or
PsychoPy CSV (docs/export.md).

For BIDS it says on the terminal what it filled in and from where (the authors: from
``--authors`` or the study file's ``authors``; the README: generated, or ``--readme``)
and which option fills what is missing.

Imports click at import time; the exporters only when the command runs.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ._options import HiddenArgument, output_option

__all__ = ["EXPORT_FORMATS", "export"]

EXPORT_FORMATS = ("csv", "bids", "parquet", "tidy", "psychopy")



@click.command("export")
@click.argument("db")
@click.argument("old_out", cls=HiddenArgument, required=False,
                type=click.Path(file_okay=False, path_type=Path))
@output_option("directory", "New or empty directory for the files.")
@click.option("--format", "fmt", type=click.Choice(EXPORT_FORMATS), default="csv",
              show_default=True,
              help="csv: the store's tables as CSV; bids: a BIDS dataset (beh, the cursor "
                   "as a physio recording); "
                   "parquet: the same tables as Parquet; tidy: one trial table for R (lme4) "
                   "and JASP, with its codebook; psychopy: PsychoPy's wide CSV, one file per "
                   "session.")
@click.option("--force", is_flag=True,
              help="Replace an earlier export of the same format in the output directory.")
@click.option("--readme", type=click.Path(dir_okay=False, path_type=Path), default=None,
              metavar="FILE", help="BIDS: README to include [default: one describing the "
                                   "study, the task and the columns].")
@click.option("--authors", default=None, metavar="'A, B'",
              help="BIDS: the dataset's authors, comma-separated [default: the study file's "
                   "authors].")
def export(db: str, old_out: Path | None, out: Path | None, fmt: str, force: bool,
           readme: Path | None, authors: str | None) -> None:
    """Export the store DB (trials and cursor samples) into a new directory.

    Example: `tactorbelt export study.sqlite -o bids --format bids --authors "A. Author,
    B. Author"`. A directory that is not empty is refused unless --force (which replaces
    only an earlier export there).
    """
    from ..experiment import export_formats
    from ..experiment.export import export_bids, export_csv

    if out is not None and old_out is not None:
        raise click.UsageError("give the output directory once, with -o DIRECTORY")
    out = out if out is not None else old_out
    if out is None:
        raise click.UsageError("give the output directory with -o DIRECTORY")
    if fmt != "bids" and (readme is not None or authors is not None):
        raise click.UsageError("--readme and --authors are for --format bids")
    names = None if authors is None else [a.strip() for a in authors.split(",") if a.strip()]
    if names == []:
        raise click.BadParameter("name at least one author, e.g. 'A. Author, B. Author'",
                                 param_hint="'--authors'")
    writers = {"csv": export_csv, "parquet": export_formats.export_parquet,
               "tidy": export_formats.export_tidy, "psychopy": export_formats.export_psychopy}
    files = (export_bids(db, out, readme=readme, authors=names, force=force) if fmt == "bids"
             else writers[fmt](db, out, force=force))
    click.echo(f"wrote {len(files)} files to {out}")
    if fmt == "bids":
        _bids_notes(out, files, names, readme)


def _bids_notes(out: Path, files: list[Path], names: list[str] | None,
                readme: Path | None) -> None:
    """Say what the BIDS export filled in, from where, and what fills what is missing."""
    desc = json.loads((out / "dataset_description.json").read_text(encoding="utf-8"))
    got = desc.get("Authors") or []
    if names is not None:
        click.echo(f"  Authors: {', '.join(got)} (from --authors)")
    elif got:
        click.echo(f"  Authors: {', '.join(got)} (from the study file's authors; --authors "
                   "'A, B' replaces them)")
    else:
        click.echo("note: no --authors given and the study file names none, so "
                   "dataset_description.json lists no authors (the BIDS validator warns "
                   "NO_AUTHORS); add --authors 'A, B', or authors = [\"A\", \"B\"] at the top "
                   "of the study file", err=True)
    if len(got) == 1:
        click.echo(f"note: one author ({got[0]}): the BIDS validator warns TOO_FEW_AUTHORS "
                   "(it takes a list of names in one string for one author); ignore it if "
                   "that is everyone, else name each: --authors 'A, B', or authors = "
                   "[\"A\", \"B\"] in the study file", err=True)
    if readme is None:
        click.echo("  README.md: generated from the study file (--readme FILE for your own)")
    kinds = {"cursor": "_recording-cursor_physio.tsv.gz", "events": "_events.tsv",
             "ratings": "_task-nasatlx_beh.tsv"}
    for what, suffix in kinds.items():
        n = sum(1 for f in files if f.name.endswith(suffix))
        if n:
            click.echo(f"  {what}: {n} file(s) *{suffix}")
