"""Connect a running Stamp to a host over a byte stream (a pseudo-terminal, a socket pair).

``serve`` runs the program in Stamp time and moves bytes both ways with the BS2's rules: what the
Stamp SEROUTs on the host pin goes to the host; what the host sends reaches the program only
while it waits in SERIN; bytes sent while it walks are lost; the programming port may echo.
Stamp time is paced against wall time by ``factor`` (1 = real time, 0 = as fast as possible);
a waiting SERIN always gets at least ``floor_s`` of wall time so a host can answer at factor 0.
This is the piece the emulator uses for ``--firmware``: it supplies the link and reads the
servo trace (``stamp.servo``) through ``on_chunk`` to move its world.
"""

from __future__ import annotations

import os
import select
import threading
import time
from collections.abc import Callable
from typing import Protocol

from .machine import ENDED, SERIN, Stamp
from .peripherals import PROGRAMMING_PORT

CHUNK_US = 20_000  # run at most this much Stamp time between looks at the link


class ByteLink(Protocol):
    """The host side of the wire, as the Stamp sees it."""

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """Bytes the host sent, waiting up to timeout_s for the first one (b"" if none)."""
        ...


class FdLink:
    """A ByteLink over a file descriptor, e.g. the master side of ``os.openpty()``."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]

    def read(self, timeout_s: float) -> bytes:
        ready, _, _ = select.select([self.fd], [], [], max(0.0, timeout_s))
        if not ready:
            return b""
        try:
            return os.read(self.fd, 4096)
        except OSError:  # the host closed its side
            return b""


def serve(stamp: Stamp, link: ByteLink, *, pin: int = PROGRAMMING_PORT, factor: float = 0.0,
          floor_s: float = 0.05, echo: bool = False, stop: threading.Event | None = None,
          on_chunk: Callable[[Stamp], None] | None = None) -> str:
    """Run stamp against link until it ends or stop is set; returns the final state."""
    stop = stop or threading.Event()
    wall0 = time.monotonic()
    stamp0 = stamp.now_us
    sent = len(stamp.output.frames)

    def pace(t_us: int) -> None:
        """Sleep until wall time catches up with Stamp time t_us (scaled by factor)."""
        if factor > 0:
            ahead = (t_us - stamp0) / 1e6 * factor - (time.monotonic() - wall0)
            if ahead > 0:
                time.sleep(ahead)

    def flush() -> None:
        """Send the new output on the host pin, each byte when its Stamp time comes."""
        nonlocal sent
        frames = sorted(stamp.output.frames[sent:], key=lambda f: f[0])
        sent = len(stamp.output.frames)
        for t_us, p, b in frames:
            if p == pin:
                pace(t_us)
                link.write(bytes((b,)))

    while not stop.is_set():
        state = stamp.run(CHUNK_US)
        if on_chunk is not None:
            on_chunk(stamp)
        flush()
        pace(stamp.now_us)
        if state == ENDED:
            return ENDED
        if state != SERIN:
            busy = link.read(0.0)
            if busy:  # sent while the program is busy: lost when it next listens
                stamp.feed(busy, pin=pin, echo=echo)
                flush()
            continue
        w = stamp.waiting()
        remaining = None if w.deadline_us is None else max(0, w.deadline_us - stamp.now_us)
        wait_s = floor_s if remaining is None else max(floor_s, remaining / 1e6 * factor)
        t0 = time.monotonic()
        data = link.read(wait_s)
        if data:
            waited_us = int((time.monotonic() - t0) / factor * 1e6) if factor > 0 else 0
            if remaining is not None:  # it came inside the window: before the timeout fires
                waited_us = min(waited_us, max(0, remaining - 1))
            if waited_us:
                stamp.advance(waited_us)
            stamp.feed(data, pin=pin, echo=echo)
            flush()
        elif remaining is not None:
            stamp.advance(remaining + 1)  # silence: the SERIN times out
    return stamp.state
