"""``tactorbelt serve``: the browser bridge, driven by a Python WebSocket client as a page
would drive it (no browser here; the headless Chromium test is tests/test_web_*.py).

Every bridge is a real ``tactorbelt serve`` process on the sim belt (wall clock) with a
fresh store; the client answers the bridge's pings at once from a background task, as
the jsPsych plugin does. No assertion depends on how fast this machine is: the clock
checks use the handshake's own bound (the page and the bridge read the same monotonic
clock here, so the true offset is known), and waits have generous deadlines.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import sqlite3
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

websockets = pytest.importorskip("websockets")
from websockets.asyncio.client import connect  # noqa: E402
from websockets.exceptions import ConnectionClosed  # noqa: E402

from support.cli import tactorbelt  # noqa: E402
from support.studies import write_study  # noqa: E402

#: The page clock of the test client: perf_counter (the bridge's clock) plus this, in ms.
PAGE_OFFSET_MS = 12_345.678
#: How long a test waits for anything the bridge should do by itself.
DEADLINE_S = 20.0


def page_now_ms() -> float:
    return time.perf_counter_ns() / 1e6 + PAGE_OFFSET_MS


class Bridge:
    """A running ``tactorbelt serve`` process."""

    def __init__(self, proc: subprocess.Popen[str], url: str, store: Path) -> None:
        self.proc = proc
        self.url = url
        self.store = store
        m = re.fullmatch(r"http://([^/]+)/examples/paper\.html\?token=(\S+)", url)
        assert m is not None, url
        self.hostport, self.token = m.groups()

    def ws_url(self, token: str | None = "") -> str:
        token = self.token if token == "" else token
        return f"ws://{self.hostport}/ws" + ("" if token is None else f"?token={token}")

    def http(self, path: str, origin: str | None = None) -> tuple[int, bytes, str]:
        """GET ``path``: status, body, content type (and :attr:`last_headers`)."""
        req = urllib.request.Request(f"http://{self.hostport}{path}",
                                     headers={"Origin": origin} if origin else {})
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                self.last_headers = r.headers
                return r.status, r.read(), r.headers.get("Content-Type", "")
        except urllib.error.HTTPError as exc:
            self.last_headers = exc.headers
            return exc.code, exc.read(), exc.headers.get("Content-Type", "")

    def stop(self, sig: int = signal.SIGTERM) -> tuple[int, str]:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            _, err = self.proc.communicate(timeout=DEADLINE_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        return self.proc.returncode, err


def start_bridge(tmp: Path, *args: str) -> Bridge:
    store = tmp / "browser.sqlite"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactorbelt", "serve", "--belt", "sim", "--store", str(store),
         "--port", "0", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()  # the bridge prints it once it listens
    if not line.startswith("open: "):
        proc.kill()
        raise AssertionError(f"no open: line: {line!r} {proc.communicate()[1]}")
    return Bridge(proc, line.removeprefix("open: ").strip(), store)


@pytest.fixture
def bridge(tmp_path: Path) -> Iterator[Bridge]:
    b = start_bridge(tmp_path)
    yield b
    b.stop()


class Page:
    """A page's connection: pongs at once (unless ``silent``), requests by id."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.silent = False
        self.pings = 0
        self.unsolicited: list[dict[str, Any]] = []
        self._replies: dict[Any, asyncio.Future[dict[str, Any]]] = {}
        self._errors: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self._next = 0
        self._reader = asyncio.create_task(self._read())

    @classmethod
    async def open(cls, url: str, **kwargs: Any) -> Page:
        return cls(await connect(url, open_timeout=DEADLINE_S, **kwargs))

    async def _read(self) -> None:
        try:
            async for raw in self.ws:
                msg = json.loads(raw)
                if msg["type"] == "ping":
                    self.pings += 1
                    if not self.silent:
                        await self.ws.send(json.dumps({"type": "pong", "seq": msg["seq"],
                                                       "t_page_ms": page_now_ms()}))
                    continue
                fut = self._replies.pop(msg.get("id"), None)
                if fut is not None:
                    fut.set_result(msg)
                elif msg["type"] == "error":
                    self._errors.put_nowait(msg)
                else:
                    self.unsolicited.append(msg)
        except ConnectionClosed:
            pass

    async def request(self, msg: dict[str, Any]) -> dict[str, Any]:
        self._next += 1
        msg = {**msg, "id": self._next}
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self._replies[self._next] = fut
        await self.ws.send(json.dumps(msg))
        return await asyncio.wait_for(fut, DEADLINE_S)

    async def raw(self, text: str) -> dict[str, Any]:
        """Send text the bridge cannot parse; its error reply."""
        await self.ws.send(text)
        return await asyncio.wait_for(self._errors.get(), DEADLINE_S)

    async def close(self) -> None:
        await self.ws.close()
        self._reader.cancel()

    async def closed_code(self) -> int | None:
        await asyncio.wait_for(self.ws.wait_closed(), DEADLINE_S)
        return self.ws.close_code


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 120))


