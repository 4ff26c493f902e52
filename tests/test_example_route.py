"""examples/route_walk.py runs on the sim belt and writes its figure."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("extra", [[], ["--mode", "static", "--stream"]])
def test_route_walk_reaches_every_waypoint_and_writes_its_png(tmp_path, extra):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, str(EXAMPLES / "route_walk.py"), "--out",
                           str(tmp_path), *extra], capture_output=True, text=True, env=env,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    png = tmp_path / "route_walk.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 50_000
    summary = json.loads((tmp_path / "route_walk.json").read_text())
    assert summary["waypoints_reached"] == ["Main Quad arch", "Memorial Church", "Hoover Tower"]
    if "--stream" in extra:
        assert summary["frames_written"] > 40_000 and summary["plays_sent"] == 0
    else:
        assert summary["device_render"] and summary["plays_sent"] > 10
    rows = (tmp_path / "route_walk.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,waypoint,distance_m,bearing_deg")
    assert len(rows) > 2000


def test_track_file_has_the_documented_columns():
    lines = (EXAMPLES / "data" / "route_track.csv").read_text().splitlines()
    assert lines[0] == "t_s,lat,lon,heading_deg"
    assert len(lines) > 2000
    route = (EXAMPLES / "data" / "route.csv").read_text().splitlines()
    assert route[0] == "name,lat,lon" and 3 <= len(route) - 1 <= 5
