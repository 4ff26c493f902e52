"""What the bridge serves over HTTP: its static files and the study as JSON.

:func:`static_file` maps a URL path into the package's ``static/`` folder (nothing
outside it), :func:`content_type` names a file's type (``.mjs`` as JavaScript),
:func:`response` builds the reply (no caching; CORS for an allowed origin), and
:func:`study_json` is ``/study.json``: what a page needs of the study to draw and run
it.

Imports the standard library, the study, geometry and ``websockets``.
"""

from __future__ import annotations

import mimetypes
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

from websockets.datastructures import Headers
from websockets.http11 import Response

from ..geometry import TargetSet

if TYPE_CHECKING:
    from ..experiment.study import Study

__all__ = ["content_type", "response", "static_file", "study_json"]


def study_json(study: Study, path: str | None) -> dict[str, Any]:
    """``/study.json``: the study's name and file, its layout, the targets of every target
    count it uses (``target_sets``; ``targets``: those of ``[targets] count``), its
    conditions and test blocks, and the whole study (``study``)."""
    layout = study.layout_obj()
    counts = sorted({study.targets.count, *study.target_counts()})
    targets = {}
    for n in counts:
        on = TargetSet.even(n).on_tactor(layout)
        targets[str(n)] = [{"target": k, "angle_deg": k * 360.0 / n,
                            "on_tactor": bool(on[k])} for k in range(n)]
    return {
        "name": study.name, "description": study.description, "file": path,
        "layout": {"tactors": layout.n, "angles_deg": list(layout.angles_deg)},
        "targets": targets[str(study.targets.count)],
        "target_sets": targets,
        "conditions": sorted({b.condition for b in study.test}
                             | set(study.training.conditions)),
        "blocks": [{"name": b.name, "condition": b.condition,
                    "n_targets": study.block_n_targets(b)} for b in study.test],
        "study": study.model_dump(mode="json"),
    }


def response(status: int, body: bytes, ctype: str, cors: str | None = None) -> Response:
    """An HTTP reply that is never cached, with CORS for ``cors`` (an allowed origin)."""
    headers = Headers([("Content-Type", ctype), ("Content-Length", str(len(body))),
                       ("Cache-Control", "no-store"), ("Connection", "close")])
    if cors is not None:
        headers["Access-Control-Allow-Origin"] = cors
        headers["Vary"] = "Origin"
    return Response(status, "OK" if status == 200 else "", headers, body)


def static_file(root: Path, path: str) -> Path | None:
    """The file under ``root`` that a URL path names, or None (outside it, missing)."""
    rel = unquote(path).lstrip("/")
    if not rel or "\x00" in rel:
        return None
    base = root.resolve()
    try:
        file = (base / rel).resolve()
        file.relative_to(base)
    except (ValueError, OSError):
        return None
    return file if file.is_file() else None


def content_type(file: Path) -> str:
    """The Content-Type of a static file (JavaScript modules included)."""
    if file.suffix in (".js", ".mjs"):
        return "text/javascript; charset=utf-8"
    if file.suffix == ".json":
        return "application/json"
    guessed = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
    return guessed + ("; charset=utf-8" if guessed.startswith("text/") else "")
