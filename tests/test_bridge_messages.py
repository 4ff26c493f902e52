"""The bridge's message parsing and clock handshake arithmetic (pure; no server)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactorbelt.bridge.messages import (
    MessageError,
    clock_estimate,
    need_int,
    opt_number,
    opt_str,
    parse,
    request_id,
)


@given(offset_ms=st.floats(-1e9, 1e9), pings=st.lists(
    st.tuples(st.integers(0, 10**15), st.integers(0, 5_000_000), st.integers(0, 5_000_000)),
    min_size=1, max_size=16))
def test_the_offset_is_within_its_uncertainty_whatever_the_delays(
        offset_ms: float, pings: list[tuple[int, int, int]]) -> None:
    """Whatever the two one-way delays of each ping, the page read its clock between the
    ping's send and the pong's arrival, so the true offset lies within the estimate's
    uncertainty (half the least round trip)."""
    samples = [(send, send + out + back, (send + out) / 1e6 + offset_ms)
               for send, out, back in pings]
    est = clock_estimate(samples)
    assert abs(est.offset_ms - offset_ms) <= est.uncertainty_ms + 1e-6 * max(
        1.0, abs(offset_ms))
    assert est.rtt_ms == pytest.approx(min(out + back for _, out, back in pings) / 1e6)
    assert est.pings == len(pings)


def test_the_least_round_trip_wins_and_page_times_convert() -> None:
    est = clock_estimate([(0, 4_000_000, 1002.0), (10_000_000, 10_200_000, 1010.1)])
    assert est.rtt_ms == pytest.approx(0.2)
    assert est.offset_ms == pytest.approx(1000.0)
    assert est.to_page_ms(20_000_000) == pytest.approx(1020.0)
    with pytest.raises(MessageError, match="no clock ping"):
        clock_estimate([])


@pytest.mark.parametrize("text, message", [
    ("{oops", "malformed JSON"),
    ("[1]", "must be a JSON object"),
    ('{"id": 1}', 'needs a string "type"'),
    ('{"type": 3}', 'needs a string "type"'),
    ('{"type": "dance"}', "unknown message type 'dance'"),
    (b"\xff\xfe", "UTF-8"),
])
def test_bad_messages_say_what_is_wrong(text: str | bytes, message: str) -> None:
    with pytest.raises(MessageError, match=message):
        parse(text)


def test_fields_are_checked() -> None:
    msg = parse('{"type": "play", "id": 7, "target": 3.0, "duration_ms": "long"}')
    assert request_id(msg) == 7 and request_id({"id": True}) is None
    assert need_int(msg, "target", 0, 23) == 3
    with pytest.raises(MessageError, match=r"must be in 0\.\.2"):
        need_int(msg, "target", 0, 2)
    with pytest.raises(MessageError, match="'duration_ms' must be a finite number"):
        opt_number(msg, "duration_ms")
    assert opt_number(msg, "absent") is None
    short = {"type": "play", "duration_ms": 0.5, "page": "x" * 2000, "user_agent": 3}
    with pytest.raises(MessageError) as info:
        opt_number(short, "duration_ms", 1.0, 60_000.0)
    assert str(info.value) == "play: 'duration_ms' must be in 1..60000, got 0.5"
    assert opt_str(short, "page") == "x" * 1000 and opt_str(short, "absent") is None
    with pytest.raises(MessageError) as info:
        opt_str(short, "user_agent")
    assert str(info.value) == "play: 'user_agent' must be a string, got 3"
