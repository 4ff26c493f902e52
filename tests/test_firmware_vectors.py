"""The shared firmware test vectors: the committed file is what the package says now.

``firmware/test/vectors.json`` is written by ``scripts/gen_firmware_vectors.py`` from
``tactorbelt.devices.wire`` and ``tactorbelt.stimuli``; the C++ host tests
(``make -C firmware test``) check the firmware against it. When the Python side
changes, this test fails until the file is regenerated, so the firmware can never
be checked against a stale contract.
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tactorbelt.devices import wire

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "gen_firmware_vectors.py"
VECTORS = REPO / "firmware" / "test" / "vectors.json"

#: Amplitudes are written with 9 decimals; another libm may round the last one apart.
AMPLITUDE_TOLERANCE = 2e-9


def _load_script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("gen_firmware_vectors", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def gen() -> ModuleType:
    return _load_script()


@pytest.fixture(scope="module")
def committed() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(VECTORS.read_text())
    return data


@pytest.fixture(scope="module")
def fresh(gen: ModuleType) -> dict[str, Any]:
    data: dict[str, Any] = gen.build_vectors()
    return data


def _assert_same(a: Any, b: Any, path: str = "") -> None:
    """Exact equality, except floats within AMPLITUDE_TOLERANCE."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"keys differ at {path}"
        for k in a:
            _assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"lengths differ at {path}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert math.isclose(a, b, rel_tol=0, abs_tol=AMPLITUDE_TOLERANCE), f"{path}: {a} != {b}"
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def test_committed_vectors_match_the_package(
    committed: dict[str, Any], fresh: dict[str, Any]
) -> None:
    """Regenerate with: python scripts/gen_firmware_vectors.py"""
    # a JSON round trip turns tuples into lists, as in the committed file
    _assert_same(committed, json.loads(json.dumps(fresh)))


def test_the_generator_is_deterministic(gen: ModuleType, fresh: dict[str, Any]) -> None:
    assert gen.dumps(fresh) == gen.dumps(gen.build_vectors())


def test_vectors_cover_the_contract(committed: dict[str, Any]) -> None:
    assert committed["format"] == 1
    assert {"data": b"123456789".hex(), "crc": 0x29B1} in committed["crc"]
    names = {f["name"] for f in committed["frames"]}
    assert names >= {"ping", "get_info", "set_amplitudes", "stop_all", "play_target",
                     "heartbeat", "set_config", "get_status", "ack", "nak", "pong", "info",
                     "status"}
    streams = committed["streams"]
    assert sum(s["crc_errors"] for s in streams) > 0
    assert sum(s["framing_errors"] for s in streams) > 0
    render = committed["render"]
    layouts = {len(c["tactor_angles_deg"]) for c in render}
    assert layouts == {5, 6, 8}
    assert {c["mode"] for c in render} == {0, 1}
    assert {c["law"] for c in render} == {0, 1, 2}
    one_khz = [c for c in render if len(c["t_us"]) == 1000]
    assert one_khz and one_khz[0]["t_us"][:3] == [0, 1000, 2000]


def test_frames_decode_to_what_they_say(committed: dict[str, Any]) -> None:
    for f in committed["frames"]:
        p = wire.Packet(f["type"], f["seq"], bytes.fromhex(f["payload"]))
        assert wire.decode_packet(bytes.fromhex(f["packet"])) == p
        assert wire.FrameDecoder().feed(bytes.fromhex(f["frame"])) == [p]


def test_quarter_point_vector_dwells_600_and_200_ms(committed: dict[str, Any]) -> None:
    """The 1 kHz case is the paper's quarter point: 600 ms on tactor 0, 200 ms on 5."""
    case = next(c for c in committed["render"] if len(c["t_us"]) == 1000)
    assert case["angle_cdeg"] == 1500 and case["mode"] == 1
    amps = case["amplitudes"]
    near_only = sum(1 for a in amps if a[0] > 0 and a[5] == 0)
    far_only = sum(1 for a in amps if a[5] > 0 and a[0] == 0)
    assert near_only == 601  # t = 0..600 ms: the transit starts after 600 ms
    assert far_only == 201  # t = 700..900 ms


def test_check_mode_reports_a_stale_file(gen: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "vectors.json"
    assert gen.main(["-o", str(out)]) == 0
    assert gen.main(["--check", "-o", str(out)]) == 0
    out.write_text(out.read_text().replace('"format": 1', '"format": 0'))
    assert gen.main(["--check", "-o", str(out)]) == 1
