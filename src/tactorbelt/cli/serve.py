"""``tactorbelt serve``: the browser bridge (docs/browser.md).

Parses the options into a :class:`tactorbelt.bridge.BridgeConfig`, prints the
``open:`` line (the example page with its token) and calls
:func:`tactorbelt.bridge.serve` until Ctrl-C (exit 130) or SIGTERM (143).

Imports click and tactorbelt.interrupts at import time; the bridge, the study and the
belt only when it runs.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import click

from ..interrupts import Terminated
from ._options import belt_options, load_calibration, number

__all__ = ["serve"]

LOOPBACK = ("127.0.0.1", "localhost", "::1")


@click.command("serve")
@belt_options
@click.option("--store", "store_url", required=True, metavar="STORE",
              help="The session store (SQLite file, or postgresql://user@host/db): one "
                   "session per page, every trial as `tactorbelt run` stores it.")
@click.option("--study", "study_file", type=click.Path(dir_okay=False, path_type=Path),
              default=None, metavar="FILE",
              help="The study file [default: the paper's template, as `tactorbelt study "
                   "init` writes it].")
@click.option("--port", type=number(int, 0, 65535), default=None,
              help="TCP port for HTTP and the WebSocket (0: any free port) [default: 8735].")
@click.option("--host", default="127.0.0.1", show_default=True, metavar="ADDRESS",
              help="Address to listen on. Anything but the loopback lets other machines "
                   "reach the bridge (they still need the token): a warning is printed.")
@click.option("--allow-origin", "allow_origins", multiple=True, metavar="ORIGIN",
              help="Also accept pages from this origin (e.g. https://lab.example.org); "
                   "repeat for more. The bridge's own pages are always accepted.")
@click.option("--token", default=None, metavar="TOKEN",
              help="The token pages must present (16 to 128 letters, digits, '-' or '_') "
                   "[default: a new random one each start]; give one to keep a hosted "
                   "page's link working across restarts, and keep it secret.")
@click.option("--heartbeat-ms", type=number(int, 50, 60_000), default=1000,
              show_default=True,
              help="Ping period; a page silent for twice this has its motors turned off.")
def serve(belt_url: str, calibration_file: str | None, store_url: str,
          study_file: Path | None, port: int | None, host: str,
          allow_origins: tuple[str, ...], token: str | None, heartbeat_ms: int) -> None:
    """Serve a browser study: the example pages and a WebSocket bridge to the belt.

    Prints one line `open: http://127.0.0.1:PORT/examples/paper.html?token=TOKEN`;
    open it in a browser (add `&participant=ID`). Exit status: 130 after Ctrl-C,
    143 after SIGTERM, with the motors off and open sessions left resumable.
    """
    from ..bridge import DEFAULT_PORT, BridgeConfig
    from ..bridge import serve as run_bridge
    from ..experiment.study import Study, load_study, template_toml

    if token is not None and not re.fullmatch(r"[A-Za-z0-9_-]{16,128}", token):
        raise click.BadParameter("use 16 to 128 letters, digits, '-' or '_'",
                                 param_hint="--token")
    for origin in allow_origins:
        if origin != "null" and "://" not in origin:
            raise click.BadParameter(f"{origin!r} is not an origin (scheme://host[:port], "
                                     "or null)", param_hint="--allow-origin")
    if study_file is None:
        text = template_toml("paper")
        study = Study.from_toml(text, path="<paper template>")
    else:
        study = load_study(study_file)
        text = study_file.read_text(encoding="utf-8")
    if host not in LOOPBACK:
        click.echo(f"warning: listening on {host}: other machines can reach the bridge "
                   "(with the token); use the default 127.0.0.1 unless you need this",
                   err=True)
    config = BridgeConfig(
        belt_url=belt_url, store_url=store_url, study=study, study_toml=text,
        study_path=None if study_file is None else str(study_file), host=host,
        port=DEFAULT_PORT if port is None else port, allow_origins=tuple(allow_origins),
        heartbeat_ms=heartbeat_ms, calibration=load_calibration(calibration_file))
    if token is not None:
        config.token = token

    def ready(url: str) -> None:
        click.echo(f"open: {url}")
        sys.stdout.flush()

    try:
        run_bridge(config, ready=ready, note=lambda line: click.echo(line, err=True))
    except KeyboardInterrupt:
        click.echo("interrupted: motors off; open sessions are left resumable", err=True)
        raise
    except Terminated as exc:
        click.echo(f"terminated by {exc.name}: motors off; open sessions are left resumable",
                   err=True)
        raise
