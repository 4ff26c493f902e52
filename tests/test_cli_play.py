"""``tactorbelt play``, ``belt-test`` and ``calibrate`` as a user runs them."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import click
import numpy as np
import pytest
from click.testing import CliRunner

from tactorbelt.cli import main
from tactorbelt.devices import sim as sim_module
from tactorbelt.devices.calibration import Calibration


@click.command(context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.pass_context
def _entry(ctx: click.Context) -> None:
    code = main(ctx.args)  # like the console script: sys.exit(main())
    if isinstance(code, int):
        ctx.exit(code)


def run(*args: str, input: str | None = None) -> tuple[int, str, str]:
    """Run the CLI in-process like the console script: (exit code, stdout, stderr)."""
    result = CliRunner().invoke(_entry, list(args), input=input, catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture
def belts(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Every sim belt the command opens."""
    opened: list[Any] = []
    real = sim_module.open_sim

    def spy(target: str = "", **options: Any) -> Any:
        belt = real(target, **options)
        opened.append(belt)
        return belt

    monkeypatch.setattr(sim_module, "open_sim", spy)
    return opened


STATS_KEYS = {"frames", "missed", "deadline_error_p50_ms", "deadline_error_p99_ms",
              "deadline_error_max_ms"}


def test_play_stats_last_line_is_json_with_the_timing_keys(belts: list[Any]) -> None:
    code, out, _ = run("play", "15", "--mode", "dynamic", "--belt", "sim:virtual",
                       "--seconds", "2", "--rate", "1000", "--stats")
    assert code == 0
    stats = json.loads(out.strip().splitlines()[-1])
    assert set(stats) >= STATS_KEYS
    assert stats["frames"] == 2000 and stats["missed"] == 0
    belt = belts[0]
    assert belt.closed and np.all(belt.levels == 0.0)
    _, levels = belt.commanded(0, 2_000_000_000)
    assert levels[:, 0].max() > 0.9 and levels[:, 5].max() > 0.9  # both bracketing tactors


def test_play_negative_angle_and_explicit_layout(belts: list[Any]) -> None:
    code, out, _ = run("play", "-30", "--belt", "sim:virtual", "--tactor-angles",
                       "0,90,180,270", "--seconds", "0.5")
    assert code == 0, out
    assert "330 deg" in out
    assert belts[0].tactor_angles_deg == (0.0, 90.0, 180.0, 270.0)


def test_play_takes_the_sim_belts_tactor_count(belts: list[Any]) -> None:
    code, _, err = run("play", "10", "--belt", "sim:8,virtual", "--seconds", "0.2")
    assert code == 0, err
    assert belts[0].n_tactors == 8


def test_play_applies_a_calibration_file(tmp_path: Path, belts: list[Any]) -> None:
    cal = tmp_path / "cal.toml"
    cal.write_text("".join("[[tactor]]\nstart = 0.3\nceiling = 0.6\n" for _ in range(6)))
    code, _, err = run("play", "30", "--belt", "sim:virtual", "--calibration", str(cal),
                       "--seconds", "1")
    assert code == 0, err
    _, levels = belts[0].commanded(0, 900_000_000)
    assert levels[:, 0].max() == pytest.approx(0.3 + 0.3 * (1 - np.exp(-4)))


@pytest.mark.parametrize("args", [
    ["abc"], ["nan"], ["inf"],
    ["15", "--belt", "bogus:thing"],
    ["15", "--belt", "sim:virtual", "--calibration", "/no/such/cal.toml"],
    ["15", "--tactors", "6", "--tactor-angles", "30,90"],
    ["15", "--seconds", "0"], ["15", "--seconds", "nan"], ["15", "--rate", "-1"],
    ["15", "--mode", "wobble"], ["15", "--law", "cubic"], ["15", "--falloff", "-1"],
    ["15", "--transit", "0.6"], ["15", "--tactors", "1"],
])
def test_play_bad_input_is_an_error_with_exit_2(args: list[str], belts: list[Any]) -> None:
    code, _, err = run("play", *args)
    assert code == 2
    assert err.startswith("error: ")
    assert "Traceback" not in err
    for belt in belts:
        assert np.all(belt.levels == 0.0)


def test_play_malformed_calibration_names_file_and_field(tmp_path: Path) -> None:
    cal = tmp_path / "cal.toml"
    cal.write_text("[[tactor]]\nstart = 2\nceiling = 0.5\n")
    code, _, err = run("play", "15", "--belt", "sim:virtual", "--calibration", str(cal))
    assert code == 2 and "cal.toml" in err and "tactor[0].start" in err


def test_play_calibration_for_another_belt(tmp_path: Path) -> None:
    cal = tmp_path / "four.toml"
    Calibration.identity(4).save(cal)
    code, _, err = run("play", "15", "--belt", "sim:virtual", "--calibration", str(cal))
    assert code == 2 and "four.toml" in err and "4 tactors" in err


def test_ctrl_c_stops_with_motors_off(monkeypatch: pytest.MonkeyPatch,
                                      belts: list[Any]) -> None:
    from tactorbelt.player import Player

    real_pump = Player.pump

    def pump_then_interrupt(self: Player, until_ns: int) -> None:
        real_pump(self, min(until_ns, 300_000_000))
        raise KeyboardInterrupt

    monkeypatch.setattr(Player, "pump", pump_then_interrupt)
    code, _, err = run("play", "15", "--belt", "sim:virtual", "--rate", "1000")
    assert code == 130
    assert "stopped: motors off" in err
    assert "error" not in err  # the user's own stop is not an error
    assert np.all(belts[0].levels == 0.0) and belts[0].closed


