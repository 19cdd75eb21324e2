"""Typed messages of PROTOCOL.md section 5, and their conversion to and from frames.

Messages only enforce that each field fits its bytes; whether a value is *allowed* (gait id
<= 31, ...) is the Stamp's to answer with a NAK, so tests can send out-of-range arguments.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import IntEnum
from typing import ClassVar

from pac_protocol.errors import BadPayload, UnknownCommand
from pac_protocol.frame import REQUEST_PAYLOAD, Frame

PROTOCOL_VERSION = 1
MAX_GENES = 9
MAX_GAIT = 31
MAX_REPS = 63
POWER_ON_MOD = 65536  # the Stamp's counts (gait cycles since power-on, ...) are 16 bits


class Cmd(IntEnum):
    HELLO = 0x01
    STATUS = 0x02
    LOAD = 0x03
    RUN = 0x04
    STEP = 0x05
    STOP = 0x06
    READ = 0x07
    NAK = 0x80
    HELLO_R = 0x81
    STATUS_R = 0x82
    LOAD_ACK = 0x83
    RUN_ACK = 0x84
    STEP_ACK = 0x85
    STOP_ACK = 0x86
    GENE_R = 0x87
    READY = 0xC0
    BOOT = 0xC1
    CYCLE = 0xC2
    DONE = 0xC3


class Err(IntEnum):
    BAD_CHECK = 0x01
    UNKNOWN_CMD = 0x02
    BAD_ARG = 0x03
    BUSY = 0x04
    EMPTY = 0x05


class State(IntEnum):
    IDLE = 0
    RUN = 1
    STEP = 2


class Reason(IntEnum):
    COMPLETED = 0
    STOPPED = 1


def _u8(v: int, name: str) -> int:
    if not 0 <= v <= 0xFF:
        raise ValueError(f"{name}={v} does not fit a byte")
    return v


def _u16(v: int, name: str) -> bytes:
    if not 0 <= v <= 0xFFFF:
        raise ValueError(f"{name}={v} does not fit 16 bits")
    return bytes([v & 0xFF, v >> 8])


def _le(b: bytes) -> int:
    return b[0] | b[1] << 8


@dataclass(frozen=True)
class Message:
    """Base: subclasses set CMD and implement ``payload`` / ``from_payload``."""

    CMD: ClassVar[Cmd]
    LEN: ClassVar[int] = 0

    def payload(self) -> bytes:
        return b""

    @classmethod
    def from_payload(cls, p: bytes) -> Message:
        return cls()

    def to_frame(self, seq: int = 0) -> Frame:
        p = self.payload()
        if self.CMD < 0x80:  # requests are padded to the fixed request size
            p = p.ljust(REQUEST_PAYLOAD, b"\x00")
        return Frame(int(self.CMD), seq, p)

    def encode(self, seq: int = 0) -> bytes:
        return self.to_frame(seq).encode()

    def describe(self) -> str:
        args = ", ".join(f"{f.name}={getattr(self, f.name)}" for f in fields(self))
        return f"{self.CMD.name}({args})"


# ---- requests (host -> Stamp) ----------------------------------------------------------------


@dataclass(frozen=True)
class Hello(Message):
    CMD: ClassVar[Cmd] = Cmd.HELLO
    LEN: ClassVar[int] = 3


@dataclass(frozen=True)
class Status(Message):
    CMD: ClassVar[Cmd] = Cmd.STATUS
    LEN: ClassVar[int] = 3


@dataclass(frozen=True)
class Stop(Message):
    CMD: ClassVar[Cmd] = Cmd.STOP
    LEN: ClassVar[int] = 3


@dataclass(frozen=True)
class Load(Message):
    """Store gene ``index`` of a turn cycle of ``count`` genes."""

    CMD: ClassVar[Cmd] = Cmd.LOAD
    LEN: ClassVar[int] = 3
    count: int
    index: int
    gait: int
    reps: int

    def payload(self) -> bytes:
        if not (0 <= self.count <= 15 and 0 <= self.index <= 15):
            raise ValueError(f"count={self.count} and index={self.index} must fit 4 bits each")
        return bytes([self.count << 4 | self.index, _u8(self.gait, "gait"), _u8(self.reps, "reps")])

    @classmethod
    def from_payload(cls, p: bytes) -> Load:
        return cls(p[0] >> 4, p[0] & 15, p[1], p[2])


@dataclass(frozen=True)
class Run(Message):
    """Run the stored turn cycle for ``cycles`` gait cycles."""

    CMD: ClassVar[Cmd] = Cmd.RUN
    LEN: ClassVar[int] = 3
    cycles: int

    def payload(self) -> bytes:
        return _u16(self.cycles, "cycles")

    @classmethod
    def from_payload(cls, p: bytes) -> Run:
        return cls(_le(p[0:2]))


@dataclass(frozen=True)
class Step(Message):
    """Execute gait cycle ``gait`` ``reps`` times."""

    CMD: ClassVar[Cmd] = Cmd.STEP
    LEN: ClassVar[int] = 3
    gait: int
    reps: int

    def payload(self) -> bytes:
        return bytes([_u8(self.gait, "gait")]) + _u16(self.reps, "reps")

    @classmethod
    def from_payload(cls, p: bytes) -> Step:
        return cls(p[0], _le(p[1:3]))


@dataclass(frozen=True)
class Read(Message):
    CMD: ClassVar[Cmd] = Cmd.READ
    LEN: ClassVar[int] = 3
    index: int

    def payload(self) -> bytes:
        return bytes([_u8(self.index, "index")])

    @classmethod
    def from_payload(cls, p: bytes) -> Read:
        return cls(p[0])


# ---- replies (Stamp -> host, SEQ of the request) ---------------------------------------------


@dataclass(frozen=True)
class Nak(Message):
    CMD: ClassVar[Cmd] = Cmd.NAK
    LEN: ClassVar[int] = 2
    command: int
    error: int

    def payload(self) -> bytes:
        return bytes([_u8(self.command, "command"), _u8(self.error, "error")])

    @classmethod
    def from_payload(cls, p: bytes) -> Nak:
        return cls(p[0], p[1])

    def error_name(self) -> str:
        try:
            return Err(self.error).name
        except ValueError:
            return f"error {self.error:#04x}"


@dataclass(frozen=True)
class HelloReply(Message):
    CMD: ClassVar[Cmd] = Cmd.HELLO_R
    LEN: ClassVar[int] = 3
    protocol: int
    firmware: int
    max_genes: int

    def payload(self) -> bytes:
        return bytes(
            [
                _u8(self.protocol, "protocol"),
                _u8(self.firmware, "firmware"),
                _u8(self.max_genes, "max_genes"),
            ]
        )

    @classmethod
    def from_payload(cls, p: bytes) -> HelloReply:
        return cls(p[0], p[1], p[2])


@dataclass(frozen=True)
class StatusReply(Message):
    CMD: ClassVar[Cmd] = Cmd.STATUS_R
    LEN: ClassVar[int] = 6
    state: int
    count: int
    done: int
    power_on: int

    def payload(self) -> bytes:
        return (
            bytes([_u8(self.state, "state"), _u8(self.count, "count")])
            + _u16(self.done, "done")
            + _u16(self.power_on, "power_on")
        )

    @classmethod
    def from_payload(cls, p: bytes) -> StatusReply:
        return cls(p[0], p[1], _le(p[2:4]), _le(p[4:6]))


@dataclass(frozen=True)
class LoadAck(Message):
    CMD: ClassVar[Cmd] = Cmd.LOAD_ACK


@dataclass(frozen=True)
class RunAck(Message):
    CMD: ClassVar[Cmd] = Cmd.RUN_ACK


@dataclass(frozen=True)
class StepAck(Message):
    CMD: ClassVar[Cmd] = Cmd.STEP_ACK


@dataclass(frozen=True)
class StopAck(Message):
    CMD: ClassVar[Cmd] = Cmd.STOP_ACK


@dataclass(frozen=True)
class GeneReply(Message):
    CMD: ClassVar[Cmd] = Cmd.GENE_R
    LEN: ClassVar[int] = 4
    count: int
    index: int
    gait: int
    reps: int

    def payload(self) -> bytes:
        return bytes(
            [
                _u8(v, n)
                for v, n in (
                    (self.count, "count"),
                    (self.index, "index"),
                    (self.gait, "gait"),
                    (self.reps, "reps"),
                )
            ]
        )

    @classmethod
    def from_payload(cls, p: bytes) -> GeneReply:
        return cls(p[0], p[1], p[2], p[3])


# ---- reports (Stamp -> host, unasked, SEQ 0) -------------------------------------------------


@dataclass(frozen=True)
class Ready(Message):
    CMD: ClassVar[Cmd] = Cmd.READY
    LEN: ClassVar[int] = 1
    state: int

    def payload(self) -> bytes:
        return bytes([_u8(self.state, "state")])

    @classmethod
    def from_payload(cls, p: bytes) -> Ready:
        return cls(p[0])


@dataclass(frozen=True)
class Boot(Message):
    CMD: ClassVar[Cmd] = Cmd.BOOT
    LEN: ClassVar[int] = 2
    protocol: int
    firmware: int

    def payload(self) -> bytes:
        return bytes([_u8(self.protocol, "protocol"), _u8(self.firmware, "firmware")])

    @classmethod
    def from_payload(cls, p: bytes) -> Boot:
        return cls(p[0], p[1])


@dataclass(frozen=True)
class Cycle(Message):
    """A finished gait cycle: its id, cycles done in this run, cycles since power-on."""

    CMD: ClassVar[Cmd] = Cmd.CYCLE
    LEN: ClassVar[int] = 5
    gait: int
    done: int
    power_on: int

    def payload(self) -> bytes:
        return (
            bytes([_u8(self.gait, "gait")])
            + _u16(self.done, "done")
            + _u16(self.power_on, "power_on")
        )

    @classmethod
    def from_payload(cls, p: bytes) -> Cycle:
        return cls(p[0], _le(p[1:3]), _le(p[3:5]))


@dataclass(frozen=True)
class Done(Message):
    CMD: ClassVar[Cmd] = Cmd.DONE
    LEN: ClassVar[int] = 3
    reason: int
    done: int

    def payload(self) -> bytes:
        return bytes([_u8(self.reason, "reason")]) + _u16(self.done, "done")

    @classmethod
    def from_payload(cls, p: bytes) -> Done:
        return cls(p[0], _le(p[1:3]))


MESSAGES: dict[int, type[Message]] = {
    int(c.CMD): c
    for c in (
        Hello,
        Status,
        Load,
        Run,
        Step,
        Stop,
        Read,
        Nak,
        HelloReply,
        StatusReply,
        LoadAck,
        RunAck,
        StepAck,
        StopAck,
        GeneReply,
        Ready,
        Boot,
        Cycle,
        Done,
    )
}
ACKS: dict[int, type[Message]] = {
    int(Cmd.LOAD): LoadAck,
    int(Cmd.RUN): RunAck,
    int(Cmd.STEP): StepAck,
    int(Cmd.STOP): StopAck,
}


def reply_cmd(request_cmd: int) -> int:
    """The CMD of a successful reply to a request: the request's CMD with bit 7 set."""
    return request_cmd | 0x80


def decode_message(frame: Frame) -> Message:
    """The typed message of a frame; UnknownCommand or BadPayload if this version has none."""
    cls = MESSAGES.get(frame.cmd)
    if cls is None:
        raise UnknownCommand(
            f"CMD {frame.cmd:02X} is not defined in protocol version {PROTOCOL_VERSION}"
        )
    if len(frame.payload) != cls.LEN:
        raise BadPayload(f"{cls.CMD.name} needs LEN {cls.LEN}, got {len(frame.payload)}")
    return cls.from_payload(frame.payload)
