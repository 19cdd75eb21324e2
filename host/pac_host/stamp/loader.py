"""Load a program into a BASIC Stamp II over its programming port (the BS2 download protocol).

The sequence (Parallax, "BASIC Stamp Programming Protocol", BS2), 9600 8N1 on the programming
port, which echoes every byte the host sends:

1. Reset into download mode: DTR (wired to ATN) asserted and TX held in break for 2 ms, DTR
   released and the break held 36 ms more, break released, 20 ms pause, input flushed.
2. Identification: the host sends ``B``, ``S``, ``2``; after the echo of each, a BS2 answers the
   byte's two's complement (``0xBE 0xAD 0xCE``). Then the host sends ``0x00`` and the BS2 answers
   its interpreter version (BCD, ``0x10`` = 1.0).
3. Program packets (18 bytes, :mod:`pac_host.stamp.image`): after the echo of each packet the
   BS2 writes the block and answers one acknowledgement byte, ``0x00`` = written
   (``0x01`` = the packet arrived damaged, ``0x02`` = EEPROM write failed).
4. End of download: the host sends ``0x00`` where the next packet's address byte would be (a
   packet address always has bit 7 set); after its echo the BS2 starts the new program.

Every echo and every answer is checked; the first departure raises a typed error and stops the
download (the blocks already acknowledged stay written, which the error says). Nothing here
prints: progress goes to an optional callback.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from pac_host.errors import PacError
from pac_host.stamp.image import ADDRESS_FLAG, BLOCK_SIZE, PACKET_SIZE, StampImage
from pac_protocol.frame import HEADER, SYNC

ID_BYTES = b"BS2"
VERSION_REQUEST = 0x00
END_OF_DOWNLOAD = 0x00
ACK_OK = 0x00
ACK_MEANING = {0x01: "the packet arrived damaged", 0x02: "the EEPROM write failed"}
# Reset timing (seconds), Parallax's BS2 sequence.
T_RESET_PULSE = 0.002
T_BREAK_HOLD = 0.036
T_SETTLE = 0.020


def id_answer(byte: int) -> int:
    """What a BS2 answers to identification byte ``byte``: its two's complement."""
    return (-byte) & 0xFF


class FlashError(PacError):
    """The download did not complete; the message says how far it got."""


class NoStampError(FlashError):
    """Nothing answered on the port (no echo): no Stamp, no power, or the wrong port."""


class WrongModuleError(FlashError):
    """Something answered, but not as a BS2 in download mode does."""


class PacketNotAcknowledged(FlashError):
    """A program packet was not acknowledged with 0x00."""


Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class FlashReport:
    """What the download established."""

    interpreter_version: int  # the BS2's answer to the version request (BCD, 0x10 = 1.0)
    packets: int
    reset_line: bool  # False when the port has no DTR line (a pseudo-terminal)

    @property
    def interpreter(self) -> str:
        v = self.interpreter_version
        return f"{v >> 4}.{v & 0x0F}"