def trials_of(store: Path) -> list[dict[str, Any]]:
    con = sqlite3.connect(store)
    con.row_factory = sqlite3.Row
    try:
        return [dict(r) for r in con.execute("SELECT * FROM trials ORDER BY trial_index")]
    finally:
        con.close()


def sessions_of(store: Path) -> list[dict[str, Any]]:
    con = sqlite3.connect(store)
    con.row_factory = sqlite3.Row
    try:
        return [dict(r) for r in con.execute("SELECT * FROM sessions ORDER BY session_id")]
    finally:
        con.close()


def wait_status(store: Path, status: str) -> list[dict[str, Any]]:
    """The sessions once the first one is stored with ``status`` (or at the deadline):
    the bridge writes a lost page's status after it turned the motors off."""
    end = time.monotonic() + DEADLINE_S
    while True:
        s = sessions_of(store)
        if (s and s[0]["status"] == status) or time.monotonic() > end:
            return s
        time.sleep(0.05)


async def wait_levels_off(page: Page) -> list[float]:
    """Ask the belt's status until every drive level is 0 (or the deadline)."""
    end = time.monotonic() + DEADLINE_S
    while True:
        status = await page.request({"type": "status"})
        levels = status["belt"]["levels"]
        if levels is not None and not any(levels):
            return levels
        if time.monotonic() > end:
            raise AssertionError(f"the motors are still on: {status['belt']}")
        await asyncio.sleep(0.05)


# -- HTTP ------------------------------------------------------------------------------------
def test_open_line_and_http(bridge: Bridge) -> None:
    """The open: line names the example page with the token; the bridge serves its
    pages, and the study only with the token."""
    assert bridge.url.startswith("http://127.0.0.1:")
    status, body, ctype = bridge.http("/")
    assert status == 200 and b"tactorbelt" in body and ctype.startswith("text/html")
    assert bridge.http("/study.json")[0] == 403
    assert bridge.http("/study.json?token=nope")[0] == 403
    status, body, ctype = bridge.http(f"/study.json?token={bridge.token}")
    assert status == 200 and ctype == "application/json"
    study = json.loads(body)
    assert study["layout"]["tactors"] == 6 and len(study["targets"]) == 24
    assert study["targets"][6] == {"target": 6, "angle_deg": 90.0, "on_tactor": True}
    assert [b["condition"] for b in study["blocks"]] == ["static", "dynamic"]
    assert bridge.http("/no/such/file.js")[0] == 404
    assert bridge.http("/%2e%2e/server.py")[0] == 404
    assert bridge.http("/../server.py")[0] == 404
    req = urllib.request.Request(f"http://{bridge.hostport}/", method="DELETE")
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(req, timeout=10)
    assert info.value.code == 405


