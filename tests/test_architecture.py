"""The house rules a contributor keeps without thinking of them (docs/architecture.md): the
layers and the absence of import cycles (import-linter's contracts in pyproject.toml, the
same check `make lint` runs), few loose modules, short command-line modules."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "tactorbelt"


def test_the_layers_hold_and_no_package_has_an_import_cycle() -> None:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
    proc = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "3 kept, 0 broken" in proc.stdout  # the layers, no cycles, the analysis rooms


def test_at_most_ten_modules_stand_loose_beside_the_packages() -> None:
    loose = sorted(p.name for p in SRC.glob("*.py") if p.name not in ("__init__.py",
                                                                        "__main__.py"))
    assert len(loose) <= 10, loose


def test_every_command_line_module_is_under_200_lines() -> None:
    long = {p.name: n for p in (SRC / "cli").glob("*.py")
            if (n := len(p.read_text().splitlines())) >= 200}
    assert not long, long
