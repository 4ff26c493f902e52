"""Packaging hook: the wheel carries the firmware sketch.

``firmware/tactorbelt`` (the Arduino sketch and its portable core) lives beside the Python
sources; ``build_py`` copies it into the package as ``tactorbelt/firmware/sketch/tactorbelt``
so that ``tactorbelt firmware export`` works from an installed wheel. Everything else is in
pyproject.toml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SKETCH = Path(__file__).parent / "firmware" / "tactorbelt"
SUFFIXES = {".ino", ".cpp", ".c", ".h", ".hpp"}


class BuildPyWithSketch(build_py):
    def run(self) -> None:
        super().run()
        if not SKETCH.is_dir():  # an sdist without the firmware: nothing to carry
            return
        target = Path(self.build_lib) / "tactorbelt" / "firmware" / "sketch" / "tactorbelt"
        if target.exists():
            shutil.rmtree(target)
        for f in sorted(SKETCH.rglob("*")):
            if f.is_file() and f.suffix in SUFFIXES:
                out = target / f.relative_to(SKETCH)
                out.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(f, out)


setup(cmdclass={"build_py": BuildPyWithSketch})
