"""`tactorbelt analyze`: the files it writes, the HTML, and bad input."""

from __future__ import annotations

import base64
import csv
import json
import os
import sqlite3
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

from support.analysis import HAND_TRIALS, _rows, hand_store
from support.synthetic import (
    create_store,
    insert_samples,
    insert_session,
    insert_trials,
    synthesize_store,
)
from tactorbelt.analysis.report.analyze import analyze
from tactorbelt.analysis.tables.tables import PER_TARGET_COLUMNS

PNG = b"\x89PNG\r\n\x1a\n"


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[str] = []
        self.hrefs: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src") or "")
        if a.get("href"):
            self.hrefs.append(a["href"] or "")
        if tag in ("script", "link", "iframe") and (a.get("src") or a.get("href")):
            self.hrefs.append(a.get("src") or a.get("href") or "")

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _parse(out: Path) -> _Links:
    p = _Links()
    p.feed((out / "report.html").read_text(encoding="utf-8"))
    return p


def _check_self_contained(out: Path) -> _Links:
    p = _parse(out)
    assert p.imgs, "the report shows figures"
    for src in p.imgs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == PNG
    for href in p.hrefs:
        if href.startswith(("#", "http://", "https://", "mailto:")):
            continue
        assert (out / href).is_file(), f"report links to missing {href}"
    text = " ".join(p.text)
    assert "nan" not in text.lower().replace("nanosec", "").split(), "no NaN in tables"
    assert "NaN" not in text and " nan " not in text
    return p


