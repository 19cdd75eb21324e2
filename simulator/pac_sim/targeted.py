"""Faults aimed at one byte of one chosen frame, for deterministic reproductions.

Random faults (``--drop-prob``) land where the generator and the timing put them; a bug they
reveal once may never come back. A :class:`FrameTarget` names its byte by what the line carries,
not by time: ``CYCLE:165:6`` is byte 6 (0-based, counted from the first sync byte) of the 165th
CYCLE report the Stamp sends; ``RUN:1:4`` is byte 4 (the SEQ) of the first RUN request the
host sends. Requests (CMD < 0x80) are counted on the host -> Stamp direction, replies and reports
on the Stamp -> host direction, each from the emulator's start. ``PACKET:3:5`` is byte 5 of the
third packet of a firmware download (BS2 download protocol, 18 bytes a packet), counted over
every download since the start (so a download tried again is not hit again).

:class:`FrameTargets` follows one direction of the clean stream frame by frame. It holds back a
frame's first three bytes (sync and LEN, at most 3 byte times) until its CMD tells whether the
frame is aimed at; bytes that are not part of a frame pass through untouched.
"""

from __future__ import annotations

from dataclasses import dataclass

from pac_host.stamp.image import PACKET_SIZE
from pac_protocol.frame import HEADER, MAX_PAYLOAD, SYNC
from pac_protocol.messages import Cmd

ACTIONS = ("drop", "corrupt")
CORRUPT_MASK = 0xFF  # a corrupted target byte has every bit flipped
PACKET = 0x100  # the kind of a download packet (not a frame type: no CMD byte has this value)


@dataclass(frozen=True)
class FrameTarget:
    """Drop or corrupt byte ``byte`` of the ``ordinal``-th frame of type ``cmd``."""

    action: str
    cmd: int
    ordinal: int
    byte: int

    def __post_init__(self) -> None:
        if self.action not in ACTIONS:
            raise ValueError(f"action must be one of {ACTIONS}, got {self.action!r}")
        if self.ordinal < 1:
            raise ValueError(f"frames are counted from 1, got {self.ordinal}")
        size = PACKET_SIZE if self.cmd == PACKET else HEADER + MAX_PAYLOAD + 1
        if not 0 <= self.byte < size:
            raise ValueError(f"a {kind_name(self.cmd)} has at most {size} bytes, byte "
                             f"{self.byte} is outside it")

    @property
    def outgoing(self) -> bool:
        """True for the Stamp -> host direction (replies and reports)."""
        return self.cmd != PACKET and bool(self.cmd & 0x80)


def kind_name(cmd: int) -> str:
    return "PACKET" if cmd == PACKET else Cmd(cmd).name


def parse_target(action: str, text: str) -> FrameTarget:
    """``KIND:N:BYTE`` (KIND a frame type of PROTOCOL.md 5, e.g. CYCLE, STATUS_R, RUN);
    ValueError naming the problem otherwise."""
    parts = text.split(":")
    if len(parts) != 3:
        raise ValueError(f"expected KIND:N:BYTE (e.g. CYCLE:165:6), got {text!r}")
    kind = parts[0].upper()
    if kind not in Cmd.__members__ and kind != "PACKET":
        raise ValueError(f"{parts[0]!r} is not a frame type ({', '.join(Cmd.__members__)}) "
                         "or PACKET")
    try:
        ordinal, byte = int(parts[1]), int(parts[2])
    except ValueError:
        raise ValueError(f"expected KIND:N:BYTE with whole numbers, got {text!r}") from None
    return FrameTarget(action, PACKET if kind == "PACKET" else int(Cmd[kind]), ordinal, byte)


class FrameTargets:
    """Applies the targets of one direction to its byte stream, chunk by chunk."""

    def __init__(self, targets: tuple[FrameTarget, ...]) -> None:
        self.targets = {(t.cmd, t.ordinal, t.byte): t.action for t in targets}
        self.counts: dict[int, int] = {}
        self.hit: list[str] = []  # what was done, in order (for tests and reports)
        self._held = bytearray()  # the current frame's bytes before its CMD
        self._frame: tuple[int, int] | None = None  # (cmd, ordinal) of the frame in progress
        self._pos = 0
        self._size = 0

    def apply(self, data: bytes) -> bytes:
        if not self.targets:
            return data
        out = bytearray()
        for b in data:
            if self._frame is None:
                out += self._header(b)
            else:
                out += self._body(b)
        return bytes(out)

    def _header(self, b: int) -> bytes:
        """A byte before the CMD is known: held, or released untouched if no frame starts."""
        pos = len(self._held)
        if (pos < 2 and b != SYNC[pos]) or (pos == 2 and b > MAX_PAYLOAD):
            held = bytes(self._held) + bytes([b])
            self._held.clear()
            if b == SYNC[0]:  # it may begin the next frame
                self._held.append(b)
                return held[:-1]
            return held
        self._held.append(b)
        if len(self._held) < HEADER - 1:
            return b""
        # the CMD byte: the frame is known, release what was held through the targets
        cmd = b
        n = self.counts.get(cmd, 0) + 1
        self.counts[cmd] = n
        self._frame, self._size, self._pos = (cmd, n), HEADER + self._held[2] + 1, 0
        held = bytes(self._held)
        self._held.clear()
        return b"".join(self._body(x) for x in held)

    def _body(self, b: int) -> bytes:
        assert self._frame is not None
        cmd, n = self._frame
        pos = self._pos
        self._pos += 1
        if self._pos >= self._size:
            self._frame = None
        action = self.targets.get((cmd, n, pos))
        if action is None:
            return bytes([b])
        self.hit.append(f"{action} {Cmd(cmd).name}:{n}:{pos}")
        return b"" if action == "drop" else bytes([b ^ CORRUPT_MASK])


class PacketTargets:
    """Applies the PACKET targets to the bytes of firmware downloads, counting packets as the
    host sent them (a dropped byte does not shift the count)."""

    def __init__(self, targets: tuple[FrameTarget, ...]) -> None:
        self.targets = {(t.ordinal, t.byte): t.action for t in targets if t.cmd == PACKET}
        self.packets = 0  # packets the host began, over every download
        self.hit: list[str] = []
        self._pos = 0  # bytes of the current packet sent so far

    def new_download(self) -> None:
        if self._pos:  # a packet cut short still counts
            self.packets += 1
        self._pos = 0

    def byte(self, b: int) -> bytes:
        """The next packet byte as the Stamp receives it (after identification)."""
        n, pos = self.packets + 1, self._pos
        self._pos += 1
        if self._pos == PACKET_SIZE:
            self.packets, self._pos = n, 0
        action = self.targets.get((n, pos))
        if action is None:
            return bytes([b])
        self.hit.append(f"{action} PACKET:{n}:{pos}")
        return b"" if action == "drop" else bytes([b ^ CORRUPT_MASK])

    @property
    def mid_packet(self) -> bool:
        return self._pos > 0


def parse_targets(drop: tuple[str, ...] = (), corrupt: tuple[str, ...] = ()
                  ) -> tuple[FrameTarget, ...]:
    """The targets of ``--drop-at`` and ``--corrupt-at`` specs; ValueError naming the option."""
    out = []
    for action, specs in (("drop", drop), ("corrupt", corrupt)):
        for spec in specs:
            try:
                out.append(parse_target(action, spec))
            except ValueError as e:
                raise ValueError(f"--{action}-at: {e}") from None
    return tuple(out)
