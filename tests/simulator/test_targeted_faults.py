"""Faults aimed at one byte of one chosen frame (pac_sim.targeted): exact, and only there."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from pac_protocol.decoder import FrameDecoder
from pac_protocol.messages import Cycle, Ready, Status
from pac_sim.cli import main as pac_sim_main
from pac_sim.targeted import FrameTargets, PacketTargets, parse_target, parse_targets


def cycles(n: int) -> bytes:
    """n CYCLE reports, each followed by READY, as the Stamp sends them during a run."""
    return b"".join(Cycle(12, k, k).encode() + Ready(1).encode() for k in range(1, n + 1))


def test_a_target_hits_its_byte_of_its_frame_and_nothing_else():
    t = FrameTargets(parse_targets(drop=("CYCLE:3:7",), corrupt=("READY:2:5",)))
    clean = cycles(4)
    out = t.apply(clean)
    assert len(out) == len(clean) - 1
    frame = len(Cycle(12, 1, 1).encode()) + len(Ready(1).encode())
    third = clean[2 * frame: 2 * frame + 11]
    assert out[2 * frame - 0: 2 * frame + 10] == third[:7] + third[8:]  # byte 7 is gone
    ready2 = frame + 11
    assert out[ready2 + 5] == clean[ready2 + 5] ^ 0xFF  # the second READY's state byte
    assert out[:ready2 + 5] == clean[:ready2 + 5]
    assert t.hit == ["corrupt READY:2:5", "drop CYCLE:3:7"]


def test_split_chunks_and_garbage_do_not_shift_the_count():
    clean = cycles(3)
    whole = FrameTargets(parse_targets(drop=("CYCLE:2:6",))).apply(clean)
    t = FrameTargets(parse_targets(drop=("CYCLE:2:6",)))
    garbage = b"\x00\xa5\x13\xa5\x5a\x09"  # not frames (the last: LEN 9 > 8)
    noisy = garbage + clean
    # garbage passes untouched and the count of CYCLEs is unchanged, in any split
    got = b"".join(t.apply(noisy[i:i + 3]) for i in range(0, len(noisy), 3))
    assert got == garbage + whole
    assert t.hit == ["drop CYCLE:2:6"]


def test_a_frame_that_lost_an_a5_byte_passes_the_check():
    """Why reports must be checked against the run: dropping a payload byte equal to A5 makes
    the next frame's sync byte complete the sum, so the decoder yields a false CYCLE."""
    report = Cycle(23, 65, 0xA5)  # gait cycle 165 since power-on: its low byte is A5
    t = FrameTargets(parse_targets(drop=("CYCLE:1:8",)))
    frames = FrameDecoder().feed(t.apply(report.encode() + Ready(1).encode()))
    assert len(frames) == 1 and frames[0].cmd == report.CMD
    assert frames[0].payload[:3] == bytes([23, 65, 0])
    assert frames[0].payload[3:] != bytes([0xA5, 0])  # the power-on count is false


def test_request_targets_and_download_packets():
    t = FrameTargets(parse_targets(corrupt=("STATUS:2:4",)))
    reqs = Status().encode(1) + Status().encode(2)
    out = t.apply(reqs)
    assert out[:9] == reqs[:9] and out[9 + 4] == 2 ^ 0xFF
    p = PacketTargets(parse_targets(drop=("PACKET:2:17",)))
    got = b"".join(p.byte(b) for b in bytes(range(36)))
    assert got == bytes(range(35))  # the second packet's last byte
    p.new_download()
    assert b"".join(p.byte(b) for b in bytes(range(36))) == bytes(range(36))  # not again


@pytest.mark.parametrize("spec,words", [
    ("CYCLE:1", "KIND:N:BYTE"), ("WALK:1:2", "not a frame type"), ("CYCLE:0:2", "from 1"),
    ("CYCLE:1:14", "at most 14 bytes"), ("PACKET:1:18", "at most 18"), ("RUN:x:1", "whole")])
def test_bad_specs_name_the_problem(spec, words):
    with pytest.raises(ValueError, match=words):
        parse_target("drop", spec)
    res = CliRunner().invoke(pac_sim_main, ["--drop-at", spec])
    assert res.exit_code == 2 and "--drop-at" in res.output and "Traceback" not in res.output


def test_a_negative_seed_is_refused_before_the_emulator_starts():
    res = CliRunner().invoke(pac_sim_main, ["--seed", "-1"])
    assert res.exit_code == 2 and "--seed" in res.output and "Traceback" not in res.output
