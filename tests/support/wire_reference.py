"""The per-byte definitions of CRC-16/CCITT-FALSE and COBS: the reference the host's
fast codec (tactorbelt.devices.wire, in C through binascii and bytes methods) is
compared with (tests/test_wire.py, benchmarks/bench_wire.py)."""

from __future__ import annotations

from tactorbelt import ProtocolError

__all__ = ["cobs_decode_reference", "cobs_encode_reference", "crc16_ccitt_false_reference"]


def crc16_ccitt_false_reference(data: bytes) -> int:
    """CRC-16/CCITT-FALSE bit by bit: the definition :func:`crc16_ccitt_false` must match."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def cobs_encode_reference(data: bytes) -> bytes:
    """COBS byte by byte: the definition :func:`cobs_encode` must match."""
    out = bytearray([0])
    code_at = 0
    code = 1
    for i, byte in enumerate(data):
        if byte == 0:
            out[code_at] = code
            code_at = len(out)
            out.append(0)
            code = 1
        else:
            out.append(byte)
            code += 1
            if code == 0xFF and i + 1 < len(data):
                out[code_at] = code
                code_at = len(out)
                out.append(0)
                code = 1
    out[code_at] = code
    return bytes(out)


def cobs_decode_reference(data: bytes) -> bytes:
    """COBS decoding byte by byte: the definition :func:`cobs_decode` must match."""
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        code = data[i]
        i += 1
        if code == 0:
            raise ProtocolError(f"COBS: unexpected 0x00 at byte {i - 1}")
        end = i + code - 1
        if end > n:
            raise ProtocolError(f"COBS: block at byte {i - 1} runs past the end ({n} bytes)")
        block = data[i:end]
        if 0 in block:
            raise ProtocolError(f"COBS: unexpected 0x00 at byte {i + block.index(0)}")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)
