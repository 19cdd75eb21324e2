"""The protocol's scripted exchanges replayed against the firmware running in the interpreter:
every frame the Stamp sends must match the vectors byte for byte. Skipped where the checkout
has no firmware or no vectors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pac_sim.pbasic import Stamp

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware" / "servobot.bs2"
VECTORS = ROOT / "protocol" / "vectors" / "exchanges.json"
SYNC = b"\xa5\x5a"
READY = 0xC0

pytestmark = pytest.mark.skipif(not (FIRMWARE.exists() and VECTORS.exists()),
                                reason="needs firmware/servobot.bs2 and protocol/vectors")
EXCHANGES = json.loads(VECTORS.read_text())["exchanges"] if VECTORS.exists() else []


class Replay:
    """The Stamp's side of an exchange: frames it sent, and bytes the host feeds it."""

    def __init__(self, genes: list[list[int]]) -> None:
        self.s = Stamp.from_file(FIRMWARE)
        data = self.s.program.symbols.data_addr
        if genes:
            self.s.eeprom.mem[data["TCCOUNT"]] = len(genes)
            for i, (gid, reps) in enumerate(genes):
                self.s.eeprom.mem[data["TCGENES"] + 2 * i:data["TCGENES"] + 2 * i + 2] = \
                    bytes([gid, reps])
        self.buf = b""
        self.last: bytes | None = None

    def next_frame(self, expected: bytes) -> bytes:
        """The next frame the Stamp sends, letting SERIN timeouts pass; a READY repeating the
        previous one (the idle loop timing out) is skipped unless it is what is expected."""
        for _ in range(200):
            frame = self._pop()
            if frame is None:
                w = self.s.run_until_serin(10.0)
                self.buf += self.s.output.take(16)
                if self._complete():
                    continue
                self.s.advance(w.deadline_us - self.s.now_us + 1)
                continue
            if frame == self.last and frame[3] == READY and frame != expected:
                continue
            self.last = frame
            return frame
        raise AssertionError("the Stamp sent no further frame")

    def _complete(self) -> bool:
        i = self.buf.find(SYNC)
        return i >= 0 and len(self.buf) >= i + 3 and len(self.buf) >= i + 6 + self.buf[i + 2]

    def _pop(self) -> bytes | None:
        if not self._complete():
            return None
        i = self.buf.find(SYNC)
        assert i == 0, f"bytes outside a frame: {self.buf[:i].hex()}"
        n = 6 + self.buf[2]
        frame, self.buf = self.buf[:n], self.buf[n:]
        return frame

    def send(self, data: bytes) -> None:
        assert self.s.waiting() is not None, "the host may send only while the Stamp listens"
        self.s.feed(data, echo=False)


@pytest.mark.parametrize("exchange", EXCHANGES, ids=[e["name"] for e in EXCHANGES])
def test_exchange(exchange):
    r = Replay(exchange["eeprom"])
    for k, step in enumerate(exchange["steps"]):
        data = bytes.fromhex(step["hex"])
        if step["from"] == "host":
            r.send(data)
        else:
            got = r.next_frame(data)
            assert got.hex(" ").upper() == step["hex"], f"step {k}: {step.get('note')}"
