"""Shared test setup: headless, no hardware, reference data, Hypothesis profiles.

Hypothesis profiles (docs/testing.md), chosen with the ``HYPOTHESIS_PROFILE`` environment
variable:

- ``dev`` (the default): random examples, remembered failures in ``.hypothesis/``.
- ``ci`` (``.ci/run``): derandomized, so every run checks the same examples; no example
  database; failures print a ``@reproduce_failure`` blob.
- ``explore``: ten times the examples of ``dev``, for hunting before a release.

No profile has a deadline or the timing health check: on a loaded 2-core machine a slow
example is not a bug, and a test that fails for timing alone is a flake.

Helpers shared by test files live in the ``support`` package (``tests/support/``);
pytest puts ``tests/`` on ``sys.path`` (rootdir conftest, no ``tests/__init__.py``), so
``from support.studies import write_study`` works from every test file.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# A shell that starts a command in the background (``make test &``) makes it ignore
# SIGINT, and a child process inherits that across exec: the tests that press Ctrl-C on
# a real process would then fail. Handling SIGINT here gives every child the default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO = Path(__file__).resolve().parents[1]
REFERENCE = Path(__file__).resolve().parent / "data" / "reference"

#: Examples per property in ``dev`` and ``ci`` (a test's own @settings may ask for more).
MAX_EXAMPLES = 100

_COMMON = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
settings.register_profile("dev", max_examples=MAX_EXAMPLES, **_COMMON)
settings.register_profile(
    "ci", max_examples=MAX_EXAMPLES, derandomize=True, database=None, print_blob=True,
    **_COMMON,
)
settings.register_profile("explore", max_examples=10 * MAX_EXAMPLES, print_blob=True, **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


@pytest.fixture
def reference_dir() -> Path:
    """Golden tables from an independent implementation (copied from shared/reference)."""
    return REFERENCE


@pytest.fixture(scope="session")
def emulator_exe() -> Path:
    """The firmware emulator binary, built once per run (skipped where it cannot be)."""
    import shutil

    from tactorbelt.devices.emulator import build_emulator, emulator_path, firmware_dir

    missing = [t for t in ("g++", "make") if shutil.which(t) is None]
    if missing and not emulator_path(firmware_dir()).is_file():
        pytest.skip(f"the firmware emulator needs {' and '.join(missing)} to build")
    return build_emulator(firmware_dir())


@pytest.fixture(scope="session")
def pg_server():  # type: ignore[no-untyped-def]
    """A throwaway PostgreSQL server (support.pgserver) for this test process: initdb in a
    temporary folder, a Unix socket only; as root it runs as the ``postgres`` user.
    Skipped (with the reason) without psycopg or the server binaries."""
    from support import pgserver

    srv = pgserver.server()
    if srv is None:
        pytest.skip(pgserver.skip_reason() or "no PostgreSQL server")
    return srv


@pytest.fixture
def pg_url(pg_server):  # type: ignore[no-untyped-def]
    """A fresh database on the throwaway server (its URL, as the admin role)."""
    return pg_server.new_database()
