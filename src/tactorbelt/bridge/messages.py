"""The bridge's messages: parsing a page's JSON, checking its fields, the clock handshake.

Every WebSocket message is a JSON object with a ``"type"`` (docs/browser.md, "The
protocol"). :func:`parse` turns text into such an object or raises
:class:`MessageError`, whose text the bridge sends back in an ``error`` reply; the
field readers (:func:`need_int`, :func:`opt_number`, ...) do the same for a missing or
wrong field. :func:`clock_estimate` is the handshake's arithmetic: the offset of the
page's ``performance.now()`` clock from the bridge's, from the ping with the least round
trip.

Pure: imports the standard library and tactorbelt._errors only.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from .._errors import ConfigError

__all__ = [
    "PAGE_TYPES",
    "ClockEstimate",
    "MessageError",
    "clock_estimate",
    "error_reply",
    "need_int",
    "need_str",
    "opt_int",
    "opt_number",
    "opt_str",
    "parse",
    "request_id",
]

#: Message types a page may send.
PAGE_TYPES = ("hello", "pong", "play", "stop", "status", "trial", "end")
#: The longest message a page may send (bytes); a trial's reply is a few hundred.
MAX_MESSAGE_BYTES = 64 * 1024


class MessageError(ConfigError):
    """A message the bridge cannot act on: malformed JSON, a missing or wrong field, an
    unknown type. The text is sent back to the page (``{"type": "error", ...}``), with
    the request's ``id`` when it had a usable one (:attr:`rid`)."""

    def __init__(self, message: str, rid: int | None = None) -> None:
        super().__init__(message)
        self.rid = rid


def parse(text: str | bytes) -> dict[str, Any]:
    """A page's message as a dict with a string ``type``.

    Raises:
        MessageError: not JSON, not an object, no ``type``, or an unknown type.
    """
    if isinstance(text, bytes | bytearray):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError:
            raise MessageError("a message must be UTF-8 JSON text") from None
    try:
        msg = json.loads(text)
    except ValueError as exc:
        raise MessageError(f"malformed JSON: {exc}") from None
    if not isinstance(msg, dict):
        raise MessageError(f"a message must be a JSON object, got {type(msg).__name__}")
    kind = msg.get("type")
    if not isinstance(kind, str):
        raise MessageError("a message needs a string \"type\"", request_id(msg))
    if kind not in PAGE_TYPES:
        raise MessageError(f"unknown message type {kind!r}; allowed: {', '.join(PAGE_TYPES)}",
                           request_id(msg))
    return msg


def request_id(msg: Mapping[str, Any]) -> int | None:
    """The request's ``id`` (an integer), or None when it has none usable."""
    rid = msg.get("id")
    if isinstance(rid, int) and not isinstance(rid, bool):
        return rid
    return None


def error_reply(rid: int | None, message: str) -> dict[str, Any]:
    """The ``error`` reply to request ``rid``."""
    return {"type": "error", "id": rid, "error": message}


def need_int(msg: Mapping[str, Any], key: str, lo: int | None = None,
             hi: int | None = None) -> int:
    """Field ``key``: an integer in [lo, hi]."""
    value = msg.get(key)
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise MessageError(f"{msg.get('type')}: {key!r} must be an integer, got "
                               f"{value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise MessageError(f"{msg.get('type')}: {key!r} must be in {lo}..{hi}, got {value}")
    return int(value)


def opt_int(msg: Mapping[str, Any], key: str, lo: int | None = None,
            hi: int | None = None) -> int | None:
    """Field ``key`` when present and not null: an integer in [lo, hi]."""
    if msg.get(key) is None:
        return None
    return need_int(msg, key, lo, hi)


def opt_number(msg: Mapping[str, Any], key: str, lo: float = -math.inf,
               hi: float = math.inf) -> float | None:
    """Field ``key`` when present and not null: a finite number in [lo, hi]."""
    value = msg.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value):
        raise MessageError(f"{msg.get('type')}: {key!r} must be a finite number, got "
                           f"{value!r}")
    x = float(value)
    if not lo <= x <= hi:
        raise MessageError(f"{msg.get('type')}: {key!r} must be in {lo:g}..{hi:g}, got {x:g}")
    return x


def need_str(msg: Mapping[str, Any], key: str, allowed: Sequence[str] | None = None) -> str:
    """Field ``key``: a string (one of ``allowed`` when given)."""
    value = msg.get(key)
    if not isinstance(value, str):
        raise MessageError(f"{msg.get('type')}: {key!r} must be a string, got {value!r}")
    if allowed is not None and value not in allowed:
        raise MessageError(f"{msg.get('type')}: {key!r} must be one of "
                           f"{', '.join(allowed)}, got {value!r}")
    return value


def opt_str(msg: Mapping[str, Any], key: str) -> str | None:
    """Field ``key`` when present and not null: a string, cut to 1000 characters."""
    return None if msg.get(key) is None else need_str(msg, key)[:1000]


@dataclass(frozen=True)
class ClockEstimate:
    """The page clock against the bridge's, from a handshake.

    ``page_ms = bridge_ns / 1e6 + offset_ms``, within ``uncertainty_ms`` (half the least
    round trip: the page read its clock somewhere between the ping's send and the pong's
    arrival).

    Attributes:
        offset_ms: page clock minus bridge clock, ms.
        uncertainty_ms: how far off the offset may be, ms.
        rtt_ms: the least round trip, ms.
        pings: pings answered.
    """

    offset_ms: float
    uncertainty_ms: float
    rtt_ms: float
    pings: int

    def to_page_ms(self, bridge_ns: int) -> float:
        """A bridge time (ns) on the page's clock (ms)."""
        return bridge_ns / 1e6 + self.offset_ms

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def clock_estimate(samples: Sequence[tuple[int, int, float]]) -> ClockEstimate:
    """The clock offset from ``(t_send_ns, t_recv_ns, t_page_ms)`` per answered ping:
    the one with the least round trip gives ``offset = t_page - (t_send + t_recv) / 2``
    and ``uncertainty = rtt / 2``.

    Raises:
        MessageError: no ping was answered.
    """
    if not samples:
        raise MessageError("the page answered no clock ping")
    send, recv, page = min(samples, key=lambda s: s[1] - s[0])
    rtt_ms = (recv - send) / 1e6
    offset = page - (send + recv) / 2e6
    return ClockEstimate(offset, rtt_ms / 2, rtt_ms, len(samples))
