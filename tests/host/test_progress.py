"""Long commands show progress on stderr: a line per step through a pipe, none with --quiet."""

from __future__ import annotations

import io
import json

from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.cli.progress import Progress, clock_text
from pac_host.experiments import experiment


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_a_line_per_step_with_count_elapsed_and_what_is_left():
    out, clock = io.StringIO(), Clock()
    p = Progress("experiment", units={"pal": "runs"}, stream=out, clock=clock)
    p("pal", 0, 8)
    clock.t += 41
    p("pal", 3, 8)
    clock.t += 20
    p("pal", 8, 8, "last")
    assert out.getvalue().splitlines() == [
        "experiment: pal 0/8 runs, 0:00 elapsed",
        "experiment: pal 3/8 runs, 0:41 elapsed, ~1:08 left",  # 41 s / 3 runs x 5 runs
        "experiment: pal 8/8 runs, 1:01 elapsed (last)"]


def test_quiet_prints_nothing():
    out = io.StringIO()
    p = Progress("evolve", quiet=True, stream=out, tty=False)
    for k in range(4):
        p("punctuations", k, 3)
    p.close()
    assert out.getvalue() == ""


def test_minor_steps_come_only_after_a_silence_and_a_resumed_stage_times_its_own_steps():
    out, clock = io.StringIO(), Clock()
    p = Progress("evolve", stream=out, clock=clock, minor=("gait cycles",), minor_every=30)
    p("punctuations", 4, 6)  # resumed after 4: they took no time in this process
    for n in range(0, 201, 10):
        clock.t += 2
        p("gait cycles", n, 200, "g160-t0")  # 42 s: one line, after 30 s of silence
    p("punctuations", 5, 6)
    lines = out.getvalue().splitlines()
    assert lines == ["evolve: punctuations 4/6, 0:00 elapsed",
                     "evolve: gait cycles 140/200, 0:28 elapsed, ~0:12 left (g160-t0)",
                     "evolve: punctuations 5/6, 0:42 elapsed, ~0:42 left"]


def test_clock_text():
    assert [clock_text(s) for s in (0, 59.6, 61, 3600 + 62)] == ["0:00", "1:00", "1:01",
                                                                 "1:01:02"]


def test_experiment_reports_each_stage_through_a_pipe_and_scales_the_optimum(tmp_path,
                                                                                monkeypatch):
    # the optimum's evaluations follow the run's generations unless given (scaled down here)
    monkeypatch.setattr(experiment, "OPTIMUM_EVALUATIONS", 100_000)
    monkeypatch.setattr(experiment, "OPTIMUM_EVALUATIONS_FLOOR", 1_000)
    args = ["experiment", "--seeds", "1", "--generations", "40", "--initial-generations", "20",
            "--optimum-runs", "2", "--search-evaluations", "2000", "--methods", "partial",
            "--budget", "80"]
    res = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "a")],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.output
    lines = [x for x in res.stderr.splitlines() if x.startswith("experiment: ")]
    stages = [x.split(",")[0] for x in lines]
    assert stages == ["experiment: optimum 0/2 runs", "experiment: optimum 1/2 runs",
                      "experiment: optimum 2/2 runs", "experiment: initial populations 0/1 seeds",
                      "experiment: initial populations 1/1 seeds", "experiment: pal 0/1 runs",
                      "experiment: pal 1/1 runs"]
    assert "elapsed, ~" in lines[1]  # an estimate of what is left, once a run is done
    assert "experiment:" not in res.stdout  # results on stdout, progress on stderr
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["config"]["optimum_evaluations"] == 4_000  # 100,000 x 40 / 1000
    res = CliRunner().invoke(main, [*args, "--optimum-evaluations", "3000", "--quiet",
                                    "--out", str(tmp_path / "b")], catch_exceptions=False)
    assert res.exit_code == 0 and res.stderr == ""
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert summary["config"]["optimum_evaluations"] == 3_000  # as given
