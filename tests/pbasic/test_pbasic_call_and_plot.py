"""Running one subroutine on its own (Stamp.call) and plotting its servo trace as a PNG."""

from __future__ import annotations

import matplotlib.image as mpimg
import pytest
from click.testing import CliRunner

from pac_sim.pbasic.trace_plot import main, plot_pulses

SWEEP = ("k VAR Byte\nw VAR Word\nEND\n"
         "Sweep:\n  FOR k = 0 TO 4\n    PULSOUT 3, w + k\n    IF k <> 2 THEN PULSOUT 4, w\n"
         "    PAUSE 10\n  NEXT\n  RETURN\n"
         "Forever:\n  GOTO Forever\n")


def test_call_runs_a_subroutine_until_its_return(stamp):
    s = stamp(SWEEP)
    s.call("Sweep", w=700)
    assert [p.width for p in s.servo.on_pin(3)] == [700, 701, 702, 703, 704]
    assert s.state == "ready" and not s.stack
    s.call("sweep", w=10)  # labels and variables are case-insensitive
    assert [p.width for p in s.servo.on_pin(3)][5:] == [10, 11, 12, 13, 14]


def test_call_of_a_routine_that_never_returns(stamp):
    with pytest.raises(RuntimeError, match="FOREVER did not RETURN|Forever did not RETURN"):
        stamp(SWEEP).call("Forever", max_s=0.5)
    with pytest.raises(KeyError, match="no label Nowhere"):
        stamp(SWEEP).call("Nowhere")


def test_plot_writes_a_png_with_one_row_per_pin(stamp, tmp_path):
    s = stamp(SWEEP)
    s.call("Sweep", w=700)
    out = plot_pulses(s.servo.pulses, tmp_path / "trace.png", "sweep")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    height, width = mpimg.imread(out).shape[:2]
    assert width > 600 and height > 150
    with pytest.raises(ValueError, match="no pulses"):
        plot_pulses([], tmp_path / "none.png")


def test_plot_command(programs, tmp_path):
    src = tmp_path / "sweep.bs2"
    src.write_text("' {$STAMP BS2}\n" + SWEEP)
    out = tmp_path / "cmd.png"
    r = CliRunner().invoke(main, [str(src), "--label", "Sweep", "--set", "w=$2EE",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:4] == b"\x89PNG"
    bad = CliRunner().invoke(main, [str(src), "--label", "Sweep", "--set", "w", "--out", str(out)])
    assert bad.exit_code == 2 and "is not variable=value" in bad.output
    (tmp_path / "broken.bs2").write_text("' {$STAMP BS2}\nGOTO Nowhere\n")
    broken = CliRunner().invoke(main, [str(tmp_path / "broken.bs2"), "--label", "X",
                                       "--out", str(out)])
    assert broken.exit_code == 2
    assert broken.output.strip().endswith("broken.bs2:2: undefined label NOWHERE")
