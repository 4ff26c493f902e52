"""The house rules a contributor keeps without thinking of them (docs/architecture.md): the
layers and the absence of import cycles (import-linter's contracts in pyproject.toml, the
same check `make lint` runs), type-checking imports counted like any other, no two modules
importing each other, few loose modules, short command-line modules."""

from __future__ import annotations

import graphlib
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "tactorbelt"


def test_the_layers_hold_and_no_package_has_an_import_cycle() -> None:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
    # no cache: grimp's cache may answer from an older tree
    proc = subprocess.run([exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "3 kept, 0 broken" in proc.stdout  # the layers, no cycles, the analysis rooms


def test_the_import_contracts_count_every_import() -> None:
    """A type used only in annotations is imported like any other: it sits in its users'
    layer or below, and no contract leaves an import out."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    assert not config.get("exclude_type_checking_imports", False)
    excluded = {c["name"]: c["ignore_imports"] for c in config["contracts"]
                if c.get("ignore_imports")}
    assert not excluded, excluded


def test_no_two_modules_import_each_other_even_for_type_checking() -> None:
    """No import cycle between any modules of tactorbelt (a package and its own modules
    included), counting function-local and TYPE_CHECKING-only imports."""
    grimp = pytest.importorskip("grimp", reason="grimp comes with import-linter "
                                "(pip install -e '.[dev]')")
    graph = grimp.build_graph("tactorbelt", exclude_type_checking_imports=False,
                              cache_dir=None)
    imports = {m: graph.find_modules_directly_imported_by(m) for m in graph.modules}
    assert len(imports) > 100  # the whole package was read, from src/
    try:
        tuple(graphlib.TopologicalSorter(imports).static_order())
    except graphlib.CycleError as exc:
        cycle = exc.args[1]
        pytest.fail("import cycle: " + " -> ".join(cycle) + "; move the type next to its "
                    "users or declare a small Protocol in the lower module")


def test_at_most_ten_modules_stand_loose_beside_the_packages() -> None:
    loose = sorted(p.name for p in SRC.glob("*.py") if p.name not in ("__init__.py",
                                                                        "__main__.py"))
    assert len(loose) <= 10, loose


def test_every_command_line_module_is_under_200_lines() -> None:
    long = {p.name: n for p in (SRC / "cli").glob("*.py")
            if (n := len(p.read_text().splitlines())) >= 200}
    assert not long, long
