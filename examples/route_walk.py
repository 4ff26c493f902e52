"""Walk a route with the belt pointing at the next waypoint, on the simulated belt.

Reads a route (``examples/data/route.csv``: name, lat, lon) and a recorded walk
(``examples/data/route_track.csv``: t_s, lat, lon, heading_deg at 5 Hz, noisy GPS and
compass; made by ``make_route_track.py``). At each track sample it

1. switches to the next waypoint once within ``--arrive-m`` (10 m) of the current one,
2. computes the great-circle initial bearing from the position to that waypoint,
3. calls ``DirectionDisplay.show_bearing(bearing, heading, t_s)``: the display filters
   the heading (One Euro), applies hysteresis, slews, and drives the belt,

on the ``sim`` belt and a simulated clock (no waiting: a 8-minute walk runs in a
couple of seconds). Then it reads back what every tactor was commanded to do and draws
``route_walk.png`` in ``--out``: the map (route and track) on top; below, the drive
of each tactor over time, drawn as a band at the tactor's body angle, with the
displayed body angle over it; and the raw and filtered heading. It also writes
``route_walk.csv`` (one row per track sample).

Usage:
    .venv/bin/python examples/route_walk.py --out out/route
    .venv/bin/python examples/route_walk.py --out out/route --mode dynamic --stream
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tactorbelt.geometry import Layout

os.environ.setdefault("MPLBACKEND", "Agg")

DATA = Path(__file__).resolve().parent / "data"
EARTH_RADIUS_M = 6_371_000.0


# -- geodesy -------------------------------------------------------------------------------
def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle (haversine) distance in metres."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    h = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(h)))


def initial_bearing_deg(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle initial bearing from point 1 to point 2, degrees clockwise from north."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dl = math.radians(lon2 - lon1)
    y = math.sin(dl) * math.cos(p2)
    x = math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dl)
    return math.degrees(math.atan2(y, x)) % 360.0


def to_local_m(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """East and north offsets (m) from (lat0, lon0): fine over a few kilometres."""
    k = EARTH_RADIUS_M * math.pi / 180.0
    return (lon - lon0) * k * math.cos(math.radians(lat0)), (lat - lat0) * k


# -- data -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Waypoint:
    name: str
    lat: float
    lon: float


def load_route(path: Path) -> list[Waypoint]:
    with path.open(newline="") as f:
        return [Waypoint(r["name"], float(r["lat"]), float(r["lon"]))
                for r in csv.DictReader(f)]


@dataclass
class WalkResult:
    """What the walk produced: a log per track sample and the commanded levels."""

    log: dict[str, np.ndarray]
    switches: list[tuple[float, str]]
    t_levels_s: np.ndarray
    levels: np.ndarray
    layout: Layout
    stats: dict[str, object]


def load_track(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in ("t_s", "lat", "lon",
                                                                 "heading_deg")}


# -- the walk -----------------------------------------------------------------------------
def walk(route: list[Waypoint], track: dict[str, np.ndarray], mode: str, stream: bool,
         arrive_m: float) -> WalkResult:
    """Replay the track on the sim belt; return the log and the commanded levels."""
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.sim import SimBelt
    from tactorbelt.display import DirectionDisplay

    t_s = track["t_s"]
    duration = float(t_s[-1] - t_s[0]) + 1.0
    clock = SimClock()
    log: dict[str, list[float]] = {k: [] for k in (
        "t_s", "waypoint", "distance_m", "bearing_deg", "heading_raw_deg",
        "heading_filtered_deg", "body_requested_deg", "body_displayed_deg", "dominant")}
    target = 1  # the walker starts at route[0] and heads for route[1]
    switches: list[tuple[float, str]] = []
    # the sim belt, as open_belt("sim", clock=clock, horizon_s=...) gives it
    belt = SimBelt(clock=clock, horizon_s=duration + 10.0)
    with belt:
        display = DirectionDisplay(belt, mode=mode, device_render=False if stream else None,
                                   rate_hz=100.0 if stream else None)
        with display:
            t0_ns = clock.now_ns()
            for i in range(len(t_s)):
                now_ns = t0_ns + round((t_s[i] - t_s[0]) * 1e9)
                display.pump(now_ns)
                lat, lon = float(track["lat"][i]), float(track["lon"][i])
                wp = route[target]
                dist = distance_m(lat, lon, wp.lat, wp.lon)
                if dist <= arrive_m:
                    switches.append((float(t_s[i]), wp.name))
                    if target == len(route) - 1:
                        break  # arrived
                    target += 1
                    wp = route[target]
                    dist = distance_m(lat, lon, wp.lat, wp.lon)
                bearing = initial_bearing_deg(lat, lon, wp.lat, wp.lon)
                display.show_bearing(bearing, float(track["heading_deg"][i]), float(t_s[i]))
                log["t_s"].append(float(t_s[i]))
                log["waypoint"].append(target)
                log["distance_m"].append(dist)
                log["bearing_deg"].append(bearing)
                log["heading_raw_deg"].append(float(track["heading_deg"][i]))
                log["heading_filtered_deg"].append(float(display.filtered_heading_deg or 0.0))
                log["body_requested_deg"].append(float(display.requested_deg or 0.0))
                shown = display.device_angle_deg if display.device_render \
                    else display.displayed_deg
                log["body_displayed_deg"].append(float(shown or 0.0))
                log["dominant"].append(float(display.dominant_tactor or 0))
            end_ns = clock.now_ns() + 1_000_000_000
            display.pump(end_ns)
            stats: dict[str, object] = {"frames_written": display.frames_written,
                     "plays_sent": display.plays_sent,
                     "device_render": display.device_render,
                     "max_frame_change": display.max_frame_change}
        t_ns, levels = belt.commanded(t0_ns, end_ns, 50.0)
        layout = belt.layout
    return WalkResult({k: np.array(v) for k, v in log.items()}, switches,
                      (t_ns - t0_ns) / 1e9 + t_s[0], levels, layout, stats)


# -- the figure ---------------------------------------------------------------------------
def _wrap_breaks(t: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert NaN where an angle wraps round 0/360, so a line is not drawn across."""
    jump = np.flatnonzero(np.abs(np.diff(angle)) > 180.0) + 1
    return np.insert(t, jump, np.nan), np.insert(angle, jump, np.nan)


