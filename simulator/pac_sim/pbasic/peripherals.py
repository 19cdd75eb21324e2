"""Virtual peripherals of the Stamp: serial lines, the servo recorder and the EEPROM.

Each is a small class the interpreter talks to and a driver (tests, the emulator) inspects.
Times are Stamp time in microseconds.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

EEPROM_SIZE = 2048
PROGRAMMING_PORT = 16


class SerialLine:
    """Bytes travelling towards one Stamp pin; the Stamp has no receive buffer.

    ``send`` queues bytes back to back from a start time; SERIN takes the bytes whose start bit
    comes at or after the moment it began listening; earlier ones are lost (counted in ``lost``).
    """

    def __init__(self) -> None:
        self.queue: deque[tuple[int, int, int]] = deque()  # (start_us, end_us, byte)
        self.free_at = 0
        self.lost = 0
        self.received = 0

    def send(self, data: bytes, at_us: int, frame_us: int) -> list[tuple[int, int, int]]:
        """Queue bytes starting at at_us (or when the previous byte ends); returns the frames."""
        t = max(at_us, self.free_at)
        frames = []
        for b in data:
            frames.append((t, t + frame_us, b))
            t += frame_us
        self.free_at = t
        self.queue.extend(frames)
        return frames

    def take(self, listen_from: int, deadline: int | None) -> tuple[int, int] | None:
        """The next byte (end_us, value) received by a SERIN listening since listen_from whose
        start bit comes no later than deadline; None if no such byte is queued."""
        q = self.queue
        while q and q[0][0] < listen_from:
            q.popleft()
            self.lost += 1
        if not q or (deadline is not None and q[0][0] > deadline):
            return None
        start, end, b = q.popleft()
        self.received += 1
        return end, b


@dataclass
class SerialOutput:
    """Every byte the Stamp (or the programming port's echo) put on a pin: (end_us, pin, byte)."""

    frames: list[tuple[int, int, int]] = field(default_factory=list)
    taken: int = 0

    def write(self, pin: int, start_us: int, frame_us: int, data: bytes) -> int:
        """Record data sent from start_us; returns the time the last stop bit ends."""
        t = start_us
        for b in data:
            t += frame_us
            self.frames.append((t, pin, b))
        return t

    def data(self, pin: int | None = None) -> bytes:
        """All bytes so far (of one pin, or every pin), in time order."""
        fr = sorted(self.frames, key=lambda f: f[0])
        return bytes(b for _, p, b in fr if pin is None or p == pin)

    def take(self, pin: int | None = None) -> bytes:
        """The bytes written since the previous take (in time order)."""
        new = sorted(self.frames[self.taken:], key=lambda f: f[0])
        self.taken = len(self.frames)
        return bytes(b for _, p, b in new if pin is None or p == pin)


@dataclass(frozen=True, slots=True)
class Pulse:
    """One PULSOUT: its start (Stamp us), pin and width in 2 us units."""

    t_us: int
    pin: int
    width: int


class ServoRecorder:
    """Records every PULSOUT; the world model turns this trace into thrust."""

    def __init__(self) -> None:
        self.pulses: list[Pulse] = []

    def record(self, t_us: int, pin: int, width: int) -> None:
        self.pulses.append(Pulse(t_us, pin, width))

    def on_pin(self, pin: int) -> list[Pulse]:
        return [p for p in self.pulses if p.pin == pin]

    def refresh_periods_us(self, pin: int) -> list[int]:
        """Intervals between successive pulses on one pin (the servo refresh period)."""
        ts = [p.t_us for p in self.pulses if p.pin == pin]
        return [b - a for a, b in zip(ts, ts[1:], strict=False)]


class Eeprom:
    """The 2 KB EEPROM: DATA from address 0 up, program tokens from the top.

    Counts the writes to each cell (the part is rated for about 10 million per cell).
    """

    def __init__(self, image: bytes | None = None) -> None:
        if image is not None and len(image) > EEPROM_SIZE:
            raise ValueError(f"EEPROM image of {len(image)} bytes exceeds {EEPROM_SIZE}")
        self.mem = bytearray(EEPROM_SIZE)
        if image is not None:
            self.mem[: len(image)] = image
        self.writes = [0] * EEPROM_SIZE

    def read(self, addr: int) -> int:
        return self.mem[addr % EEPROM_SIZE]

    def write(self, addr: int, value: int) -> None:
        a = addr % EEPROM_SIZE
        self.mem[a] = value & 0xFF
        self.writes[a] += 1
