"""The emulator against the shared vectors, through a real pty and pyserial: every invalid and
refused frame gets the reply the vectors expect, and every scripted exchange is byte-exact."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pac_protocol.messages import Cmd, Hello

ROOT = Path(__file__).resolve().parents[2]
FRAMES = json.loads((ROOT / "protocol" / "vectors" / "frames.json").read_text())
EXCHANGES = json.loads((ROOT / "protocol" / "vectors" / "exchanges.json").read_text())
REQUEST_LIKE = [v for v in FRAMES["invalid"] if not bytes.fromhex(v["hex"])[3:4] >= b"\x80"]


def _answer_after_ready(host, data: bytes):
    host.until(Cmd.READY)
    host.send(data)
    return host.frame()


@pytest.mark.parametrize("v", REQUEST_LIKE + FRAMES["refused"], ids=lambda v: v["name"])
def test_stamp_answers_each_vector(make_sim, raw_host, v):
    sim, port = make_sim(idle_floor_s=0.15)
    host = raw_host(port)
    f = _answer_after_ready(host, bytes.fromhex(v["hex"]))
    if v["stamp_reply"] is None:
        assert f is not None and f.cmd == Cmd.READY  # ignored: timed out, listening again
    else:
        assert f is not None and f.hex() == v["stamp_reply"]
    # nothing was acted on, and the Stamp still answers a good request
    assert [c for c, _ in sim.stamp.executed] == []
    assert sim.eeprom.writes == 0
    f = _answer_after_ready(host, Hello().encode(77))
    while f.cmd == Cmd.READY:  # the timeout READY of an ignored frame may come first
        host.send(Hello().encode(77))
        f = host.frame()
    assert f.cmd == Cmd.HELLO_R and f.seq == 77


@pytest.mark.parametrize("ex", EXCHANGES["exchanges"], ids=lambda e: e["name"])
def test_exchange_is_byte_exact(make_sim, raw_host, ex):
    sim, port = make_sim(started=False, idle_floor_s=1.0, window_floor_s=0.2)
    for i, (g, r) in enumerate(ex["eeprom"]):
        sim.eeprom.write_gene(i, g, r)
    if ex["eeprom"]:
        sim.eeprom.write_count(len(ex["eeprom"]))
    sim.start()
    host = raw_host(port)
    last = None
    for step in ex["steps"]:
        if step["from"] == "host":
            assert last is not None and last.cmd == Cmd.READY, (
                f"host step {step['note']} not after READY"
            )
            host.send(bytes.fromhex(step["hex"]))
            continue
        f = host.frame()
        while f is not None and last is not None and f.cmd == Cmd.READY and f == last:
            f = host.frame()  # the idle loop repeating READY
        assert f is not None, f"expected {step['note']}, got nothing"
        assert f.hex() == step["hex"], f"expected {step['note']} ({step['hex']}), got {f.hex()}"
        last = f
