"""`pac-sim --firmware`: the firmware itself behind the emulator's pty, its servo trace moving
the world. The protocol tests of tests/simulator run against this backend too (their
``make_sim`` fixture is parametrized); these are the checks only the firmware backend has."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fw_build import SOURCE

from pac_host.errors import InputError
from pac_host.model import rollout, shifted_table
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.pbasic import StampNotListening
from pac_sim.runner import SimConfig, SimStamp
from pac_sim.thrust import MAX_THRUST, side_of, thrust_for

BIN = Path(sys.executable).parent
AFFECTER = "IF k >= (strength * 2) THEN drag = side + 1"
LISTEN_IN_RUN = "  GOSUB Listen                               ' STOP here"


def variant(tmp_path: Path, old: str, new: str, count: int) -> str:
    src = SOURCE.read_text(encoding="latin-1")
    assert src.count(old) == count, old
    path = tmp_path / "variant.bs2"
    path.write_text(src.replace(old, new), encoding="latin-1")
    return str(path)


def walk(firmware: str, steps: list[tuple[int, int]], **kw) -> tuple[SimStamp, list[int]]:
    """STEP each (gait id, repetitions) through a real pty; returns the emulator (closed) and
    the gait ids the firmware reported in its CYCLE frames."""
    sim = SimStamp(SimConfig(factor=0.0, firmware=firmware, **kw))
    reported = []
    with sim:
        link = StampLink(open_port(sim.path), name=sim.path)
        link.hello()
        for g, r in steps:
            link.step(g, r)
            reported += [c.gait for c in link.wait_done()[0]]
        link.port.close()
    return sim, reported


def test_every_gait_id_walks_its_own_row():
    ids = list(range(32))
    sim, reported = walk(str(SOURCE), [(g, 1) for g in ids])
    assert reported == ids
    walked = list(sim.stamp.walked)
    assert sim.stamp.inexact == 0 and all(w.exact for w in walked)
    for g, w in zip(ids, walked, strict=True):
        side, a = g >> 4, g & 15
        assert w.thrust == tuple(thrust_for(a) if side_of(leg) == side else MAX_THRUST
                                 for leg in range(6)), g
        assert w.gait == (15 if a == 15 else g)  # a straight gait cycle carries no side bit
    poses = rollout(shifted_table().rows, (45.0, 30.0, 90.0), [w.gait for w in walked], ())
    true = np.array([h.true_pose for h in sim.world.history])
    np.testing.assert_allclose(true, poses[1:], atol=1e-9)


def test_a_wrong_affecter_walks_a_wrong_path(tmp_path):
    """`* 3` instead of `* 2`: the firmware still reports gait 3 and 20, but its servos give
    9 and 12 thrusts, which select rows 4 and 22: the robot ends up elsewhere."""
    steps = [(3, 3), (20, 2)]
    good, rep_good = walk(str(SOURCE), steps)
    bad, rep_bad = walk(variant(tmp_path, AFFECTER, AFFECTER.replace("* 2", "* 3"), 2), steps)
    assert rep_good == rep_bad == [3, 3, 3, 20, 20]
    assert [h.gait for h in good.world.history] == [3, 3, 3, 20, 20]
    assert [h.gait for h in bad.world.history] == [4, 4, 4, 22, 22]
    assert bad.stamp.inexact == 3 and good.stamp.inexact == 0  # 9 is odd: matches no strength
    rows = shifted_table().rows
    for sim, ids in ((good, [3, 3, 3, 20, 20]), (bad, [4, 4, 4, 22, 22])):
        end = rollout(rows, (45.0, 30.0, 90.0), ids, ())[-1]
        np.testing.assert_allclose(sim.world.history[-1].true_pose, end, atol=1e-9)
    end_good, end_bad = good.world.history[-1].true_pose, bad.world.history[-1].true_pose
    assert np.hypot(end_good[0] - end_bad[0], end_good[1] - end_bad[1]) > 3.0  # cm


def test_a_firmware_that_never_listens_is_reported_at_start(tmp_path):
    deaf = variant(tmp_path, "  GOSUB Listen\n", "  PAUSE 1\n", 1)
    with pytest.raises(StampNotListening, match="the Stamp is not listening: no SERIN within "):
        SimStamp(SimConfig(firmware=deaf))
    res = subprocess.run([str(BIN / "pac-sim"), "--realtime", "0", "--firmware", deaf],
                         capture_output=True, text=True, timeout=30)
    assert res.returncode == 1 and res.stdout == ""
    assert res.stderr.count("\n") == 1 and "the Stamp is not listening" in res.stderr
    assert f"{deaf}: " in res.stderr


def test_a_firmware_that_stops_listening_ends_the_emulator(tmp_path):
    """No listening window between gait cycles: a long STEP walks on, deaf, and the emulator
    says so (10 s of Stamp time without SERIN) instead of serving a mute robot forever."""
    fw = variant(tmp_path, LISTEN_IN_RUN, "  PAUSE 1 '", 1)
    sim = SimStamp(SimConfig(factor=0.0, firmware=fw))
    with sim:
        link = StampLink(open_port(sim.path), name=sim.path)
        link.hello()
        link.step(12, 50)
        sim.wait(10.0)
        link.port.close()
    assert isinstance(sim.error, StampNotListening)
    assert "no SERIN for 10 s of Stamp time" in str(sim.error)
    assert 5 <= sim.stamp.cycles_total < 50


def test_pbasic_outside_the_subset_is_one_line_naming_the_line(tmp_path):
    fw = variant(tmp_path, "Boot:\n", "Boot:\n  FREQOUT 0, 100, 2000\n", 1)
    line = SOURCE.read_text(encoding="latin-1").split("\n").index("Boot:") + 2
    res = subprocess.run([str(BIN / "pac-sim"), "--firmware", fw], capture_output=True,
                         text=True, timeout=30)
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert f"{fw}:{line}: FREQOUT is not supported" in res.stderr


def test_the_tokenizers_image_is_the_starting_eeprom(built, tmp_path):
    sim, reported = walk(str(SOURCE), [(7, 1)], image=str(built.path))
    assert reported == [7] and [h.gait for h in sim.world.history] == [7]
    other = tmp_path / "other.json"
    doc = json.loads(built.path.read_text())
    other.write_text(json.dumps(doc | {"source_sha256": "0" * 64}))
    with pytest.raises(InputError, match="was not built from"):
        SimStamp(SimConfig(firmware=str(SOURCE), image=str(other)))
    with pytest.raises(InputError, match="--firmware runs PBASIC source"):
        SimStamp(SimConfig(firmware=str(built.path)))
