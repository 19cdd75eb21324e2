"""Control structures: IF, DO, FOR, SELECT, GOTO, GOSUB/RETURN, BRANCH, ON, EXIT, END, STOP."""

from __future__ import annotations

import pytest

from pac_sim.pbasic import PbasicRuntimeError, Stamp

EXPECTED = (
    "1 5 9 321\r"
    "do 5\r"
    "zero one two big four!\r"
    "aabdc\r"
    "depth 4\r"
    "b0 b1 none n1\r"
    "30 2\r"
    "99 2\r"
)


def test_constructs_program(programs):
    s = Stamp.from_file(programs / "constructs.bs2")
    assert s.run_for(5) == "ended"
    assert s.debug_text == EXPECTED
    assert s.halted_by == "END"


def test_for_leaves_counter_past_end(run):
    s = run("i VAR Byte\nn VAR Byte\nFOR i = 0 TO 10 STEP 3\n n = n + 1\nNEXT\nEND\n")
    assert (s.var("i"), s.var("n")) == (12, 4)


def test_for_body_runs_once_even_when_start_is_past_end_counting_down(run):
    s = run("i VAR Byte\nn VAR Byte\nFOR i = 5 TO 2\n n = n + 1\nNEXT\nEND\n")
    assert (s.var("i"), s.var("n")) == (1, 4)


def test_byte_counter_to_255_never_ends(stamp):
    # as on the Stamp: 255 + 1 wraps to 0 in a Byte, which is <= 255 again
    s = stamp("i VAR Byte\nFOR i = 0 TO 255\nNEXT\nEND\n")
    assert s.run_for(2.0) == "ready"


def test_gosub_fifth_level_is_an_error(stamp):
    s = stamp("d VAR Byte\nGOSUB A\nEND\nA:\n  d = d + 1\n  GOSUB A\n  RETURN\n")
    with pytest.raises(PbasicRuntimeError, match=r"t\.bs2:8: GOSUB nested more than 4 deep"):
        s.run_for(1)
    assert s.var("d") == 4


def test_return_without_gosub(stamp):
    with pytest.raises(PbasicRuntimeError, match=r"t\.bs2:3: RETURN without GOSUB"):
        stamp("RETURN\n").run_for(1)


def test_stop_and_running_off_the_end(run):
    assert run("x VAR Byte\nx = 1\nSTOP\nx = 2\n").halted_by == "STOP"
    s = run("x VAR Byte\nx = 3\n")
    assert s.halted_by == "END" and s.var("x") == 3


def test_goto_loop_with_single_line_if_label(run):
    s = run("n VAR Byte\nTop:\n  n = n + 1\n  IF n < 10 THEN Top\nEND\n")
    assert s.var("n") == 10


def test_loop_while_at_the_end_runs_body_first(run):
    s = run("n VAR Byte\nDO\n  n = n + 1\nLOOP WHILE n > 100\nEND\n")
    assert s.var("n") == 1


def test_exit_leaves_only_the_inner_loop(run):
    s = run("i VAR Byte\nj VAR Byte\nn VAR Byte\nFOR i = 1 TO 3\n  FOR j = 1 TO 10\n"
            "    IF j = 2 THEN EXIT\n    n = n + 1\n  NEXT\nNEXT\nEND\n")
    assert s.var("n") == 3


def test_reset_starts_over_with_cleared_ram_and_kept_eeprom(stamp):
    s = stamp("n VAR Byte\nc VAR Byte\nREAD 0, c\nc = c + 1\nWRITE 0, c\n"
              "DO\n  n = n + 1\n  PAUSE 10\nLOOP\n")
    s.run_for(0.1)
    assert s.var("n") > 5 and s.var("c") == 1
    t = s.now_us
    s.reset()
    assert s.var("n") == 0 and s.now_us == t
    s.run_for(0.05)
    assert s.var("c") == 2 and s.eeprom.writes[0] == 2  # the boot count survived the reset


def test_missing_file_is_an_input_error(tmp_path):
    from pac_host.errors import InputError

    with pytest.raises(InputError, match="nope.bs2: cannot read"):
        Stamp.from_file(tmp_path / "nope.bs2")
