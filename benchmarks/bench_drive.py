"""The drive-shaping goals, measured: plain against shaped, on the sim belt and the emulator.

For each belt and drive: ``tactorbelt validate onsets`` at levels 0.5 and 1.0 (latency,
10-90 % rise, 90-10 % fall, overshoot; the median over tactors and pulses, the largest
overshoot in the JSON) and
``tactorbelt validate stimulus --all`` for the paper's static and dynamic stimuli (the
RMS felt-against-intended error over the between-tactor targets, the static onset errors).
Prints one markdown table of each (docs/belts.md, "The goals, measured"), then the goals'
figures as one JSON object (``make bench``; the sim belt's; ``emulator_`` before those of
the emulator): ``drive_<config>_rise_ms`` and ``_fall_ms`` at level 1.0 and
``drive_<config>_half_rise_ms`` and ``_half_fall_ms`` at 0.5 for ``plain``, ``shaped`` (3.6 V)
and ``kick`` (5 V); ``drive_overshoot_max_pct`` over the shaped pulses; with ``--stimulus``,
``drive_<config>_dynamic_x`` (plain's dynamic RMS over the shaped one, the same run) and
``drive_<config>_static_onset_max_ms``.

    python benchmarks/bench_drive.py [--emulator] [--stimulus] [-o DIR]

The belts: ``plain``; ``shaped 3.6 V``: kicks up to the motor's maximum voltage (the
default, 1.2 x rated); ``shaped 5 V kick``: a 5 V supply, kicks at it for at most 40 ms
(``supply_v=5&kick_ms=40``, 1.67 x rated). The emulator's motors are in units of the full
duty, so its belts get a calibration whose ceiling is the rated level (3 V over the supply).
On the emulator, ``validate stimulus`` senses with the board's IMU (``--sense board``),
which mixes the tactors, so it plays the stimulus once per driven tactor (docs/validation.md,
"per-tactor replay"); that takes minutes per row. Shaped, a played
stimulus is previewed by the shaper (``erm.LEAD_TICKS``, 3 ms: docs/belts.md "Preview");
``validate onsets`` plays frames, which are not.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

TACTORBELT = str(Path(sys.executable).with_name("tactorbelt"))

#: A configuration's key in the JSON.
KEYS = {"plain": "plain", "shaped 3.6 V": "shaped", "shaped 5 V kick": "kick"}
#: (name, belt URL query, drive, supply V for the emulator's calibration ceiling)
CONFIGS = (
    ("plain", "", "plain", 3.0),
    ("shaped 3.6 V", "", "shaped", 3.0),
    ("shaped 5 V kick", "supply_v=5&kick_ms=40", "shaped", 5.0),
)


def _calibration(path: Path, n: int, ceiling: float) -> Path:
    path.write_text("".join(f"[[tactor]]\nstart = 0.0\nceiling = {ceiling:.6f}\n"
                            for _ in range(n)))
    return path


def _run(args: list[str]) -> None:
    subprocess.run([TACTORBELT, *args], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.PIPE, timeout=1800)


def _belt(kind: str, query: str, supply: float, emu_supply: float | None) -> str:
    if kind == "sim":
        return "sim:virtual" + (f"?{query}" if query else "")
    q = query or (f"supply_v={emu_supply:g}" if emu_supply else "")
    return "emulator" + (f"?{q}" if q else "")


def onsets(out: Path, kind: str) -> list[dict[str, Any]]:
    rows = []
    for name, query, drive, supply in CONFIGS:
        d = out / f"onsets-{kind}-{name.replace(' ', '_')}"
        emu_supply = 3.6 if (kind == "emulator" and name == "shaped 3.6 V") else None
        sup = emu_supply or supply
        args = ["validate", "onsets", "--belt", _belt(kind, query, supply, emu_supply),
                "--levels", "0.5,1.0", "--pulses", "3", "--drive", drive, "-o", str(d),
                "--force"]
        if kind == "emulator":
            args += ["--sense", "board", "--calibration",
                     str(_calibration(out / f"cal-{sup:g}.toml", 6, 3.0 / sup))]
        _run(args)
        pulses = json.loads((d / "validation.json").read_text())["pulses"]
        for level in (0.5, 1.0):
            ps = [p for p in pulses if p["level"] == level]

            def med(key: str, ps: list[dict[str, Any]] = ps) -> float:
                return statistics.median(p[key] for p in ps if p[key] is not None)

            rows.append({"belt": kind, "drive": name, "level": level,
                         "latency_ms": med("latency_ms"), "rise_ms": med("rise_ms"),
                         "fall_ms": med("fall_ms"),
                         "overshoot": med("overshoot"),
                         "overshoot_max": max(p["overshoot"] or 0.0 for p in ps)})
    return rows


def stimulus(out: Path, kind: str) -> list[dict[str, Any]]:
    rows = []
    for name, query, drive, supply in CONFIGS:
        emu_supply = 3.6 if (kind == "emulator" and name == "shaped 3.6 V") else None
        sup = emu_supply or supply
        row: dict[str, Any] = {"belt": kind, "drive": name}
        for cond in ("static", "dynamic"):
            d = out / f"stimulus-{kind}-{cond}-{name.replace(' ', '_')}"
            args = ["validate", "stimulus", "--belt", _belt(kind, query, supply, emu_supply),
                    "--all", "--condition", cond, "--drive", drive, "-o", str(d), "--force"]
            if kind == "emulator":
                args += ["--sense", "board", "--calibration",
                         str(_calibration(out / f"cal-{sup:g}.toml", 6, 3.0 / sup))]
            _run(args)
            res = json.loads((d / "stimulus.json").read_text())
            row[f"{cond}_rms"] = res["between_tactor_rms_error"]
            if cond == "static":
                errs = [abs(t["onset_error_ms"]) for tg in res["targets"]
                        for t in tg["tactors"] if t.get("onset_error_ms") is not None]
                row["static_onset_mean_ms"] = statistics.mean(errs)
                row["static_onset_max_ms"] = max(errs)
        rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--emulator", action="store_true", help="the emulator (IMU) too")
    ap.add_argument("--stimulus", action="store_true", help="validate stimulus --all too")
    ap.add_argument("-o", "--output", type=Path, default=None)
    a = ap.parse_args()
    out = a.output or Path(tempfile.mkdtemp(prefix="bench-drive-"))
    out.mkdir(parents=True, exist_ok=True)
    kinds = ["sim", "emulator"] if a.emulator else ["sim"]
    print("| belt | drive | level | latency (10 %) ms | rise 10-90 % ms | fall 90-10 % ms "
          "| overshoot (median) |")
    print("|---|---|---|---|---|---|---|")
    results: dict[str, Any] = {"onsets": [], "stimulus": []}
    for kind in kinds:
        for r in onsets(out, kind):
            results["onsets"].append(r)
            print(f"| {r['belt']} | {r['drive']} | {r['level']:g} | {r['latency_ms']:.1f} | "
                  f"{r['rise_ms']:.1f} | {r['fall_ms']:.1f} | {r['overshoot'] * 100:.1f} % |",
                  flush=True)
    if a.stimulus:
        print("\n| belt | drive | dynamic RMS (18 between-tactor targets) | static RMS "
              "| static onset error, mean / max ms |")
        print("|---|---|---|---|---|")
        for kind in kinds:
            for r in stimulus(out, kind):
                results["stimulus"].append(r)
                print(f"| {r['belt']} | {r['drive']} | {r['dynamic_rms']:.4f} | "
                      f"{r['static_rms']:.4f} | {r['static_onset_mean_ms']:.1f} / "
                      f"{r['static_onset_max_ms']:.1f} |", flush=True)
    (out / "bench_drive.json").write_text(json.dumps(results, indent=1))
    print(f"\nresults: {out / 'bench_drive.json'}")
    print(json.dumps(figures(results)))


def figures(results: dict[str, Any]) -> dict[str, float]:
    """The goals' figures of ``results`` (see the module docstring)."""
    out: dict[str, float] = {}
    for r in results["onsets"]:
        pre = ("" if r["belt"] == "sim" else "emulator_") + f"drive_{KEYS[r['drive']]}_"
        half = "half_" if r["level"] == 0.5 else ""
        out[f"{pre}{half}rise_ms"] = round(r["rise_ms"], 2)
        out[f"{pre}{half}fall_ms"] = round(r["fall_ms"], 2)
    for kind in ("sim", "emulator"):
        shaped = [r["overshoot_max"] for r in results["onsets"]
                  if r["belt"] == kind and r["drive"] != "plain"]
        if shaped:
            pre = "" if kind == "sim" else "emulator_"
            out[f"{pre}drive_overshoot_max_pct"] = round(100 * max(shaped), 2)
        rows = {r["drive"]: r for r in results["stimulus"] if r["belt"] == kind}
        for name, r in rows.items():
            if name == "plain":
                continue
            pre = ("" if kind == "sim" else "emulator_") + f"drive_{KEYS[name]}_"
            out[f"{pre}dynamic_x"] = round(rows["plain"]["dynamic_rms"] / r["dynamic_rms"], 3)
            out[f"{pre}static_onset_max_ms"] = round(r["static_onset_max_ms"], 2)
    return out


if __name__ == "__main__":
    main()
