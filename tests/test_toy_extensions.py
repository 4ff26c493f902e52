"""A new amplitude law and a new belt backend are what docs/architecture.md ("Adding
things") says they are, checked with toy ones added exactly that way and nothing else.

- The ``cosine`` law (``cos^2(90 deg * D/s)``): its name in ``tactorbelt._lawnames`` and
  its function in ``tactorbelt.laws.LAW_FUNCTIONS``. It keeps every property the built-in
  laws keep (support/laws.py), a study file names it (in ``[stimulus]`` and in a
  ``[[test]]`` block), and a model session on the sim belt plays it and is stored.
- The ``toy:`` backend (support/toy_belt.py: a belt that keeps its frames in memory): its
  module and one ``Backend(...)`` line in ``tactorbelt.devices.registry.BACKENDS``. The
  belt contract suite covers it with no test code of its own, ``open_belt`` and
  ``tactorbelt devices`` find it, and a model session runs on it and leaves its motors off.

Every registration is undone after each test (monkeypatch); the contract suite and
``tactorbelt devices`` run in a process of their own that registers the toy first, as a
registry line in the source would be.
"""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np
import pytest

from support import toy_belt
from support.laws import LAW_PROPERTIES
from support.studies import study_toml
from tactorbelt import StudyFileError, _lawnames, laws
from tactorbelt.cli import main
from tactorbelt.devices.registry import BACKENDS
from tactorbelt.experiment.study import Study
from tactorbelt.geometry import Layout
from tactorbelt.laws import amplitudes
from tactorbelt.stimuli import make_stimulus

TESTS = Path(__file__).resolve().parent


def _cosine(dist: np.ndarray, spacing: np.ndarray, falloff_deg: float) -> np.ndarray:
    """``cos^2(pi/2 * D/s)``: 1 on the tactor, 0 at its neighbour, and the two tactors'
    amplitudes sum to 1 between them."""
    return np.asarray(np.square(np.cos(0.5 * np.pi * np.minimum(dist / spacing, 1.0))))


@pytest.fixture(autouse=True)
def _registries_unchanged() -> Iterator[None]:
    """No test leaves a law or a backend registered (checked after monkeypatch undoes)."""
    before = (_lawnames.LawName, _lawnames.LAWS, dict(laws.LAW_FUNCTIONS), dict(BACKENDS))
    yield
    assert (_lawnames.LawName, _lawnames.LAWS, laws.LAW_FUNCTIONS, BACKENDS) == before


@pytest.fixture
def cosine(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, ...]]:
    """Register the law as the table says: a name in _lawnames, a function in
    LAW_FUNCTIONS. Returns the shapes the function was called with."""
    calls: list[tuple[int, ...]] = []

    def law(dist: np.ndarray, spacing: np.ndarray, falloff_deg: float) -> np.ndarray:
        calls.append(dist.shape)
        return _cosine(dist, spacing, falloff_deg)

    name = Literal[(*get_args(_lawnames.LawName), "cosine")]
    monkeypatch.setattr(_lawnames, "LawName", name)
    monkeypatch.setattr(_lawnames, "LAWS", get_args(name))
    monkeypatch.setitem(laws.LAW_FUNCTIONS, "cosine", law)
    return calls


def _cli(*args: str) -> None:
    try:
        main(list(args))
    except SystemExit as exc:
        assert not exc.code, f"tactorbelt {' '.join(args)} exited {exc.code}"


def _trials(db: Path) -> list[tuple[Any, ...]]:
    with sqlite3.connect(db) as con:
        return con.execute("SELECT block_name, condition, status FROM trials").fetchall()


# -- a law -------------------------------------------------------------------------------------
@pytest.mark.parametrize("check", LAW_PROPERTIES, ids=lambda c: c.__name__)
def test_a_registered_law_keeps_the_properties_of_a_law(cosine: list[Any], check: Any) -> None:
    check("cosine")


