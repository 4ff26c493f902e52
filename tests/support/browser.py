"""A real browser on the bridge: ``tactorbelt serve`` in a subprocess and Debian's headless
Chromium driven by Selenium through ``chromium-driver`` (tests/test_browser.py,
benchmarks/bench_browser.py).

    reason = browser_missing()            # None, or why the browser tests skip
    with serve(study, db) as bridge:      # the `open:` URL, the token, the port
        with chromium() as driver:
            result = answer_page(driver, bridge.page_url("P01"))

Selenium is given the system's chromedriver and chromium (it never downloads a browser).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

CHROMIUM = ("chromium", "chromium-browser")
CHROMEDRIVER = "chromedriver"


def _which(names: Sequence[str]) -> str | None:
    for name in names:
        path = shutil.which(name)
        if path:
            return path
    return None


def browser_missing() -> str | None:
    """Why a browser test cannot run here, or None."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[dev]')"
    if _which(CHROMIUM) is None:
        return "Chromium is not installed (apt-get install chromium chromium-driver)"
    if _which([CHROMEDRIVER]) is None:
        return "ChromeDriver is not installed (apt-get install chromium-driver)"
    return None


@dataclass
class Bridge:
    """A running ``tactorbelt serve``: its process, its printed `open:` URL, its output."""

    proc: subprocess.Popen[str]
    open_url: str
    lines: list[str] = field(default_factory=list)

    @property
    def port(self) -> int:
        port = urlsplit(self.open_url).port
        assert port is not None
        return port

    @property
    def origin(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def token(self) -> str:
        query = urlsplit(self.open_url).query
        return dict(p.split("=", 1) for p in query.split("&") if "=" in p)["token"]

    def page_url(self, participant: str, **query: Any) -> str:
        extra = "".join(f"&{k}={v}" for k, v in query.items())
        return f"{self.open_url}&participant={participant}{extra}"

    def ws_url(self, token: str | None = "") -> str:
        t = self.token if token == "" else token
        return f"ws://127.0.0.1:{self.port}/ws" + ("" if t is None else f"?token={t}")

    def output(self) -> str:
        return "\n".join(self.lines)

    def request(self, message: dict[str, Any], timeout: float = 10.0) -> dict[str, Any]:
        """One request on a connection of its own (as a page from the bridge's origin)."""
        from websockets.sync.client import connect

        with connect(self.ws_url(), origin=self.origin, open_timeout=timeout) as ws:  # type: ignore[arg-type]
            ws.send(json.dumps({"id": 1, **message}))
            deadline = time.monotonic() + timeout
            while True:
                reply = json.loads(ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
                if reply.get("type") == "ping":
                    ws.send(json.dumps({"type": "pong", "seq": reply["seq"],
                                        "t_page_ms": time.perf_counter() * 1e3}))
                elif reply.get("id") == 1:
                    return dict(reply)

    def belt_status(self) -> dict[str, Any]:
        reply = self.request({"type": "status"})
        assert reply["type"] == "status", reply
        return dict(reply["belt"])


@contextlib.contextmanager
def serve(study: Path, store: Path, *args: str, python: str | None = None,
          command: Sequence[str] | None = None, timeout: float = 60.0,
          env: dict[str, str] | None = None) -> Iterator[Bridge]:
    """``tactorbelt serve --belt sim`` on a free port (``--port 0``: the `open:` line says
    which) until the block ends (SIGTERM)."""
    cmd = [*(command or [python or sys.executable, "-m", "tactorbelt"]), "serve",
           "--belt", "sim", "--store", str(store), "--study", str(study), "--port", "0", *args]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**(os.environ if env is None else env),
                                 "PYTHONUNBUFFERED": "1"}, cwd=store.parent)
    lines: list[str] = []
    opened = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if line.startswith("open: "):
                opened.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + timeout
        while not opened.wait(0.1):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError("tactorbelt serve printed no `open:` line:\n"
                                     + "\n".join(lines))
        url = next(ln for ln in lines if ln.startswith("open: ")).removeprefix("open: ").strip()
        yield Bridge(proc, url, lines)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        reader.join(timeout=5)


@contextlib.contextmanager
def chromium(width: int = 1000, height: int = 800) -> Iterator[Any]:
    """Headless Chromium through the system's ChromeDriver."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(_which(CHROMIUM))
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                f"--window-size={width},{height}", "--no-first-run",
                "--disable-background-timer-throttling", "--disable-renderer-backgrounding"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(str(_which([CHROMEDRIVER]))), options=options)
    driver.set_script_timeout(30)
    try:
        yield driver
    finally:
        driver.quit()


@dataclass
class PageRun:
    state: str
    error: str | None
    clicks: int
    data: list[dict[str, Any]]
    welcome: dict[str, Any]

    def of_type(self, kind: str) -> list[dict[str, Any]]:
        return [d for d in self.data if d.get("tactorbelt") == kind]


def page_state(driver: Any) -> str:
    return str(driver.execute_script("return window.tactorbelt && window.tactorbelt.state"))


def answer_page(driver: Any, url: str, timeout: float = 120.0) -> PageRun:
    """Open the example page and click a target on every response screen until the page
    is done (or stopped with an error); the k-th answer is target k mod n."""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.common.by import By

    driver.get(url)
    deadline = time.monotonic() + timeout
    clicks = 0
    state = page_state(driver)
    while state not in ("done", "error"):
        if time.monotonic() > deadline:
            raise AssertionError(f"the page did not finish within {timeout} s (state {state})")
        targets = driver.find_elements(By.CSS_SELECTOR, "[data-target]")
        if targets:
            with contextlib.suppress(WebDriverException):  # the screen went meanwhile
                targets[clicks % len(targets)].click()
                clicks += 1
        else:
            time.sleep(0.01)
        state = page_state(driver)
    info = driver.execute_script(
        "return {error: window.tactorbelt.error, data: window.tactorbelt.data || [],"
        " welcome: window.tactorbelt.welcome}")
    return PageRun(state, info["error"], clicks, info["data"], info["welcome"] or {})


def store_rows(db: Path, participant: str) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The participant's last session and its trials, as the store holds them."""
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    con.row_factory = sqlite3.Row
    try:
        session = con.execute("SELECT * FROM sessions WHERE participant = ? "
                              "ORDER BY session_id DESC LIMIT 1", (participant,)).fetchone()
        assert session is not None, f"no session of {participant} in {db}"
        trials = con.execute("SELECT * FROM trials WHERE session_id = ? ORDER BY trial_index",
                             (session["session_id"],)).fetchall()
        return dict(session), [dict(t) for t in trials]
    finally:
        con.close()
