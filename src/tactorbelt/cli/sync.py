"""``tactorbelt sync LOCAL URL``: push what a shared store lacks of a local one.

Calls :func:`tactorbelt.experiment.sync.sync_stores`; sessions are matched by their
``session_uuid``, so running it twice changes nothing.
"""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["sync"]


@click.command("sync")
@click.argument("local", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.argument("url")
@click.option("--site", metavar="NAME", default=None,
              help="Site of sessions that have none (older stores) [default: "
                   "$TACTORBELT_SITE, else the host name].")
def sync(local: Path, url: str, site: str | None) -> None:
    """Push every session and trial of the store LOCAL that URL (postgresql://...) lacks.

    Idempotent: what is there already is left alone. A session whose participant id is
    taken at another site is refused (exit 2) and the others are pushed; a session of a
    site that URL's role does not write refuses the whole sync (exit 2, nothing pushed).
    """
    from ..experiment.sync import sync_stores

    report = sync_stores(local, url, site=site)
    click.echo(report.summary(url))
    for line in report.errors:
        click.echo(f"refused: {line}", err=True)
    if report.errors:
        raise click.exceptions.Exit(2)