def _run(args: list[str]) -> tuple[int, str, str]:
    """Run the real command line in a subprocess (exit code, stdout, stderr)."""
    proc = subprocess.run([sys.executable, "-c", "from tactorbelt.cli import main; main()",
                           *args], capture_output=True, text=True, timeout=240,
                          env={**os.environ, "MPLBACKEND": "Agg", "COLUMNS": "120"})
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def several_out(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("rep")
    db = base / "study.sqlite"
    synthesize_store(db, 4, repetitions=2, seed=2, timeout_rate=0.05)
    out = base / "out"
    analyze([db], out, seed=0, n_boot=500)
    return db, out


def test_analyze_writes_every_output(several_out: tuple[Path, Path]) -> None:
    _, out = several_out
    for name in ("report.html", "summary.json", "per_target.csv", "fig1b.png", "polar.png",
                 "confusion.png", "trajectories.png", "paired.png"):
        assert (out / name).is_file(), name
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == PNG


def test_report_is_self_contained_and_names_what_it_covers(several_out: tuple[Path, Path]) -> None:
    db, out = several_out
    p = _check_self_contained(out)
    assert len(p.imgs) == 5
    text = " ".join(p.text)
    con = sqlite3.connect(db)
    n_timeout = con.execute("SELECT count(*) FROM trials WHERE status = 'timeout'").fetchone()[0]
    con.close()
    assert "4 participant(s), 4 session(s)" in text
    assert f"Timed-out trials ({n_timeout})" in text
    assert "count as incorrect" in text and "aborted' trials are left out" in text
    assert "Wilcoxon signed-rank test" in text
    assert "SHA-256" in text and "Provenance" in text


def test_summary_json_headline_numbers(several_out: tuple[Path, Path]) -> None:
    _, out = several_out
    j = json.loads((out / "summary.json").read_text())
    for cond in ("static", "dynamic"):
        for kind in ("on_tactor", "between_tactor"):
            e = j["conditions"][cond][kind]
            assert 0 <= e["accuracy"] <= 1 and e["median_rt_s"] > 0
    t = j["between_accuracy_test"]
    assert t["computed"] and 0 <= t["p_value"] <= 1 and len(t["ci95"]) == 2
    assert j["counts"]["participants"] == 4 and j["counts"]["sessions"] == 4
    assert j["simulated_model_data"] is False


def test_per_target_csv_recomputed_from_trials(several_out: tuple[Path, Path]) -> None:
    db, out = several_out
    with (out / "per_target.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == PER_TARGET_COLUMNS
    con = sqlite3.connect(db)
    q = ("SELECT s.participant, t.condition, t.target_deg, t.on_tactor, count(*), "
         "avg(CASE WHEN t.status = 'done' AND t.correct = 1 THEN 1.0 ELSE 0.0 END) "
         "FROM trials t JOIN sessions s USING(session_id) WHERE t.block = 'test' AND "
         "t.status IN ('done', 'timeout') GROUP BY 1, 2, 3")
    ref = {(p, c, float(tg)): (on, n, acc) for p, c, tg, on, n, acc in con.execute(q)}
    con.close()
    assert len(rows) == len(ref)
    for r in rows:
        on, n, acc = ref[(r["participant"], r["condition"], float(r["target_deg"]))]
        assert int(r["on_tactor"]) == on and int(r["n"]) == n
        assert float(r["accuracy"]) == pytest.approx(acc)


def test_cli_analyze_prints_table_and_report_path(tmp_path: Path) -> None:
    db = hand_store(tmp_path / "hand.sqlite")
    out = tmp_path / "rep"
    code, stdout, stderr = _run(["analyze", str(db), "--out", str(out), "--seed", "3"])
    assert code == 0, stderr
    assert f"report: {(out / 'report.html').resolve()}" in stdout
    assert "between-tactor" in stdout and "Fisher's exact test" in stdout
    assert "Traceback" not in stderr
    _check_self_contained(out)
    assert not (out / "paired.png").exists()  # one participant: no paired plot


def test_cli_bad_inputs_say_what_is_wrong(tmp_path: Path) -> None:
    text = tmp_path / "notes.sqlite"
    text.write_text("not a database")
    empty = tmp_path / "empty.sqlite"
    create_store(empty).close()
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE x(a)")
    con.close()
    for path, msg in ((text, "not an SQLite database"), (empty, "empty store"),
                      (other, "not a tactorbelt store"),
                      (tmp_path / "missing.sqlite", "no such file")):
        code, _, stderr = _run(["analyze", str(path), "--out", str(tmp_path / "o")])
        assert code == 2, stderr
        assert stderr.startswith("error: ") and msg in stderr
        assert "Traceback" not in stderr


def test_no_test_trials_gives_a_report_that_says_so(tmp_path: Path) -> None:
    db = tmp_path / "training.sqlite"
    conn = create_store(db)
    sid = insert_session(conn, status="interrupted", ended_at=None)
    insert_trials(conn, _rows(sid, [t for t in HAND_TRIALS if t[0] == "training"]))
    conn.close()
    out = tmp_path / "o"
    summary = analyze([db], out)
    assert not summary.between_accuracy_test.computed
    p = _check_self_contained(out)
    text = " ".join(p.text)
    assert "not computed" in text and "no test-block trial" in text
    assert "Incomplete sessions (1)" in text and "interrupted" in text
    j = json.loads((out / "summary.json").read_text())
    assert j["between_accuracy_test"]["computed"] is False
    assert j["conditions"]["static"]["between_tactor"]["accuracy"] is None
    with (out / "per_target.csv").open() as fh:
        assert fh.readline().strip() == ",".join(PER_TARGET_COLUMNS)


def test_only_one_condition_report_says_what_it_could_not_compute(tmp_path: Path) -> None:
    db = tmp_path / "static.sqlite"
    conn = create_store(db)
    sid = insert_session(conn)
    insert_trials(conn, _rows(sid, [t for t in HAND_TRIALS if t[1] == "static"]))
    conn.close()
    out = tmp_path / "o"
    analyze([db], out)
    text = " ".join(_check_self_contained(out).text)
    assert "no dynamic between-tactor test trials" in text
    assert "no dynamic test trials" in text


def test_model_participant_data_are_called_simulated(tmp_path: Path) -> None:
    db = tmp_path / "model.sqlite"
    synthesize_store(db, 3, repetitions=1, participant_prefix="model-", samples=False,
                     belt="sim")
    out = tmp_path / "o"
    summary = analyze([db], out, n_boot=200)
    assert summary.simulated
    text = " ".join(_check_self_contained(out).text)
    assert "answered by the model participant, not by people" in text
    j = json.loads((out / "summary.json").read_text())
    assert j["simulated_model_data"] is True and j["simulated_sessions"] == 3


@pytest.mark.parametrize(("belt", "person_on_sim"), [("sim", True), ("sim:virtual", True),
                                                     ("serial:/dev/ttyACM0", False)])
def test_a_person_is_never_called_a_model_participant(tmp_path: Path, belt: str,
                                                      person_on_sim: bool) -> None:
    """A mouse session on the sim belt is a person's data on a belt that did not vibrate,
    not the model participant's (as it was once labelled)."""
    db = hand_store(tmp_path / "person.sqlite", participant="P01", input="mouse", belt=belt)
    out = tmp_path / "o"
    summary = analyze([db], out, n_boot=200)
    j = json.loads((out / "summary.json").read_text())
    assert j["simulated_model_data"] is False and j["simulated_sessions"] == 0
    assert j["simulated_belt_sessions"] == int(person_on_sim)
    text = " ".join(_check_self_contained(out).text)
    assert "model participant" not in text.lower()
    assert ("no motor vibrated" in text) is person_on_sim
    assert not summary.simulated


def test_trajectory_figure_reads_samples_of_chosen_trials(tmp_path: Path) -> None:
    db = tmp_path / "s.sqlite"
    conn = create_store(db)
    sid = insert_session(conn)
    insert_trials(conn, _rows(sid, HAND_TRIALS))
    for tid in range(1, len(HAND_TRIALS) + 1):
        insert_samples(conn, tid, [0.0, 0.5, 1.0], [0.0, 0.2, 0.5], [0.0, 0.5, 0.9])
    conn.close()
    out = tmp_path / "o"
    analyze([db], out, n_boot=100)
    assert (out / "trajectories.png").read_bytes()[:8] == PNG


def test_analyze_into_a_file_is_an_error(tmp_path: Path) -> None:
    db = hand_store(tmp_path / "hand.sqlite")
    f = tmp_path / "file.txt"
    f.write_text("x")
    code, _, stderr = _run(["analyze", str(db), "--out", str(f)])
    assert code == 2 and "is a file" in stderr


def test_all_timed_out_is_said_in_words_not_nan(tmp_path: Path) -> None:
    db = tmp_path / "timeouts.sqlite"
    conn = create_store(db)
    sid = insert_session(conn)
    rows = [("test", cond, t, int(t % 60 == 30), None, None, None, "timeout")
            for cond in ("static", "dynamic") for t in (0.0, 15.0, 30.0)]
    insert_trials(conn, _rows(sid, rows))
    conn.close()
    out = tmp_path / "o"
    analyze([db], out, n_boot=100)
    j = json.loads((out / "summary.json").read_text())
    e = j["conditions"]["static"]["between_tactor"]
    assert e["accuracy"] == 0.0 and e["median_rt_s"] is None and "timed out" in e["note"]
    text = " ".join(_check_self_contained(out).text)
    assert "no answered trial" in text
    t = j["tests"][1]
    assert t["key"] == "between_rt" and t["computed"] is False
    assert "no answered trial" in t["reason"]


def test_report_tables_speak_words_not_columns_or_json(tmp_path: Path) -> None:
    """The provenance table has no empty header row; the sessions table names its columns
    in words and shows a block order as a list, not JSON."""
    import html.parser

    db = hand_store(tmp_path / "hand.sqlite", condition_order='["static", "dynamic"]')
    out = tmp_path / "o"
    analyze([db], out, n_boot=200)
    page = (out / "report.html").read_text()

    class Headers(html.parser.HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.rows: list[list[str]] = []
            self.in_th = False

        def handle_starttag(self, tag: str, attrs: object) -> None:
            if tag == "tr":
                self.rows.append([])
            self.in_th = tag == "th"

        def handle_endtag(self, tag: str) -> None:
            self.in_th = False

        def handle_data(self, data: str) -> None:
            if self.in_th:
                self.rows[-1].append(data)

    p = Headers()
    p.feed(page)
    header_rows = [r for r in p.rows if r]
    assert all(any(h.strip() for h in r) for r in header_rows)
    assert "<th></th>" not in page
    assert "session_key" not in page and "condition_order" not in page
    assert "static, dynamic" in page and '["static", "dynamic"]' not in page


def test_stored_text_is_shown_as_text_never_as_markup(tmp_path: Path) -> None:
    """The report's template escapes every stored value: a participant id or study name
    holding markup is shown as those characters, not run as HTML."""
    db = hand_store(tmp_path / "hand.sqlite", participant="<b>P&1</b>",
                    study_name="<script>alert(1)</script>")
    out = tmp_path / "o"
    analyze([db], out, n_boot=200)
    page = (out / "report.html").read_text()
    assert "&lt;b&gt;P&amp;1&lt;/b&gt;" in page and "<b>P&1</b>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page and "<script>" not in page
    _check_self_contained(out)
