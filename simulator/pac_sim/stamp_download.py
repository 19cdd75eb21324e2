"""The Stamp's side of the BS2 download protocol (see :mod:`pac_host.stamp.loader`).

A byte-in, bytes-out state machine: :meth:`StampDownload.feed` takes what the host sent and
returns what the module sends back (the programming port's echo of every byte, then the
identification answers, the interpreter version, one acknowledgement per packet). When the
host ends the download, :attr:`eeprom` is the new 2 KB EEPROM and :attr:`firmware_version`
the ServoBot firmware version found in it (EEPROM 0..2 = ``"SB"``, version; ``None`` for any
other program), which the emulator's firmware then reports in BOOT and HELLO_R.

How a download starts on a pseudo-terminal. A real BS2 enters download mode when the host
resets it through DTR (wired to ATN) while holding its receive line in break. A pty has no
modem-control lines (setting DTR fails with ENOTTY) and Linux drops a break on a pty, so the
emulator cannot see either. It uses what the host does next instead: :func:`starts_download`
is true for the identification byte ``B`` (0x42) arriving after at least
:data:`RESET_SILENCE_S` of silence from the host. The reset sequence itself is 58 ms of
silence, and a protocol request always begins with its sync byte 0xA5, so a request or a
request's payload byte is never taken for a reset.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from pac_host.stamp.image import (
    ADDRESS_FLAG,
    BLOCK_SIZE,
    EEPROM_SIZE,
    FW_TAG,
    PACKET_SIZE,
    TURN_CYCLE_ADDR,
    firmware_version_of,
)
from pac_host.stamp.loader import (
    ACK_OK,
    END_OF_DOWNLOAD,
    ID_BYTES,
    VERSION_REQUEST,
    id_answer,
)
from pac_sim.targeted import PacketTargets

RESET_SILENCE_S = 0.02
BS2_INTERPRETER = 0x10  # BCD 1.0
ACK_DAMAGED = 0x01
ACK_EEPROM_FAILED = 0x02


def starts_download(byte: int, silence_s: float) -> bool:
    """True if ``byte`` after ``silence_s`` seconds of host silence is a download's first byte."""
    return byte == ID_BYTES[0] and silence_s >= RESET_SILENCE_S


@dataclass
class DownloadFaults:
    """Ways to make the emulated module misbehave, for testing the host's loader."""

    id_answers: bytes | None = None  # answers to B, S, 2 (a different module answers otherwise)
    refuse_packet: int | None = None  # 0-based packet index answered with ACK_EEPROM_FAILED
    mute_packet: int | None = None  # 0-based packet index echoed but never acknowledged


@dataclass
class StampDownload:
    """One download session, from the first identification byte to the end byte."""

    eeprom_before: bytes = bytes(EEPROM_SIZE)
    echo: bool = True  # the programming port's hardware echo (off if the line already echoes)
    interpreter_version: int = BS2_INTERPRETER
    faults: DownloadFaults = field(default_factory=DownloadFaults)

    def __post_init__(self) -> None:
        self._mem = bytearray(self.eeprom_before)
        self._stage = 0  # 0..2 identification bytes, 3 version request, 4 packets
        self._packet = bytearray()
        self.packets = 0
        self.finished = False  # the host sent the end byte: the new program runs
        self.failed: str | None = None  # why the module left download mode early
        self.restart: bytes | None = None  # a new download's first bytes (the host reset)

    @property
    def active(self) -> bool:
        return not self.finished and self.failed is None

    @property
    def in_packets(self) -> bool:
        """True once identification is done: host bytes are packet bytes (or the end byte)."""
        return self.active and self._stage > len(ID_BYTES)

    @property
    def packet_pos(self) -> int:
        """Bytes of the current packet received so far."""
        return len(self._packet)

    @property
    def eeprom(self) -> bytes:
        return bytes(self._mem)

    @property
    def firmware_version(self) -> int | None:
        return firmware_version_of(self._mem)

    def feed(self, data: bytes) -> bytes:
        """Process host bytes; return the module's bytes (echo and answers) in wire order."""
        out = bytearray()
        for b in data:
            if not self.active:
                break  # out of download mode: the caller hands further bytes to the firmware
            if self.echo:
                out.append(b)
            out += self._step(b)
        return bytes(out)

    def _step(self, b: int) -> bytes:
        if self._stage < len(ID_BYTES):
            if b != ID_BYTES[self._stage]:
                self.failed = f"identification byte 0x{b:02X} where {chr(ID_BYTES[self._stage])!r}"
                return b""
            answers = self.faults.id_answers
            ans = answers[self._stage] if answers is not None else id_answer(b)
            self._stage += 1
            return bytes([ans])
        if self._stage == len(ID_BYTES):
            if b != VERSION_REQUEST:
                self.failed = f"0x{b:02X} where the version request 0x00 belongs"
                return b""
            self._stage += 1
            return bytes([self.interpreter_version])
        if not self._packet:
            if b == END_OF_DOWNLOAD:
                self.finished = True
                return b""
            if not b & ADDRESS_FLAG:
                self.failed = f"0x{b:02X} where a packet address (bit 7 set) belongs"
                return b""
        self._packet.append(b)
        if len(self._packet) < PACKET_SIZE:
            return b""
        return self._packet_done()

    def _packet_done(self) -> bytes:
        p, index = bytes(self._packet), self.packets
        self._packet.clear()
        self.packets += 1
        if index == self.faults.mute_packet:
            return b""
        if sum(p) & 0xFF:
            return bytes([ACK_DAMAGED])
        if index == self.faults.refuse_packet:
            return bytes([ACK_EEPROM_FAILED])
        addr = (p[0] & 0x7F) * BLOCK_SIZE
        self._mem[addr : addr + BLOCK_SIZE] = p[1 : 1 + BLOCK_SIZE]
        return bytes([ACK_OK])