# -- the handshake and the schedule --------------------------------------------------------
def test_handshake_welcome_and_schedule(bridge: Bridge) -> None:
    """hello opens a session, the handshake finds the page clock within its own bound,
    and the schedule is the one `tactorbelt run` makes for the participant."""
    from tactorbelt.experiment.recorder import SessionRecorder
    from tactorbelt.experiment.study import paper_study

    async def go() -> dict[str, Any]:
        page = await Page.open(bridge.ws_url())
        welcome = await page.request({"type": "hello", "participant": "P02",
                                      "user_agent": "Mozilla/5.0 HeadlessChrome/120.0",
                                      "page": "examples/paper.html"})
        await page.close()
        return welcome

    w = run(go())
    assert w["type"] == "welcome" and w["resumed"] is False and w["done"] == []
    clock = w["clock"]
    assert clock["pings"] == 16
    assert clock["uncertainty_ms"] == pytest.approx(clock["rtt_ms"] / 2)
    # the page clock is perf_counter + PAGE_OFFSET_MS: the estimate is within its bound
    assert abs(clock["offset_ms"] - PAGE_OFFSET_MS) <= clock["uncertainty_ms"] + 0.01
    schedule, _ = SessionRecorder.schedule_for(paper_study(), "P02")
    got = w["schedule"]
    assert len(got) == len(schedule) == 288
    for entry, t in zip(got, schedule, strict=True):
        assert (entry["index"], entry["block"], entry["condition"], entry["angle_deg"]) == (
            t.trial_index, t.block, t.condition, t.target_deg)
        assert entry["target"] * 360 / entry["n_targets"] == pytest.approx(t.target_deg)
        assert entry["training"] == (t.block == "training")
    s = sessions_of(bridge.store)
    assert len(s) == 1 and s[0]["participant"] == "P02" and s[0]["input"] == "browser"
    opts = json.loads(sqlite3.connect(bridge.store).execute(
        "SELECT value FROM meta WHERE key='run_options:1'").fetchone()[0])
    page = opts["pages"][-1]
    assert page["user_agent"].endswith("HeadlessChrome/120.0")
    assert page["browser"] == "chromium-headless"
    assert page["clock"]["offset_ms"] == clock["offset_ms"]
    assert page["clock"]["uncertainty_ms"] == clock["uncertainty_ms"]


# -- play and trial ------------------------------------------------------------------------
def test_play_onset_on_page_clock_and_trial_stored_once(bridge: Bridge) -> None:
    """A play's onset comes back on the page's clock, between the request and the
    reply (within the handshake's uncertainty); its trial is stored once, with the
    response, the RT and the onset; a second store of it is refused."""

    async def go() -> tuple[dict[str, Any], ...]:
        page = await Page.open(bridge.ws_url())
        w = await page.request({"type": "hello", "participant": "P01"})
        first = w["schedule"][0]
        sent = page_now_ms()
        played = await page.request({"type": "play", "index": 0})
        got = page_now_ms()
        status = await page.request({"type": "status"})
        stored = await page.request({"type": "trial", "index": 0, "play_id": played["id"],
                                     "response": {"target": first["target"], "rt_ms": 812.5,
                                                  "device": "mouse"}})
        again = await page.request({"type": "trial", "index": 0, "play_id": played["id"],
                                    "response": {"target": 3, "rt_ms": 500.0}})
        after = await page.request({"type": "status"})
        await page.close()
        return w, played, status, stored, again, after, {"sent": sent, "got": got}

    w, played, status, stored, again, after, t = run(go())
    unc = played["uncertainty_ms"]
    assert played["type"] == "played" and played["onset_source"] == "host"
    assert t["sent"] - unc - 0.01 <= played["onset_ms"] <= t["got"] + unc + 0.01
    assert played["skin_onset_ms"] is None  # the sim belt has no measured latencies
    assert played["stimulus"]["index"] == 0
    assert played["duration_ms"] == 10_000.0
    assert status["belt"]["playing"] is True and any(status["belt"]["levels"])
    assert stored == {"type": "stored", "id": stored["id"], "index": 0, "status": "done",
                      "correct": True}
    assert again["type"] == "error" and "already stored" in again["error"]
    assert not any(after["belt"]["levels"])  # the response stopped the stimulus
    rows = trials_of(bridge.store)
    assert len(rows) == 1
    row = rows[0]
    assert row["trial_index"] == 0 and row["status"] == "done" and row["correct"] == 1
    assert row["rt_s"] == pytest.approx(0.8125)
    assert row["target_deg"] == w["schedule"][0]["angle_deg"]
    assert row["response_target_deg"] == row["target_deg"]
    assert row["n_samples"] == 0
    onset_page_ms = row["onset_ns"] / 1e6 + w["clock"]["offset_ms"]
    assert onset_page_ms == pytest.approx(played["onset_ms"], abs=1e-3)
    assert row["acquired_ns"] - row["onset_ns"] == 812_500_000
    assert row["stimulus_off_ns"] >= row["onset_ns"]


