"""The firmware's own PBASIC, executed statement by statement, speaks protocol/PROTOCOL.md.

Each test scripts a host conversation in the spec's byte-exact frames (section 8) and checks
that the bytes the firmware sends are exactly the spec's. The host answers only inside SERIN
(the Stamp leads); a scripted silence is a SERIN that times out.
"""

from __future__ import annotations

from collections import Counter

import pytest
from fw_build import SOURCE
from fw_pbasic import Host, Machine, Program, Stop

BOOT = "A5 5A 02 C1 00 01 01 3A"
READY_IDLE = "A5 5A 01 C0 00 00 3E"
READY_RUN = "A5 5A 01 C0 00 01 3D"
SILENCE = None


def hx(s: str) -> bytes:
    return bytes.fromhex(s)


def fr(cmd: int, seq: int, *payload: int) -> str:
    """A frame not among the spec's examples, built by the spec's rule (2.1, 2.2)."""
    body = bytes([len(payload), cmd, seq, *payload])
    return "A5 5A " + (body + bytes([0xFF - sum(body) % 256])).hex(" ")


class ScriptHost(Host):
    """Plays a list of ("S", frame) expected-from-Stamp and ("H", frame | None) host turns.

    At each SERIN the host checks that everything the Stamp sent so far is exactly the expected
    frames, then answers with the next host turn if the Stamp has sent every frame before it;
    otherwise it stays silent (the SERIN times out). ("H", None) is an explicit silence."""

    def __init__(self, script: list[tuple[str, str | None]]) -> None:
        super().__init__()
        self.script = script
        self.i = 0
        self.expected = bytearray()
        self.timeouts: list[int] = []
        self.silences = 0

    def _take_stamp_lines(self) -> None:
        while self.i < len(self.script) and self.script[self.i][0] == "S":
            frame = hx(self.script[self.i][1])
            if len(self.expected) + len(frame) > len(self.received):
                return
            self.expected += frame
            self.i += 1

    def serin(self, timeout_ms: int) -> bytes | None:
        self._take_stamp_lines()
        assert bytes(self.received) == bytes(self.expected), (
            f"Stamp sent {bytes(self.received).hex(' ')}\nexpected  {bytes(self.expected).hex(' ')}"
        )
        if self.i >= len(self.script):
            raise Stop
        self.timeouts.append(timeout_ms)
        who, frame = self.script[self.i]
        if who == "S":  # the Stamp still has frames to send: the host keeps quiet
            self.silences += 1
            assert self.silences < 50, "the Stamp keeps listening but never sends what is expected"
            return None
        self.i += 1
        self.silences = 0
        return None if frame is None else hx(frame)


@pytest.fixture(scope="module")
def prog() -> Program:
    return Program(SOURCE.read_text(encoding="latin-1"))


def converse(prog: Program, script, machine: Machine | None = None) -> tuple[Machine, ScriptHost]:
    host = ScriptHost(script)
    m = machine or Machine(prog, host)
    m.host = host
    with pytest.raises(Stop):
        m.run("Boot")
    host._take_stamp_lines()
    assert host.i == len(script), "the firmware stopped before the script ended"
    assert bytes(host.received) == bytes(host.expected)
    return m, host


def test_spec_exchange_load_and_run_two_gait_cycles(prog):
    """PROTOCOL.md section 8, the whole exchange, preceded by BOOT."""
    m, host = converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", "A5 5A 03 01 01 00 00 00 FA"),   # HELLO seq 1
        ("S", "A5 5A 03 81 01 01 01 09 6F"),                      # HELLO_R v1 fw1 9
        ("S", READY_IDLE), ("H", "A5 5A 03 03 02 10 0C 0A D1"),   # LOAD 1 gene (12, 10)
        ("S", "A5 5A 00 83 02 7A"),
        ("S", READY_IDLE), ("H", "A5 5A 03 04 03 02 00 00 F3"),   # RUN 2
        ("S", "A5 5A 00 84 03 78"),
        ("S", "A5 5A 05 C2 00 0C 01 00 01 00 2A"),                # CYCLE 1
        ("S", READY_RUN), ("H", SILENCE),
        ("S", "A5 5A 05 C2 00 0C 02 00 02 00 28"),                # CYCLE 2
        ("S", "A5 5A 03 C3 00 00 02 00 37"),                      # DONE completed
        ("S", READY_IDLE),
    ])
    assert host.timeouts == [500, 500, 500, 100]  # T_IDLE when idle, T_RUN between cycles
    assert m.eeprom[4:7] == bytes([1, 12, 10])  # TcCount, gene 0
    # two gait cycles of 58 activations (other FOR loops pulse nothing). Gait 12 = right turn,
    # strength 12: the last 29 - 24 = 5 thrust activations of each half drag the right hips
    # (0 and 4 in the first half, 2 in the second), so those get no pulse.
    walked = [a for a in m.activations if a.pulses]
    assert len(walked) == 2 * 58
    sizes = Counter(len(a.pulses) for a in walked)
    assert sizes == {12: 2 * 48, 10: 2 * 5, 11: 2 * 5}


