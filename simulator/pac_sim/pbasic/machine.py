"""The virtual BASIC Stamp II: runs a compiled PBASIC program against virtual peripherals.

A driver (tests, the emulator) loads a program, runs it until it blocks in SERIN, feeds bytes
or lets Stamp time pass, and reads what came out: SEROUT bytes, the servo trace, DEBUG text,
EEPROM. All times are Stamp time in microseconds, never host time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pac_host.errors import InputError

from . import clock
from .compiler import Compiled, Compiler, SerinSpec
from .errors import PbasicRuntimeError, StampEnded, StampNotListening
from .parser import parse
from .peripherals import (
    EEPROM_SIZE,
    PROGRAMMING_PORT,
    Eeprom,
    SerialLine,
    SerialOutput,
    ServoRecorder,
)

READY, SERIN, ENDED = "ready", "serin", "ended"


@dataclass
class SerinWait:
    """Where the Stamp waits: pin, baudmode, since when and until when (None: no timeout)."""

    pin: int
    baudmode: int
    since_us: int
    deadline_us: int | None
    line: int


class _Session:
    """A SERIN in progress: its generator and timing."""

    def __init__(self, spec: SerinSpec, pin: int, baud: int, start: int, timeout_ms: int | None,
                 nxt: int) -> None:
        self.spec, self.pin, self.baud, self.nxt = spec, pin, baud, nxt
        self.listen_from = start
        self.t = start
        self.timeout_us = None if timeout_ms is None else timeout_ms * 1000
        self.deadline = None if timeout_ms is None else start + self.timeout_us
        self.gen = spec.consumer()
        next(self.gen)


class Stamp:
    """One BS2 running one program. Build with ``Stamp.from_source`` or ``Stamp.from_file``."""

    def __init__(self, stmts: list, filename: str = "<source>",
                 eeprom_image: bytes | None = None, program_start: int | None = None) -> None:
        self.ram = [0] * 16
        self.stack: list[int] = []
        self.inputs = 0  # levels driven onto the pins from outside (bit per pin)
        self.eeprom = Eeprom()
        self.output = SerialOutput()
        self.servo = ServoRecorder()
        self.lines: dict[int, SerialLine] = {}
        self.debug_log = bytearray()
        self.icount = 0
        self.extra_us = 0
        self.state = READY
        self.halted_by: str | None = None
        self.session: _Session | None = None
        self.program: Compiled = Compiler(stmts, filename, self).compile()
        self.filename = filename
        image = self.program.data_image
        if eeprom_image is not None:
            self._check_image(eeprom_image)
            image = eeprom_image
        self.eeprom.mem[:] = image
        self.program_start = program_start  # first EEPROM byte of the program's tokens
        self.pc = 0

    @classmethod
    def from_source(cls, text: str, filename: str = "<source>", **kw) -> Stamp:
        """Parse and compile PBASIC source; syntax errors name file:line."""
        return cls(parse(text, filename), filename, **kw)

    @classmethod
    def from_file(cls, path: str | Path, **kw) -> Stamp:
        """Parse and compile a PBASIC source file (read as Latin-1, as the editor saves it)."""
        try:
            text = Path(path).read_text(encoding="latin-1")
        except OSError as e:
            raise InputError(f"{path}: cannot read: {e.strerror}") from None
        return cls.from_source(text, str(path), **kw)

    def _check_image(self, image: bytes) -> None:
        if len(image) != EEPROM_SIZE:
            raise InputError(f"tokenizer image must be {EEPROM_SIZE} bytes, got {len(image)}")
        for addr in sorted(self.program.symbols.data_used):
            if image[addr] != self.program.data_image[addr]:
                raise InputError(f"tokenizer image differs from the DATA at address {addr}: "
                                 f"{image[addr]} != {self.program.data_image[addr]}")

    def reset(self) -> None:
        """Reset as the BS2 does (power glitch, DTR): RAM cleared, program from the top; the
        EEPROM keeps what was written, Stamp time and the recorded traces go on."""
        self.ram[:] = [0] * len(self.ram)
        self.stack.clear()
        self.session = None
        self.state = READY
        self.halted_by = None
        self.pc = 0
        self.io_sync()

    # ---- clock ----
    @property
    def now_us(self) -> int:
        """Stamp time since reset, in microseconds."""
        return self.icount * clock.INSTRUCTION_US + self.extra_us

    @property
    def now_s(self) -> float:
        return self.now_us / 1e6

    def _set_time(self, t_us: int) -> None:
        self.extra_us = t_us - self.icount * clock.INSTRUCTION_US

    # ---- pins ----
    def io_sync(self) -> None:
        """Recompute INS: output pins read their own OUT bit, inputs what the outside drives."""
        r = self.ram
        r[0] = ((self.inputs & ~r[2]) | (r[1] & r[2])) & 0xFFFF

    def set_input(self, pin: int, level: int) -> None:
        """Drive an input pin from outside (a switch, a sensor)."""
        self.inputs = (self.inputs | (1 << pin)) if level else (self.inputs & ~(1 << pin))
        self.io_sync()

    # ---- variables (for drivers and tests) ----
    def var(self, name: str) -> int:
        """The value of a declared (or predefined) variable."""
        loc = self.program.symbols.vars[name.upper()]
        reg, sh = divmod(loc.off, 16)
        return (self.ram[reg] >> sh) & ((1 << loc.size) - 1)

    def set_var(self, name: str, value: int) -> None:
        """Store into a declared (or predefined) variable, truncated to its size."""
        loc = self.program.symbols.vars[name.upper()]
        reg, sh = divmod(loc.off, 16)
        mask = (1 << loc.size) - 1
        self.ram[reg] = (self.ram[reg] & ~(mask << sh) & 0xFFFF) | ((value & mask) << sh)
        self.io_sync()

    def line_at(self, pc: int | None = None) -> int:
        return self.program.lines[self.pc if pc is None else pc]

    # ---- running ----
    def run(self, max_us: int | None = None, *, silent: bool = False) -> str:
        """Run until blocked in SERIN, ended, or max_us more Stamp time passed.

        silent=True treats the serial lines as quiet until the limit: a SERIN whose timeout
        falls before the limit times out and the program goes on. Returns the state: "serin"
        (waiting for bytes), "ended" or "ready" (time limit reached while running).
        """
        limit = None if max_us is None else self.now_us + max_us
        while True:
            if self.state == ENDED:
                return ENDED
            if self.state == SERIN and not self._serin_progress(limit if silent else None,
                                                                  silent):
                return SERIN
            if limit is not None and self.now_us >= limit:
                return READY
            self._burst(limit)

    def _burst(self, limit: int | None) -> None:
        """Run plain instructions until a special one (then run it), or until the time limit."""
        code = self.program.code
        pc = self.pc
        step = clock.INSTRUCTION_US
        nmax = 1 << 62 if limit is None else max(1, -(-(limit - self.now_us) // step))
        n = 0
        try:
            while n < nmax:
                npc = code[pc]()
                if npc < 0:
                    break
                pc = npc
                n += 1
        finally:
            self.icount += n
            self.pc = pc
        if n < nmax:
            npc = self.program.specials[pc]()
            self.icount += 1
            if npc >= 0:
                self.pc = npc

    def call(self, label: str, max_s: float = 10.0, **variables: int) -> None:
        """Run one subroutine on its own, as GOSUB would: set variables, jump to label, stop at
        its RETURN. For testing a firmware's routines (e.g. one gait cycle) in isolation."""
        pos = self.program.labels.get(label.upper())
        if pos is None:
            raise KeyError(f"no label {label} in {self.filename}")
        for name, value in variables.items():
            self.set_var(name, value)
        self.stack.clear()
        self.stack.append(len(self.program.code) - 1)
        self.session = None
        self.state = READY
        self.pc = pos
        state = self.run(int(max_s * 1e6), silent=True)
        if state != ENDED or self.halted_by != "CALL":
            where = f"{self.filename}:{self.line_at()}"
            raise RuntimeError(f"{where}: {label} did not RETURN within {max_s:g} s ({state})")
        self.state = READY

    def run_until_serin(self, limit_s: float = 5.0) -> SerinWait:
        """Run until the program waits in SERIN; raise StampNotListening if it does not within
        limit_s of Stamp time, StampEnded if it reaches END/STOP."""
        state = self.run(int(limit_s * 1e6))
        if state == SERIN:
            return self.waiting()
        if state == ENDED:
            raise StampEnded(f"{self.filename}:{self.line_at()}: the program reached "
                             f"{self.halted_by} at {self.now_s:.3f} s without waiting in SERIN")
        raise StampNotListening(
            f"{self.filename}: the Stamp is not listening: no SERIN within {limit_s:g} s of "
            f"Stamp time (running line {self.line_at()})")

    def run_for(self, seconds: float) -> str:
        """Let seconds of Stamp time pass with quiet serial lines (SERIN timeouts fire)."""
        return self.run(int(seconds * 1e6), silent=True)

    def waiting(self) -> SerinWait | None:
        """Where the Stamp waits in SERIN, or None when it does not."""
        s = self.session
        if self.state != SERIN or s is None:
            return None
        return SerinWait(s.pin, s.baud, s.t, s.deadline, s.spec.line)

    # ---- serial input ----
    def line(self, pin: int) -> SerialLine:
        if pin not in self.lines:
            self.lines[pin] = SerialLine()
        return self.lines[pin]

    def feed(self, data: bytes, pin: int | None = None, at_us: int | None = None,
             baudmode: int = 84, echo: bool = True) -> None:
        """Bytes sent towards a pin starting at Stamp time at_us (default: now), back to back at
        baudmode. Bytes that start before a SERIN listens are lost. The programming port (16)
        echoes every byte it receives, as the BS2's does (echo=False leaves the echo out)."""
        if pin is None:
            pin = self.session.pin if self.state == SERIN and self.session else PROGRAMMING_PORT
        t = self.now_us if at_us is None else at_us
        frame = clock.byte_us(baudmode)
        frames = self.line(pin).send(bytes(data), t, frame)
        if pin == PROGRAMMING_PORT and echo:
            for start, _, b in frames:
                self.output.write(PROGRAMMING_PORT, start, frame, bytes((b,)))

    def advance(self, us: int) -> None:
        """Let us of Stamp time pass while the Stamp waits in SERIN or has ended; a SERIN whose
        timeout falls inside that time times out (the program then waits at its next run)."""
        target = self.now_us + us
        if self.state == SERIN:
            self._serin_progress(target, True)
        elif self.state != ENDED:
            raise RuntimeError("advance() is for a Stamp waiting in SERIN; use run() otherwise")
        if self.state != READY:
            self._set_time(max(self.now_us, target))

    def serin(self, spec: SerinSpec, nxt: int) -> int:
        """Begin a SERIN (called by its compiled instruction): -1 while it waits for bytes."""
        timeout = spec.timeout() if spec.timeout is not None else None
        self.session = _Session(spec, spec.pin(), spec.baud(), self.now_us, timeout, nxt)
        self.state = SERIN
        return self.pc if self._serin_progress(None, False) else -1

    def _serin_progress(self, quiet_until: int | None, silent: bool) -> bool:
        """Consume queued bytes. True when the SERIN finished or timed out, False while it
        waits. silent: no other bytes come before quiet_until (None: ever)."""
        s = self.session
        line = self.line(s.pin)
        while True:
            got = line.take(s.listen_from, s.deadline)
            if got is None:
                if not silent:
                    return False
                if s.deadline is not None and (quiet_until is None or s.deadline <= quiet_until):
                    self._finish_serin(s.deadline, s.spec.tlabel.pos)
                    return True
                if quiet_until is not None:  # waited in silence until then
                    self._set_time(max(self.now_us, quiet_until))
                return False
            end, b = got
            s.t = end
            if s.timeout_us is not None:
                s.deadline = end + s.timeout_us
            try:
                s.gen.send(b)
            except StopIteration:
                self._finish_serin(end, s.nxt)
                return True

    def _finish_serin(self, t_us: int, nxt: int) -> None:
        self._set_time(max(self.now_us, t_us))
        self.session = None
        self.state = READY
        self.pc = nxt

    # ---- other specials (called by compiled instructions; each returns the next pc) ----
    def halt(self, kind: str, pc: int) -> int:
        self.state = ENDED
        self.halted_by = kind
        self.pc = pc
        return -1

    def timed(self, kind: str, arg: int, nxt: int) -> int:
        if kind == "PAUSE":
            self.extra_us += arg * 1000
        elif kind == "NAP":
            self.extra_us += clock.NAP_BASE_US << min(arg, 7)
        else:  # SLEEP
            self.extra_us += arg * 1_000_000
        return nxt

    def pulsout(self, pin: int, width: int, nxt: int) -> int:
        self.ram[2] |= 1 << pin
        self.io_sync()
        self.servo.record(self.now_us, pin, width)
        self.extra_us += 2 * width
        return nxt

    def serout(self, pin: int, baudmode: int, pace_ms: int, data: bytes, nxt: int) -> int:
        frame = clock.byte_us(baudmode)
        t = self.now_us
        for i, b in enumerate(data):
            if i and pace_ms:
                t += pace_ms * 1000
            t = self.output.write(pin, t, frame, bytes((b,)))
        self._set_time(t)
        return nxt

    def debug(self, data: bytes, nxt: int) -> int:
        self.debug_log.extend(data)
        self.extra_us += len(data) * clock.byte_us(clock.DEBUG_BAUDMODE)
        return nxt

    def eeprom_write(self, addr: int, data: bytes, nxt: int) -> int:
        for i, b in enumerate(data):
            a = (addr + i) % EEPROM_SIZE
            if self.program_start is not None and a >= self.program_start:
                raise PbasicRuntimeError(self.filename, self.line_at(),
                                         f"WRITE to EEPROM address {a} overwrites the program "
                                         f"(its tokens start at {self.program_start})")
            self.eeprom.write(a, b)
        self.extra_us += clock.WRITE_US * len(data)
        return nxt

    @property
    def debug_text(self) -> str:
        return self.debug_log.decode("latin-1")