def test_play_kinds_and_timeout(bridge: Bridge) -> None:
    """A target with a condition, an angle and raw amplitudes play too; a trial answered
    with no target is stored as a timeout; raw amplitudes stop after their duration."""

    async def go() -> tuple[Any, ...]:
        page = await Page.open(bridge.ws_url())
        by_target = await page.request({"type": "play", "target": 6, "condition": "static",
                                        "duration_ms": 200})
        by_angle = await page.request({"type": "play", "angle_deg": 45, "condition": "dynamic",
                                       "duration_ms": 200})
        raw = await page.request({"type": "play", "amplitudes": [1, 0, 0, 0, 0, 0.5],
                                  "duration_ms": 150})
        on = await page.request({"type": "status"})
        off = await wait_levels_off(page)
        w = await page.request({"type": "hello", "participant": "P03"})
        await page.request({"type": "play", "index": 1})
        timeout = await page.request({"type": "trial", "index": 1,
                                      "response": {"target": None, "rt_ms": None}})
        ended = await page.request({"type": "end", "status": "completed"})
        await page.close()
        return by_target, by_angle, raw, on, off, w, timeout, ended

    by_target, by_angle, raw, on, off, w, timeout, ended = run(go())
    assert by_target["stimulus"] == {"kind": "target", "target": 6, "n_targets": 24,
                                     "angle_deg": 90.0, "condition": "static"}
    assert by_angle["stimulus"]["condition"] == "dynamic"
    assert by_angle["stimulus"]["angle_deg"] == 45.0
    assert raw["stimulus"] == {"kind": "amplitudes", "amplitudes": [1.0, 0, 0, 0, 0, 0.5]}
    assert on["belt"]["levels"] == [1.0, 0, 0, 0, 0, 0.5]
    assert off == [0.0] * 6
    assert timeout["status"] == "timeout"
    assert ended["status"] == "interrupted"  # 1 of 288 trials: not complete
    row = trials_of(bridge.store)[0]
    assert row["trial_index"] == 1 and row["status"] == "timeout" and row["rt_s"] is None
    assert sessions_of(bridge.store)[0]["status"] == "interrupted"


# -- refusals ----------------------------------------------------------------------------
def test_wrong_origin_and_missing_token_are_closed_1008(tmp_path: Path) -> None:
    """No token, a wrong token or an Origin not allowed: closed with 1008 and a reason
    (logged); an origin given with --allow-origin and the bridge's own are accepted."""
    b = start_bridge(tmp_path, "--allow-origin", "https://lab.example.org")
    try:
        async def refused(url: str, origin: str | None = None) -> tuple[int | None, str]:
            kwargs = {"origin": origin} if origin else {}
            async with connect(url, open_timeout=DEADLINE_S, **kwargs) as ws:
                with pytest.raises(ConnectionClosed):
                    await asyncio.wait_for(ws.recv(), DEADLINE_S)
                return ws.close_code, ws.close_reason or ""

        async def accepted(origin: str) -> dict[str, Any]:
            page = await Page.open(b.ws_url(), origin=origin)
            status = await page.request({"type": "status"})
            await page.close()
            return status

        assert run(refused(b.ws_url(None))) == (1008, "missing token")
        assert run(refused(b.ws_url("wrong"))) == (1008, "wrong token")
        code, reason = run(refused(b.ws_url(), "http://evil.example"))
        assert code == 1008 and "http://evil.example" in reason
        assert run(accepted("https://lab.example.org"))["type"] == "status"
        assert run(accepted(b.url.split("/examples")[0]))["type"] == "status"
        # a page hosted at an allowed origin may read the study (CORS); others may not
        assert b.http(f"/study.json?token={b.token}", "https://lab.example.org")[0] == 200
        assert b.last_headers["Access-Control-Allow-Origin"] == "https://lab.example.org"
        assert b.http(f"/study.json?token={b.token}", "http://evil.example")[0] == 200
        assert b.last_headers.get("Access-Control-Allow-Origin") is None
    finally:
        _, err = b.stop()
    assert err.count("refused a WebSocket connection") == 3


