"""The virtual clock: per-instruction cost, PULSOUT widths and PAUSEs in the servo trace."""

from __future__ import annotations

from pac_sim.pbasic import Stamp
from pac_sim.pbasic.clock import INSTRUCTION_US, byte_us


def test_instruction_costs_250_us(run):
    s = run("x VAR Word\nx = 1\nx = 2\nx = x + 1\nEND\n")
    assert s.icount == 4 and s.now_us == 4 * INSTRUCTION_US


def test_servo_trace_timing_is_exact(stamp):
    s = stamp("DO\n  PULSOUT 12, 750\n  PULSOUT 13, 500\n  PAUSE 15\nLOOP\n")
    s.run_for(0.1)
    p12 = s.servo.on_pin(12)
    p13 = s.servo.on_pin(13)
    period = (250 + 2 * 750) + (250 + 2 * 500) + (250 + 15_000) + 250  # + the LOOP jump
    assert [p.t_us for p in p12[:3]] == [0, period, 2 * period]
    assert p13[0].t_us == 250 + 2 * 750
    assert s.servo.refresh_periods_us(12)[:5] == [period] * 5
    assert {p.width for p in p12} == {750}
    assert s.var("DIRS") == (1 << 12) | (1 << 13)  # PULSOUT makes its pin an output


def test_sweep_program_with_listening_window(programs):
    s = Stamp.from_file(programs / "servo_refresh.bs2")
    s.run_until_serin(1.0)
    hips = [p.width for p in s.servo.on_pin(12)]
    assert hips == [700 + 10 * k for k in range(10)]
    s.output.take()
    s.feed(b"C800\r")
    s.run_until_serin(1.0)
    hips = [p.width for p in s.servo.on_pin(12)][10:]
    assert hips == [750 + 10 * k for k in range(10)]
    assert s.var("centre") == 800
    # the echo of "C800\r" comes back on the programming port before the next READY
    assert s.output.take(16) == b"C800\rR"
    # silence: the 30 ms window times out and the sweep goes on with the same centre
    t = s.now_us
    s.advance(40_000)
    s.run_until_serin(1.0)
    assert [p.width for p in s.servo.on_pin(12)][20:] == hips
    assert s.servo.on_pin(12)[20].t_us >= t + 30_000


def test_serin_completes_at_the_last_stop_bit(stamp):
    s = stamp("a VAR Byte\nb VAR Byte\nSERIN 3, 84, [a, b]\nEND\n")
    s.run()
    s.feed(b"xy", pin=3, at_us=1000)
    s.run()
    assert s.now_us >= 1000 + 2 * byte_us(84)
    assert (s.var("a"), s.var("b")) == (ord("x"), ord("y"))


def test_nap_and_sleep_take_their_time(run):
    s = run("NAP 2\nEND\n")
    assert s.now_us == 18_000 * 4 + 2 * INSTRUCTION_US
    s = run("SLEEP 2\nEND\n")
    assert s.now_us == 2_000_000 + 2 * INSTRUCTION_US
