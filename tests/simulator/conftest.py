"""Fixtures for talking to the emulator through a real pseudo-terminal with pyserial.

``make_sim`` is parametrized over the emulator's two backends: ``model`` (the protocol-level
model of the firmware) and ``firmware`` (firmware/servobot.bs2 run by the PBASIC interpreter),
so every test that talks to an emulator checks both the same way.
"""

from __future__ import annotations

import re
import time
from collections import deque
from pathlib import Path

import pytest

from pac_protocol.decoder import FrameDecoder
from pac_protocol.frame import Frame
from pac_protocol.messages import Cmd
from pac_protocol.port import open_port
from pac_sim.runner import SimConfig, SimStamp

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "servobot.bs2"
BACKENDS = ("model", "firmware")


def firmware_variant(tmp: Path, **cons: int) -> str:
    """A copy of the firmware with some CONs changed (e.g. PROTO_VER), as a maintainer would."""
    src = FIRMWARE.read_text(encoding="latin-1")
    for name, value in cons.items():
        src, n = re.subn(rf"^({name}\s+CON )\S+", rf"\g<1>{value}", src, flags=re.M)
        assert n == 1, name
    path = tmp / "variant.bs2"
    path.write_text(src, encoding="latin-1")
    return str(path)


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


@pytest.fixture(params=BACKENDS)
def backend(request) -> str:
    return request.param


@pytest.fixture
def firmware_source() -> str:
    return str(FIRMWARE)


@pytest.fixture
def make_sim(backend, tmp_path):
    """Factory: an emulator (not yet started) with a pyserial port opened on it, of either
    backend. With the firmware, protocol_version/firmware_version make a firmware variant."""
    made = []

    def make(started: bool = True, **kw) -> tuple[SimStamp, object]:
        kw.setdefault("factor", 0.0)
        if backend == "firmware":
            versions = {"PROTO_VER": kw.pop("protocol_version", None),
                        "FW_VERSION": kw.pop("firmware_version", None)}
            versions = {k: v for k, v in versions.items() if v is not None}
            kw["firmware"] = firmware_variant(tmp_path, **versions) if versions else str(FIRMWARE)
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
