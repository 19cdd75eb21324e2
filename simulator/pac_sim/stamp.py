"""The Stamp's firmware, emulated at the protocol level exactly as PROTOCOL.md describes it.

The code is shaped like the PBASIC it stands for: a boot, an idle loop of READY + SERIN, one
dispatch of a received request in the order of checks of PROTOCOL.md 5.1, and a run loop that
walks one gait cycle, reports it, then listens for T_RUN before the next.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from itertools import cycle, repeat
from typing import Protocol

from pac_protocol.frame import REQUEST_PAYLOAD, check_value
from pac_protocol.messages import (
    ACKS,
    MAX_GAIT,
    MAX_GENES,
    MAX_REPS,
    PROTOCOL_VERSION,
    Boot,
    Cmd,
    Cycle,
    Done,
    Err,
    GeneReply,
    HelloReply,
    Message,
    Nak,
    Ready,
    Reason,
    State,
    StatusReply,
)
from pac_protocol.timing import T_CYCLE_S, T_EEPROM_WRITE_S, T_IDLE_S, T_PROCESS_S, T_RUN_S
from pac_sim.eeprom import Eeprom
from pac_sim.line import DownloadStart, Shutdown
from pac_sim.stamp_download import StampDownload, serve_downloads, servobot_eeprom
from pac_sim.world import World

FIRMWARE_VERSION = 1


class Line(Protocol):
    def send(self, data: bytes) -> None: ...
    def serin(self, timeout_s: float, idle: bool = False) -> bytes | None: ...
    def discard_input(self) -> None: ...
    def pause(self, seconds: float) -> None: ...


class _Reset(Exception):
    """A (simulated) reset: RAM is gone, the program starts again."""


class StampEmulator:
    """Runs the firmware loop on a :class:`Line` until the line is stopped.

    ``reset_after``: reset once, after that many gait cycles since the emulator started, in the
    middle of sending that cycle's CYCLE report (a reset mid-frame). ``mute_after``: after that
    many gait cycles (that cycle's CYCLE report still sent), nothing more reaches the host.
    """

    def __init__(
        self,
        line: Line,
        eeprom: Eeprom | None = None,
        world: World | None = None,
        *,
        protocol_version: int = PROTOCOL_VERSION,
        firmware_version: int = FIRMWARE_VERSION,
        reset_after: int | None = None,
        mute_after: int | None = None,
    ) -> None:
        self.line = line
        self.eeprom = eeprom or Eeprom()
        self.world = world
        self.protocol_version = protocol_version
        self.firmware_version = firmware_version
        self.reset_after = reset_after
        self.mute_after = mute_after
        self.boots = 0
        self.cycles_total = 0  # gait cycles since the emulator started, across resets
        self.executed: list[tuple[int, int]] = []  # (cmd, seq) of every request acted on
        self.downloads: list[StampDownload] = []  # every download session, in order
        self.error = None  # the model never stops serving on its own (the firmware backend may)
        self._reset_pending = threading.Event()
        self._boot_state()

    def _boot_state(self) -> None:
        self.state = State.IDLE
        self.last_seq = 0
        self.done = 0
        self.power_on = 0  # unwrapped; reported mod 65536

    # ---- program ------------------------------------------------------------------------------

    def run(self) -> None:
        """The firmware's main program; returns when the line is stopped."""
        try:
            while True:
                try:
                    if self.firmware_version is None:
                        self._foreign()
                    self._boot()
                    while True:
                        self._check_reset()
                        req = self._listen(State.IDLE, T_IDLE_S)
                        if req is not None:
                            self._dispatch(req)
                except _Reset:
                    continue
                except DownloadStart as d:
                    serve_downloads(self.line, d.data, self._eeprom_image, self._flashed,
                                self.line.aimed_packets)
        except Shutdown:
            return

    # ---- being flashed (the BS2 download protocol, pac_sim.stamp_download) -------------------

    def _eeprom_image(self) -> bytes:
        return servobot_eeprom(self.firmware_version or 0, bytes(self.eeprom.image))

    def _flashed(self, dl: StampDownload) -> None:
        """After a download: run what was flashed. A completed download of the ServoBot firmware
        sets the firmware version and the turn cycle from the image; anything else (another
        program, or a download cut short after some packets) leaves no firmware that answers."""
        self.downloads.append(dl)
        if not dl.finished and not dl.packets:
            return  # identification failed: nothing was written, the old program runs again
        version = dl.firmware_version if dl.finished else None
        self.firmware_version = version
        if version is not None:
            self.eeprom.write_flashed(dl.eeprom)

    def _foreign(self) -> None:
        """A program that is not the ServoBot firmware: says nothing, until the next download."""
        while True:
            self.line.serin(T_IDLE_S, idle=True)

    def reset(self) -> None:
        """Press the reset button: takes effect at the Stamp's next step."""
        self._reset_pending.set()

    def _check_reset(self) -> None:
        if self._reset_pending.is_set():
            self._reset_pending.clear()
            raise _Reset

    def _boot(self) -> None:
        self._boot_state()
        self.boots += 1
        if self.world is not None:
            self.world.power_on = 0
        self._send(Boot(self.protocol_version, self.firmware_version))

    def _send(self, m: Message, seq: int = 0) -> None:
        self.line.send(m.encode(seq))

    def _listen(self, state: State, timeout_s: float) -> bytes | None:
        self.line.discard_input()
        self._send(Ready(state))
        return self.line.serin(timeout_s, idle=state == State.IDLE)

    # ---- one request --------------------------------------------------------------------------

    def _dispatch(self, req: bytes) -> bool:
        """Answer one request in the order of checks of PROTOCOL.md 5.1. True if it was STOP
        during a run (the caller ends the run)."""
        cmd, seq, p0, p1, p2, chk = req
        self.line.pause(T_PROCESS_S)
        if check_value(bytes([REQUEST_PAYLOAD, cmd, seq, p0, p1, p2])) != chk:
            self._send(Nak(cmd, Err.BAD_CHECK), seq)
            return False
        acting = cmd in (Cmd.LOAD, Cmd.RUN, Cmd.STEP)
        if acting and seq == self.last_seq:
            self._send(ACKS[cmd](), seq)
            return False
        if acting and self.state != State.IDLE:
            self._send(Nak(cmd, Err.BUSY), seq)
            return False
        handler = {
            Cmd.HELLO: self._hello,
            Cmd.STATUS: self._status,
            Cmd.LOAD: self._load,
            Cmd.RUN: self._run,
            Cmd.STEP: self._step,
            Cmd.STOP: self._stop,
            Cmd.READ: self._read,
        }.get(cmd)
        if handler is None:
            self._send(Nak(cmd, Err.UNKNOWN_CMD), seq)
            return False
        return handler(seq, p0, p1, p2)

    def _nak_arg(self, cmd: Cmd, seq: int) -> bool:
        self._send(Nak(cmd, Err.BAD_ARG), seq)
        return False

    def _hello(self, seq: int, *_: int) -> bool:
        self.last_seq = 0
        self._send(HelloReply(self.protocol_version, self.firmware_version, MAX_GENES), seq)
        return False

    def _status(self, seq: int, *_: int) -> bool:
        self._send(
            StatusReply(self.state, self.eeprom.count, self.done & 0xFFFF, self.power_on & 0xFFFF),
            seq,
        )
        return False

    def _read(self, seq: int, p0: int, *_: int) -> bool:
        if p0 >= MAX_GENES:
            return self._nak_arg(Cmd.READ, seq)
        self._send(GeneReply(self.eeprom.count, p0, *self.eeprom.gene(p0)), seq)
        return False

    def _stop(self, seq: int, *_: int) -> bool:
        self.executed.append((Cmd.STOP, seq))
        self._send(ACKS[Cmd.STOP](), seq)
        return self.state != State.IDLE

    def _load(self, seq: int, p0: int, gait: int, reps: int) -> bool:
        count, index = p0 >> 4, p0 & 15
        if not (
            1 <= count <= MAX_GENES and index < count and gait <= MAX_GAIT and reps <= MAX_REPS
        ):
            return self._nak_arg(Cmd.LOAD, seq)
        writes = 2
        if index == 0:
            self.eeprom.write_count(0)
            writes += 1
        self.eeprom.write_gene(index, gait, reps)
        if index == count - 1:
            self.eeprom.write_count(count)
            writes += 1
        self.line.pause(writes * T_EEPROM_WRITE_S)
        self.last_seq = seq
        self.executed.append((Cmd.LOAD, seq))
        self._send(ACKS[Cmd.LOAD](), seq)
        return False

    def _run(self, seq: int, lo: int, hi: int, _: int) -> bool:
        n = lo | hi << 8
        genes = [(g, r) for g, r in self.eeprom.turn_cycle() if r > 0]
        if n == 0:
            return self._nak_arg(Cmd.RUN, seq)
        if not genes:
            self._send(Nak(Cmd.RUN, Err.EMPTY), seq)
            return False
        self.last_seq = seq
        self.executed.append((Cmd.RUN, seq))
        self._send(ACKS[Cmd.RUN](), seq)
        gaits = (g for g, r in cycle(genes) for _ in range(r))
        self._execute(State.RUN, gaits, n)
        return False

    def _step(self, seq: int, gait: int, lo: int, hi: int) -> bool:
        reps = lo | hi << 8
        if gait > MAX_GAIT or reps == 0:
            return self._nak_arg(Cmd.STEP, seq)
        self.last_seq = seq
        self.executed.append((Cmd.STEP, seq))
        self._send(ACKS[Cmd.STEP](), seq)
        self._execute(State.STEP, repeat(gait), reps)
        return False

    # ---- walking ------------------------------------------------------------------------------

    def _execute(self, state: State, gaits: Iterator[int], n: int) -> None:
        """Walk ``n`` gait cycles, reporting each and listening between them (PROTOCOL.md 4.3)."""
        self.state, self.done = state, 0
        prev: int | None = None
        try:
            for k in range(n):
                self._check_reset()
                self.line.pause(T_CYCLE_S)
                g = next(gaits)
                n0 = self.power_on
                self.power_on += 1
                self.done += 1
                self.cycles_total += 1
                if self.world is not None:
                    self.world.advance(g, n0, prev)
                prev = g
                report = Cycle(g, self.done & 0xFFFF, self.power_on & 0xFFFF).encode()
                if self.reset_after is not None and self.cycles_total == self.reset_after:
                    self.line.send(report[: len(report) // 2])
                    raise _Reset
                self.line.send(report)
                if self.mute_after is not None and self.cycles_total == self.mute_after:
                    self.line.mute()
                if k < n - 1:
                    req = self._listen(state, T_RUN_S)
                    if req is not None and self._dispatch(req):
                        self._send(Done(Reason.STOPPED, self.done & 0xFFFF))
                        return
            self._send(Done(Reason.COMPLETED, self.done & 0xFFFF))
        finally:
            self.state = State.IDLE
