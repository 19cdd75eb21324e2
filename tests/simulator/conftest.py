"""Fixtures for talking to the emulator through a real pseudo-terminal with pyserial."""

from __future__ import annotations

import time
from collections import deque

import pytest

from pac_protocol.decoder import FrameDecoder
from pac_protocol.frame import Frame
from pac_protocol.messages import Cmd
from pac_protocol.port import open_port
from pac_sim.runner import SimConfig, SimStamp


class RawHost:
    """A bare host: pyserial on the emulator's pty, frames decoded, nothing else."""

    def __init__(self, port) -> None:
        self.port = port
        self.decoder = FrameDecoder()
        self.frames: deque[Frame] = deque()

    def frame(self, timeout: float = 3.0) -> Frame | None:
        deadline = time.monotonic() + timeout
        while not self.frames:
            if time.monotonic() > deadline:
                return None
            data = self.port.read(max(1, self.port.in_waiting))
            self.frames.extend(self.decoder.feed(data))
        return self.frames.popleft()

    def until(self, cmd: int, timeout: float = 3.0) -> list[Frame]:
        """Frames up to and including the first with CMD ``cmd``."""
        got = []
        while True:
            f = self.frame(timeout)
            assert f is not None, f"no {Cmd(cmd).name} frame; got {[g.hex() for g in got]}"
            got.append(f)
            if f.cmd == cmd:
                return got

    def send(self, data: bytes) -> None:
        self.port.write(data)


@pytest.fixture
def make_sim():
    """Factory: an emulator (not yet started) with a pyserial port opened on it."""
    made = []

    def make(started: bool = True, **kw) -> tuple[SimStamp, object]:
        kw.setdefault("factor", 0.0)
        sim = SimStamp(SimConfig(**kw))
        port = open_port(sim.path, timeout=0.02)
        made.append((sim, port))
        if started:
            sim.start()
        return sim, port

    yield make
    for sim, port in made:
        port.close()
        sim.close()


@pytest.fixture
def raw_host():
    """The RawHost class (fixtures are how test modules here share helpers)."""
    return RawHost
