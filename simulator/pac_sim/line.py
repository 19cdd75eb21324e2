"""The Stamp's serial line, emulated on a pseudo-terminal.

What the firmware loop sees: ``send`` (SEROUT), ``serin`` (SERIN with ``WAIT(A5 5A 03)`` and a
timeout), ``pause`` (time passes while the Stamp walks and cannot listen). Faithful to the BS2:
bytes that arrive while not inside ``serin`` are lost; the timeout restarts on every byte; with
``echo`` every byte the host sends comes back (the pin-16 programming port). Timing is scaled by
``factor`` (1 = real time, 0 = as fast as possible); at 9600 baud a byte takes 1.042 ms x factor.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty
from dataclasses import dataclass

import numpy as np

from pac_protocol.frame import REQUEST_PAYLOAD, SYNC
from pac_protocol.timing import BYTE_S
from pac_sim.stamp_download import starts_download
from pac_sim.targeted import FrameTarget, FrameTargets, PacketTargets

WAIT_PATTERN = SYNC + bytes([REQUEST_PAYLOAD])  # WAIT($A5, $5A, $03)
REQUEST_TAIL = 3 + REQUEST_PAYLOAD  # CMD SEQ P0 P1 P2 CHK after the WAIT
WINDOW_FLOOR_S = 0.002  # shortest real run window, so a host can still answer at factor 0
IDLE_FLOOR_S = 0.05  # shortest real idle window: a silent host then costs 20 READY/s, not 500


class Shutdown(Exception):
    """The emulator was asked to stop."""


class DownloadStart(Exception):
    """The host reset the Stamp into download mode (see :mod:`pac_sim.stamp_download`).

    ``data`` holds the bytes received with the first identification byte, not yet echoed."""

    def __init__(self, data: bytes) -> None:
        super().__init__("download started")
        self.data = data


@dataclass(frozen=True)
class Faults:
    """Fault injection, per byte in both directions, plus a mute device; ``targets`` aim at
    chosen bytes of chosen frames (:mod:`pac_sim.targeted`)."""

    drop_prob: float = 0.0
    corrupt_prob: float = 0.0
    silent: bool = False
    targets: tuple[FrameTarget, ...] = ()

    def __post_init__(self) -> None:
        for name in ("drop_prob", "corrupt_prob"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {v}")


class PtyLine:
    """A pseudo-terminal pair; the host opens :attr:`path` with pyserial."""

    def __init__(
        self,
        factor: float = 0.0,
        *,
        echo: bool = False,
        faults: Faults = Faults(),
        rng: np.random.Generator | None = None,
        window_floor_s: float = WINDOW_FLOOR_S,
        idle_floor_s: float = IDLE_FLOOR_S,
    ) -> None:
        if factor < 0:
            raise ValueError(f"real-time factor must be >= 0, got {factor}")
        self.factor = factor
        self.echo = echo
        self.faults = faults
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.window_floor_s = window_floor_s
        self.idle_floor_s = idle_floor_s
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave, termios.TCSANOW)  # no line editing, no local echo
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self._slave)
        self._stopped = threading.Event()
        self._wake_r, self._wake_w = os.pipe()  # stop() wakes a blocked select at once
        self._closed = False
        self.sent = 0
        self.received = 0
        self.lost = 0  # bytes that arrived while the Stamp was not listening
        self._last_rx = time.monotonic()  # when the host last sent a byte
        self.muted = False  # set by mute(): the cable is pulled, nothing reaches the host
        self.aimed_out = FrameTargets(tuple(t for t in faults.targets if t.outgoing))
        self.aimed_in = FrameTargets(tuple(t for t in faults.targets if not t.outgoing))
        self.aimed_packets = PacketTargets(faults.targets)

    # ---- faults -------------------------------------------------------------------------------

    def _damage(self, data: bytes, outgoing: bool) -> bytes:
        """The line's faults on bytes going out (to the host) or coming in: targeted, then
        random."""
        data = (self.aimed_out if outgoing else self.aimed_in).apply(data)
        f = self.faults
        if not (f.drop_prob or f.corrupt_prob) or not data:
            return data
        out = bytearray()
        for b in data:
            if f.drop_prob and self.rng.random() < f.drop_prob:
                continue
            if f.corrupt_prob and self.rng.random() < f.corrupt_prob:
                b ^= int(self.rng.integers(1, 256))
            out.append(b)
        return bytes(out)

    # ---- raw I/O ------------------------------------------------------------------------------

    def _write(self, data: bytes) -> None:
        try:
            os.write(self.master, data)
        except BlockingIOError:
            pass  # nobody reads the port and its buffer is full: bytes fall on the floor
        except OSError:
            pass

    def read_raw(self, timeout: float) -> bytes:
        """Bytes from the host within ``timeout``, untouched: no echo, no damage, no reset
        detection (the download protocol reads this way)."""
        if self._stopped.is_set():
            raise Shutdown
        r, _, _ = select.select([self.master, self._wake_r], [], [], max(0.0, timeout))
        if self._stopped.is_set():
            raise Shutdown
        if not r:
            return b""
        try:
            data = os.read(self.master, 256)
        except (BlockingIOError, OSError):
            return b""
        self._last_rx = time.monotonic()
        return data

    def _read(self, timeout: float, downloads: bool = True) -> bytes:
        """Bytes from the host within ``timeout`` (echoed if pin 16), after line damage.

        Raises :class:`DownloadStart` when they begin a download (the host reset the Stamp),
        unless ``downloads`` is False."""
        before = self._last_rx
        data = self.read_raw(timeout)
        if not data:
            return b""
        if downloads and not self.faults.silent and starts_download(
            data[0], self._last_rx - before
        ):
            raise DownloadStart(data)  # a reset: whatever the firmware was doing ends here
        if self.echo and not (self.faults.silent or self.muted):
            self._write(data)
        return self._damage(data, outgoing=False)

    def write_raw(self, data: bytes) -> None:
        """Bytes to the host, untouched and at once (the download protocol)."""
        self._write(data)

    def _sleep(self, seconds: float) -> None:
        if seconds > 0 and self._stopped.wait(seconds):
            raise Shutdown
        if self._stopped.is_set():
            raise Shutdown

    # ---- what the firmware sees ---------------------------------------------------------------

    def send(self, data: bytes) -> None:
        """SEROUT: the whole frame is on the host's side when its last byte would have arrived."""
        self._sleep(len(data) * BYTE_S * self.factor)
        self.deliver(data)

    def deliver(self, data: bytes) -> None:
        """Bytes from the Stamp to the host now, through the line's faults (no pacing: for a
        driver that paces the bytes itself, as the PBASIC host link does)."""
        if self.faults.silent or self.muted:
            return
        data = self._damage(data, outgoing=True)
        self.sent += len(data)
        self._write(data)

    def receive(self, timeout: float, downloads: bool = False) -> bytes:
        """Bytes from the host within ``timeout``: echoed if pin 16, damaged by the line's
        faults (for a driver that runs a program's own SERIN). With ``downloads``, the start of
        a download raises :class:`DownloadStart`, as in :meth:`serin`."""
        return self._read(timeout, downloads=downloads)

    def mute(self) -> None:
        """From now on nothing the Stamp sends reaches the host (a pulled cable, a dead
        level shifter): the host sees a robot that stopped answering."""
        self.muted = True

    def pause(self, seconds: float) -> None:
        """Time passes (walking, EEPROM writes); host bytes arriving meanwhile are lost."""
        deadline = time.monotonic() + seconds * self.factor
        while True:
            rem = deadline - time.monotonic()
            self.lost += len(self._read(rem)) if rem > 0 else self._drain()
            if rem <= 0:
                return

    def _drain(self) -> int:
        n = 0
        while chunk := self._read(0):
            n += len(chunk)
        return n

    def discard_input(self) -> None:
        """Lose whatever arrived while the Stamp was not listening (call before READY)."""
        self.lost += self._drain()

    def serin(self, timeout_s: float, idle: bool = False) -> bytes | None:
        """SERIN [WAIT($A5,$5A,$03), cmd, seq, p0, p1, p2, chk] with a timeout restarted by every
        byte. Returns the 6 bytes or None on timeout. Bytes after the request are lost.
        The real window is ``timeout_s`` x factor, at least the idle or run floor."""
        floor = self.idle_floor_s if idle else self.window_floor_s
        window = max(timeout_s * self.factor, floor)
        deadline = time.monotonic() + window
        k = 0
        got = bytearray()
        first = None
        while True:
            rem = deadline - time.monotonic()
            if rem <= 0:
                return None
            data = self._read(rem)
            if not data:
                continue
            self.received += len(data)
            first = first or time.monotonic()
            deadline = time.monotonic() + window
            for i, b in enumerate(data):
                if k < len(WAIT_PATTERN):
                    k = k + 1 if b == WAIT_PATTERN[k] else (1 if b == WAIT_PATTERN[0] else 0)
                    continue
                got.append(b)
                if len(got) == REQUEST_TAIL:
                    self.lost += len(data) - i - 1
                    # the request's last byte arrives 9 byte times after its first
                    self._sleep(first + 9 * BYTE_S * self.factor - time.monotonic())
                    return bytes(got)

    def stop(self) -> None:
        if self._stopped.is_set():
            return
        self._stopped.set()
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass

    def close(self) -> None:
        """Stop and release the pty. Idempotent: closing twice must not close descriptor
        numbers the process has since handed to someone else."""
        if self._closed:
            return
        self._closed = True
        self.stop()
        for fd in (self.master, self._slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
