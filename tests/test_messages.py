"""Messages a researcher meets are in their words: no protocol names, no Python reprs.

Each case runs the command as a user does (a real process) and reads what it prints.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from support.cli import tactorbelt

#: protocol message names and Python internals that must not reach a user
JARGON = re.compile(r"GET_INFO|PLAY_TARGET|SET_AMPLITUDES|STOP_ALL|SET_CONFIG|GET_STATUS|"
                    r"\bNAK\b|b'|b\"|codec|Traceback|\(\d+, '")


def _clean(text: str) -> None:
    assert not JARGON.search(text), text


def test_point_on_a_rendering_belt_counts_directions(tmp_path: Path) -> None:
    proc = tactorbelt("point", "--bearing", "10", "--seconds", "0.5", "--belt", "sim:virtual")
    assert proc.returncode == 0, proc.stderr
    assert "1 direction sent to the belt" in proc.stderr
    _clean(proc.stderr)


def test_a_binary_heading_file_is_not_a_text_file(tmp_path: Path) -> None:
    binary = tmp_path / "track.bin"
    binary.write_bytes(b"# tactor\xff\xfe\x00\x01")
    proc = tactorbelt("point", "--bearing", "10", "--heading-from", str(binary),
                      "--belt", "sim:virtual")
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"error: cannot read headings from {binary}: not a text file")
    _clean(proc.stderr)


@pytest.mark.parametrize("command", ["export", "analyze"])
def test_a_study_file_given_as_the_store(tmp_path: Path, command: str) -> None:
    study = tmp_path / "study.toml"
    assert tactorbelt("study", "init", str(study)).returncode == 0
    proc = tactorbelt(command, str(study), "-o", str(tmp_path / "out"))
    assert proc.returncode == 2
    assert "not a tactorbelt store" in proc.stderr
    assert "a new file name" not in proc.stderr  # export and analyze only read
    _clean(proc.stderr)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_serial_device_that_never_answers(tmp_path: Path) -> None:
    """A port with something that is not tactorbelt firmware on it (here: silence)."""
    controller, device = os.openpty()
    try:
        port = os.ttyname(device)
        proc = tactorbelt("play", "15", "--seconds", "0.1", "--belt",
                          f"serial:{port}?timeout_s=0.1")
    finally:
        os.close(device)
        os.close(controller)
    assert proc.returncode == 3
    assert proc.stderr.startswith(f"error: no tactorbelt firmware answered on {port} "
                                  "(asked 3 times for its version, 100 ms each)")
    _clean(proc.stderr)


def test_a_heading_file_saved_with_a_byte_order_mark(tmp_path: Path) -> None:
    """Windows editors often start UTF-8 text with a byte order mark."""
    headings = tmp_path / "h.txt"
    headings.write_bytes("10\n20\n".encode("utf-8-sig"))
    proc = tactorbelt("point", "--bearing", "10", "--heading-from", str(headings),
                      "--belt", "sim:virtual")
    assert proc.returncode == 0, proc.stderr
    assert "2 headings" in proc.stderr
