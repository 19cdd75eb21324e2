"""Framing: ``A5 5A LEN CMD SEQ PAYLOAD[LEN] CHK`` (PROTOCOL.md section 2).

CHK makes the byte sum of LEN..CHK equal 0xFF modulo 256 (the one's-complement sum also used
by Dynamixel protocol 1.0): the Stamp checks it with one addition per byte.
"""

from __future__ import annotations

from dataclasses import dataclass

from pac_protocol.errors import BadCheck, BadLength, BadSync, TrailingBytes, Truncated

SYNC = b"\xa5\x5a"
HEADER = 5  # A5 5A LEN CMD SEQ
MAX_PAYLOAD = 8
REQUEST_PAYLOAD = 3  # every host -> Stamp frame carries exactly 3 payload bytes
REQUEST_SIZE = HEADER + REQUEST_PAYLOAD + 1  # 9 bytes


def check_value(body: bytes | bytearray) -> int:
    """CHK for ``body`` = LEN CMD SEQ PAYLOAD: 0xFF minus their byte sum, modulo 256."""
    return 0xFF - (sum(body) & 0xFF)


@dataclass(frozen=True)
class Frame:
    """One frame: a command byte, a sequence number and 0..8 payload bytes."""

    cmd: int
    seq: int
    payload: bytes = b""

    def __post_init__(self) -> None:
        if not (0 <= self.cmd <= 0xFF and 0 <= self.seq <= 0xFF):
            raise ValueError(f"cmd and seq must be bytes, got cmd={self.cmd} seq={self.seq}")
        if len(self.payload) > MAX_PAYLOAD:
            raise ValueError(f"payload of {len(self.payload)} bytes exceeds {MAX_PAYLOAD}")
        object.__setattr__(self, "payload", bytes(self.payload))

    @property
    def is_reply(self) -> bool:
        """Stamp -> host frames have bit 7 of CMD set; host -> Stamp requests have it clear."""
        return bool(self.cmd & 0x80)

    def encode(self) -> bytes:
        body = bytes([len(self.payload), self.cmd, self.seq]) + self.payload
        return SYNC + body + bytes([check_value(body)])

    def hex(self) -> str:
        return self.encode().hex(" ").upper()


def parse_frame(data: bytes) -> Frame:
    """Strictly parse exactly one frame; raise the typed :class:`FrameError` naming the fault."""
    data = bytes(data)
    if data[:2] != SYNC[: len(data[:2])]:
        raise BadSync(f"frame must start with A5 5A, got {data[:2].hex(' ').upper() or 'nothing'}")
    if len(data) < HEADER:
        raise Truncated(f"frame of {len(data)} bytes is shorter than its {HEADER}-byte header")
    n = data[2]
    if n > MAX_PAYLOAD:
        raise BadLength(f"LEN {n} exceeds the maximum payload of {MAX_PAYLOAD}")
    size = HEADER + n + 1
    if len(data) < size:
        raise Truncated(f"LEN {n} needs {size} bytes, got {len(data)}")
    if len(data) > size:
        raise TrailingBytes(f"{len(data) - size} bytes after the {size}-byte frame")
    body = data[2:-1]
    if check_value(body) != data[-1]:
        raise BadCheck(f"CHK {data[-1]:02X} but the frame's bytes need {check_value(body):02X}")
    return Frame(data[3], data[4], data[5:-1])