def draw(route: list[Waypoint], track: dict[str, np.ndarray], result: WalkResult,
         mode: str, out: Path) -> None:
    import matplotlib.pyplot as plt
    from matplotlib import colors as mcolors
    from matplotlib.patches import Circle

    from tactorbelt.figures import tactor_colors

    log, layout, levels = result.log, result.layout, result.levels
    t_lv, switches = result.t_levels_s, result.switches

    lat0, lon0 = route[0].lat, route[0].lon
    wx, wy = to_local_m(np.array([w.lat for w in route]), np.array([w.lon for w in route]),
                        lat0, lon0)
    n_walk = len(log["t_s"])
    tx, ty = to_local_m(track["lat"][:n_walk], track["lon"][:n_walk], lat0, lon0)

    fig = plt.figure(figsize=(11, 16), layout="constrained")
    gs = fig.add_gridspec(4, 1, height_ratios=[1.3, 1.15, 0.6, 0.55])
    ax_map = fig.add_subplot(gs[0])
    ax_amp = fig.add_subplot(gs[1])
    ax_head = fig.add_subplot(gs[3], sharex=ax_amp)
    ax_zoom = fig.add_subplot(gs[2])
    # zoom on the second waypoint switch (the sharpest turn), else the first
    t_zoom = switches[1][0] if len(switches) > 1 else (switches[0][0] if switches
                                                        else float(log["t_s"][0]))
    zoom = (t_zoom - 4.0, t_zoom + 16.0)

    # map
    ax_map.plot(wx, wy, "-", color="0.55", lw=6, alpha=0.35, solid_capstyle="round",
                label="route")
    sc = ax_map.scatter(tx, ty, c=log["t_s"], cmap="viridis", s=4, lw=0,
                        label="recorded track (GPS)")
    for k, (x, y, w) in enumerate(zip(wx, wy, route, strict=True)):
        ax_map.add_patch(Circle((x, y), 10.0, fill=False, ls="--", color="k", lw=0.8))
        ax_map.plot(x, y, "o", color="k", ms=6)
        ax_map.annotate(f"{k}  {w.name}", (x, y), xytext=(10, -4), textcoords="offset points",
                        fontsize=10, weight="bold", va="top",
                        bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
    # every 30 s: the wearer's heading (blue) and the bearing shown (red)
    step = max(1, round(30.0 / float(np.median(np.diff(log["t_s"])))))
    for i in range(0, n_walk, step):
        for ang, col in ((log["heading_filtered_deg"][i], "tab:blue"),
                         (log["bearing_deg"][i], "tab:red")):
            a = math.radians(ang)
            ax_map.annotate("", (tx[i] + 22 * math.sin(a), ty[i] + 22 * math.cos(a)),
                            (tx[i], ty[i]),
                            arrowprops={"arrowstyle": "-|>", "color": col, "lw": 1.6})
    ax_map.plot([], [], color="tab:blue", lw=1.6, label="heading (filtered), every 30 s")
    ax_map.plot([], [], color="tab:red", lw=1.6, label="bearing to next waypoint")
    ax_map.set_aspect("equal", adjustable="datalim")
    ax_map.set_xlabel("east (m)")
    ax_map.set_ylabel("north (m)")
    ax_map.set_title("Route (Stanford campus) and the recorded walk; dashed circles: "
                     "10 m arrival radius")
    ax_map.legend(loc="upper right", fontsize=9, framealpha=0.9)
    cb = fig.colorbar(sc, ax=ax_map, shrink=0.8, pad=0.01)
    cb.set_label("time (s)")
    ax_map.grid(alpha=0.3)

    # tactor drive as bands at each tactor's body angle (0 = navel in the middle)
    angles = np.array(layout.angles_deg)
    signed = (angles + 180.0) % 360.0 - 180.0
    cols = tactor_colors(layout.n)
    gaps = np.array(layout.gaps_deg())
    _, ccw = layout.neighbour_indices()
    t_end = float(log["t_s"][-1]) + 1.0
    keep = t_lv <= t_end
    lv, tl = levels[keep], t_lv[keep]
    n_bins = min(1200, lv.shape[0])  # about one column per pixel: no moire
    edges = np.linspace(0, lv.shape[0], n_bins + 1).astype(int)
    binned = np.add.reduceat(lv, edges[:-1], axis=0) / np.diff(edges)[:, None]
    for k in range(layout.n):
        lo = signed[k] - gaps[ccw[k]] / 2.0
        hi = signed[k] + gaps[k] / 2.0
        cmap = mcolors.LinearSegmentedColormap.from_list(f"t{k}", [(1, 1, 1, 0), cols[k]])
        for shift in (-360.0, 0.0, 360.0):
            a0, a1 = lo + shift, hi + shift
            if a1 <= -180 or a0 >= 180:
                continue
            ax_amp.imshow(binned[:, k][None, :], aspect="auto", cmap=cmap, vmin=0, vmax=1,
                          extent=(float(tl[0]), float(tl[-1]), a0, a1),
                          origin="lower", interpolation="nearest")
        ax_amp.axhline(signed[k], color=cols[k], lw=0.6, alpha=0.6)
        ax_amp.axhline(hi if hi < 180 else lo, color="0.75", lw=0.6)
    def signed_deg(a: np.ndarray) -> np.ndarray:
        return (np.asarray(a) + 180.0) % 360.0 - 180.0

    tb, req = _wrap_breaks(log["t_s"], signed_deg(log["bearing_deg"] - log["heading_raw_deg"]))
    ax_amp.plot(tb, req, color="k", lw=0.5, alpha=0.3,
                label="bearing - raw heading (unfiltered)")
    tb, body = _wrap_breaks(log["t_s"], signed_deg(log["body_displayed_deg"]))
    ax_amp.plot(tb, body, color="k", lw=1.3, label="displayed body angle")
    for n_sw, (t_sw, name) in enumerate(switches, start=1):
        for ax in (ax_amp, ax_head):
            ax.axvline(t_sw, color="tab:red", ls="--", lw=1)
        ax_amp.text(t_sw - 2, 172, f"reached {n_sw}: {name}", color="tab:red", fontsize=8,
                    ha="right", va="top",
                    bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1})
    ax_amp.axvspan(*zoom, color="0.5", alpha=0.12, lw=0)
    ax_amp.set_ylim(-180, 180)
    ticks = {-180.0: "-180 spine", -90.0: "-90 left", 0.0: "0 navel", 90.0: "90 right",
             180.0: "180 spine"}
    for k in range(layout.n):
        ticks[float(signed[k])] = f"T{k} ({angles[k]:g})"
    ax_amp.set_yticks(list(ticks))
    ax_amp.set_yticklabels(list(ticks.values()), fontsize=8)
    ax_amp.set_ylabel("body angle (deg, + = clockwise)")
    ax_amp.set_title(f"Drive of each tactor over the walk ({mode} mode, paper law): "
                     "colour = drive 0..1 in the tactor's sector; grey: zoom below",
                     fontsize=10)
    ax_amp.legend(loc="lower right", fontsize=8, framealpha=0.9)
    ax_amp.set_xlim(float(log["t_s"][0]), t_end)

    # zoom: each tactor's drive as a line, around the turn at a waypoint
    zsel = (t_lv >= zoom[0]) & (t_lv <= zoom[1])
    for k in range(layout.n):
        ax_zoom.plot(t_lv[zsel], levels[zsel, k], color=cols[k], lw=1.3,
                     label=f"T{k} ({angles[k]:g} deg)")
    ax_zoom.set_xlim(*zoom)
    ax_zoom.set_ylim(-0.02, 1.05)
    ax_zoom.set_ylabel("drive level")
    ax_zoom.set_title(f"Zoom, {zoom[0]:.0f}-{zoom[1]:.0f} s: the cue moves round the body "
                      "as the walker reaches a waypoint and turns to the next", fontsize=10)
    ax_zoom.legend(loc="upper right", fontsize=8, ncols=3, framealpha=0.9)
    ax_zoom.grid(alpha=0.3)
    zb = (log["t_s"] >= zoom[0]) & (log["t_s"] <= zoom[1])
    ax_zb = ax_zoom.twinx()
    tb, body = _wrap_breaks(log["t_s"][zb], signed_deg(log["body_displayed_deg"][zb]))
    ax_zb.plot(tb, body, color="k", lw=1.0, ls=":", label="displayed body angle")
    ax_zb.set_ylim(-180, 180)
    ax_zb.set_yticks([-180, -90, 0, 90, 180])
    ax_zb.set_ylabel("body angle (deg), dotted")

    # heading
    tb, hr = _wrap_breaks(log["t_s"], log["heading_raw_deg"])
    ax_head.plot(tb, hr, color="0.6", lw=0.6, label="heading, raw (compass)")
    tb, hf = _wrap_breaks(log["t_s"], log["heading_filtered_deg"])
    ax_head.plot(tb, hf, color="tab:blue", lw=1.2, label="heading, One Euro filtered")
    tb, br = _wrap_breaks(log["t_s"], log["bearing_deg"])
    ax_head.plot(tb, br, color="tab:red", lw=1.0, label="bearing to next waypoint")
    ax_head.set_ylim(0, 360)
    ax_head.set_yticks([0, 90, 180, 270, 360])
    ax_head.set_ylabel("compass (deg)")
    ax_head.set_xlabel("time (s)")
    ax_head.legend(loc="upper left", fontsize=8, ncols=3, framealpha=0.9)
    ax_head.grid(alpha=0.3)

    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("route_walk_out"),
                        help="output directory (default: route_walk_out)")
    parser.add_argument("--mode", choices=["static", "dynamic"], default="dynamic")
    parser.add_argument("--stream", action="store_true",
                        help="stream frames at 100 Hz instead of device rendering")
    parser.add_argument("--arrive-m", type=float, default=10.0,
                        help="switch to the next waypoint within this distance (m)")
    parser.add_argument("--route", type=Path, default=DATA / "route.csv")
    parser.add_argument("--track", type=Path, default=DATA / "route_track.csv")
    args = parser.parse_args(argv)

    route = load_route(args.route)
    if len(route) < 2:
        print("error: a route needs at least 2 waypoints", file=sys.stderr)
        return 2
    track = load_track(args.track)
    result = walk(route, track, args.mode, args.stream, args.arrive_m)
    args.out.mkdir(parents=True, exist_ok=True)
    log = result.log
    with (args.out / "route_walk.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(log))
        for row in zip(*log.values(), strict=True):
            w.writerow([f"{v:.6g}" for v in row])
    png = args.out / "route_walk.png"
    draw(route, track, result, args.mode, png)
    summary = {"waypoints_reached": [name for _, name in result.switches],
               "walk_s": float(log["t_s"][-1] - log["t_s"][0]), **result.stats}
    (args.out / "route_walk.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    print(f"wrote {png}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