def test_the_registered_law_is_the_one_played(cosine: list[Any]) -> None:
    assert laws.LAWS[-1] == "cosine"  # laws.LAWS reads the registry, it is not a copy
    layout = Layout.even(6)
    a = amplitudes(layout, np.linspace(30.0, 90.0, 61), "cosine")
    np.testing.assert_allclose(a.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(amplitudes(layout, [45.0, 60.0], "cosine")[:, :2],
                               [[np.cos(np.pi / 8) ** 2, np.sin(np.pi / 8) ** 2], [0.5, 0.5]])
    stim = make_stimulus(layout, 45.0, "dynamic", law="cosine")
    assert stim.law == "cosine" and cosine


def test_a_study_file_names_the_registered_law(cosine: list[Any]) -> None:
    study = Study.from_toml(study_toml(law="cosine", tactors=6, targets=6), path="c.toml")
    assert study.stimulus.law == "cosine"
    block = Study.from_toml(study_toml(tactors=6, targets=6, blocks=[
        {"condition": "static", "repetitions": 1},
        {"condition": "dynamic", "repetitions": 1, "law": "cosine"}]), path="b.toml")
    assert [b.law for b in block.test] == [None, "cosine"]
    with pytest.raises(StudyFileError) as info:
        Study.from_toml(study_toml(law="cosin"), path="bad.toml")
    assert info.value.field == "stimulus.law"
    assert "'paper', 'linear', 'energy' or 'cosine' (got 'cosin'" in str(info.value)
    assert "did you mean 'cosine'?" in str(info.value)


def test_an_unregistered_law_is_refused_by_the_study_file() -> None:
    for key in ("law", "blocks"):
        text = (study_toml(law="cosine") if key == "law" else study_toml(blocks=[
            {"condition": "static", "repetitions": 1, "law": "cosine"}]))
        with pytest.raises(StudyFileError, match="'paper', 'linear' or 'energy' "
                                                 "\\(got 'cosine'\\)"):
            Study.from_toml(text, path="c.toml")


def test_a_model_session_plays_the_registered_law(cosine: list[Any], tmp_path: Path) -> None:
    study = tmp_path / "cosine.toml"
    study.write_text(study_toml(name="cosine", law="cosine", tactors=6, targets=6,
                                training=0, repetitions=1, iti_s=0.1, break_every=0,
                                timeout_s=4.0), encoding="utf-8")
    db = tmp_path / "cosine.sqlite"
    _cli("run", str(study), "-p", "P01", "--headless", "--input", "model", "--db", str(db))
    rows = _trials(db)
    assert len(rows) == 2 * 6 and {r[1] for r in rows} == {"static", "dynamic"}
    assert {r[2] for r in rows} <= {"done", "timeout"}
    assert cosine  # the sim belt rendered the stimuli with the registered function


# -- a belt backend ----------------------------------------------------------------------------
def _with_toy(*args: str) -> subprocess.CompletedProcess[str]:
    """Run ``python *args`` with tests/ on the path (the toy's module is importable)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(TESTS), os.environ.get("PYTHONPATH")) if p)}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          cwd=TESTS.parent, timeout=600)


def test_the_belt_contract_suite_covers_a_registered_backend() -> None:
    """tests/test_belt_contract.py, run with the toy registered (as a pytest plugin that
    adds its registry line before collection), runs every case over it and passes."""
    proc = _with_toy("-m", "pytest", "-q", "-rA", "-p", "no:cacheprovider",
                     "-p", "support.toy_belt", "tests/test_belt_contract.py")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    passed = [ln.split(" ", 1)[1] for ln in proc.stdout.splitlines()
              if ln.startswith("PASSED ")]
    toy = {t.split("::", 1)[1] for t in passed if "[toy" in t}
    assert {"test_motors_are_off_after_the_with_block[toy]",
            "test_the_calibration_is_applied_to_every_frame[toy]",
            "test_the_player_streams_to_the_belt[toy]"} <= toy
    assert len(toy) >= 15, toy
    assert not [ln for ln in proc.stdout.splitlines() if "[toy" in ln
                and not ln.startswith("PASSED ")]


def test_open_belt_and_devices_find_a_registered_backend(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from tactorbelt.devices import open_belt
    from tactorbelt.devices.registry import belt_url_help

    monkeypatch.setitem(BACKENDS, "toy", toy_belt.BACKEND)
    monkeypatch.setattr(toy_belt, "OPENED", [])
    assert "toy:: a toy belt that keeps its frames in memory" in belt_url_help()
    with open_belt("toy:") as belt:
        (opened,) = toy_belt.OPENED
        assert opened is belt and isinstance(belt, toy_belt.ToyBelt)
        belt.set_amplitudes([0.5, 0, 0, 0, 0, 0.25])
        assert belt.frames[-1][1].tolist() == [0.5, 0, 0, 0, 0, 0.25]
    assert belt.closed and not belt.frames[-1][1].any()
    with pytest.raises(Exception, match="unknown option 'speed' in belt URL 'toy:\\?speed=1'"):
        open_belt("toy:?speed=1")
    # the command line, in a process where the registry line is there from the start
    code = ("import sys\nfrom support import toy_belt\ntoy_belt.register()\n"
            "from tactorbelt.cli import main\nmain(sys.argv[1:])\n")
    proc = _with_toy("-c", code, "devices", "--no-ble", "--skip", "serial",
                     "--skip", "audio")
    assert proc.returncode == 0, proc.stderr
    assert "Toy belts:\n  toy  toy belt (frames kept in memory)  6 tactors -> --belt toy:" in (
        proc.stdout)
    proc = _with_toy("-c", code, "play", "--help")
    assert proc.returncode == 0 and "toy:: a toy belt" in proc.stdout.replace("\n", " ")


def test_a_model_session_runs_on_a_registered_backend(monkeypatch: pytest.MonkeyPatch,
                                                      tmp_path: Path) -> None:
    monkeypatch.setitem(BACKENDS, "toy", toy_belt.BACKEND)
    monkeypatch.setattr(toy_belt, "OPENED", [])
    study = tmp_path / "toy.toml"
    study.write_text(study_toml(name="toy", tactors=6, targets=6, training=0, repetitions=1,
                                iti_s=0.1, break_every=0, timeout_s=4.0), encoding="utf-8")
    db = tmp_path / "toy.sqlite"
    _cli("run", str(study), "-p", "P01", "--headless", "--input", "model", "--belt", "toy:",
         "--db", str(db))
    rows = _trials(db)
    assert len(rows) == 2 * 6 and {r[2] for r in rows} <= {"done", "timeout"}
    (belt,) = toy_belt.OPENED
    assert belt.closed
    assert len(belt.frames) > 1000  # streamed: the toy renders nothing itself
    assert max(float(lv.max()) for _, lv in belt.frames) > 0.5
    assert not belt.frames[-1][1].any()  # motors off at the end
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT belt, status FROM sessions").fetchall() == [
            ("toy:", "complete")]
