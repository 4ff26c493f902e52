"""Reliability against the real firmware core (the emulator): faults on the link and on the host.

- the emulator killed in the middle of a trial (in-process and through ``tactorbelt run``):
  the trial is stored ``aborted``, the error names the port, the session resumes and
  completes on a fresh emulator;
- the host frozen (SIGSTOP) while a belt plays: the firmware's heartbeat failsafe turns
  every output off within the heartbeat timeout, measured in device time;
- the continuous-on limit (SET_CONFIG max_on_ms) and the clamping of PLAY_TARGET fields;
- motors off on every way out of every command that drives a belt (normal end, error,
  SIGINT), read from the emulator's levels log while the test holds the port open, so
  that a closing port cannot be what turned the outputs off.

These run in real time against a real process (the behaviour under test is timing), so
they wait on the wall clock; the whole file takes about half a minute. Skipped when g++
or make is missing.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.belts import wait_for
from support.studies import study_toml
from tactorbelt import DeviceError
from tactorbelt.clock import WallClock
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices.emulator import EmulatorBelt
from tactorbelt.experiment.listeners import NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.experiment.trial import TrialState
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse
from tactorbelt.stimuli import make_stimulus

pytestmark = pytest.mark.emulator

# 6 between-tactor trials
STUDY = study_toml(minimal=True, name="reliability", tactors=6, targets=6,
                   max_presentation_s=2.0, timeout_s=2.0, iti_s=0.05, break_every=0,
                   training=0, conditions=["dynamic"], repetitions=1)





def read_log(path: Path) -> np.ndarray:
    """The levels log as rows of (t_us, state, level_0, ...); a partial last line is dropped."""
    if not path.exists():
        return np.zeros((0, 8), dtype=np.int64)
    lines = path.read_text().splitlines()
    rows = []
    width = len(lines[0].split(",")) if lines else 0
    for line in lines[1:]:
        parts = line.split(",")
        if len(parts) == width and all(p.strip().lstrip("-").isdigit() for p in parts):
            rows.append([int(p) for p in parts])
    return np.array(rows, dtype=np.int64).reshape(-1, max(width, 1))


class Emulator:
    """A bare emulator process with a levels log, for commands given ``--belt serial:PTY``.

    ``hold()`` keeps the port open from the test, so that the emulator never sees the
    port close when a command exits: outputs that are off afterwards were turned off by
    the command (STOP_ALL: state idle) or by the failsafe (state 3), never by a hang-up.
    """

    def __init__(self, exe: Path, tmp: Path, *args: str) -> None:
        self.log = tmp / f"levels-{time.monotonic_ns()}.csv"
        self.proc = subprocess.Popen([str(exe), "--levels-log", str(self.log), *args],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL)
        assert self.proc.stdout is not None
        self.pty = self.proc.stdout.readline().decode().strip()
        assert self.pty.startswith("/dev/"), self.pty
        self.fd: int | None = None
        self.n0 = 0  # rows of the levels log before the command under test
        self._seq = 200
        self._dec = wire.FrameDecoder()

    @property
    def url(self) -> str:
        return f"serial:{self.pty}"

    def hold(self) -> None:
        self.fd = os.open(self.pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)

    def rows(self) -> np.ndarray:
        return read_log(self.log)

    def request(self, build: Callable[[int], wire.Packet], timeout_s: float = 1.0
                ) -> wire.Reply:
        """Send one request on the held port (a second connection) and read its reply."""
        assert self.fd is not None
        self._seq = (self._seq + 1) & 0xFF
        os.write(self.fd, b"\x00" + wire.encode_frame(build(self._seq)))
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.fd], [], [], 0.05)
            if not ready:
                continue
            for p in self._dec.feed(os.read(self.fd, 4096)):
                if p.seq == self._seq:
                    return wire.parse_reply(p)
        raise AssertionError("the emulator did not answer the second connection")

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        if self.proc.stdin is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()


@pytest.fixture
def emulator(emulator_exe: Path, tmp_path: Path) -> Iterator[Emulator]:
    emu = Emulator(emulator_exe, tmp_path)
    emu.hold()
    yield emu
    emu.close()


def tactorbelt_cmd(*args: str) -> list[str]:
    # the console script, not `python -m tactorbelt`: __main__.py drops the exit code of
    # click's Exit (see test_reliability_inputs.py::test_python_m_tactorbelt_keeps_exit_codes)
    return [str(Path(sys.executable).with_name("tactorbelt")), *args]


def spawn(*args: str, stdin: Any = subprocess.DEVNULL, emu: Emulator | None = None
          ) -> subprocess.Popen[str]:
    """Start a tactorbelt command; with ``emu``, its levels log is read from this point on."""
    if emu is not None:
        emu.n0 = len(emu.rows())
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(tactorbelt_cmd(*args), stdin=stdin, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def finish(proc: subprocess.Popen[str], timeout_s: float = 30.0) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout_s)
    return proc.returncode, out, err


def motors_on(emu: Emulator) -> bool:
    """True once the command under test has turned a motor on."""
    rows = emu.rows()[emu.n0:]
    return bool(len(rows) and rows[:, 2:].any())


def assert_stopped_by_the_command(emu: Emulator) -> None:
    """The last output change is every level 0 in state idle: a STOP_ALL (the port is held,
    so not a hang-up; not the failsafe, which would be state 3)."""
    time.sleep(0.3)  # longer than the heartbeat timeout: a failsafe would show by now
    rows = emu.rows()[emu.n0:]
    assert len(rows) and rows[:, 2:].any(), "the command never drove the motors"
    last = rows[-1]
    assert last[1] == wire.State.IDLE, f"last state {last[1]} (3 = failsafe): not stopped"
    assert not last[2:].any()
    status = emu.request(wire.get_status)
    assert isinstance(status, wire.Status)
    assert status.state == wire.State.IDLE and status.levels == (0,) * 6
    assert status.failsafe_count == 0


# -- the emulator killed mid-trial -----------------------------------------------------------


class KillAt(NullObserver):
    """Kills the emulator when the stimulus of trial ``at`` has started."""

    def __init__(self, belt: EmulatorBelt, at: int) -> None:
        self.belt = belt
        self.at = at
        self.killed = False

    def on_trial_state(self, trial: Any, state: TrialState, now_ns: int) -> None:
        if state is TrialState.STIMULUS and trial.trial_index == self.at and not self.killed:
            self.killed = True
            self.belt.process.kill()
            self.belt.process.wait()


def _cursor(study: Study) -> ScriptedCursor:
    answers = {t.trial_index: t.target_deg for t in make_schedule(study, "P01")}
    return ScriptedCursor(ScriptedResponse(answer="correct", reaction_s=0.05, movement_s=0.1),
                          answers=answers)


def test_emulator_killed_mid_trial_aborts_the_trial_and_the_session_resumes(
    emulator_exe: Path, tmp_path: Path
) -> None:
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    clock = WallClock()
    with Store.open(db) as store:
        belt = open_belt("emulator", build=False, layout=study.layout_obj())
        assert isinstance(belt, EmulatorBelt)
        killer = KillAt(belt, at=2)
        try:
            with pytest.raises(DeviceError) as info:
                run_session(study, "P01", belt, _cursor(study), store, clock,
                            observer=killer)
        finally:
            belt.close()  # best effort on a dead device: never raises
        assert killer.killed
        msg = str(info.value)
        assert belt.pty_path in msg and "--resume" in msg and "motors off" in msg
        (sess,) = store.sessions("P01")
        assert sess["status"] == "interrupted"
        rows = store.trials(sess["session_id"])
        assert [(r["trial_index"], r["status"]) for r in rows] == [
            (0, "done"), (1, "done"), (2, "aborted")]
        assert rows[2]["abort_reason"].startswith("device error")
        # resumed on a fresh emulator: the rest of the schedule, trial 2 again
        with open_belt("emulator", build=False, layout=study.layout_obj()) as belt2:
            res = run_session(study, "P01", belt2, _cursor(study), store, clock, resume=True)
            assert belt2.status().levels == (0,) * 6  # type: ignore[attr-defined]
        assert res.status == "complete" and res.n_done == 6
        assert [r.trial.trial_index for r in res.results] == [2, 3, 4, 5]
        rows = store.trials(sess["session_id"])
        assert sorted(r["trial_index"] for r in rows) == list(range(6))
        assert {r["status"] for r in rows} == {"done"}
        assert [r["attempts"] for r in sorted(rows, key=lambda r: r["trial_index"])] == [
            1, 1, 2, 1, 1, 1]


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


def _emulator_child(pid: int) -> int | None:
    for child in _children(pid):
        with contextlib.suppress(OSError):
            if Path(f"/proc/{child}/comm").read_text().strip() == "emulator":
                return child
    return None


def test_cli_run_with_the_emulator_killed_says_which_port_and_resumes(
    emulator_exe: Path, tmp_path: Path
) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    db = tmp_path / "s.sqlite"
    args = ("run", str(study_file), "-p", "P01", "--belt", "emulator", "--headless",
            "--input", "scripted", "--db", str(db))
    proc = spawn(*args)
    try:
        assert wait_for(lambda: _emulator_child(proc.pid) is not None, 15)
        emu_pid = _emulator_child(proc.pid)
        assert emu_pid is not None

        def trials() -> int:
            if not db.exists():
                return 0
            with contextlib.closing(__import__("sqlite3").connect(db, timeout=1)) as c:
                try:
                    return int(c.execute("SELECT COUNT(*) FROM trials").fetchone()[0])
                except Exception:
                    return 0

        assert wait_for(lambda: trials() >= 2, 20)
        os.kill(emu_pid, signal.SIGKILL)
        code, _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 3, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]  # (logged warnings about the lost port come first)
    assert last.startswith("error: belt emulator failed during the session")
    assert "/dev/pts/" in last and "stopped answering" in last and "--resume" in last
    with Store.open(db, readonly=True) as store:
        rows = store.trials()
        assert len(rows) >= 2 and rows[-1]["status"] == "aborted"
        assert rows[-1]["abort_reason"].startswith("device error")
        assert store.sessions()[0]["status"] == "interrupted"
    # a fresh emulator: the session completes, every trial exactly once
    code, out, err = finish(spawn(*args, "--resume"), 60)
    assert code == 0, err
    assert "complete, 6/6 trials done" in out
    with Store.open(db, readonly=True) as store:
        rows = store.trials()
        assert sorted(r["trial_index"] for r in rows) == list(range(6))
        assert {r["status"] for r in rows} == {"done"}


# -- the host going silent -------------------------------------------------------------------


@pytest.mark.parametrize("stream", [False, True], ids=["device-rendered", "streamed-1khz"])
def test_frozen_host_trips_the_failsafe_within_the_heartbeat_timeout(
    emulator: Emulator, stream: bool
) -> None:
    """``tactorbelt play`` SIGSTOPped while the belt plays: every output off, state
    failsafe, within the heartbeat timeout (250 ms) of the freeze, in device time."""
    extra = ["--rate", "1000"] if stream else []
    proc = spawn("play", "45", "--mode", "dynamic", "--belt", emulator.url, "--seconds", "30",
                 *extra, emu=emulator)
    try:
        assert wait_for(lambda: motors_on(emulator), 15), proc.stderr
        time.sleep(0.3)
        os.kill(proc.pid, signal.SIGSTOP)
        t_stop = time.monotonic()
        assert wait_for(lambda: (emulator.rows()[:, 1] == wire.State.FAILSAFE).any(), 3)
        # map the wall clock to device time with a PING on the second connection
        t0 = time.monotonic()
        pong = emulator.request(lambda seq: wire.ping(seq, 1234))
        t1 = time.monotonic()
        assert isinstance(pong, wire.Pong)
        stop_us = pong.device_time_us - ((t0 + t1) / 2 - t_stop) * 1e6
        rows = emulator.rows()
        (fired,) = np.flatnonzero(rows[:, 1] == wire.State.FAILSAFE)
        assert not rows[fired, 2:].any()
        assert rows[fired - 1, 2:].any() or rows[:fired, 2:].any()
        latency_ms = (rows[fired, 0] - stop_us) / 1000
        print(f"failsafe {latency_ms:.1f} ms after SIGSTOP (heartbeat 250 ms, "
              f"{'streaming' if stream else 'device-rendered'})")
        # the last packet came at most one keep-alive period (83 ms) before the freeze
        assert 250 - 83 - 10 <= latency_ms <= 250 + 25, latency_ms
        status = emulator.request(wire.get_status)
        assert isinstance(status, wire.Status)
        assert status.state == wire.State.FAILSAFE and status.levels == (0,) * 6
        assert status.failsafe_count == 1
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        os.kill(proc.pid, signal.SIGCONT)
        proc.communicate()


# -- safety limits in the firmware -----------------------------------------------------------


def test_continuous_on_limit_cuts_each_channel_until_it_is_commanded_off(
    emulator_exe: Path, tmp_path: Path
) -> None:
    log = tmp_path / "levels.csv"
    with open_belt("emulator", build=False, levels_log=log) as belt:
        belt.set_config(250, max_on_ms=300)  # type: ignore[attr-defined]
        belt.set_amplitudes([0.5, 0.5, 0, 0, 0, 0])
        time.sleep(0.1)
        belt.set_amplitudes([0.5, 0.5, 0.5, 0, 0, 0])  # channel 2 starts 100 ms later
        t_end = time.monotonic() + 0.6
        while time.monotonic() < t_end:  # a stuck host streaming the same frame
            belt.set_amplitudes([0.5, 0.5, 0.5, 0, 0, 0])
            time.sleep(0.01)
        status = belt.status()  # type: ignore[attr-defined]
        assert status.state == wire.State.STREAMING  # not the failsafe: the limit
        assert status.levels == (0,) * 6
        belt.set_amplitudes([0, 0.5, 0.5, 0, 0, 0])  # channel 0 commanded off: re-armed
        belt.set_amplitudes([0.5, 0.5, 0.5, 0, 0, 0])
        assert belt.status().levels == (32768, 0, 0, 0, 0, 0)  # type: ignore[attr-defined]
        # a static between-tactor target keeps two tactors on: cut as well
        belt.play(make_stimulus(belt.layout, 60.0, "static"), None)
        assert wait_for(lambda: belt.status().levels == (0,) * 6, 2)  # type: ignore[attr-defined]
        assert belt.status().state == wire.State.PLAYING  # type: ignore[attr-defined]
    rows = read_log(log)
    streaming = rows[rows[:, 1] == wire.State.STREAMING]
    on0 = streaming[np.flatnonzero(streaming[:, 2] > 0)[0], 0]
    off0 = streaming[np.flatnonzero((streaming[:, 0] > on0) & (streaming[:, 2] == 0))[0], 0]
    on2 = streaming[np.flatnonzero(streaming[:, 4] > 0)[0], 0]
    off2 = streaming[np.flatnonzero((streaming[:, 0] > on2) & (streaming[:, 4] == 0))[0], 0]
    print(f"max-on 300 ms: channel 0 cut after {(off0 - on0) / 1000:.1f} ms, "
          f"channel 2 after {(off2 - on2) / 1000:.1f} ms")
    assert 300_000 <= off0 - on0 <= 320_000
    assert 300_000 <= off2 - on2 <= 320_000


def test_out_of_range_max_on_is_refused_by_host_and_device(emulator_exe: Path) -> None:
    from tactorbelt import ConfigError

    with open_belt("emulator", build=False) as belt:
        for bad in (99, 600_001):
            with pytest.raises(ConfigError):
                belt.set_config(250, max_on_ms=bad)  # type: ignore[attr-defined]
            # the device refuses it too (NAK 4), when the host check is bypassed
            reply = belt._request(  # type: ignore[attr-defined]
                lambda seq, bad=bad: wire.Packet(wire.MsgType.SET_CONFIG, seq,
                                                 (250).to_bytes(2, "little")
                                                 + bad.to_bytes(4, "little")), "SET_CONFIG")
            assert reply == wire.Nak(reply.seq, wire.NakCode.OUT_OF_RANGE)


@pytest.mark.parametrize("fields", [
    # angle_cdeg, mode, law, falloff_cdeg, period_ms, transit_ms
    (65535, 1, 0, 0, 0, 0),          # angle past 360, falloff 0, period 0, transit 0
    (4500, 1, 0, 65535, 65535, 65535),  # transit longer than the period
    (4500, 1, 2, 1, 10, 65535),
    (3000, 0, 1, 0, 1, 1),
])
def test_firmware_clamps_play_target_fields(emulator_exe: Path, tmp_path: Path,
                                            fields: tuple[int, int, int, int, int, int]
                                            ) -> None:
    """Out-of-range fields are clamped (docs/protocol.md), and what plays is exactly the
    stimulus of the clamped values; only the two enumerations are refused."""
    log = tmp_path / "levels.csv"
    angle, mode, law, falloff, period, transit = fields
    with open_belt("emulator", build=False, levels_log=log) as belt:
        reply = belt._request(  # type: ignore[attr-defined]
            lambda seq: wire.play_target(seq, angle, mode, law, falloff, period, transit,
                                         200), "PLAY_TARGET")
        assert isinstance(reply, wire.Ack)
        assert wait_for(lambda: belt.status().state == wire.State.IDLE, 2)  # type: ignore[attr-defined]
        # enumerations out of range are refused and change nothing
        for bad_mode, bad_law in ((2, 0), (0, 3), (255, 255)):
            reply = belt._request(  # type: ignore[attr-defined]
                lambda seq, m=bad_mode, la=bad_law: wire.play_target(seq, 4500, m, la, 1500, 1000,
                                                             100, 0), "PLAY_TARGET")
            assert reply == wire.Nak(reply.seq, wire.NakCode.OUT_OF_RANGE)
        assert belt.status().levels == (0,) * 6  # type: ignore[attr-defined]
    rows = read_log(log)
    playing = rows[rows[:, 1] == wire.State.PLAYING]
    assert len(playing) and playing[:, 2:].any()
    assert playing[:, 2:].min() >= 0 and playing[:, 2:].max() <= 65535
    # the clamped stimulus, rendered by the Python package
    period_c = max(period, 10)
    transit_c = min(max(transit, 1), (period_c - 1) // 2)
    stim = make_stimulus(belt.layout, (angle % 36000) / 100, ("static", "dynamic")[mode],
                         ("paper", "linear", "energy")[law], max(falloff, 1) / 100,
                         period_c / 1000, transit_c / 1000)
    t = (playing[:, 0] - playing[0, 0]) / 1e6
    with np.errstate(over="ignore"):  # laws.py: exp overflows (harmlessly) for T = 0.01
        want = np.vectorize(wire.amplitude_to_level)(stim.amplitudes(t))
    close = np.all(np.abs(playing[:, 2:] - want) <= 2, axis=1)
    # (a change logged on a millisecond tick that is also a phase boundary may be
    # computed on either side of it in float32: allow one such row in twenty)
    assert close.mean() >= 0.95, (playing[~close][:5], want[~close][:5])


def test_amplitudes_are_checked_and_clamped_at_every_host_layer(emulator_exe: Path) -> None:
    from tactorbelt import ConfigError
    from tactorbelt.devices.calibration import Calibration, TactorCalibration

    # Belt base: refuses what is not N finite values in [0, 1]
    cal = Calibration((TactorCalibration(start=0.2, gain=5.0, ceiling=0.6),) * 6)
    with open_belt("emulator", build=False, calibration=cal) as belt:
        for bad in ([1.01] * 6, [-0.01] * 6, [float("nan")] * 6, [float("inf")] * 6,
                    [0.5] * 5, [0.5] * 7, "loud"):
            with pytest.raises(ConfigError):
                belt.set_amplitudes(bad)
        assert belt.status().levels == (0,) * 6  # type: ignore[attr-defined]
        # calibration: gain 5 cannot push past the ceiling
        belt.set_amplitudes([1.0, 0.9, 0.5, 0.1, 0.01, 0.0])
        levels = belt.status().levels  # type: ignore[attr-defined]
        ceiling = wire.amplitude_to_level(0.6)
        assert max(levels) == ceiling and levels[-1] == 0
        assert min(levels[:-1]) >= wire.amplitude_to_level(0.2)
    # wire encoding: clamps to 0..65535
    assert wire.amplitude_to_level(1e300) == 65535 and wire.amplitude_to_level(-1e300) == 0


def test_levels_in_a_malformed_frame_never_reach_the_outputs(emulator_exe: Path) -> None:
    """SET_AMPLITUDES with the wrong channel count is NAKed; outputs unchanged."""
    with open_belt("emulator", build=False) as belt:
        belt.set_amplitudes([0.25] * 6)
        for n in (5, 7, 0):
            reply = belt._request(  # type: ignore[attr-defined]
                lambda seq, n=n: wire.Packet(wire.MsgType.SET_AMPLITUDES, seq,
                                             b"\xff\xff" * n), "SET_AMPLITUDES")
            assert reply == wire.Nak(reply.seq, wire.NakCode.BAD_LENGTH)
        assert belt.status().levels == (wire.amplitude_to_level(0.25),) * 6  # type: ignore[attr-defined]


# -- motors off on every way out of every command --------------------------------------------


def _interrupt_when_on(proc: subprocess.Popen[str], emu: Emulator, sig: int = signal.SIGINT
                       ) -> tuple[int, str, str]:
    assert wait_for(lambda: motors_on(emu) or proc.poll() is not None, 20)
    assert proc.poll() is None, proc.communicate()
    time.sleep(0.05)
    proc.send_signal(sig)
    return finish(proc)


def test_play_stops_the_motors_at_its_end(emulator: Emulator) -> None:
    code, out, err = finish(spawn("play", "45", "--mode", "dynamic", "--belt", emulator.url,
                                  "--seconds", "0.4", emu=emulator))
    assert code == 0, err
    assert "done: motors off" in out
    assert_stopped_by_the_command(emulator)


@pytest.mark.parametrize("rate", [None, "1000"], ids=["device-rendered", "streamed"])
def test_play_stops_the_motors_on_sigint(emulator: Emulator, rate: str | None) -> None:
    extra = ["--rate", rate] if rate else []
    proc = spawn("play", "45", "--mode", "dynamic", "--belt", emulator.url, "--seconds", "30",
                 *extra, emu=emulator)
    code, _, err = _interrupt_when_on(proc, emulator)
    assert code == 130, err
    assert "Traceback" not in err
    assert_stopped_by_the_command(emulator)


def test_belt_test_stops_the_motors_at_its_end_and_on_sigint(emulator: Emulator) -> None:
    code, out, err = finish(spawn("belt-test", "--belt", emulator.url, "--seconds-each",
                                  "0.05", "--gap", "0", emu=emulator))
    assert code == 0, err
    assert "done: all motors off" in out
    assert_stopped_by_the_command(emulator)
    proc = spawn("belt-test", "--belt", emulator.url, "--seconds-each", "5", emu=emulator)
    code, _, err = _interrupt_when_on(proc, emulator)
    assert code == 130 and "Traceback" not in err, err
    assert_stopped_by_the_command(emulator)


def test_point_stops_the_motors_at_its_end_and_on_sigint(emulator: Emulator) -> None:
    code, _, err = finish(spawn("point", "--bearing", "45", "--belt", emulator.url,
                                "--seconds", "0.4", "-q", emu=emulator))
    assert code == 0, err
    assert_stopped_by_the_command(emulator)
    proc = spawn("point", "--bearing", "45", "--belt", emulator.url, "--seconds", "30", "-q",
                 emu=emulator)
    code, _, err = _interrupt_when_on(proc, emulator)
    # the user's own stop: exit 130 like every command, no error line
    assert code == 130 and "Traceback" not in err and "error" not in err, err
    assert_stopped_by_the_command(emulator)


def test_run_stops_the_motors_at_its_end_and_on_sigint(emulator: Emulator,
                                                       tmp_path: Path) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY.replace("count = 6", "count = 2"))
    args = ("run", str(study_file), "-p", "P01", "--belt", emulator.url, "--headless",
            "--input", "scripted", "--db", str(tmp_path / "a.sqlite"))
    code, out, err = finish(spawn(*args, emu=emulator))
    assert code == 0, err
    assert "complete" in out
    assert_stopped_by_the_command(emulator)
    study_file.write_text(STUDY)
    args = (*args[:-1], str(tmp_path / "b.sqlite"))
    code, _, err = _interrupt_when_on(spawn(*args, emu=emulator), emulator)
    assert code == 130 and "Traceback" not in err, err
    assert "--resume" in err
    assert_stopped_by_the_command(emulator)
    with Store.open(tmp_path / "b.sqlite", readonly=True) as store:
        assert store.trials()[-1]["status"] == "aborted"
        assert store.sessions()[0]["status"] == "interrupted"


@pytest.mark.parametrize("keys,code", [
    ("+++++\n+++\n" * 6, 0),        # every tactor: start, then ceiling
    ("+++++\n+++\n+++", 2),         # input ends part way: error, nothing written
    ("+++++\nq", 1),                # the experimenter quits
], ids=["complete", "input-ends", "quit"])
def test_calibrate_stops_the_motors_on_every_way_out(emulator: Emulator, tmp_path: Path,
                                                     keys: str, code: int) -> None:
    out_file = tmp_path / "cal.toml"
    proc = spawn("calibrate", "--belt", emulator.url, "-o", str(out_file),
                 stdin=subprocess.PIPE, emu=emulator)
    assert proc.stdin is not None
    # the first key presses, then the rest once the emulator has shown a motor on: piped
    # all at once, the set and the stop can reach a starved emulator before one tick, and
    # its output log would never show the motor driven
    first, rest = keys[:5], keys[5:]
    proc.stdin.write(first)
    proc.stdin.flush()
    assert wait_for(lambda: motors_on(emulator) or proc.poll() is not None, 20)
    _, err = proc.communicate(rest, timeout=30)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    assert out_file.exists() == (code == 0)
    assert_stopped_by_the_command(emulator)


def test_calibrate_stops_the_motors_on_sigint(emulator: Emulator) -> None:
    proc = spawn("calibrate", "--belt", emulator.url, stdin=subprocess.PIPE, emu=emulator)
    assert proc.stdin is not None
    proc.stdin.write("+++++")  # a tactor on, waiting for enter
    proc.stdin.flush()
    code, _, err = _interrupt_when_on(proc, emulator)
    assert code == 130 and "Traceback" not in err, err
    assert_stopped_by_the_command(emulator)
