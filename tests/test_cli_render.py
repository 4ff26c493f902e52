import io
import json
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from tactorbelt.cli import main


def run(*args):
    """Run the CLI in-process like the console script; return (code, stdout, stderr)."""
    runner = CliRunner()
    result = runner.invoke(_entry, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


import click  # noqa: E402


@click.command(context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.pass_context
def _entry(ctx):
    main(ctx.args)


@pytest.mark.parametrize("deg", [15, 60])
def test_cli_csv_matches_golden(reference_dir, deg):
    code, out, _ = run("render", str(deg), "--mode", "dynamic")
    assert code == 0
    assert out.splitlines()[0] == "t_s,tactor_0,tactor_1,tactor_2,tactor_3,tactor_4,tactor_5"
    assert out.splitlines()[1].split(",")[1] == "0.981684361"  # 9 decimals
    got = np.loadtxt(io.StringIO(out), delimiter=",", skiprows=1)
    ref = np.loadtxt(reference_dir / f"paper_law_dynamic_{deg}deg_1000hz.csv",
                     delimiter=",", skiprows=1)
    np.testing.assert_allclose(got, ref, atol=1e-6)


def test_cli_static_golden(reference_dir):
    ref = np.loadtxt(reference_dir / "paper_law_static_24.csv", delimiter=",", skiprows=1)
    for row in ref[::5]:
        code, out, _ = run("render", f"{row[0]:g}", "--duration", "0.001")
        got = np.loadtxt(io.StringIO(out), delimiter=",", skiprows=1)
        np.testing.assert_allclose(got[1:], row[1:], atol=1e-6)


def test_cli_json_and_png(tmp_path):
    code, out, _ = run("render", "45", "--mode", "dynamic", "--format", "json",
                       "--rate", "100")
    doc = json.loads(out)
    assert doc["stimulus"]["dwell_near_s"] == pytest.approx(0.6)
    assert len(doc["t_s"]) == 100 and len(doc["amplitudes"][0]) == 6
    png = tmp_path / "s.png"
    code, _, _ = run("render", "45", "--format", "png", "-o", str(png))
    assert code == 0 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_negative_and_large_angles_are_normalised():
    _, a, _ = run("render", "-15", "--duration", "0.001")
    _, b, _ = run("render", "345", "--duration", "0.001")
    _, c, _ = run("render", "705", "--duration", "0.001")
    assert a == b == c


def test_cli_uneven_layout():
    code, out, _ = run("render", "20", "--tactor-angles", "0,40,180", "--law", "linear",
                       "--duration", "0.001")
    assert code == 0
    assert out.splitlines()[1] == "0.000000000,0.500000000,0.500000000,0.000000000"


def test_figure_amplitudes(tmp_path):
    png = tmp_path / "amp.png"
    code, _, _ = run("figure", "amplitudes", "-o", str(png))
    assert code == 0 and png.stat().st_size > 10_000


@pytest.mark.parametrize(
    "args, message",
    [
        (["abc"], "finite number"),
        (["nan"], "finite number"),
        (["inf"], "finite number"),
        (["15", "--rate", "0"], "rate"),
        (["15", "--rate", "-5"], "rate"),
        (["15", "--duration", "0"], "duration"),
        (["15", "--duration", "x"], "duration"),
        (["15", "--transit", "0.5"], "2\\*transit"),
        (["15", "--tactors", "1"], "at least 2"),
        (["15", "--tactor-angles", "30,90,30"], "duplicate"),
        (["15", "--law", "cubic"], "paper"),
        (["15", "--mode", "wobble"], "static"),
    ],
)
def test_bad_input_is_one_line_error_exit_2(args, message):
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "render", *args],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ")
    assert "Traceback" not in proc.stderr
    import re

    assert re.search(message, proc.stderr)