DOWNLOAD_IDLE_S = 1.0  # a download the host leaves quiet this long is abandoned


class RawLine(Protocol):
    def read_raw(self, timeout: float) -> bytes: ...
    def write_raw(self, data: bytes) -> None: ...


def servobot_eeprom(firmware_version: int, turn_cycle: bytes) -> bytes:
    """The EEPROM of a Stamp running the ServoBot firmware, as far as the emulator models it:
    the version tag at 0 and the turn cycle at :data:`TURN_CYCLE_ADDR` (the rest reads 0)."""
    mem = bytearray(EEPROM_SIZE)
    mem[: len(FW_TAG) + 1] = FW_TAG + bytes([firmware_version])
    mem[TURN_CYCLE_ADDR : TURN_CYCLE_ADDR + len(turn_cycle)] = turn_cycle
    return bytes(mem)


def serve_download(
    line: RawLine, first: bytes, eeprom_before: bytes, idle_s: float = DOWNLOAD_IDLE_S,
    aim: PacketTargets | None = None,
) -> StampDownload:
    """Answer one download on ``line``, starting with the bytes ``first`` already received.

    Returns when the host ends the download, breaks the protocol, goes quiet for ``idle_s``,
    or resets the Stamp again (a new download starts: its bytes are in ``restart``). ``aim``
    drops or corrupts chosen packet bytes (``PACKET:N:BYTE`` faults).
    """
    dl = StampDownload(eeprom_before=eeprom_before)
    if aim is not None:
        aim.new_download()
    line.write_raw(dl.feed(first))
    last = time.monotonic()
    while dl.active:
        data = line.read_raw(idle_s)
        if not data:
            break
        now = time.monotonic()
        if dl.in_packets and starts_download(data[0], now - last):
            dl.failed, dl.restart = "the host reset the Stamp mid-download", data
            break
        last = now
        line.write_raw(_feed_aimed(dl, data, aim))
    return dl


def _feed_aimed(dl: StampDownload, data: bytes, aim: PacketTargets | None) -> bytes:
    if aim is None or not aim.targets:
        return dl.feed(data)
    out = bytearray()
    for b in data:  # END ends a download only between packets
        if dl.in_packets and (aim.mid_packet or b != END_OF_DOWNLOAD):
            out += dl.feed(aim.byte(b))
        else:
            out += dl.feed(bytes([b]))
    return bytes(out)


def serve_downloads(line: RawLine, first: bytes, eeprom_now: Callable[[], bytes],
                    flashed: Callable[[StampDownload], None],
                    aim: PacketTargets | None = None) -> None:
    """:func:`serve_download`, then again for every reset the host makes mid-download (a
    flash tried again after a failure); ``flashed`` sees each session as it ends."""
    data: bytes | None = first
    while data:
        dl = serve_download(line, data, eeprom_now(), aim=aim)
        flashed(dl)
        data = dl.restart
