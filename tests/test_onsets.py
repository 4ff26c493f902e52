"""Device-true onsets: the clock mapping, and stored onsets against the emulator's own log.

- :class:`~tactorbelt.devices._clocksync.ClockSync` on synthetic round trips with a
  known offset, drift and asymmetric link delays;
- a study run on the emulator (firmware 1.1, ONSET events) stores ``device_onset_ns``
  and ``onset_uncertainty_ns`` per trial; each stored device onset is within 0.5 ms of
  the output change in the emulator's levels log, put on the host clock by an offset
  bracket the test measures itself after the run (PING round trips on its own
  connection: ``send - d <= offset <= receive - d`` for every one, so the intersection
  holds the true offset; the emulator's clock is CLOCK_MONOTONIC minus its start);
- a DEBUG_HANG on an emulator with its watchdog: the reset is reported (warning,
  ``watchdog_reset``, DIAG) and ONSET events come back.

The emulator tests skip without g++ or make.
"""

from __future__ import annotations

import itertools
import logging
import random
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from support.belts import hang
from support.emulator_clock import clock_offset_bracket
from support.studies import study_toml
from tactorbelt.clock import WallClock
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices._clocksync import ClockSync
from tactorbelt.devices._firmware import FirmwareBelt
from tactorbelt.devices.emulator import EmulatorBelt
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse
from tactorbelt.stimuli import make_stimulus

# --- the estimator ------------------------------------------------------------------------