def test_malformed_and_unknown_messages_get_an_error_reply(bridge: Bridge) -> None:
    """Nothing a page sends crashes the bridge: every bad message gets an error reply
    and the connection stays usable."""

    async def go() -> tuple[list[dict[str, Any]], list[dict[str, Any]], dict[str, Any]]:
        page = await Page.open(bridge.ws_url())
        raw = [await page.raw(t) for t in ("{not json", "[1, 2]", '{"no": "type"}',
                                            '{"type": "explode", "id": 4}', "\x00")]
        bad = [await page.request(m) for m in (
            {"type": "play"},
            {"type": "play", "target": 99, "condition": "static"},
            {"type": "play", "target": 1, "condition": "wobbly"},
            {"type": "play", "amplitudes": [2, 0, 0, 0, 0, 0], "duration_ms": 100},
            {"type": "play", "amplitudes": [1, 0], "duration_ms": 100},
            {"type": "play", "amplitudes": [1, 0, 0, 0, 0, 0]},
            {"type": "play", "index": 0},
            {"type": "trial", "index": 0, "response": {}},
            {"type": "hello", "participant": "no spaces allowed"},
            {"type": "hello"},
            {"type": "end", "status": "completed"},
        )]
        status = await page.request({"type": "status"})
        await page.close()
        return raw, bad, status

    raw, bad, status = run(go())
    assert all(r["type"] == "error" and r["id"] is None for r in raw[:3]), raw
    assert "malformed JSON" in raw[0]["error"]
    assert "unknown message type 'explode'" in raw[3]["error"]
    assert raw[3]["id"] == 4  # an unknown type's error still names the request
    assert all(r["type"] == "error" and isinstance(r["error"], str) for r in bad), bad
    assert [r["id"] for r in bad] == list(range(1, len(bad) + 1))
    assert "'target' must be in 0..23" in bad[1]["error"]
    assert "send 'hello' first" in bad[6]["error"]
    assert "participant id" in bad[8]["error"]
    assert status["type"] == "status" and status["belt"]["connected"] is True


# -- a page that goes away -------------------------------------------------------------------
def test_heartbeat_loss_and_close_turn_the_motors_off(bridge: Bridge) -> None:
    """A page that stops answering the heartbeat has its motors turned off and its
    session left interrupted (a new hello resumes it); so does a page that closes."""

    async def go() -> tuple[Any, ...]:
        watcher = await Page.open(bridge.ws_url())  # never says hello: no heartbeat
        page = await Page.open(bridge.ws_url())
        w = await page.request({"type": "hello", "participant": "P05"})
        await page.request({"type": "play", "amplitudes": [1] * 6, "duration_ms": 60_000})
        on = (await watcher.request({"type": "status"}))["belt"]["levels"]
        page.silent = True
        off = await wait_levels_off(watcher)
        lost = await page.closed_code()
        again = await Page.open(bridge.ws_url())
        resumed = await again.request({"type": "hello", "participant": "P05"})
        await again.request({"type": "play", "index": 0})
        await again.close()  # a page that closes mid-stimulus
        off2 = await wait_levels_off(watcher)
        await watcher.close()
        return w, on, off, lost, resumed, off2

    w, on, off, lost, resumed, off2 = run(go())
    assert w["heartbeat_ms"] == 1000
    assert on == [1.0] * 6 and off == [0.0] * 6 and off2 == [0.0] * 6
    assert lost == 4000
    assert resumed["resumed"] is True and resumed["session_id"] == w["session_id"]
    s = wait_status(bridge.store, "interrupted")
    assert len(s) == 1 and s[0]["status"] == "interrupted" and s[0]["resumed"] == 1


