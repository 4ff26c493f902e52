"""Generate the example route walk's recorded track (run once; the output is committed).

Writes ``examples/data/route_track.csv`` (``t_s,lat,lon,heading_deg``, 5 Hz) for a walk
along ``examples/data/route.csv`` (a short walk on the Stanford campus: the Oval, the
Main Quad arch, Memorial Church, Hoover Tower), with the noise a phone or a belt's own
IMU/GPS would record:

- position: GPS error as a slow random walk (AR(1), 2.5 m standard deviation, 10 s
  correlation time) plus 0.5 m white noise; the walker also wanders up to about a
  metre off the straight line between waypoints;
- speed: 1.35 m/s with slow variation, and a 6-second stop (a crossing) after the arch;
- heading (the torso's): the walking course, smoothed through the corners, plus the
  torso's sway at the stride frequency (+-4 deg at 0.9 Hz), two glances to the side
  (the wearer turns 50 deg for about 4 s), 3 deg of white compass noise, and a
  magnetic disturbance of +12 deg for 8 s near a building.

Seeded (numpy default_rng(2012)), so running it again writes the same file.

Usage: .venv/bin/python examples/make_route_track.py
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data"
EARTH_RADIUS_M = 6_371_000.0
RATE_HZ = 5.0


def load_route(path: Path) -> list[tuple[str, float, float]]:
    with path.open(newline="") as f:
        return [(r["name"], float(r["lat"]), float(r["lon"])) for r in csv.DictReader(f)]


def main() -> None:
    rng = np.random.default_rng(2012)
    route = load_route(DATA / "route.csv")
    lat0, lon0 = route[0][1], route[0][2]
    m_per_deg_lat = EARTH_RADIUS_M * math.pi / 180.0
    m_per_deg_lon = m_per_deg_lat * math.cos(math.radians(lat0))
    pts = np.array([[(lon - lon0) * m_per_deg_lon, (lat - lat0) * m_per_deg_lat]
                    for _, lat, lon in route])  # east, north (m)
    seg = np.diff(pts, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = float(cum[-1])

    dt = 1.0 / RATE_HZ
    # speed: 1.35 m/s with slow variation, and a stop after the first waypoint
    n_max = int(total / 1.0 / dt) + 200
    t = np.arange(n_max) * dt
    slow = np.convolve(rng.normal(0.0, 1.0, n_max), np.ones(50) / 50, mode="same")
    speed = np.clip(1.35 + 0.6 * slow, 1.1, 1.6)
    stop_at = float(cum[1]) + 8.0
    s = np.zeros(n_max)
    stopped_for = 0.0
    for i in range(1, n_max):
        if s[i - 1] >= stop_at and stopped_for < 6.0:
            stopped_for += dt
            s[i] = s[i - 1]
            continue
        s[i] = s[i - 1] + speed[i] * dt
    n = int(np.searchsorted(s, total)) + 1
    t, s = t[:n], np.minimum(s[:n], total)
    moving = np.concatenate([[True], np.diff(s) > 0])

    # true position along the polyline, with a small lateral wander
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    u = (s - cum[k]) / seg_len[k]
    pos = pts[k] + seg[k] * u[:, None]
    normal = np.stack([-seg[k, 1], seg[k, 0]], axis=1) / seg_len[k][:, None]
    wander = np.convolve(rng.normal(0.0, 1.0, n), np.ones(40) / 40, mode="same") * 4.0
    pos = pos + normal * wander[:, None]

    # course: direction of travel (compass degrees), smoothed through corners
    course = np.degrees(np.arctan2(seg[k, 0], seg[k, 1]))
    course_u = np.unwrap(np.radians(course))
    kernel = np.ones(int(3.0 * RATE_HZ)) / int(3.0 * RATE_HZ)
    padded = np.concatenate([np.full(len(kernel), course_u[0]), course_u,
                             np.full(len(kernel), course_u[-1])])
    course_s = np.degrees(np.convolve(padded, kernel, mode="same")[len(kernel):-len(kernel)])

    heading = course_s.copy()
    heading += np.where(moving, 4.0 * np.sin(2 * math.pi * 0.9 * t), 0.0)  # torso sway
    for start, length, angle in ((70.0, 4.0, 50.0), (260.0, 4.5, -55.0)):  # glances
        w = np.clip(np.minimum(t - start, start + length - t) / 0.6, 0.0, 1.0)
        heading += angle * w
    heading += np.where((t > 330.0) & (t < 338.0), 12.0, 0.0)  # magnetic disturbance
    heading += rng.normal(0.0, 3.0, n)  # compass noise
    heading = np.mod(heading, 360.0)

    # GPS error: AR(1) with 10 s correlation and 2.5 m sd, plus white noise
    a = math.exp(-dt / 10.0)
    err = np.zeros((n, 2))
    drive = rng.normal(0.0, 2.5 * math.sqrt(1 - a * a), (n, 2))
    err[0] = rng.normal(0.0, 2.5, 2)
    for i in range(1, n):
        err[i] = a * err[i - 1] + drive[i]
    meas = pos + err + rng.normal(0.0, 0.5, (n, 2))
    lat = lat0 + meas[:, 1] / m_per_deg_lat
    lon = lon0 + meas[:, 0] / m_per_deg_lon

    out = DATA / "route_track.csv"
    with out.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "lat", "lon", "heading_deg"])
        for row in zip(t, lat, lon, heading, strict=True):
            w.writerow([f"{row[0]:.1f}", f"{row[1]:.7f}", f"{row[2]:.7f}", f"{row[3]:.1f}"])
    print(f"wrote {out}: {n} samples, {t[-1]:.0f} s, {total:.0f} m of route")


if __name__ == "__main__":
    main()