class StampLoader:
    """Downloads an image through an open pyserial port (9600 8N1)."""

    def __init__(
        self,
        port: serial.SerialBase,
        answer_timeout: float = 0.25,
        ack_timeout: float = 1.0,
        progress: Progress | None = None,
    ) -> None:
        self.port = port
        self.answer_timeout = answer_timeout
        self.ack_timeout = ack_timeout
        self.progress = progress or (lambda stage, done, total: None)
        self.packets_written = 0  # acknowledged packets of the last (or current) download
        self._name = getattr(port, "port", None) or getattr(port, "name", "the port")

    # -- wire helpers -------------------------------------------------------------------------
    def _read(self, n: int, timeout: float) -> bytes:
        deadline = time.monotonic() + timeout
        buf = bytearray()
        while len(buf) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            self.port.timeout = min(left, 0.05)
            buf += self.port.read(n - len(buf))
        return bytes(buf)

    def _send_echoed(self, data: bytes, what: str, skip_frames: bool = False) -> None:
        """Send and check the programming port's echo. ``skip_frames``: first drop whole
        protocol frames the running firmware sent before it saw ``data`` (no reset line)."""
        self.port.write(data)
        self.port.flush()
        timeout = self.answer_timeout + len(data) * 0.002
        echo = self._read(len(data), timeout)
        while skip_frames and echo[:1] == SYNC[:1] and echo != data:
            head = echo + self._read(HEADER - len(echo), timeout)
            if head[:2] != SYNC or len(head) < HEADER:
                echo = head
                break
            self._read(head[2] + 1, timeout)  # the rest of the frame: payload and check
            echo = self._read(len(data), timeout)
        if not echo:
            raise NoStampError(
                f"no BASIC Stamp on {self._name}: {what} was not echoed within "
                f"{self.answer_timeout:.2f} s (check the cable, the port and the robot's power)"
            )
        if echo != data:
            raise FlashError(
                f"{what}: the echo on {self._name} differs from what was sent "
                f"({data.hex(' ')} -> {echo.hex(' ')}); the line is damaged or the speed is wrong"
            )

    def _answer(self, timeout: float) -> int | None:
        got = self._read(1, timeout)
        return got[0] if got else None

    # -- protocol steps -----------------------------------------------------------------------
    def reset(self) -> bool:
        """Reset the Stamp into download mode. False if the port has no DTR line (a pty)."""
        port = self.port
        has_line = True
        try:
            port.break_condition = True
            port.dtr = True
            time.sleep(T_RESET_PULSE)
            port.dtr = False
            time.sleep(T_BREAK_HOLD)
        except (OSError, serial.SerialException):
            has_line = False  # no modem-control lines: a pseudo-terminal or a bare 3-wire link
        finally:
            try:
                port.break_condition = False
            except (OSError, serial.SerialException):
                pass
        time.sleep(T_SETTLE)
        port.reset_input_buffer()
        return has_line

    def identify(self, reset_line: bool = True) -> int:
        """The identification exchange; returns the interpreter version byte.

        Without a reset line (``reset`` returned False: a pseudo-terminal) the firmware runs
        until the first identification byte reaches it, so frames it sent just before may
        precede that byte's echo: they are skipped, whole frames only.
        """
        for b in ID_BYTES:
            what = f"identification byte {chr(b)!r} (0x{b:02X})"
            self._send_echoed(bytes([b]), what, skip_frames=not reset_line and b == ID_BYTES[0])
            got = self._answer(self.answer_timeout)
            want = id_answer(b)
            if got is None:
                raise WrongModuleError(
                    f"the module on {self._name} echoed {what} but did not answer it: not a BS2 "
                    "in download mode (another Stamp model, or the reset did not reach ATN)"
                )
            if got != want:
                raise WrongModuleError(
                    f"the module on {self._name} is not a BS2: it answered 0x{got:02X} to {what}, "
                    f"a BS2 answers 0x{want:02X}"
                )
        self._send_echoed(bytes([VERSION_REQUEST]), "the version request")
        version = self._answer(self.answer_timeout)
        if version is None:
            raise WrongModuleError(
                f"the module on {self._name} passed identification but sent no version byte"
            )
        return version

    def send_packet(self, index: int, total: int, packet: bytes) -> None:
        block = packet[0] & ~ADDRESS_FLAG
        where = (
            f"packet {index + 1} of {total} (EEPROM 0x{block * BLOCK_SIZE:03X}-"
            f"0x{block * BLOCK_SIZE + BLOCK_SIZE - 1:03X})"
        )
        self._send_echoed(packet, where)
        ack = self._answer(self.ack_timeout)
        kept = f"; {index} packet(s) before it were written, the program is incomplete"
        if ack is None:
            raise PacketNotAcknowledged(
                f"{where} was not acknowledged within {self.ack_timeout:.1f} s{kept}"
            )
        if ack != ACK_OK:
            meaning = ACK_MEANING.get(ack, "unknown code")
            raise PacketNotAcknowledged(
                f"{where} was refused with 0x{ack:02X} ({meaning}){kept}"
            )

    def finish(self) -> None:
        self._send_echoed(bytes([END_OF_DOWNLOAD]), "the end-of-download byte")

    def flash(self, image: StampImage) -> FlashReport:
        """Reset, identify, send every packet, end the download. Raises on the first failure."""
        packets = image.packets
        for p in packets:
            if len(p) != PACKET_SIZE:
                raise ValueError("image packets must be 18 bytes")
        self.packets_written = 0
        self.progress("reset", 0, len(packets))
        line = self.reset()
        self.progress("identify", 0, len(packets))
        version = self.identify(line)
        for i, p in enumerate(packets):
            self.send_packet(i, len(packets), p)
            self.packets_written = i + 1
            self.progress("packet", i + 1, len(packets))
        self.finish()
        self.progress("done", len(packets), len(packets))
        return FlashReport(interpreter_version=version, packets=len(packets), reset_line=line)