def _round_trips(sync: ClockSync, offset_ns: int, drift: float, n: int, seed: int = 1,
                 start_ns: int = 10**12, every_ns: int = 100_000_000) -> None:
    """Feed ``n`` round trips: one way 50..2000 us out, 50..400 us back (asymmetric)."""
    rng = random.Random(seed)
    for i in range(n):
        send = start_ns + i * every_ns
        at_device = send + rng.randint(50_000, 2_000_000)
        recv = at_device + rng.randint(50_000, 400_000)
        device_us = int((at_device - offset_ns) / (1.0 + drift) // 1000)
        sync.add(send, recv, device_us)


def test_clock_sync_finds_the_offset_from_the_fastest_round_trips() -> None:
    sync = ClockSync()
    offset = 123_456_789_000
    _round_trips(sync, offset, 0.0, 64)
    device_us = (10**12 + 64 * 100_000_000 - offset) // 1000  # just after the last one
    host, unc = sync.to_host(device_us)  # type: ignore[misc]
    truth = device_us * 1000 + offset
    assert abs(host - truth) <= unc
    assert unc < 400_000  # the fastest quarter, not the average (~1 ms of asymmetry)


def test_clock_sync_follows_a_drifting_device_clock() -> None:
    sync = ClockSync()
    offset, drift = 5_000_000_000, 50e-6  # 50 ppm: 320 us over the 6.4 s window
    _round_trips(sync, offset, drift, 64)
    fit = sync.fit()
    assert fit is not None and abs(fit.drift - drift) < 15e-6
    device_us = int((10**12 + 64 * 100_000_000 - offset) / (1 + drift) // 1000)
    host, unc = sync.to_host(device_us)  # type: ignore[misc]
    assert abs(host - (10**12 + 64 * 100_000_000)) <= unc + 1000


def test_clock_sync_unwraps_a_pong_time_and_forgets_on_reset() -> None:
    sync = ClockSync()
    assert sync.to_host(1) is None
    t = 10**12
    d = (1 << 32) + 1_000  # just past the 32-bit wrap of PONG's time
    sync.add(t, t + 100_000, d)
    later = t + 5_000_000_000
    assert sync.unwrap32((d + 5_000_000) & 0xFFFFFFFF, later, later + 100_000) == d + 5_000_000
    sync.reset()
    assert len(sync) == 0 and sync.fit() is None


# --- the emulator ---------------------------------------------------------------------------

# 12 between-tactor trials, rendered on the device
STUDY = study_toml(minimal=True, name="onsets", tactors=6, targets=6,
                   max_presentation_s=1.0, timeout_s=1.0, iti_s=0.05, break_every=0,
                   training=0, conditions=["dynamic"], repetitions=2)



class BareEmulator:
    """An emulator process the test owns (a belt opens ``serial:PTY`` on it)."""

    def __init__(self, exe: Path, log: Path) -> None:
        self.log = log
        self.proc = subprocess.Popen([str(exe), "--levels-log", str(log)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL)
        assert self.proc.stdout is not None
        self.pty = self.proc.stdout.readline().decode().strip()
        assert self.pty.startswith("/dev/"), self.pty

    def rows(self) -> list[list[int]]:
        lines = self.log.read_text().splitlines()[1:]
        return [[int(v) for v in ln.split(",")] for ln in lines if ln.count(",") >= 2]

    def offset_bracket(self, pings: int = 200) -> tuple[int, int]:
        """[lo, hi] holding the emulator's clock zero on perf_counter_ns (a fresh port)."""
        return clock_offset_bracket(self.pty, pings)

    def close(self) -> None:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.close()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()


@pytest.fixture
def bare_emulator(emulator_exe: Path, tmp_path: Path) -> Iterator[BareEmulator]:
    emu = BareEmulator(emulator_exe, tmp_path / "levels.csv")
    yield emu
    emu.close()


def _starts(rows: list[list[int]]) -> list[int]:
    """Device times (us) at which the emulator started playing (state 2 from another)."""
    return [b[0] for a, b in itertools.pairwise(rows) if b[1] == 2 and a[1] != 2]


@pytest.mark.emulator
def test_stored_device_onsets_match_the_emulator_levels_log(
        bare_emulator: BareEmulator, tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    answers = {t.trial_index: t.target_deg for t in make_schedule(study, "P01")}
    cursor = ScriptedCursor(ScriptedResponse(answer="correct", reaction_s=0.05,
                                             movement_s=0.1), answers=answers)
    with Store.open(tmp_path / "s.sqlite") as store:
        with open_belt(f"serial:{bare_emulator.pty}") as belt:
            assert isinstance(belt, FirmwareBelt) and belt.reports_onsets
            result = run_session(study, "P01", belt, cursor, store, WallClock())
        assert result.status == "complete"
        rows = store.trials()
    lo, hi = bare_emulator.offset_bracket()
    zero_ns = (lo + hi) // 2 + 500  # the middle of the log's microsecond, too
    slack_ns = (hi - lo) // 2 + 500
    starts = _starts(bare_emulator.rows())
    assert len(starts) == len(rows) == 12
    errors_us = []
    for row, t_us in zip(rows, starts, strict=True):
        truth_ns = zero_ns + t_us * 1000
        assert row["device_onset_ns"] is not None and row["onset_uncertainty_ns"] > 0
        error = abs(row["device_onset_ns"] - truth_ns)
        errors_us.append(error / 1000)
        assert error <= 500_000 + slack_ns, (row["trial_index"], error)
        # (The host's own stamp is not compared with the log: the emulator stamps a
        # request with the time its read loop began, which on a loaded machine can be
        # milliseconds away from when the host wrote it; the device onset and the log
        # share that stamp, which is what this test checks.)
    print(f"device onsets vs levels log: max {max(errors_us):.0f} us "
          f"(truth bracket +-{slack_ns / 1000:.0f} us)")


@pytest.mark.emulator
def test_a_hang_resets_the_emulator_by_its_watchdog_and_the_belt_reports_it(
        emulator_exe: Path, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="tactorbelt.devices"), open_belt(
            "emulator?watchdog_ms=200&debug_frames=true&heartbeat_ms=1000",
            build=False) as belt:
        assert isinstance(belt, EmulatorBelt) and not belt.watchdog_reset
        belt.play(make_stimulus(belt.layout, 45.0, mode="dynamic"))
        hang(belt)  # the loop stops: no tick, no failsafe; the watchdog fires at 200 ms
        time.sleep(0.6)
        diag = belt.diag()
        assert diag.watchdog_reset and belt.watchdog_reset
        assert belt.info.firmware_version == "1.3.0"
        assert belt.status().state == wire.State.IDLE  # a fresh core: outputs off
        assert belt.lost is None
        belt.play(make_stimulus(belt.layout, 45.0, mode="dynamic"))
        assert belt.last_onset() is not None  # ONSET events on again
    assert any("watchdog" in r.getMessage() and r.levelno == logging.WARNING
               for r in caplog.records)


# --- the store: two nullable trial columns, added to older stores on open ------------------


def test_trials_keep_device_onsets_and_older_stores_gain_the_columns(tmp_path: Path) -> None:
    import sqlite3

    from support.stores import make_result, make_session

    db = tmp_path / "old.sqlite"
    with Store.open(db) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))  # no device onset: NULL
    conn = sqlite3.connect(db)  # a store written before the columns existed
    for column in ("device_onset_ns", "onset_uncertainty_ns", "n_targets", "load"):
        conn.execute(f"ALTER TABLE trials DROP COLUMN {column}")
    conn.execute("UPDATE meta SET value='1' WHERE key='schema_version'")  # schema 1
    conn.commit()
    conn.close()
    with Store.open(db) as store:
        r = make_result(1)
        r.device_onset_ns, r.onset_uncertainty_ns = 1_000_123_456, 42_000
        store.write_trial(sid, r)
        rows = store.trials(sid)
    assert [(t["device_onset_ns"], t["onset_uncertainty_ns"]) for t in rows] == [
        (None, None), (1_000_123_456, 42_000)]


def test_the_offset_bracket_is_where_most_round_trips_agree() -> None:
    """A round trip stamped by a read loop that began before its PING arrived (a loaded
    machine) lies past the others: it is outvoted, not a contradiction; consistent
    round trips give their intersection."""
    from support.emulator_clock import most_agreed

    assert most_agreed([(0, 10), (2, 8), (3, 12)]) == (3, 3, 8)
    assert most_agreed([(0, 10), (2, 8), (3, 12), (20, 30)]) == (3, 3, 8)
    assert most_agreed([(5, 5), (5, 9)]) == (2, 5, 5)
