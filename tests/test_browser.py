"""The browser study in a real browser: ``tactorbelt serve`` on the sim belt, the example
page (web/examples/paper.html, from the package's bridge/static) in Debian's headless
Chromium driven by Selenium, every trial answered by clicking a ``[data-target]``.

Checks the page's jsPsych data against the store (every trial stored once, with the
response the page sent and the onset it was given), the refusals a browser meets (no
token, wrong token, another origin: close code 1008), and that a tab closed or hung while
a stimulus plays turns the motors off. The wheel test builds the wheel, installs it into
a fresh venv and serves the example from there. Skips with the reason where Chromium,
ChromeDriver or selenium are missing.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import math
import os
import shutil
import subprocess
import sys
import threading
import time
import urllib.request
import venv
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from support.browser import (
    Bridge,
    answer_page,
    browser_missing,
    chromium,
    page_state,
    serve,
    store_rows,
)
from support.studies import write_study

ROOT = Path(__file__).resolve().parents[1]
STATIC = ROOT / "src" / "tactorbelt" / "bridge" / "static"
MISSING = browser_missing()
needs_browser = pytest.mark.skipif(MISSING is not None, reason=MISSING or "")

# Chromium gives pages performance.now() in steps of 100 us (5 us when cross-origin
# isolated): the handshake's pong stamps and the page's own stamps may each be a step off
PAGE_CLOCK_STEP_MS = 0.1


def short_study(directory: Path) -> Path:
    """4 targets; one static training pass, one static and one dynamic block: 12 trials."""
    return write_study(directory, targets=4, repetitions=1, training=1,
                       training_conditions=["static"], break_every=0, iti_s=0.05)


@pytest.fixture(scope="module")
def bridge(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bridge]:
    if MISSING is not None:
        pytest.skip(MISSING)
    tmp = tmp_path_factory.mktemp("browser")
    with serve(short_study(tmp), tmp / "study.sqlite") as b:
        yield b


@pytest.fixture(scope="module")
def driver(bridge: Bridge) -> Iterator[Any]:
    with chromium() as d:
        yield d


@pytest.fixture(scope="module")
def paper_run(bridge: Bridge, driver: Any) -> Any:
    return answer_page(driver, bridge.page_url("P01", message_ms=50), timeout=120)


def _wait(cond: Any, timeout: float, step: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(step)
    return bool(cond())


def _click_until_stored(driver: Any, db: Path, participant: str, n: int) -> bool:
    """True once the store holds n trials of the participant; until then clicks the first
    target on the screen, if one is there."""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.common.by import By

    try:
        if len(store_rows(db, participant)[1]) >= n:
            return True
    except AssertionError:  # no session yet: the page is still saying hello
        pass
    with contextlib.suppress(WebDriverException, IndexError):
        driver.find_elements(By.CSS_SELECTOR, "[data-target]")[0].click()
    return False


# -- the paper's protocol, answered by clicks -------------------------------------------

@needs_browser
def test_the_page_runs_the_schedule_and_shows_done(bridge: Bridge, driver: Any,
                                                   paper_run: Any) -> None:
    from selenium.webdriver.common.by import By

    assert paper_run.state == "done", (paper_run.error, bridge.output())
    assert driver.find_element(By.ID, "tactorbelt-done").is_displayed()
    # the page runs the study file's timing: its ITI and response timeout
    settings = driver.execute_script("return window.tactorbelt.settings")
    assert settings == {"iti_ms": 50, "message_ms": 50, "timeout_ms": 10000}
    schedule = paper_run.welcome["schedule"]
    assert len(schedule) == 12
    # training first, then the test blocks in the study's order for P01
    blocks = [s["block_name"] for s in schedule]
    assert blocks == ["training"] * 4 + ["static"] * 4 + ["dynamic"] * 4
    responses = paper_run.of_type("response")
    assert [r["index"] for r in responses] == list(range(12))
    assert all(r["stored"] and r["device"] == "mouse" for r in responses)
    # every answer was a click on the screen's targets (0..3)
    assert {r["response"] for r in responses} <= {0, 1, 2, 3}


@needs_browser
def test_every_trial_is_stored_once_as_the_page_answered_it(bridge: Bridge,
                                                            paper_run: Any) -> None:
    db = Path(bridge.proc.args[bridge.proc.args.index("--store") + 1])
    session, trials = store_rows(db, "P01")
    assert session["input"] == "browser"
    assert session["status"] == "complete"
    assert [t["trial_index"] for t in trials] == list(range(12))
    by_index = {r["index"]: r for r in paper_run.of_type("response")}
    schedule = {s["index"]: s for s in paper_run.welcome["schedule"]}
    for t in trials:
        page = by_index[t["trial_index"]]
        assert t["status"] == "done"
        assert t["target_deg"] == pytest.approx(schedule[t["trial_index"]]["angle_deg"])
        assert t["response_deg"] == pytest.approx(page["response"] * 90.0)
        assert t["rt_s"] == pytest.approx(page["rt_ms"] / 1000.0, abs=1e-9)
        assert t["rt_s"] > 0


@needs_browser
def test_onsets_are_on_the_page_clock_within_the_handshake(bridge: Bridge,
                                                           paper_run: Any) -> None:
    clock = paper_run.welcome["clock"]
    assert clock["pings"] >= 8 and clock["uncertainty_ms"] == pytest.approx(clock["rtt_ms"] / 2)
    db = Path(bridge.proc.args[bridge.proc.args.index("--store") + 1])
    _, trials = store_rows(db, "P01")
    stored = {t["trial_index"]: t for t in trials}
    stimuli = paper_run.of_type("stimulus")
    assert len(stimuli) == 12
    tol = clock["uncertainty_ms"] + 2 * PAGE_CLOCK_STEP_MS
    for s in stimuli:
        t = stored[s["index"]]
        assert s["clock_offset_ms"] == clock["offset_ms"]
        assert s["clock_uncertainty_ms"] == clock["uncertainty_ms"]
        # the onset the page got is the stored one, moved onto the page clock
        best_ns = t["device_onset_ns"] if t["device_onset_ns"] is not None else t["onset_ns"]
        assert s["onset_source"] == ("device" if t["device_onset_ns"] is not None else "host")
        assert s["onset_ms"] == pytest.approx(best_ns / 1e6 + clock["offset_ms"], abs=1e-3)
        # ... and it lies, on the page's own clock, between the play request leaving the
        # page and its reply arriving (the belt started the stimulus in between)
        assert s["request_ms"] - tol <= s["onset_ms"] <= s["reply_ms"] + tol, s
        assert math.isfinite(s["onset_uncertainty_ms"])


@needs_browser
def test_a_reload_resumes_and_every_trial_is_still_stored_once(bridge: Bridge, driver: Any,
                                                                paper_run: Any) -> None:
    from selenium.webdriver.common.by import By

    url = bridge.page_url("P06", message_ms=50)
    driver.get(url)
    db = Path(bridge.proc.args[bridge.proc.args.index("--store") + 1])
    for n in (1, 2):  # two trials answered and stored (a click only while fewer are:
        # the next trial's screen comes only after the bridge stored this one)
        assert _wait(lambda n=n: _click_until_stored(driver, db, "P06", n), 30), \
            bridge.output()
    # the third trial's stimulus plays, its response screen is up: reload the page
    assert _wait(lambda: driver.execute_script(
        "const p = window.tactorbelt.bridge.lastPlay; return p && p.request.index === 2"), 30)
    assert _wait(lambda: driver.find_elements(By.CSS_SELECTOR, "[data-target]"), 30)
    run = answer_page(driver, url, timeout=120)  # the reload
    assert run.state == "done", (run.error, bridge.output())
    assert run.welcome["resumed"] is True
    assert sorted(run.welcome["done"]) == [0, 1]
    assert [r["index"] for r in run.of_type("response")] == list(range(2, 12))
    session, trials = store_rows(db, "P06")
    assert session["status"] == "complete"
    assert [t["trial_index"] for t in trials] == list(range(12))


@needs_browser
def test_a_touch_screen_tap_answers_with_device_touch(bridge: Bridge, driver: Any,
                                                     paper_run: Any) -> None:
    from selenium.webdriver.common.actions import interaction
    from selenium.webdriver.common.actions.action_builder import ActionBuilder
    from selenium.webdriver.common.actions.pointer_input import PointerInput
    from selenium.webdriver.common.by import By

    driver.get(bridge.page_url("P07", message_ms=50))
    assert _wait(lambda: driver.find_elements(By.CSS_SELECTOR, "[data-target]"), 30)
    target = driver.find_elements(By.CSS_SELECTOR, "[data-target]")[1]
    k = int(target.get_attribute("data-target"))
    finger = PointerInput(interaction.POINTER_TOUCH, "finger")
    actions = ActionBuilder(driver, mouse=finger)
    actions.pointer_action.move_to(target).pointer_down().pointer_up()
    actions.perform()
    values = "return window.tactorbelt.jsPsych.data.get().filter({tactorbelt: 'response'}).values()"
    assert _wait(lambda: driver.execute_script(values), 20)
    (answer,) = driver.execute_script(values)
    assert answer["device"] == "touch" and answer["stored"] is True
    assert answer["response"] == k
    driver.get("about:blank")


# -- refusals ------------------------------------------------------------------------------

_OPEN_SOCKET = """
const done = arguments[arguments.length - 1];
const ws = new WebSocket(arguments[0]);
const timer = setTimeout(() => done({code: null, reason: "no close within 10 s"}), 10000);
ws.onclose = (e) => { clearTimeout(timer); done({code: e.code, reason: e.reason}); };
"""


@needs_browser
def test_a_socket_without_the_token_or_with_a_wrong_one_is_closed_1008(
        bridge: Bridge, driver: Any, paper_run: Any) -> None:
    driver.get(f"{bridge.origin}/examples/paper.html?token={bridge.token}")  # asks for an id
    assert _wait(lambda: page_state(driver) == "asking", 10)
    for url in (bridge.ws_url(None), bridge.ws_url("wrong-token")):
        closed = driver.execute_async_script(_OPEN_SOCKET, url)
        assert closed["code"] == 1008, (url, closed)
        assert closed["reason"], closed


class _Blank(http.server.BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        body = b"<!doctype html><title>elsewhere</title><p>another origin</p>"
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args: Any) -> None:
        pass


@needs_browser
def test_a_page_from_another_origin_is_closed_1008_even_with_the_token(
        bridge: Bridge, driver: Any, paper_run: Any) -> None:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Blank)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        driver.get(f"http://127.0.0.1:{server.server_address[1]}/")
        closed = driver.execute_async_script(_OPEN_SOCKET, bridge.ws_url())
        assert closed["code"] == 1008, closed
        assert closed["reason"], closed
    finally:
        server.shutdown()
        server.server_close()


@needs_browser
def test_a_page_hosted_elsewhere_reaches_the_bridge_it_names(tmp_path: Path) -> None:
    """The static files on another web server (another origin); the page names the bridge
    (?bridge=HOST:PORT), which allows that origin: the trial is played and stored."""
    from selenium.webdriver.common.by import By

    handler = functools.partial(_Quiet, directory=str(STATIC))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    origin = f"http://127.0.0.1:{server.server_address[1]}"
    db = tmp_path / "hosted.sqlite"
    try:
        with serve(short_study(tmp_path), db, "--allow-origin", origin) as b, \
                chromium() as driver:
            driver.get(f"{origin}/examples/paper.html?bridge=127.0.0.1:{b.port}"
                       f"&token={b.token}&participant=P05&message_ms=50")
            assert _wait(lambda: driver.find_elements(By.CSS_SELECTOR, "[data-target]"), 30), \
                (page_state(driver), b.output())
            driver.find_elements(By.CSS_SELECTOR, "[data-target]")[0].click()
            assert _wait(lambda: len(store_rows(db, "P05")[1]) == 1, 20), b.output()
    finally:
        server.shutdown()
        server.server_close()


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args: Any) -> None:
        pass


# -- a page that goes away mid-stimulus ----------------------------------------------------

def _start_and_wait_for_stimulus(driver: Any, url: str) -> None:
    from selenium.webdriver.common.by import By

    driver.get(url)
    # the response screen appears once the belt has started the trial's stimulus
    assert _wait(lambda: driver.find_elements(By.CSS_SELECTOR, "[data-target]"), 30), \
        page_state(driver)


@needs_browser
def test_closing_the_tab_mid_stimulus_turns_the_motors_off(bridge: Bridge, driver: Any,
                                                           paper_run: Any) -> None:
    first = driver.current_window_handle
    driver.switch_to.new_window("tab")
    try:
        _start_and_wait_for_stimulus(driver, bridge.page_url("P02", message_ms=50))
        assert bridge.belt_status()["playing"] is True
        driver.close()
    finally:
        driver.switch_to.window(first)
    # the socket's close (or, at the latest, the missed heartbeat) stops the belt
    assert _wait(lambda: not bridge.belt_status()["playing"], 10), bridge.output()
    db = Path(bridge.proc.args[bridge.proc.args.index("--store") + 1])
    assert _wait(lambda: store_rows(db, "P02")[0]["status"] == "interrupted", 10)


@needs_browser
def test_a_page_that_stops_answering_turns_the_motors_off_within_the_heartbeat(
        bridge: Bridge, driver: Any, paper_run: Any) -> None:
    from selenium.webdriver.common.by import By

    _start_and_wait_for_stimulus(driver, bridge.page_url("P03", message_ms=50))
    assert bridge.belt_status()["playing"] is True
    heartbeat_s = driver.execute_script("return window.tactorbelt.welcome.heartbeat_ms") / 1000
    # the page's only thread spins: no pong answers the heartbeat's pings
    spin_ms = 3 * heartbeat_s * 1000 + 2000
    driver.execute_script("setTimeout(() => { const t = performance.now();"
                          f" while (performance.now() - t < {spin_ms}); }}, 0);")
    assert _wait(lambda: not bridge.belt_status()["playing"], 3 * heartbeat_s + 10), \
        bridge.output()
    # when the page runs again it learns why (the bridge closed it: 4000) and says so
    assert _wait(lambda: page_state(driver) == "error", 30)
    assert "4000" in driver.find_element(By.ID, "tactorbelt-error").text
    driver.get("about:blank")


# -- the wheel -----------------------------------------------------------------------------

def _static_files() -> list[Path]:
    return sorted(p for p in STATIC.rglob("*") if p.is_file())


@pytest.mark.slow
def test_the_wheel_serves_the_example_page_and_bundles(tmp_path: Path) -> None:
    """Build the wheel, install it (not editable) into a fresh venv, run `tactorbelt serve`
    from there: the pages and bundles it serves are the package's, and (with Chromium)
    the example runs its first trial."""
    # no PYTHONPATH a caller may have set: src/ must not shadow the installed wheel
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    wheels = tmp_path / "wheels"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(ROOT)],
        capture_output=True, text=True, timeout=600, env=env)
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = wheels.glob("tactorbelt-*.whl")
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / ("Scripts" if os.name == "nt" else "bin") / "python"
    install = subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel)],
                             capture_output=True, text=True, timeout=600, env=env)
    assert install.returncode == 0, install.stderr[-2000:]
    # the dependencies come from this interpreter's site-packages, after the venv's own
    # (a path line: the editable install's .pth hooks there are not run), so the tactorbelt
    # imported is the wheel's
    purelib = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = subprocess.run([str(py), "-c", purelib], capture_output=True, text=True,
                          timeout=60, env=env).stdout.strip()
    deps = subprocess.run([sys.executable, "-c", purelib], capture_output=True, text=True,
                          timeout=60, env=env).stdout.strip()
    (Path(site) / "dev-deps.pth").write_text(deps + "\n")
    where = subprocess.run([str(py), "-c", "import tactorbelt; print(tactorbelt.__file__)"],
                           capture_output=True, text=True, timeout=60, cwd=tmp_path, env=env)
    assert where.stdout.startswith(site), where.stdout + where.stderr
    study = short_study(tmp_path)
    with serve(study, tmp_path / "study.sqlite", command=[str(py), "-m", "tactorbelt"],
               env=env) as b:
        for path in _static_files():
            rel = path.relative_to(STATIC).as_posix()
            with urllib.request.urlopen(f"{b.origin}/{rel}", timeout=30) as response:
                assert response.status == 200, rel
                assert response.read() == path.read_bytes(), rel
        if MISSING is not None:
            return  # the files are served; the page itself needs the browser
        from selenium.webdriver.common.by import By

        with chromium() as driver:
            driver.get(b.page_url("W01", message_ms=50))
            assert _wait(lambda: driver.find_elements(By.CSS_SELECTOR, "[data-target]"), 30), \
                (page_state(driver), b.output())
            driver.find_elements(By.CSS_SELECTOR, "[data-target]")[0].click()
            assert _wait(lambda: store_rows(tmp_path / "study.sqlite", "W01")[1], 20)


# -- the committed bundles ------------------------------------------------------------------

def test_the_committed_bundles_equal_a_fresh_build() -> None:
    """web/'s build, run in memory, gives the files committed in bridge/static (`make web`
    rebuilds them). Needs node and web/'s node_modules (`npm ci` in web/)."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (apt-get install nodejs npm)")
    if not (ROOT / "web" / "node_modules" / "esbuild").is_dir():
        pytest.skip("web/node_modules is missing (run `npm ci` in web/)")
    check = subprocess.run([node, "scripts/build.mjs", "--check"], cwd=ROOT / "web",
                           capture_output=True, text=True, timeout=300)
    assert check.returncode == 0, check.stdout + check.stderr


def test_the_package_carries_the_pages_and_bundles() -> None:
    names = {p.relative_to(STATIC).as_posix() for p in _static_files()}
    assert {"examples/paper.html", "vendor/jspsych.js", "vendor/jspsych.css",
            "vendor/LICENSE-jspsych.txt", "plugins/jspsych-plugin-tactile.js",
            "plugins/jspsych-plugin-tactile.mjs", "plugins/jspsych-plugin-belt-response.js",
            "plugins/jspsych-plugin-belt-response.mjs", "plugins/bridge-client.js"} <= names
    assert (STATIC / "examples" / "paper.html").read_bytes() == \
        (ROOT / "web" / "examples" / "paper.html").read_bytes()
    assert "MIT" in (STATIC / "vendor" / "LICENSE-jspsych.txt").read_text()