def test_belt_test_names_each_tactor_in_turn(belts: list[Any]) -> None:
    code, out, _ = run("belt-test", "--belt", "sim:virtual", "--seconds-each", "0.5")
    assert code == 0
    lines = [ln for ln in out.splitlines() if ln.startswith("tactor ")]
    assert lines == [
        "tactor 0 at 30 deg (right-front)", "tactor 1 at 90 deg (right)",
        "tactor 2 at 150 deg (right-back)", "tactor 3 at 210 deg (left-back)",
        "tactor 4 at 270 deg (left)", "tactor 5 at 330 deg (left-front)",
    ]
    belt = belts[0]
    # tactor k (and only k) vibrated in the k-th slot
    slot = 750_000_000  # 0.5 s pulse + 0.25 s gap
    lead = 3_000_000  # the shaped sim belt's preview ends a streamed pulse 3 ms early
    for k in range(6):
        _, lv = belt.commanded(k * slot, k * slot + 500_000_000 - lead)
        assert np.all(lv[:, k] == 1.0)
        assert np.all(np.delete(lv, k, axis=1) == 0.0)
    assert np.all(belt.levels == 0.0)


def test_belt_test_bad_input() -> None:
    code, _, err = run("belt-test", "--belt", "nope:1")
    assert code == 2 and err.startswith("error: ")
    code, _, err = run("belt-test", "--belt", "sim:virtual", "--seconds-each", "-1")
    assert code == 2 and err.startswith("error: ")


def test_calibrate_with_piped_keys_writes_the_profile(tmp_path: Path,
                                                      belts: list[Any]) -> None:
    out = tmp_path / "cal.toml"
    keys = "".join(["+" * (k + 1) + "\n" + "]" + "+" * k + "\n" for k in range(6)])
    code, _, err = run("calibrate", "--belt", "sim:virtual", "-o", str(out), input=keys)
    assert code == 0, err
    cal = Calibration.load(out)
    for k, t in enumerate(cal.tactors):
        assert t.start == pytest.approx(0.02 * (k + 1))
        assert t.ceiling == pytest.approx(0.02 * (k + 1) + 0.02 * (5 + k))
    assert "tactor 2 at 150 deg (right-back)" in err
    assert np.all(belts[0].levels == 0.0)


def test_calibrate_minus_does_not_go_below_zero_or_the_start() -> None:
    keys = "---+++-\n--\n" + "+\n\n" * 5
    code, out, err = run("calibrate", "--belt", "sim:virtual", input=keys)
    assert code == 0, err
    cal = Calibration.from_toml(out)
    assert cal.tactors[0].start == pytest.approx(0.04)
    assert cal.tactors[0].ceiling == pytest.approx(0.04)


def test_calibrate_input_ending_early_writes_nothing(tmp_path: Path, belts: list[Any]) -> None:
    out = tmp_path / "cal.toml"
    code, _, err = run("calibrate", "--belt", "sim:virtual", "-o", str(out), input="+++\n")
    assert code == 2 and "nothing was written" in err
    assert not out.exists()
    assert np.all(belts[0].levels == 0.0)


def test_calibrate_quit(tmp_path: Path) -> None:
    out = tmp_path / "cal.toml"
    code, _, err = run("calibrate", "--belt", "sim:virtual", "-o", str(out), input="++q")
    assert code == 1 and not out.exists()


@pytest.mark.parametrize(("command", "sig", "code"), [
    (["play", "15", "--seconds", "60"], signal.SIGTERM, 143),
    (["play", "15", "--seconds", "60"], signal.SIGHUP, 129),
    (["point", "--bearing", "90"], signal.SIGINT, 130),
    (["point", "--bearing", "90"], signal.SIGTERM, 143),
    (["belt-test", "--seconds-each", "5"], signal.SIGTERM, 143),
])
def test_signals_end_a_real_process_promptly(command: list[str], sig: int, code: int) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "tactorbelt", *command],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(2.0)  # started and playing
        assert proc.poll() is None, proc.communicate()
        sent = time.monotonic()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=10)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, err
    assert took < 1.5
    assert "error" not in err and "Traceback" not in err


@pytest.mark.parametrize("drive", ["plain", "shaped"])
def test_play_drive_sets_the_belts_drive_and_the_felt_onset(drive: str,
                                                            belts: list[Any]) -> None:
    code, out, _ = run("play", "30", "--belt", "sim:virtual", "--seconds", "0.3",
                       "--drive", drive)
    assert code == 0 and f"drive {drive}" in out
    belt = belts[0]
    assert belt.drive == drive
    onset = belt.commands()[0].t_ns
    _, vib = belt.vibration(onset, onset + 300_000_000)
    # tactor 0 (30 deg, at 0.98) reaches a tenth of its amplitude after 15 ms plain, 12
    # ms shaped (the overdrive, 1.2 times the rated drive, is 1.22 times its level)
    t10 = int(np.argmax(vib[:, 0] >= 0.1 * vib[-1, 0]))
    assert (t10 >= 15) if drive == "plain" else (t10 <= 13)


def test_play_and_point_refuse_an_unknown_drive() -> None:
    code, _, err = run("play", "30", "--belt", "sim:virtual", "--drive", "fast")
    assert code == 2 and "fast" in err
    code, _, err = run("point", "--belt", "sim:virtual?drive=fast", "--bearing", "0",
                       "--seconds", "0.1")
    assert code == 2 and "drive must be one of plain, shaped" in err