def test_sigterm_ends_with_143_and_the_motors_off(tmp_path: Path) -> None:
    """SIGTERM while a page plays: the motors off, the session interrupted, the page
    closed (1001), exit status 143; Ctrl-C exits 130."""
    b = start_bridge(tmp_path)

    async def go() -> tuple[list[float], int | None]:
        page = await Page.open(b.ws_url())
        await page.request({"type": "hello", "participant": "P07"})
        await page.request({"type": "play", "amplitudes": [0.8] * 6, "duration_ms": 60_000})
        on = (await page.request({"type": "status"}))["belt"]["levels"]
        b.proc.send_signal(signal.SIGTERM)
        return on, await page.closed_code()

    on, code = run(go())
    rc, err = b.stop()
    assert on == [0.8] * 6
    assert code == 1001
    assert rc == 143, err
    assert "stopping: motors off" in err and "terminated by SIGTERM" in err
    assert "Traceback" not in err
    assert sessions_of(b.store)[0]["status"] == "interrupted"
    rc, err = start_bridge(tmp_path).stop(signal.SIGINT)
    assert rc == 130, err
    assert "interrupted: motors off" in err and "Traceback" not in err


# -- the store is the same store --------------------------------------------------------------
def _same(a: Any, b: Any, where: str = "") -> None:
    """Equal JSON values, floats to 1e-9 (a response time that went through milliseconds
    may differ from the lab's in its last bit)."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12, nan_ok=True), where
    else:
        assert a == b, where


def test_browser_sessions_analyse_and_export_like_lab_ones(tmp_path: Path) -> None:
    """Two participants run through `tactorbelt run` (the model participant), then the
    same participants through the bridge, each trial answered as the lab answered it:
    the browser sessions are complete, store the same trials, and `analyze` gives the
    same statistics from both stores; `export` reads the browser store."""
    study = write_study(tmp_path, name="browser", targets=6, repetitions=1, training=1,
                        training_conditions=["static"], break_every=0)
    participants = ("P01", "P02")
    lab = tmp_path / "lab.sqlite"
    for pid in participants:
        proc = tactorbelt("run", str(study), "-p", pid, "--headless", "--input", "model",
                          "--db", str(lab))
        assert proc.returncode == 0, proc.stderr
    lab_rows = trials_of(lab)
    lab_session = {s["session_id"]: s["participant"] for s in sessions_of(lab)}
    answers = {(lab_session[r["session_id"]], r["trial_index"]): r for r in lab_rows}
    b = start_bridge(tmp_path, "--study", str(study))

    async def session(pid: str) -> dict[str, Any]:
        page = await Page.open(b.ws_url())
        w = await page.request({"type": "hello", "participant": pid})
        for t in w["schedule"]:
            lab_trial = answers[(pid, t["index"])]
            played = await page.request({"type": "play", "index": t["index"]})
            response = ({"target": None, "rt_ms": None} if lab_trial["status"] == "timeout"
                        else {"angle_deg": lab_trial["response_deg"],
                              "rt_ms": lab_trial["rt_s"] * 1000.0, "device": "mouse"})
            stored = await page.request({"type": "trial", "index": t["index"],
                                         "play_id": played["id"], "response": response})
            assert stored["type"] == "stored" and stored["status"] == lab_trial["status"]
        ended = await page.request({"type": "end", "status": "completed"})
        await page.close()
        return ended

    try:
        ended = [run(session(pid)) for pid in participants]
    finally:
        rc, err = b.stop()
    assert rc == 143, err
    assert [e["status"] for e in ended] == ["complete"] * 2
    keys = ("trial_index", "block", "block_index", "block_name", "condition", "repetition",
            "target_deg", "on_tactor", "n_targets", "load", "status", "response_deg",
            "response_target_deg", "correct")
    browser_rows = trials_of(b.store)
    assert len(browser_rows) == len(lab_rows)
    assert sorted(tuple(r[k] for k in keys) for r in browser_rows) == sorted(
        tuple(r[k] for k in keys) for r in lab_rows)
    assert [s["status"] for s in sessions_of(b.store)] == ["complete"] * 2
    summaries = []
    for name, db in (("browser", b.store), ("lab", lab)):
        out = tmp_path / f"report-{name}"
        proc = tactorbelt("analyze", str(db), "-o", str(out), "--bootstrap-sims", "0")
        assert proc.returncode == 0, proc.stderr
        summaries.append(json.loads((out / "summary.json").read_text()))
    browser, lab_summary = summaries
    for section in ("counts", "conditions", "cells", "between_accuracy_test", "tests",
                    "contrasts", "mixed_model", "rt_mixed_model", "rt_from", "study"):
        _same(browser[section], lab_summary[section], section)
    exported = tmp_path / "csv"
    proc = tactorbelt("export", str(b.store), "-o", str(exported))
    assert proc.returncode == 0, proc.stderr
    lines = (exported / "trials.csv").read_text().splitlines()
    assert len(lines) == 1 + len(browser_rows)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_host_other_than_loopback_warns_and_a_token_can_be_fixed(tmp_path: Path) -> None:
    """--host with another address works but says that other machines can reach it;
    --token keeps a hosted page's link working across restarts; a short one is refused."""
    b = start_bridge(tmp_path, "--host", "0.0.0.0", "--token", "lab-token-0123456789")
    assert b.token == "lab-token-0123456789"
    rc, err = b.stop()
    assert rc == 143
    assert "warning: listening on 0.0.0.0" in err
    assert os.path.exists(b.store)
    proc = tactorbelt("serve", "--store", str(tmp_path / "x.sqlite"), "--token", "short")
    assert proc.returncode == 2 and "--token" in proc.stderr


