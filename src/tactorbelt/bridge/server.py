"""``tactorbelt serve``: the WebSocket bridge between a browser page and a belt.

One asyncio server (the ``websockets`` library) on one port:

- **HTTP GET** (``process_request``): the bridge's pages and plugins from the
  package's ``static/`` folder, and ``/study.json`` (the study, for the page; needs the
  token). Anything else is 404. A request from an allowed origin (``--allow-origin``)
  gets CORS headers, so a page hosted there can read them.
- **WebSocket** at ``/ws?token=TOKEN``: accepted, then closed with code 1008 and a
  reason (logged) when the token is missing or wrong or the ``Origin`` header is not
  an allowed origin (default: the bridge's own ``http://127.0.0.1:PORT`` and
  ``http://localhost:PORT``; a client that sends no Origin is not a page and needs the
  token only).

A page says ``hello`` with its participant: the bridge opens (or resumes) that
participant's session in the store, runs the clock handshake (16 pings, the offset
from the least round trip) and sends ``welcome`` with the schedule ``tactorbelt run``
makes for the participant. ``play`` starts a stimulus (a scheduled trial, a target
and condition, an angle, or raw amplitudes) and answers, once the belt has started
it, with the onset on the page's ``performance.now()`` clock; ``trial`` stores a
trial (one transaction, through the runner's session seam); ``stop``, ``status`` and ``end`` do
what they say. After the handshake the bridge pings four times every ``heartbeat_ms``;
a page that has not answered for ``heartbeat_ms``, that closes or that reloads has its
motors turned off and its session left ``interrupted`` (a new ``hello`` resumes it).
SIGINT and SIGTERM (and SIGHUP) turn the motors off, leave every open session
``interrupted``, close the pages (code 1001) and end :func:`serve` with
KeyboardInterrupt or :class:`~tactorbelt.interrupts.Terminated`.

The belt is used from one thread (:class:`.belt.BeltPort`), the store from another;
the event loop never waits on either. Malformed or unknown messages get an ``error``
reply; nothing a page sends ends the bridge.

I/O edge: imports the devices (through :mod:`.belt`), the store (through the session
seam, :class:`~tactorbelt.experiment.recorder.SessionRecorder`), the experiment's study
and runner helpers, and ``websockets``.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import logging
import math
import secrets
import signal
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar
from urllib.parse import parse_qs

from websockets.asyncio.server import serve as ws_serve

from .._errors import ConfigError, StoreError, TactorbeltError
from ..calibration.perceptual import profile_for_session
from ..experiment.provenance import default_site
from ..experiment.recorder import SessionRecorder
from ..experiment.runner import check_participant, skin_latency
from ..experiment.store import Store, open_store
from ..interrupts import Terminated
from ..stimuli import Stimulus, make_stimulus
from .belt import BeltPort, Onset
from .http import content_type, response, static_file, study_json
from .messages import (
    MAX_MESSAGE_BYTES,
    ClockEstimate,
    MessageError,
    clock_estimate,
    error_reply,
    need_int,
    need_str,
    opt_int,
    opt_number,
    opt_str,
    parse,
    request_id,
)

if TYPE_CHECKING:
    from websockets.asyncio.server import Server, ServerConnection
    from websockets.http11 import Request, Response

    from ..experiment.schedule import ScheduledTrial
    from ..experiment.study import Study

__all__ = ["DEFAULT_PORT", "BridgeConfig", "serve"]

log = logging.getLogger("tactorbelt.bridge")

#: The port ``tactorbelt serve`` listens on unless ``--port`` says otherwise.
DEFAULT_PORT = 8735
#: The page the ``open:`` line names.
EXAMPLE_PAGE = "examples/paper.html"
#: Pings of the clock handshake, and how long one may wait for its pong.
HANDSHAKE_PINGS = 16
#: Heartbeat pings sent per heartbeat period (the motors go off one period after the
#: page's last answer).
PINGS_PER_HEARTBEAT = 4
PING_TIMEOUT_S = 1.0
#: The close code of a refused connection (policy violation), and of a lost page.
CLOSE_REFUSED = 1008
CLOSE_LOST = 4000
CLOSE_REPLACED = 4001
#: The longest play a page may ask for.
MAX_DURATION_MS = 60_000.0
#: The folder of the pages and plugins (package data; the web/ build writes there).
STATIC_DIR = Path(__file__).parent / "static"
#: The input kind stored with a browser session.
INPUT_KIND = "browser"

T = TypeVar("T")


@dataclass
class BridgeConfig:
    """What ``tactorbelt serve`` was asked for.

    Attributes:
        belt_url: the belt.
        store_url: the store (SQLite path or ``postgresql://``).
        study: the study; ``study_toml`` its text (stored with each session);
            ``study_path`` its file (None: the paper template).
        host, port: where to listen (port 0: any free port).
        allow_origins: origins allowed besides the bridge's own.
        token: the token a page must present (default: a new random one).
        heartbeat_ms: the heartbeat period.
        calibration: the motor calibration (None: the belt's).
        static_dir: the folder served over HTTP.
    """

    belt_url: str
    store_url: str
    study: Study
    study_toml: str
    study_path: str | None = None
    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    allow_origins: tuple[str, ...] = ()
    token: str = field(default_factory=lambda: secrets.token_urlsafe(18))
    heartbeat_ms: int = 1000
    calibration: Any = None
    static_dir: Path = STATIC_DIR


def browser_name(user_agent: str | None) -> str | None:
    """The browser a user agent names (``chromium``, ``chrome``, ``edge``, ``firefox``,
    ``safari``), or None."""
    if not user_agent:
        return None
    for token, name in (("Edg/", "edge"), ("HeadlessChrome/", "chromium-headless"),
                        ("Chromium/", "chromium"), ("Chrome/", "chrome"),
                        ("Firefox/", "firefox"), ("Safari/", "safari")):
        if token in user_agent:
            return name
    return "other"


@dataclass
class _Play:
    """A play request's outcome, kept for the trial that refers to it."""

    play_id: int | None
    onset: Onset
    stimulus: dict[str, Any]
    index: int | None
    target_deg: float | None
    condition: str | None
    skin: tuple[int, int] | None


class _Page:
    """One WebSocket connection (a page)."""

    def __init__(self, bridge: _Bridge, ws: ServerConnection) -> None:
        self.bridge = bridge
        self.ws = ws
        self.clock: ClockEstimate | None = None
        self.recording: SessionRecorder | None = None
        self.ended = False
        self.profile: Any = None
        self.plays: dict[int, _Play] = {}
        self.by_index: dict[int, _Play] = {}
        self.stored: set[int] = set()
        self._stimuli: dict[tuple[Any, ...], Stimulus] = {}
        self._pending: dict[int, asyncio.Future[tuple[float, int]]] = {}
        self._seq = 0
        self.last_pong_ns = time.perf_counter_ns()
        self._heartbeat: asyncio.Task[None] | None = None
        self._queue: asyncio.Queue[tuple[dict[str, Any], int]] = asyncio.Queue()
        self.closed_reason: str | None = None
        self.remote = str(ws.remote_address[0]) if ws.remote_address else "?"

    # -- sending ----------------------------------------------------------------------------
    async def send(self, msg: dict[str, Any]) -> None:
        with contextlib.suppress(Exception):  # a page that went away: its close is handled
            await self.ws.send(json.dumps(msg, allow_nan=False))

    # -- the connection's life --------------------------------------------------------------
    async def run(self) -> None:
        worker = asyncio.create_task(self._work())
        try:
            async for raw in self.ws:
                t_recv = time.perf_counter_ns()
                try:
                    msg = parse(raw)
                except MessageError as exc:
                    await self.send(error_reply(exc.rid, str(exc)))
                    continue
                if msg["type"] == "pong":
                    self._pong(msg, t_recv)
                else:
                    self._queue.put_nowait((msg, t_recv))
        finally:
            worker.cancel()
            with contextlib.suppress(BaseException):
                await worker
            await self.gone("the page closed" if self.closed_reason is None
                            else self.closed_reason)

    async def _work(self) -> None:
        while True:
            msg, t_recv = await self._queue.get()
            rid = request_id(msg)
            try:
                reply = await self.handle(msg, t_recv)
            except TactorbeltError as exc:
                reply = error_reply(rid, str(exc))
            except Exception as exc:  # never a crash: the page hears what went wrong
                log.warning("bridge: %s request failed: %s: %s", msg.get("type"),
                            type(exc).__name__, exc)
                reply = error_reply(rid, f"internal error: {type(exc).__name__}: {exc}")
            if reply is not None:
                await self.send(reply)

    async def gone(self, why: str) -> None:
        """The page is gone (closed, reloaded, silent): its motors off, its session
        ``interrupted``."""
        if self._heartbeat is not None:
            self._heartbeat.cancel()
            self._heartbeat = None
        await self.bridge.release(self, why)

    # -- pings ------------------------------------------------------------------------------
    def _pong(self, msg: dict[str, Any], t_recv: int) -> None:
        self.last_pong_ns = t_recv
        seq = msg.get("seq")
        fut = self._pending.pop(seq, None) if isinstance(seq, int) else None
        if fut is None or fut.done():
            return
        t_page = msg.get("t_page_ms")
        if isinstance(t_page, bool) or not isinstance(t_page, int | float) \
                or not math.isfinite(t_page):
            fut.set_exception(MessageError("pong: 't_page_ms' must be a finite number"))
            return
        fut.set_result((float(t_page), t_recv))

    async def handshake(self) -> ClockEstimate:
        """The clock handshake: pings one after another, the offset from the least
        round trip."""
        loop = asyncio.get_running_loop()
        samples: list[tuple[int, int, float]] = []
        for _ in range(HANDSHAKE_PINGS):
            self._seq += 1
            seq = self._seq
            fut: asyncio.Future[tuple[float, int]] = loop.create_future()
            self._pending[seq] = fut
            t_send = time.perf_counter_ns()
            await self.ws.send(json.dumps({"type": "ping", "seq": seq}))
            try:
                t_page, t_recv = await asyncio.wait_for(fut, PING_TIMEOUT_S)
            except (TimeoutError, MessageError):
                self._pending.pop(seq, None)
                continue
            samples.append((t_send, t_recv, t_page))
        self.clock = clock_estimate(samples)
        return self.clock

    async def ensure_clock(self) -> ClockEstimate:
        return self.clock if self.clock is not None else await self.handshake()

    def start_heartbeat(self) -> None:
        if self._heartbeat is None:
            self.last_pong_ns = time.perf_counter_ns()
            self._heartbeat = asyncio.create_task(self._beat())

    async def _beat(self) -> None:
        # the motors go off within one heartbeat of the page's last answer; four pings a
        # period, so one late answer (a busy page, a loaded machine) is not a lost page
        period_ns = self.bridge.config.heartbeat_ms * 1_000_000
        ping_ns = period_ns // PINGS_PER_HEARTBEAT
        step = self.bridge.config.heartbeat_ms / 8000
        next_ping = time.perf_counter_ns()
        while True:
            now = time.perf_counter_ns()
            if now - self.last_pong_ns > period_ns:
                why = (f"no answer to the heartbeat for "
                       f"{(now - self.last_pong_ns) / 1e6:.0f} ms")
                log.warning("bridge: page %s: %s; motors off", self.remote, why)
                self.closed_reason = why
                self._heartbeat = None
                await self.bridge.release(self, why)
                with contextlib.suppress(Exception):
                    await self.ws.close(CLOSE_LOST, why[:120])
                return
            if now >= next_ping:
                self._seq += 1
                await self.send({"type": "ping", "seq": self._seq})
                next_ping = now + ping_ns
            await asyncio.sleep(step)

    # -- requests ---------------------------------------------------------------------------
    async def handle(self, msg: dict[str, Any], t_recv: int) -> dict[str, Any] | None:
        kind = msg["type"]
        if kind in ("play", "stop", "trial", "end") and request_id(msg) is None:
            raise MessageError(f"{kind}: needs an integer 'id'")
        if kind == "play":
            return await self.play(msg, t_recv)
        if kind == "stop":
            await self.bridge.belt.call(self.bridge.belt.stop)
            return {"type": "stopped", "id": request_id(msg)}
        handler = {"hello": self.hello, "status": self.status, "trial": self.trial,
                   "end": self.end}[kind]  # parse() let only the page's types through
        return await handler(msg)

    async def hello(self, msg: dict[str, Any]) -> dict[str, Any]:
        rid = request_id(msg)
        if self.recording is not None:
            raise MessageError(f"hello: this page already runs session "
                               f"{self.recording.session_id}")
        participant = check_participant(need_str(msg, "participant"))
        user_agent = opt_str(msg, "user_agent")
        page = opt_str(msg, "page")
        rec = await self.bridge.open_session(self, participant)
        self.recording = rec
        self.ended = False
        try:
            clock = await self.handshake()
        except BaseException:
            await self.bridge.release(self, "the clock handshake failed")
            raise
        info = {"connected_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "user_agent": user_agent, "browser": browser_name(user_agent), "page": page,
                "clock": clock.to_dict()}
        await self.bridge.store_call(self.bridge.keep_page, rec, info)
        done = sorted(await self.bridge.store_call(rec.finished))
        self.stored = set(done)
        self.start_heartbeat()
        self.bridge.note(
            f"session {rec.session_id} of {participant} "
            f"{'resumed' if rec.resumed else 'opened'} ({info['browser'] or 'a page'}, "
            f"{len(done)}/{len(rec.schedule)} trials done; clock +/-{clock.uncertainty_ms:.3f}"
            " ms)")
        return {"type": "welcome", "id": rid, "session_id": rec.session_id,
                "resumed": rec.resumed, "heartbeat_ms": self.bridge.config.heartbeat_ms,
                "clock": clock.to_dict(),
                "schedule": [self.bridge.trial_dict(t) for t in rec.schedule],
                "done": done}

    def stimulus(self, target_deg: float, condition: str, block_name: str | None
                 ) -> tuple[Stimulus, float]:
        """The stimulus of a target and condition with a block's ``[stimulus]`` (the
        study's without a block), as the runner makes it; its longest presentation."""
        study = self.bridge.config.study
        sp = study.stimulus if block_name is None else study.trial_stimulus(block_name)
        key = (round(float(target_deg), 9), condition, sp.law, sp.falloff_deg, sp.period_s,
               sp.transit_s)
        stim = self._stimuli.get(key)
        if stim is None:
            stim = self._stimuli[key] = make_stimulus(
                self.bridge.layout, float(target_deg), condition, sp.law, sp.falloff_deg,
                sp.period_s, sp.transit_s, profile=self.profile)
        return stim, float(sp.max_presentation_s)

    async def play(self, msg: dict[str, Any], t_recv: int) -> dict[str, Any]:
        rid = request_id(msg)
        bridge = self.bridge
        duration_ms = opt_number(msg, "duration_ms", 1.0, MAX_DURATION_MS)
        study = bridge.config.study
        index: int | None = None
        stim: Stimulus | None = None
        levels: list[float] | None = None
        target_deg: float | None = None
        condition: str | None = None
        if msg.get("index") is not None:
            rec = self._session("play")
            index = need_int(msg, "index", 0, len(rec.schedule) - 1)
            t = rec.schedule[index]
            target_deg, condition = t.target_deg, t.condition
            stim, max_s = self.stimulus(t.target_deg, t.condition, t.block_name)
            info = {"kind": "trial", **bridge.trial_dict(t)}
        elif msg.get("target") is not None or msg.get("angle_deg") is not None:
            condition = need_str(msg, "condition", ("static", "dynamic"))
            if msg.get("target") is not None:
                n = opt_int(msg, "n_targets", 1, 360) or study.targets.count
                k = need_int(msg, "target", 0, n - 1)
                target_deg = k * 360.0 / n
            else:
                n = study.targets.count
                target_deg = float(opt_number(msg, "angle_deg") or 0.0) % 360.0
            stim, max_s = self.stimulus(target_deg, condition, None)
            info = {"kind": "target", "target": _target_number(target_deg, n),
                    "n_targets": n, "angle_deg": target_deg, "condition": condition}
        elif msg.get("amplitudes") is not None:
            amps = msg.get("amplitudes")
            n_t = bridge.layout.n
            if (not isinstance(amps, list) or len(amps) != n_t
                    or not all(isinstance(a, int | float) and not isinstance(a, bool)
                               and math.isfinite(a) and 0.0 <= a <= 1.0 for a in amps)):
                raise MessageError(f"play: 'amplitudes' must be {n_t} numbers in 0..1")
            if duration_ms is None:
                raise MessageError("play: raw 'amplitudes' need a 'duration_ms'")
            levels = [float(a) for a in amps]
            max_s = duration_ms / 1000.0
            info = {"kind": "amplitudes", "amplitudes": levels}
        else:
            raise MessageError("play: give one of 'index', 'target' (with 'condition'), "
                               "'angle_deg' (with 'condition') or 'amplitudes' (with "
                               "'duration_ms')")
        duration_s = duration_ms / 1000.0 if duration_ms is not None else max_s
        clock = await self.ensure_clock()
        self.start_heartbeat()
        onset = await bridge.play(self, stim, levels, duration_s)
        skin: tuple[int, int] | None = None
        if stim is not None and bridge.has_latency:
            lat = skin_latency(bridge.belt.belt.calibration, stim)
            if lat is not None:
                skin = (onset.best_ns + round(lat[0] * 1e6),
                        round(math.hypot(lat[1] * 1e6, onset.uncertainty_ns)))
        p = _Play(rid, onset, info, index, target_deg, condition, skin)
        if rid is not None:
            self.plays[rid] = p
            if len(self.plays) > 10_000:  # a long session: keep the recent ones
                self.plays.pop(next(iter(self.plays)))
        if index is not None:
            self.by_index[index] = p
        unc_ms = clock.uncertainty_ms + onset.uncertainty_ns / 1e6
        return {"type": "played", "id": rid, "onset_ms": clock.to_page_ms(onset.best_ns),
                "onset_source": "device" if onset.device_ns is not None else "host",
                "command_ms": clock.to_page_ms(onset.onset_ns),
                "received_ms": clock.to_page_ms(t_recv),
                "skin_onset_ms": None if skin is None else clock.to_page_ms(skin[0]),
                "skin_onset_sd_ms": None if skin is None else skin[1] / 1e6,
                "uncertainty_ms": unc_ms, "duration_ms": duration_s * 1000.0,
                "stimulus": info}

    def _session(self, what: str) -> SessionRecorder:
        if self.recording is None or self.ended:
            raise MessageError(f"{what}: no session on this page; send 'hello' first")
        return self.recording

    async def status(self, msg: dict[str, Any]) -> dict[str, Any]:
        belt = await self.bridge.belt.call(self.bridge.belt.status)
        belt["url"] = self.bridge.config.belt_url
        return {"type": "status", "id": request_id(msg), "belt": belt,
                "session_id": None if self.recording is None else self.recording.session_id,
                "clock": None if self.clock is None else self.clock.to_dict()}

    async def trial(self, msg: dict[str, Any]) -> dict[str, Any]:
        rid = request_id(msg)
        rec = self._session("trial")
        index = need_int(msg, "index", 0, len(rec.schedule) - 1)
        if index in self.stored:
            raise MessageError(f"trial: trial {index} is already stored")
        resp = msg.get("response")
        if not isinstance(resp, dict):
            raise MessageError("trial: 'response' must be an object (target, angle_deg, "
                               "rt_ms, device)")
        play_id = opt_int(msg, "play_id")
        p = self.plays.get(play_id) if play_id is not None else self.by_index.get(index)
        if p is None:
            raise MessageError(f"trial: trial {index} was not played on this page"
                               + (f" (no play {play_id})" if play_id is not None else ""))
        t = rec.schedule[index]
        if p.index != index and (p.target_deg is None or p.condition != t.condition
                                 or abs(((p.target_deg - t.target_deg) + 180) % 360 - 180)
                                 > 1e-6):
            raise MessageError(f"trial: play {p.play_id} was not trial {index}'s stimulus "
                               f"({t.target_deg:g} deg, {t.condition})")
        n = t.n_targets or self.bridge.config.study.targets.count
        target = opt_int(resp, "target", 0, n - 1)
        angle = opt_number(resp, "angle_deg")
        rt_ms = opt_number(resp, "rt_ms", 0.0, 3_600_000.0)
        response_deg = (angle % 360.0 if angle is not None
                        else None if target is None else target * 360.0 / n)
        off_ns = await self.bridge.end_play(self, p.onset)
        rt_s = None if rt_ms is None else rt_ms / 1000.0
        if response_deg is not None and rt_s is None:
            raise MessageError("trial: a response needs its 'rt_ms'")
        result = rec.result_for(index, onset_ns=p.onset.onset_ns, response_deg=response_deg,
                                rt_s=rt_s, device_onset_ns=p.onset.device_ns,
                                onset_uncertainty_ns=(p.onset.uncertainty_ns
                                                      if p.onset.device_ns is not None
                                                      else None),
                                stimulus_off_ns=off_ns)
        if result.rt_s is not None and p.onset.device_ns is not None:
            # the page timed the response from the onset it was given: the device's
            result.acquired_ns = result.crossed_ns = (p.onset.device_ns
                                                      + round(result.rt_s * 1e9))
        await self.bridge.store_call(rec.record, result, p.skin)
        self.stored.add(index)
        return {"type": "stored", "id": rid, "index": index, "status": result.status,
                "correct": result.correct}

    async def end(self, msg: dict[str, Any]) -> dict[str, Any]:
        rid = request_id(msg)
        rec = self._session("end")
        status = need_str(msg, "status", ("completed", "complete", "interrupted", "aborted"))
        done = await self.bridge.store_call(rec.finished)
        if status in ("completed", "complete"):
            status = "complete" if len(done) >= len(rec.schedule) else "interrupted"
        await self.bridge.belt.call(self.bridge.belt.stop)
        await self.bridge.end_session(self, status)
        return {"type": "ended", "id": rid, "status": status,
                "n_done": len(done), "n_total": len(rec.schedule)}


def _target_number(target_deg: float, n: int) -> int:
    """The number K of the target at ``target_deg`` among ``n`` at ``k*360/n``."""
    return round(float(target_deg) * n / 360.0) % n


class _Bridge:
    """The server's state: the belt, the store, the pages."""

    def __init__(self, config: BridgeConfig, note: Callable[[str], None]) -> None:
        self.config = config
        self.note = note
        self.layout = config.study.layout_obj()
        self.belt = BeltPort(config.belt_url, self.layout, config.calibration,
                             config.study.stimulus.drive)
        self._store_exec = ThreadPoolExecutor(1, thread_name_prefix="tactorbelt-store")
        self.store: Store | None = None
        self.has_latency = False
        self.owner: _Page | None = None  # the page whose play the belt plays
        self.sessions: dict[str, _Page] = {}  # participant -> the page running it
        self.closing = False
        self.port = config.port
        self.origins: set[str] = set(config.allow_origins)

    async def store_call(self, fn: Callable[..., T], *args: Any) -> T:
        return await asyncio.get_running_loop().run_in_executor(self._store_exec, fn, *args)

    # -- the belt ---------------------------------------------------------------------------
    async def play(self, page: _Page, stim: Stimulus | None, levels: list[float] | None,
                   duration_s: float) -> Onset:
        if self.closing:
            raise TactorbeltError("the bridge is shutting down")
        self.owner = page
        if stim is not None:
            return await self.belt.call(self.belt.play_stimulus, stim, duration_s)
        assert levels is not None
        onset = await self.belt.call(self.belt.play_levels, levels, duration_s)
        self.belt.stop_later(onset)
        return onset

    async def end_play(self, page: _Page, onset: Onset) -> int:
        """A trial was answered: its stimulus stops (as in the lab, at the response)
        when it still plays; when its stimulus was off."""
        if self.owner is page and await self.belt.call(self.belt.playing, onset.play):
            return await self.belt.call(self.belt.stop)
        return min(onset.end_ns, time.perf_counter_ns())

    # -- sessions ---------------------------------------------------------------------------
    async def open_session(self, page: _Page, participant: str) -> SessionRecorder:
        other = self.sessions.get(participant)
        if other is not None and other is not page:
            # the same participant from a new page: a reload (or a second tab); the
            # newer page takes the session over
            other.closed_reason = "another page took over the session"
            await self.release(other, other.closed_reason)
            with contextlib.suppress(Exception):
                await other.ws.close(CLOSE_REPLACED, "another page took over the session")
        busy = [p for pid, p in self.sessions.items() if pid != participant]
        if busy:
            running = busy[0]
            sid = running.recording.session_id if running.recording is not None else "?"
            raise MessageError(
                f"hello: the belt runs session {sid} of another participant on another "
                "page; end or close that page first")
        rec, profile = await self.store_call(self._open, participant)
        page.profile = profile
        self.sessions[participant] = page
        return rec

    def _open(self, participant: str) -> tuple[SessionRecorder, Any]:
        """Open (or resume) the participant's session as ``tactorbelt run`` would (a
        participant with a complete session is refused, as ``run`` does without
        ``--new-session``); with its wearer profile where the study asks for one."""
        store = self.store
        assert store is not None
        study = self.config.study
        belt = self.belt.belt
        resume = store.find_resumable(participant) is not None
        site = default_site()
        if not resume:
            complete = [s for s in store.sessions(participant) if s["status"] == "complete"]
            if complete:
                raise StoreError(
                    f"participant {participant!r} has completed session "
                    f"{complete[-1]['session_number']} in {store.url}; check the "
                    "participant id")
            # a shared (PostgreSQL) store: this login writes this site, and the id is
            # this site's (as run does); a SQLite store takes any
            store.check_site(site)
            store.claim_participant(participant, site)
        profile = profile_for_session(study, store, belt, self.belt.clock, participant,
                                      None, resume=resume)
        rec = SessionRecorder.open(
            store, study, participant, input_kind=INPUT_KIND, resume=resume,
            study_toml=self.config.study_toml, belt_url=belt.session_url,
            firmware_version=belt.firmware_version, calibration=belt.calibration.to_list(),
            clock="wall", site=site)
        if profile is not None:
            rec.set_profile(profile.to_toml())
        return rec, profile

    def keep_page(self, rec: SessionRecorder, info: dict[str, Any]) -> None:
        """Keep a page's user agent and clock with its session's run options (every page
        that ran the session, the latest last)."""
        opts = rec.store.run_options(rec.session_id) or {}
        pages = list(opts.get("pages") or [])
        pages.append(info)
        rec.set_run_options({"input_kind": INPUT_KIND, "belt_url": self.config.belt_url,
                             "study": self.config.study_path, "pages": pages[-50:]})

    async def end_session(self, page: _Page, status: str) -> None:
        rec = page.recording
        if rec is None or page.ended:
            return
        page.ended = True
        if self.sessions.get(rec.participant) is page:
            del self.sessions[rec.participant]
        with contextlib.suppress(Exception):
            await self.store_call(rec.end, status)
        self.note(f"session {rec.session_id} of {rec.participant}: {status}")

    async def release(self, page: _Page, why: str) -> None:
        """A page is gone: its motors off, its session ``interrupted``."""
        if self.owner is page:
            self.owner = None
            try:
                await self.belt.call(self.belt.stop)
            except Exception as exc:
                log.warning("bridge: turning the motors off failed: %s", exc)
        if page.recording is not None and not page.ended:
            await self.end_session(page, "interrupted")
            self.note(f"  ({why}; motors off; the page can resume it)")

    def trial_dict(self, t: ScheduledTrial) -> dict[str, Any]:
        n = t.n_targets or self.config.study.targets.count
        return {"index": t.trial_index, "block": t.block, "block_index": t.block_index,
                "block_name": t.block_name, "condition": t.condition,
                "target": _target_number(t.target_deg, n), "n_targets": n,
                "angle_deg": t.target_deg, "on_tactor": t.on_tactor,
                "repetition": t.repetition, "load": t.load, "training": t.block == "training"}

    # -- HTTP and the WebSocket door --------------------------------------------------------
    def http(self, connection: ServerConnection, request: Request) -> Response | None:
        path, _, query = request.path.partition("?")
        if request.method != "GET":
            return connection.respond(405, "only GET\n")
        if path == "/ws":
            return None  # the WebSocket: token and origin are checked once accepted
        origin = request.headers.get("Origin")
        # a page hosted at an allowed origin may read the study and the plugins (CORS)
        cors = origin if origin is not None and origin in self.origins else None
        if path == "/study.json":
            token = parse_qs(query).get("token", [""])[0]
            if not secrets.compare_digest(token, self.config.token):
                log.warning("bridge: refused /study.json without the token from %s",
                            connection.remote_address)
                return connection.respond(403, "the token is missing or wrong\n")
            body = study_json(self.config.study, self.config.study_path)
            return response(200, json.dumps(body, indent=1).encode(), "application/json",
                            cors)
        if path in ("", "/"):
            path = "/index.html"
        file = static_file(self.config.static_dir, path)
        if file is None:
            return connection.respond(404, f"not found: {path}\n")
        return response(200, file.read_bytes(), content_type(file), cors)

    async def door(self, ws: ServerConnection) -> None:
        request = ws.request
        assert request is not None
        _, _, query = request.path.partition("?")
        token = parse_qs(query).get("token", [None])[0]
        origin = request.headers.get("Origin")
        why = None
        if token is None:
            why = "missing token"
        elif not secrets.compare_digest(token, self.config.token):
            why = "wrong token"
        elif origin is not None and origin not in self.origins:
            why = f"origin {origin} is not allowed"
        if why is not None:
            log.warning("bridge: refused a WebSocket connection from %s (origin %s): %s",
                        ws.remote_address[0] if ws.remote_address else "?", origin, why)
            await ws.close(CLOSE_REFUSED, why)
            return
        if self.closing:
            await ws.close(1001, "the bridge is shutting down")
            return
        await _Page(self, ws).run()

    # -- the whole run ----------------------------------------------------------------------
    async def main(self, ready: Callable[[str], None]) -> int | None:
        """Serve until a signal; the signal's number (None: the server ended)."""
        loop = asyncio.get_running_loop()
        stop = asyncio.Event()
        got: list[int] = []

        def on_signal(signum: int) -> None:
            got.append(signum)
            stop.set()

        for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
            if s is not None:
                with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                    loop.add_signal_handler(s, on_signal, int(s))
        self.store = await self.store_call(open_store, self.config.store_url)
        try:
            await self.belt.aopen()
            self.has_latency = bool(self.belt.belt.calibration.has_timing)
            async with ws_serve(self.door, self.config.host, self.config.port,
                                process_request=self.http, ping_interval=None,
                                max_size=MAX_MESSAGE_BYTES, server_header=None,
                                logger=logging.getLogger("tactorbelt.bridge.ws")) as server:
                self.port = next((int(sock.getsockname()[1]) for sock in server.sockets),
                                 self.config.port)  # port 0: the one the system gave
                self.origins |= {f"http://127.0.0.1:{self.port}", f"http://localhost:{self.port}"}
                if self.config.host not in ("127.0.0.1", "localhost", "0.0.0.0", "::"):
                    self.origins.add(f"http://{self.config.host}:{self.port}")
                ready(self.open_url())
                if not got:
                    await stop.wait()
                await self.shutdown(server)
        finally:
            self.closing = True
            await self.belt.aclose()
            with contextlib.suppress(Exception):
                await self.store_call(self.store.close)
            self._store_exec.shutdown(wait=False)
        return got[0] if got else None

    async def shutdown(self, server: Server) -> None:
        """Motors off, every open session ``interrupted``, the pages closed."""
        self.closing = True
        try:
            await self.belt.call(self.belt.stop)
            self.note("stopping: motors off")
        except Exception as exc:
            log.warning("bridge: turning the motors off failed: %s", exc)
        for page in list(self.sessions.values()):
            page.closed_reason = "the bridge stopped"
            await self.end_session(page, "interrupted")
        server.close(close_connections=True)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(server.wait_closed(), 5.0)

    def open_url(self) -> str:
        host = self.config.host
        shown = "127.0.0.1" if host in ("127.0.0.1", "0.0.0.0", "::", "localhost") else host
        if ":" in shown:
            shown = f"[{shown}]"
        return f"http://{shown}:{self.port}/{EXAMPLE_PAGE}?token={self.config.token}"


def serve(config: BridgeConfig, *, ready: Callable[[str], None],
          note: Callable[[str], None] | None = None) -> None:
    """Run the bridge until SIGINT, SIGTERM or SIGHUP (see the module docstring).

    Args:
        config: what to serve.
        ready: called once with the example page's URL (with the token) when the bridge
            listens.
        note: called with a line for the experimenter (sessions opened and ended).

    Raises:
        KeyboardInterrupt: after SIGINT (Ctrl-C), with the motors off.
        Terminated: after SIGTERM or SIGHUP, with the motors off.
        ConfigError: a bad host or port; StoreError, DeviceError: as the store, the belt.
    """
    if not 0 <= int(config.port) <= 65535:
        raise ConfigError(f"port must be in 0..65535, got {config.port}")
    if config.heartbeat_ms < 50:
        raise ConfigError(f"heartbeat must be at least 50 ms, got {config.heartbeat_ms}")
    bridge = _Bridge(config, note or (lambda line: None))
    try:
        signum = asyncio.run(bridge.main(ready))
    except OSError as exc:
        if exc.errno not in (errno.EADDRINUSE, errno.EADDRNOTAVAIL, errno.EACCES):
            raise
        raise ConfigError(f"cannot listen on {config.host}:{config.port}: {exc.strerror or exc}"
                          ) from None
    finally:
        bridge.belt.close_now()  # the last resort: nothing plays after serve()
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    if signum is not None:
        raise Terminated(signum)
