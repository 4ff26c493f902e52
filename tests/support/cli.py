"""The ``tactorbelt`` command as a user runs it: a real subprocess.

    from support.cli import model_store, tactorbelt

    proc = tactorbelt("export", str(db), "-o", str(out))   # CompletedProcess, text
    db = model_store(tmp_path, participants=("P01", "P02"))

``model_store`` writes a small study (6 targets, one training pass, one static and one
dynamic block of one repetition) and runs each participant headless with the model
cursor through ``tactorbelt run``, the way a researcher tries the toolkit first.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from support.studies import write_study

__all__ = ["model_store", "tactorbelt"]


def tactorbelt(*args: str, cwd: Path | None = None, input: str | None = None,
               timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """Run ``tactorbelt ARGS`` in a fresh Python process."""
    return subprocess.run([sys.executable, "-m", "tactorbelt", *args], capture_output=True,
                          text=True, cwd=cwd, input=input, timeout=timeout)


def model_store(directory: Path, participants: tuple[str, ...] = ("P01",),
                name: str = "first-use") -> Path:
    """A store of one headless model session per participant, made through the CLI."""
    study = write_study(directory, name=name, targets=6, repetitions=1, training=1,
                        training_conditions=["static"], break_every=0)
    db = directory / "study.sqlite"
    for pid in participants:
        proc = tactorbelt("run", str(study), "-p", pid, "--headless", "--input", "model",
                          "--db", str(db))
        assert proc.returncode == 0, proc.stderr
    return db
