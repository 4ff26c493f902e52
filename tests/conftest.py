"""Shared test setup: headless, no hardware, reference data."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO = Path(__file__).resolve().parents[1]
REFERENCE = Path(__file__).resolve().parent / "data" / "reference"


@pytest.fixture
def reference_dir() -> Path:
    """Golden tables from an independent implementation (copied from shared/reference)."""
    return REFERENCE
