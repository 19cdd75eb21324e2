"""The firmware, run in the PBASIC interpreter, answers with PROTOCOL.md's byte-exact frames.

The protocol's scripted exchanges (protocol/vectors/exchanges.json) are replayed against the
firmware in tests/pbasic; these tests add the request/reply examples of PROTOCOL.md section 8,
the listening timeouts, and what the exchanges do not show (a retried LOAD is not written
twice, a damaged stored count reads as 0).
"""

from __future__ import annotations

import pytest
from fw_build import SOURCE
from fw_stamp import converse, label

from pac_protocol.messages import GeneReply, Nak, Read, Run, Status, StatusReply
from pac_sim.pbasic import Stamp

BOOT = "A5 5A 02 C1 00 01 01 3A"
READY_IDLE = "A5 5A 01 C0 00 00 3E"
READY_RUN = "A5 5A 01 C0 00 01 3D"


def S(hexstr: str) -> tuple[str, bytes]:  # noqa: N802 - the Stamp's turn, as in the spec
    return "S", bytes.fromhex(hexstr)


def H(hexstr: str | None) -> tuple[str, bytes | None]:  # noqa: N802 - the host's turn
    return "H", None if hexstr is None else bytes.fromhex(hexstr)


@pytest.fixture
def stamp() -> Stamp:
    return Stamp.from_file(SOURCE)


def test_spec_exchange_with_its_listening_timeouts(stamp):
    """PROTOCOL.md section 8's whole exchange; idle SERINs wait T_IDLE, run windows T_RUN."""
    timeouts = converse(stamp, [
        S(BOOT),
        S(READY_IDLE), H("A5 5A 03 01 01 00 00 00 FA"), S("A5 5A 03 81 01 01 01 09 6F"),
        S(READY_IDLE), H("A5 5A 03 03 02 10 0C 0A D1"), S("A5 5A 00 83 02 7A"),
        S(READY_IDLE), H("A5 5A 03 04 03 02 00 00 F3"), S("A5 5A 00 84 03 78"),
        S("A5 5A 05 C2 00 0C 01 00 01 00 2A"), S(READY_RUN), H(None),
        S("A5 5A 05 C2 00 0C 02 00 02 00 28"), S("A5 5A 03 C3 00 00 02 00 37"),
        S(READY_IDLE),
    ])
    assert timeouts == [500, 500, 500, 100]


def test_spec_request_reply_examples(stamp):
    converse(stamp, [
        S(BOOT),
        S(READY_IDLE), H("A5 5A 03 03 03 30 0C 0A B0"), S("A5 5A 00 83 03 79"),   # LOAD 3 genes
        S(READY_IDLE), H("A5 5A 03 03 04 31 03 02 BF"), S("A5 5A 00 83 04 78"),
        S(READY_IDLE), H("A5 5A 03 03 05 32 1B 3F 68"), S("A5 5A 00 83 05 77"),
        S(READY_IDLE), H("A5 5A 03 07 09 01 00 00 EB"),                           # READ gene 1
        S("A5 5A 04 87 09 03 01 03 02 62"),
        S(READY_IDLE), H("A5 5A 03 03 05 32 1B 3F 69"), S("A5 5A 02 80 05 03 01 74"),  # bad CHK
        S(READY_IDLE), H("A5 5A 03 06 08 00 00 00 EE"), S("A5 5A 00 86 08 71"),   # STOP idle
        S(READY_IDLE), H(Status().encode(2).hex()),
        S(StatusReply(0, 3, 0, 0).encode(2).hex()),
        S(READY_IDLE),
    ])


def test_retried_load_is_acknowledged_but_not_written_again(stamp):
    tc = label(stamp, "TcCount")
    converse(stamp, [
        S(BOOT),
        S(READY_IDLE), H("A5 5A 03 03 02 10 0C 0A D1"), S("A5 5A 00 83 02 7A"),
        S(READY_IDLE), H("A5 5A 03 03 02 10 0C 0A D1"), S("A5 5A 00 83 02 7A"),   # the retry
        S(READY_IDLE),
    ])
    assert stamp.eeprom.mem[tc : tc + 3] == bytes([1, 12, 10])
    assert stamp.eeprom.writes[tc] == 2  # invalidated, then committed: once
    assert stamp.eeprom.writes[tc + 1] == stamp.eeprom.writes[tc + 2] == 1


def test_damaged_stored_count_reads_as_0(stamp):
    stamp.eeprom.mem[label(stamp, "TcCount")] = 12  # never written by the firmware
    converse(stamp, [
        S(BOOT),
        S(READY_IDLE), H(Read(0).encode(2).hex()), S(GeneReply(0, 0, 0, 0).encode(2).hex()),
        S(READY_IDLE), H(Status().encode(3).hex()), S(StatusReply(0, 0, 0, 0).encode(3).hex()),
        S(READY_IDLE), H(Run(1).encode(4).hex()), S(Nak(4, 5).encode(4).hex()),  # EMPTY
        S(READY_IDLE),
    ])
