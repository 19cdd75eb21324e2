"""The host link against the emulator through a real pty and pyserial: every command, STOP
during RUN, echo, silence, version mismatch, bad ports, garbage, damaged bytes, resets."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pac_host.errors import exit_code
from pac_protocol.errors import Nacked, NoAnswer, PortError, StampReset, VersionMismatch
from pac_protocol.link import StampLink
from pac_protocol.messages import Cmd, Done, Err, Load, Reason, State
from pac_protocol.port import open_port
from pac_sim.line import Faults


def link_on(make_sim, **kw) -> tuple[object, StampLink]:
    sim, port = make_sim(**kw)
    return sim, StampLink(port, name=sim.path)


def test_every_command(make_sim):
    sim, link = link_on(make_sim)
    assert (link.hello().protocol, link.hello().max_genes) == (1, 9)
    st = link.status()
    assert (st.state, st.count, st.done, st.power_on) == (State.IDLE, 0, 0, 0)
    genes = [(5, 2), (20, 0), (27, 1)]
    link.load(genes)
    assert [link.read_gene(i) for i in range(3)] == [
        type(link.read_gene(0))(3, i, g, r) for i, (g, r) in enumerate(genes)
    ]
    link.run(7)
    cycles, done = link.wait_done()
    assert [c.gait for c in cycles] == [5, 5, 27, 5, 5, 27, 5]  # reps 0 skipped, loops
    assert [c.done for c in cycles] == list(range(1, 8)) and done == Done(Reason.COMPLETED, 7)
    link.step(12, 3)
    cycles, done = link.wait_done()
    assert [c.gait for c in cycles] == [12] * 3 and [c.power_on for c in cycles] == [8, 9, 10]
    link.stop()  # idle: acknowledged, nothing happens
    st = link.status()
    assert (st.state, st.count, st.done, st.power_on) == (State.IDLE, 3, 3, 10)
    assert sim.world.seq == 10
    assert link.stats.retries == 0


def test_refusals_raise_typed_errors_without_retry(make_sim):
    sim, link = link_on(make_sim)
    link.hello()
    with pytest.raises(Nacked) as e:
        link.run(5)
    assert e.value.error == Err.EMPTY and "EMPTY (no runnable turn cycle" in str(e.value)
    with pytest.raises(Nacked) as e:
        link.request(Load(3, 0, 32, 1))
    assert e.value.error == Err.BAD_ARG
    assert link.stats.retries == 0 and sim.eeprom.writes == 0


def test_stop_during_run_is_honoured_at_a_cycle_boundary(make_sim):
    sim, link = link_on(make_sim, factor=0.01)  # gait cycle 11.6 ms, run window 1 ms (floor 2)
    link.hello()
    link.load([(12, 10)])
    link.run(500)
    first = link.next_event()
    assert first.CMD == Cmd.CYCLE
    link.stop()
    cycles, done = link.wait_done()
    assert done.reason == Reason.STOPPED
    assert len(cycles) + 1 == done.done < 500  # every cycle walked was reported, none after
    assert sim.world.seq == done.done  # the robot walked no gait cycle after the STOP
    assert link.status().state == State.IDLE


def test_echo_of_the_programming_port_is_ignored(make_sim):
    sim, link = link_on(make_sim, echo=True)
    link.hello()
    link.step(3, 2)
    assert [c.gait for c in link.wait_done()[0]] == [3, 3]
    assert link.stats.echoes == link.stats.sends == 2


def test_silent_device_is_no_answer_naming_the_port(make_sim):
    sim, port = make_sim(faults=Faults(silent=True))
    link = StampLink(port, name=sim.path, ready_timeout=0.3)
    with pytest.raises(NoAnswer) as e:
        link.hello()
    msg = str(e.value)
    assert sim.path in msg and "no READY" in msg and "received nothing" in msg
    assert exit_code(e.value) == 1


def test_protocol_version_mismatch_names_both_versions(make_sim):
    sim, link = link_on(make_sim, protocol_version=2, firmware_version=7)
    with pytest.raises(VersionMismatch) as e:
        link.hello()
    msg = str(e.value)
    assert sim.path in msg and "expected protocol version 1" in msg and "version 2" in msg
    assert "firmware 7" in msg


@pytest.mark.parametrize(
    "path, words", [("/nonexistent/tty", "does not exist"), ("/dev/null", "not a serial device")]
)
def test_bad_ports(path, words):
    with pytest.raises(PortError) as e:
        open_port(path)
    assert words in str(e.value) and path in str(e.value) and exit_code(e.value) == 2


def test_not_a_device_file(tmp_path):
    f = tmp_path / "plain"
    f.write_text("x")
    with pytest.raises(PortError, match="not a serial device"):
        open_port(str(f))


def test_resync_after_random_garbage_both_ways(make_sim):
    """Garbage bytes sent to the Stamp at random times, and bytes damaged on the way back:
    every request still gets through and nothing is executed twice or wrongly."""
    rng = np.random.default_rng(3)
    sim, port = make_sim(faults=Faults(corrupt_prob=0.02), seed=11)
    link = StampLink(port, name=sim.path, attempts=8)
    link.hello()
    for k in range(12):
        port.write(rng.integers(0, 256, int(rng.integers(1, 40))).astype(np.uint8).tobytes())
        if k % 3 == 0:
            port.write(b"\xa5\x5a\x03")  # a half request: the Stamp must resync
        link.load([(k % 32, k % 7 + 1)])
        assert link.read_gene(0).gait == k % 32
    assert sim.eeprom.turn_cycle() == [(11, 5)]
    loads = [s for c, s in sim.stamp.executed if c == Cmd.LOAD]
    assert len(loads) == len(set(loads)) == 12  # each LOAD acted on exactly once
    assert link.decoder.bad_checks + link.decoder.skipped > 0  # damage really happened


def test_damaged_requests_are_nacked_retried_never_acted_on(make_sim):
    sim, port = make_sim(faults=Faults(corrupt_prob=0.03, drop_prob=0.01), seed=5)
    link = StampLink(port, name=sim.path, attempts=10)
    link.hello()
    link.load([(1, 1), (2, 2), (3, 3)])
    for n in range(1, 6):
        link.step(n, 1)
        while not isinstance(link.next_event(0.3), Done | type(None)):
            pass
    st = link.status()
    assert sim.eeprom.turn_cycle() == [(1, 1), (2, 2), (3, 3)]
    steps = [s for c, s in sim.stamp.executed if c == Cmd.STEP]
    assert len(steps) == 5 and sim.world.seq == 5 == st.power_on
    assert [h.gait for h in sim.world.history] == [1, 2, 3, 4, 5]
    assert link.stats.retries > 0  # the fault path was exercised


def test_reset_mid_frame_during_run(make_sim):
    sim, link = link_on(make_sim, reset_after=3)
    link.hello()
    link.load([(12, 5)])
    link.run(10)
    with pytest.raises(StampReset):
        link.wait_done()
    assert link.decoder.bad_checks + link.decoder.skipped > 0  # the cut CYCLE was dropped
    link.hello()
    st = link.status()
    assert (st.state, st.power_on, st.count) == (State.IDLE, 0, 1)  # RAM gone, EEPROM kept
    link.run(2)
    assert [c.power_on for c in link.wait_done()[0]] == [1, 2]
    assert sim.stamp.boots == 2


def test_host_dies_mid_request(make_sim):
    sim, port = make_sim()
    link = StampLink(port, name=sim.path)
    link.hello()
    port.write(Load(1, 0, 9, 9).encode(200)[:5])  # half a request, then the host dies
    fresh = StampLink(port, name=sim.path)  # a new session on the same line
    fresh.hello()
    fresh.load([(4, 4)])
    assert sim.eeprom.turn_cycle() == [(4, 4)]
    assert (Cmd.LOAD, 200) not in sim.stamp.executed


def test_reset_button_while_idle_is_a_boot_event(make_sim):
    sim, link = link_on(make_sim)
    link.hello()
    link.step(12, 2)
    link.wait_done()
    sim.stamp.reset()
    ev = link.next_event(2.0)
    assert ev is not None and ev.CMD == Cmd.BOOT
    assert link.stats.boots == 2  # the power-on BOOT and this one
    assert link.status().power_on == 0 and sim.stamp.boots == 2


def test_stop_from_a_second_session_while_running(make_sim):
    """A run started by one host session is stopped by another (e.g. `pac-host robot stop`)."""
    sim, port = make_sim(factor=0.01)
    first = StampLink(port, name=sim.path)
    first.hello()
    first.load([(12, 1), (28, 1)])
    first.run(5000)
    second = StampLink(open_port(sim.path), name=sim.path)
    second.hello()  # in a window between gait cycles
    second.stop()
    second.port.close()
    st = first.status()
    assert st.state == State.IDLE and 0 < st.done < 5000 and sim.world.seq == st.done


def test_mute_after_n_gait_cycles(make_sim):
    """A pulled cable: the CYCLE report of gait cycle 4 still arrives, then nothing; the robot
    itself walks on (the world keeps moving)."""
    sim, port = make_sim(mute_after=4)
    link = StampLink(port, name=sim.path, ready_timeout=0.3)
    link.hello()
    link.step(12, 9)
    cycles = []
    while (ev := link.next_event(0.5)) is not None:
        cycles.append(ev)
    assert [c.done for c in cycles if c.CMD == Cmd.CYCLE] == [1, 2, 3, 4]
    assert all(c.CMD == Cmd.CYCLE for c in cycles)  # no DONE, no READY after the fourth
    with pytest.raises(NoAnswer):
        link.status()
    deadline = time.monotonic() + 3.0
    while sim.world.seq < 9 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sim.world.seq == 9