def test_sim_belt_plays_after_any_number_of_stops() -> None:
    """The bridge stops the belt whenever a page asks (stop, a response, a lost page),
    so a play may follow any number of stops: the sim belt's checkpoint must never look
    up the render of a play it is still registering (it raised KeyError once in 256)."""
    from tactorbelt.clock import WallClock
    from tactorbelt.devices import open_belt
    from tactorbelt.player import Player
    from tactorbelt.stimuli import make_stimulus

    clock = WallClock()
    with open_belt("sim", clock=clock) as belt:
        belt.set_drive("plain")
        player = Player(belt, clock)
        stim = make_stimulus(belt.layout, 45.0, "dynamic")
        for i in range(600):
            player.start(stim, duration_s=10.0)
            player.stop()
            for _ in range(i % 3):
                belt.stop()
        assert not belt.levels.any()


def test_a_shared_postgresql_store(tmp_path: Path, pg_url: str) -> None:
    """--store postgresql://...: the session and its trial land in the shared store,
    claimed for this site as run claims them."""
    store = pg_url
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactorbelt", "serve", "--belt", "sim", "--store", store,
         "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "TACTORBELT_SITE": "lab-a"})
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith("open: "), proc.communicate()[1]
    b = Bridge(proc, line.removeprefix("open: ").strip(), tmp_path / "unused")

    async def go() -> dict[str, Any]:
        page = await Page.open(b.ws_url())
        w = await page.request({"type": "hello", "participant": "P09"})
        played = await page.request({"type": "play", "index": 0})
        stored = await page.request({"type": "trial", "index": 0, "play_id": played["id"],
                                     "response": {"target": w["schedule"][0]["target"],
                                                  "rt_ms": 700.0}})
        await page.close()
        return stored

    try:
        assert run(go())["status"] == "done"
    finally:
        rc, err = b.stop()
    assert rc == 143, err
    from tactorbelt.experiment.store import open_store

    with open_store(store, readonly=True) as s:
        sessions = s.sessions("P09")
        assert [x["site"] for x in sessions] == ["lab-a"]
        assert [x["input"] for x in sessions] == ["browser"]
        trials = s.trials(sessions[0]["session_id"])
        assert [(t["trial_index"], t["status"]) for t in trials] == [(0, "done")]


def test_skin_onsets_where_the_calibration_has_latencies(tmp_path: Path) -> None:
    """With measured latencies in the motor calibration, a play's reply carries the onset
    at the skin on the page's clock, and the trial stores it."""
    from tactorbelt.devices.calibration import Calibration, TactorCalibration

    cal = tmp_path / "belt.toml"
    Calibration(tuple(TactorCalibration(0.0, 1.0, 1.0, latency_ms=20.0, latency_sd_ms=0.5)
                      for _ in range(6)), validated="2026-11-27",
                validation_method="test").save(cal)
    b = start_bridge(tmp_path, "--calibration", str(cal))

    try:
        w, played = run(_first_trial_answered(b.ws_url()))
    finally:
        b.stop()
    assert played["skin_onset_ms"] == pytest.approx(played["onset_ms"] + 20.0, abs=1e-6)
    assert played["skin_onset_sd_ms"] == pytest.approx(0.5)
    row = trials_of(b.store)[0]
    assert row["skin_onset_ns"] - row["onset_ns"] == 20_000_000
    assert row["skin_onset_sd_ns"] == 500_000


