"""`pac-host camera` end to end on rendered frames, its bad input (one line, exit 2), and the
camera in the loop: `evolve` against pac-sim with poses through rendered frames."""

from __future__ import annotations

import json

import cv2
import numpy as np
from click.testing import CliRunner

from pac_host.cli.main import main
from pac_host.model.table import GaitTable, save_table


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _one_error_line(res, code, text):
    assert res.exit_code == code, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("pac-host: error:")]
    assert len(lines) == 1 and text in lines[0], res.output
    assert "Traceback" not in res.output


def test_render_calibrate_check_on_files(tmp_path):
    d = tmp_path / "frames"
    res = _invoke("camera", "render", "--out", d, "--pose", "60,200,-30", "--board", "8",
                  "--floor", "2")
    assert res.exit_code == 0, res.output
    calib = tmp_path / "calib.json"
    res = _invoke("camera", "calibrate", "--floor", d / "floor", "--lens", d / "board",
                  "--out", calib)
    assert res.exit_code == 0, res.output
    assert "reprojection error" in res.output and "cm RMS" in res.output
    doc = json.loads(calib.read_text())
    assert doc["format"] == "pac-camera-calibration/1" and doc["lens"]["images"] >= 5
    png = tmp_path / "check.png"
    res = _invoke("camera", "check", "--source", d / "robot", "--calib", calib, "--out", png)
    assert res.exit_code == 0, res.output
    x, y, h = (float(v) for v in res.output.split("robot at (")[1].replace(") cm, heading", ",")
               .split(" deg")[0].split(","))
    assert abs(x - 60) < 0.5 and abs(y - 200) < 0.5 and abs(h + 30) < 1.5
    assert cv2.imread(str(png)).shape == (480, 640, 3)

    res = _invoke("camera", "sheets", "--out", tmp_path / "sheets")
    assert res.exit_code == 0 and "24 A4 pages" in res.output, res.output
    pdf = (tmp_path / "sheets" / "markers.pdf").read_bytes()
    assert pdf.count(b"/Type /Page") - pdf.count(b"/Type /Pages") == 24

    # bad input: too few floor markers, a file of the wrong kind, a camera that is not there
    few = tmp_path / "few"
    few.mkdir()
    img = cv2.imread(str(d / "floor" / "000.png"), cv2.IMREAD_GRAYSCALE)
    img[:, 100:] = 150  # only the near end's two markers stay in view
    cv2.imwrite(str(few / "0.png"), img)
    _one_error_line(_invoke("camera", "calibrate", "--floor", few, "--out", tmp_path / "c2.json"),
                    2, "of the 22 floor markers seen")
    assert not (tmp_path / "c2.json").exists()
    table = tmp_path / "table.json"
    assert _invoke("table", "export", table).exit_code == 0
    _one_error_line(_invoke("camera", "check", "--source", d / "robot", "--calib", table,
                            "--out", png), 2, "not a camera calibration")
    _one_error_line(_invoke("measure", "--ids", "12", "--repeats", "2", "--out",
                            tmp_path / "m.json", "--observer", f"camera:{tmp_path}/none.mp4,"
                            f"calib={calib}"), 2, "no such camera index, folder or video file")
    _one_error_line(_invoke("measure", "--ids", "12", "--repeats", "2", "--out",
                            tmp_path / "m.json", "--observer", f"camera:{d / 'robot'}"),
                    2, "give calib=FILE")


SMALL = ["--generations", "40", "--interval", "40", "--initial-generations", "20",
         "--cga-population", "32", "--model-population", "16", "--model-generations", "10",
         "--seed", "0", "--search-evaluations", "20000"]  # the observers, not the search


