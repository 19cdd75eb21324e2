"""The codec against protocol/vectors/frames.json and the examples printed in PROTOCOL.md."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from pac_protocol import errors
from pac_protocol.decoder import FrameDecoder
from pac_protocol.frame import parse_frame
from pac_protocol.messages import MESSAGES, Cmd, decode_message

ROOT = Path(__file__).resolve().parents[2]
VECTORS = json.loads((ROOT / "protocol" / "vectors" / "frames.json").read_text())
ERRORS = {
    c.code: c
    for c in vars(errors).values()
    if isinstance(c, type) and issubclass(c, errors.ProtocolError) and hasattr(c, "code")
}


def raw(v: dict) -> bytes:
    return bytes.fromhex(v["hex"])


@pytest.mark.parametrize("v", VECTORS["valid"], ids=lambda v: v["name"])
def test_valid_vector_decodes_and_reencodes(v):
    b = raw(v)
    assert b[:2] == b"\xa5\x5a" and sum(b[2:]) % 256 == 0xFF  # the check rule, independently
    assert b[2] == len(b) - 6
    f = parse_frame(b)
    assert f.seq == v["seq"] and f.is_reply == (v["direction"] != "request")
    m = decode_message(f)
    assert m.CMD.name == v["message"]
    assert {k: getattr(m, k) for k in v["fields"]} == v["fields"]
    assert type(m)(**v["fields"]).encode(v["seq"]) == b
    assert FrameDecoder().feed(b"\x00\xa5" + b + b"\xa5") == [f]


@pytest.mark.parametrize("v", VECTORS["invalid"], ids=lambda v: v["name"])
def test_invalid_vector_raises_its_error(v):
    b = raw(v)
    if v["parse_error"]:
        with pytest.raises(ERRORS[v["parse_error"]]):
            parse_frame(b)
        if v["parse_error"] != "trailing_bytes":
            d = FrameDecoder()
            assert d.feed(b) + d.expire() == []  # never a frame from a broken one
    else:
        with pytest.raises(ERRORS[v["decode_error"]]):
            decode_message(parse_frame(b))


def test_every_message_type_has_a_vector():
    names = {v["message"] for v in VECTORS["valid"]}
    assert names == {c.CMD.name for c in MESSAGES.values()}
    assert {e.code for e in ERRORS.values()} >= {v["parse_error"] for v in VECTORS["invalid"]} - {
        None
    }


def test_protocol_md_examples_are_in_the_vectors():
    """Every hex frame printed in PROTOCOL.md obeys the check rule and is a vector or exchange."""
    text = (ROOT / "protocol" / "PROTOCOL.md").read_text()
    shown = set(re.findall(r"A5 5A(?: [0-9A-F]{2})+", text))
    assert len(shown) >= 30
    ex = json.loads((ROOT / "protocol" / "vectors" / "exchanges.json").read_text())
    known = {v["hex"] for v in VECTORS["valid"] + VECTORS["invalid"]}
    known |= {s["hex"] for e in ex["exchanges"] for s in e["steps"]}
    for h in shown:
        b = bytes.fromhex(h)
        if len(b) != 6 + b[2]:
            continue  # the PBASIC snippet's SEROUT list is not an example frame
        assert sum(b[2:]) % 256 == 0xFF, h
        assert h in known, h


def test_exchanges_use_every_message_type():
    """The byte-exact exchanges (run through the emulator) cover every CMD the protocol has."""
    ex = json.loads((ROOT / "protocol" / "vectors" / "exchanges.json").read_text())
    cmds = {bytes.fromhex(s["hex"])[3] for e in ex["exchanges"] for s in e["steps"]}
    assert cmds == set(MESSAGES)


def test_request_frames_are_nine_bytes():
    for v in VECTORS["valid"]:
        if v["direction"] == "request":
            assert len(raw(v)) == 9
    assert Cmd.HELLO | 0x80 == Cmd.HELLO_R