async def _first_trial_answered(url: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """A page says hello as P01, plays the schedule's first trial and answers it right;
    the welcome and the play's reply."""
    page = await Page.open(url)
    w = await page.request({"type": "hello", "participant": "P01"})
    played = await page.request({"type": "play", "index": 0})
    await page.request({"type": "trial", "index": 0, "play_id": played["id"],
                        "response": {"target": w["schedule"][0]["target"], "rt_ms": 650.0}})
    await page.close()
    return w, played


@pytest.mark.emulator
def test_device_onsets_on_a_firmware_belt(tmp_path: Path, emulator_exe: Path) -> None:
    """On a belt that reports its onsets (the firmware emulator), a play's onset is the
    device's own, on the page's clock, and the trial stores it beside the command time."""
    b = start_bridge(tmp_path, "--belt", "emulator")

    try:
        w, played = run(_first_trial_answered(b.ws_url()))
    finally:
        rc, err = b.stop()
    assert rc == 143, err
    assert played["onset_source"] == "device"
    assert played["uncertainty_ms"] > w["clock"]["uncertainty_ms"]
    row = trials_of(b.store)[0]
    assert row["device_onset_ns"] is not None and row["onset_uncertainty_ns"] is not None
    device_page_ms = row["device_onset_ns"] / 1e6 + w["clock"]["offset_ms"]
    assert device_page_ms == pytest.approx(played["onset_ms"], abs=1e-3)
    assert played["command_ms"] == pytest.approx(row["onset_ns"] / 1e6
                                                 + w["clock"]["offset_ms"], abs=1e-3)
    assert row["acquired_ns"] - row["device_onset_ns"] == 650_000_000


def test_a_killed_bridge_loses_no_answered_trial(tmp_path: Path) -> None:
    """Every answered trial is committed when its reply comes: a bridge killed outright
    (SIGKILL: no cleanup at all) keeps them, and the participant's page resumes the
    session on a new bridge with those trials done."""
    b = start_bridge(tmp_path)

    async def answer(bridge: Bridge, n: int) -> dict[str, Any]:
        page = await Page.open(bridge.ws_url())
        w = await page.request({"type": "hello", "participant": "P04"})
        for t in [t for t in w["schedule"] if t["index"] not in w["done"]][:n]:
            played = await page.request({"type": "play", "index": t["index"]})
            stored = await page.request({"type": "trial", "index": t["index"],
                                         "play_id": played["id"],
                                         "response": {"target": t["target"], "rt_ms": 500}})
            assert stored["type"] == "stored"
        return w

    first = run(answer(b, 3))
    b.proc.kill()
    b.proc.communicate(timeout=DEADLINE_S)
    b2 = start_bridge(tmp_path)
    try:
        second = run(answer(b2, 0))
    finally:
        b2.stop()
    assert second["resumed"] is True and second["session_id"] == first["session_id"]
    assert second["done"] == [0, 1, 2]
    assert [r["trial_index"] for r in trials_of(b2.store)] == [0, 1, 2]


def test_one_session_per_page_and_a_reload_takes_over(bridge: Bridge) -> None:
    """A second page for the same participant (a reload, a second tab) takes the session
    over and the first page is closed (4001); a page for another participant is refused
    while a session runs."""

    async def go() -> tuple[Any, ...]:
        first = await Page.open(bridge.ws_url())
        w1 = await first.request({"type": "hello", "participant": "P11"})
        other = await Page.open(bridge.ws_url())
        busy = await other.request({"type": "hello", "participant": "P12"})
        second = await Page.open(bridge.ws_url())
        w2 = await second.request({"type": "hello", "participant": "P11"})
        code = await first.closed_code()
        await second.close()
        await other.close()
        return w1, busy, w2, code

    w1, busy, w2, code = run(go())
    assert busy["type"] == "error" and "another participant" in busy["error"]
    assert w2["session_id"] == w1["session_id"] and w2["resumed"] is True
    assert code == 4001
    assert [s["participant"] for s in sessions_of(bridge.store)] == ["P11"]