def test_camera_in_the_loop_gets_the_tracker_fed_results(tmp_path):
    """The same PAL run, once observed by pac-sim's tracker (noise-free: the truth), once by
    the camera observer through rendered frames: the same figures, the same learning, poses
    within the camera's noise."""
    runs = {}
    for name, extra in (("tracker", ["--sim-noise", "0,0"]),
                        ("camera", ["--observer", "camera:sim,frames=2"])):
        out = tmp_path / name
        # from the exact start: a search over a placement's stencil of start poses would turn
        # the camera's sub-millimetre differences in the fitted model into other tests
        res = _invoke("evolve", "--out", out, "--budget", "12", "--placement-error", "none",
                      *SMALL, *extra)
        assert res.exit_code == 0, res.output
        runs[name] = ([json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()],
                      [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()])
    (tlog, truns), (clog, cruns) = runs["tracker"], runs["camera"]
    assert len(clog) == len(tlog) == 2 and len(cruns) == len(truns) == 6
    # the first punctuation's tests come from the same model: the same figures
    t, c = tlog[0], clog[0]
    assert c["tests"] == t["tests"] and c["observed"] == t["observed"]
    assert c["operational"] == t["operational"]
    # later models are fitted to poses that differ by the camera's noise, so a search may break
    # a tie of equal turn cycles the other way; where the two walked the same gait cycles they
    # saw the same figures
    for t, c in zip(tlog[1:], clog[1:], strict=True):
        same = [i for i, (a, b) in enumerate(zip(t["tests"], c["tests"], strict=True)) if a == b]
        assert len(same) >= 2 and all(c["observed"][i] == t["observed"][i] for i in same)
    walked = [(t, c) for t, c in zip(truns, cruns, strict=True)
              if t["gait_cycles"] == c["gait_cycles"]]
    assert len(walked) >= 5
    err = np.array([np.array(c["poses"]) - np.array(t["poses"])
                    for t, c in walked]).reshape(-1, 3)
    pos = np.hypot(err[:, 0], err[:, 1])
    assert len(pos) == len(walked) * 12 and np.median(pos) < 0.5
    assert np.median(np.abs(err[:, 2])) < 1
    # each run starts where the camera saw the robot stand before its first gait cycle (the
    # tracker's run: where the emulator placed it)
    seen = [json.loads(x) for x in (tmp_path / "camera" / "observations.jsonl").read_text()
            .splitlines()]
    at_start = {o["run_id"]: o["pose"] for o in seen if o["type"] == "pose" and o["cycle"] == 0}
    np.testing.assert_allclose([at_start[c["run_id"]] for c in cruns],
                               [c["start_pose"] for c in cruns], atol=1e-4)  # as logged
    err = np.array([np.subtract(c["start_pose"], t["start_pose"])
                    for t, c in zip(truns, cruns, strict=True)])
    assert np.hypot(err[:, 0], err[:, 1]).max() < 0.5 and np.abs(err[:, 2]).max() < 1


def test_a_robot_leaving_the_view_is_a_lost_observation_mid_run(tmp_path):
    # a robot that walks straight ahead whatever gait cycle it is sent: its first test leaves
    # the camera's view across the far edge, whichever turn cycle the run tests; each gait
    # cycle it is not seen is a gap, and the ninth stops the test (more than a quarter of 32)
    table = tmp_path / "straight.json"
    save_table(GaitTable(np.tile([15.0, 0.0, 0.0], (32, 1)), name="straight"), table)
    out = tmp_path / "lost"
    res = _invoke("evolve", "--out", out, "--budget", "30", *SMALL, "--sim-table", table,
                  "--observer", "camera:sim,frames=1,cameras=1")
    _one_error_line(res, 1, "lost observation of 9 of")
    obs = [json.loads(x) for x in (out / "observations.jsonl").read_text().splitlines()]
    lost = [o for o in obs if o["type"] == "lost"]
    assert len(lost) == 9 and len({o["run_id"] for o in lost}) == 1
    assert [o["cycle"] for o in lost] == list(range(lost[0]["cycle"], lost[0]["cycle"] + 9))
    seen = [o for o in obs if o["type"] == "pose" and o["run_id"] == lost[0]["run_id"]]
    assert [o["cycle"] for o in seen] == list(range(0, lost[0]["cycle"]))  # from its start


def test_measure_through_the_camera_starts_where_it_saw_the_robot(tmp_path):
    """measure keeps a placement's first move only when its start was seen: through the
    camera it is, so every gait cycle walked counts."""
    out = tmp_path / "m.json"
    res = _invoke("measure", "--ids", "12", "--repeats", "2", "--cycles", "3", "--out", out,
                  "--observer", "camera:sim,frames=1")
    assert res.exit_code == 0, res.output
    seen = [json.loads(x) for x in
            (tmp_path / "m.observations.jsonl").read_text().splitlines()]
    at_start = {o["run_id"]: o["pose"] for o in seen if o["type"] == "pose" and o["cycle"] == 0}
    runs = [json.loads(x) for x in (tmp_path / "m.runs.jsonl").read_text().splitlines()]
    assert len(runs) == 2 and set(at_start) == {r["run_id"] for r in runs}
    for r in runs:
        np.testing.assert_allclose(r["start_pose"], at_start[r["run_id"]], atol=1e-4)
        assert np.hypot(r["start_pose"][0] - 90, r["start_pose"][1] - 90) < 0.5
    report = json.loads((tmp_path / "m.measure.json").read_text())
    assert [f["n"] for f in report["fits"]] == [6]  # 2 placements x 3 moves, none dropped