def test_spec_request_reply_examples(prog):
    converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", "A5 5A 03 01 01 00 00 00 FA"),
        ("S", "A5 5A 03 81 01 01 01 09 6F"),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 03 30 0C 0A B0"),   # LOAD 3 genes
        ("S", "A5 5A 00 83 03 79"),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 04 31 03 02 BF"),
        ("S", "A5 5A 00 83 04 78"),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 05 32 1B 3F 68"),
        ("S", "A5 5A 00 83 05 77"),
        ("S", READY_IDLE), ("H", "A5 5A 03 07 09 01 00 00 EB"),   # READ gene 1
        ("S", "A5 5A 04 87 09 03 01 03 02 62"),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 05 32 1B 3F 69"),   # damaged: bad check
        ("S", "A5 5A 02 80 05 03 01 74"),
        ("S", READY_IDLE), ("H", fr(0x09, 0x0A, 0, 0, 0)),   # unknown command 09
        ("S", "A5 5A 02 80 0A 09 02 68"),
        ("S", READY_IDLE), ("H", fr(0x03, 0x0B, 0x0A, 0, 0)),   # LOAD count 0: bad arg
        ("S", "A5 5A 02 80 0B 03 03 6C"),
        ("S", READY_IDLE), ("H", "A5 5A 03 06 08 00 00 00 EE"),   # STOP while idle: ACK only
        ("S", "A5 5A 00 86 08 71"),
        ("S", READY_IDLE), ("H", "A5 5A 03 02 02 00 00 00 F8"),   # STATUS
        ("S", fr(0x82, 0x02, 0, 3, 0, 0, 0, 0)),
        ("S", READY_IDLE),
    ])


def test_empty_turn_cycle_is_refused(prog):
    converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", fr(0x04, 0x0D, 2, 0, 0)),   # RUN 2, nothing stored
        ("S", "A5 5A 02 80 0D 04 05 67"),
        ("S", READY_IDLE),
    ])


def test_stop_busy_and_retry_while_running(prog):
    m, _ = converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 02 10 0C 0A D1"),   # LOAD (12, 10)
        ("S", "A5 5A 00 83 02 7A"),
        ("S", READY_IDLE), ("H", fr(0x04, 0x0C, 200, 0, 0)),   # RUN 200, seq 12
        ("S", fr(0x84, 0x0C)),
        ("S", "A5 5A 05 C2 00 0C 01 00 01 00 2A"),
        ("S", READY_RUN), ("H", fr(0x04, 0x0C, 200, 0, 0)),    # retry of the RUN: ACK again
        ("S", fr(0x84, 0x0C)),
        ("S", "A5 5A 05 C2 00 0C 02 00 02 00 28"),                # ... and it was not restarted
        ("S", READY_RUN), ("H", fr(0x04, 0x0D, 200, 0, 0)),    # a new RUN: busy
        ("S", "A5 5A 02 80 0D 04 04 68"),
        ("S", fr(0xC2, 0, 12, 3, 0, 3, 0)),
        ("S", READY_RUN), ("H", fr(0x06, 0x0E, 0, 0, 0)),    # STOP
        ("S", fr(0x86, 0x0E)),
        ("S", fr(0xC3, 0, 1, 3, 0)),                      # DONE stopped after 3
        ("S", READY_IDLE),
    ])
    assert len([a for a in m.activations if a.pulses]) == 3 * 58


def test_retried_load_is_not_written_twice(prog):
    m, _ = converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 02 10 0C 0A D1"),
        ("S", "A5 5A 00 83 02 7A"),
        ("S", READY_IDLE), ("H", "A5 5A 03 03 02 10 0C 0A D1"),   # the same LOAD again
        ("S", "A5 5A 00 83 02 7A"),
        ("S", READY_IDLE),
    ])
    assert m.writes == 4  # count 0, gene (2 bytes), count 1: once



def test_stored_count_over_9_reads_as_0(prog):
    m = Machine(prog)
    m.eeprom[prog.labels["TCCOUNT"]] = 12  # never written by the firmware: damaged EEPROM
    converse(prog, [
        ("S", BOOT),
        ("S", READY_IDLE), ("H", fr(0x07, 0x02, 0, 0, 0)),         # READ gene 0
        ("S", fr(0x87, 0x02, 0, 0, 0, 0)),
        ("S", READY_IDLE), ("H", fr(0x02, 0x03, 0, 0, 0)),         # STATUS
        ("S", fr(0x82, 0x03, 0, 0, 0, 0, 0, 0)),
        ("S", READY_IDLE), ("H", fr(0x04, 0x04, 1, 0, 0)),         # RUN 1: empty
        ("S", fr(0x80, 0x04, 0x04, 0x05)),
        ("S", READY_IDLE),
    ], m)
