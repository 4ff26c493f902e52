"""The project reads on its own: every document it cites is in the repository."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md"), REPO / "firmware" / "README.md"])
_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page: Path) -> None:
    missing = [target for target in _LINK.findall(page.read_text())
               if "://" not in target and not (page.parent / target).exists()]
    assert not missing, f"{page.relative_to(REPO)} links to missing files: {missing}"


def test_nothing_cites_a_design_file_outside_the_repository() -> None:
    roots = ["src", "docs", "tests", "examples", "benchmarks", "scripts", "firmware"]
    hits = [str(p.relative_to(REPO)) for root in roots for p in (REPO / root).rglob("*")
            if p.is_file() and p.suffix in {".py", ".md", ".h", ".cpp", ".ino", ".toml"}
            and p.name != "test_docs_links.py" and "DESIGN.md" in p.read_text(errors="replace")]
    assert not hits, f"cite docs/conventions.md instead of DESIGN.md in: {hits}"
