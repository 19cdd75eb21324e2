"""Observers: tracker streams over TCP and named pipes, manual entry; bad input is an error
naming the observer (never a silent zero), and a non-number typed by the operator is asked
again."""

from __future__ import annotations

import os
import socket
import threading

import pytest

from pac_host.errors import InputError
from pac_host.robot.observers import (
    ManualObserver,
    ObserverError,
    TrackerObserver,
    open_observer,
    open_pipe,
)


@pytest.fixture
def feed():
    """A TCP tracker that sends the given lines to the first client, then stays open."""
    srv = socket.create_server(("127.0.0.1", 0))
    conns = []

    def serve(lines: list[str]) -> str:
        def run():
            c, _ = srv.accept()
            conns.append(c)
            c.sendall("".join(line + "\n" for line in lines).encode())

        threading.Thread(target=run, daemon=True).start()
        return f"tracker:127.0.0.1:{srv.getsockname()[1]}"

    yield serve
    for c in conns:
        c.close()
    srv.close()


def test_tracker_matches_poses_to_gait_cycles_by_power_on(feed):
    spec = feed(["# header", "POSE 0 -1 7 1 2 3",       # a snapshot at rest: not a gait cycle
                 "POSE 7 12 7 9 9 9",                   # a gait cycle from before the run
                 "POSE 8 12 8 10.5 20 90", "POSE 9 3 9 11 21 95.5", "POSE 10 3 10 12 22 99"])
    ob = open_observer(spec, timeout=2)
    seen = []
    ob.begin("r1", 7, seen.append)
    ob.on_cycle(9)  # the CYCLE report of gait cycle 1 was lost: its pose still comes
    obs = ob.finish(3)
    ob.close()
    assert obs.poses.tolist() == [[10.5, 20, 90], [11, 21, 95.5], [12, 22, 99]]
    assert [s["cycle"] for s in seen] == [1, 2, 3] and seen[0]["run_id"] == "r1"


def _fails(spec: str, cycles: int, timeout: float, words: str) -> None:
    ob = open_observer(spec, timeout=timeout)
    ob.begin("r1", 0, lambda _: None)
    with pytest.raises(ObserverError, match=words):
        ob.finish(cycles)
    ob.close()


@pytest.mark.parametrize("line", ["POSE 1 12 1 10 20", "POSE 1 12 1 a b c", "hello",
                                  "POSE 1 12 1 10 20 nan"])
def test_malformed_tracker_line_names_the_observer(feed, line):
    spec = feed([line])
    _fails(spec, 1, 2, f"observer {spec}: malformed line")


def test_silent_tracker_is_an_error_not_a_zero(feed):
    _fails(feed(["POSE 1 12 1 10 20 90"]), 2, 0.2,
           r"no pose for gait cycle 2 of run r1 within 0.2 s")


def test_tracker_that_skips_a_gait_cycle_is_an_error(feed):
    _fails(feed(["POSE 1 12 1 10 20 90", "POSE 3 12 3 10 20 90"]), 3, 1, "skipped a line")


def test_named_pipe_tracker_and_a_closed_stream(tmp_path):
    fifo = tmp_path / "camera"
    os.mkfifo(fifo)
    ob = TrackerObserver(open_pipe(str(fifo), f"pipe:{fifo}"), timeout=1)
    with open(fifo, "w") as w:
        w.write("POSE 1 5 1 1.5 2.5 3.5\nPOSE 2 5 2 4 5 6\n")
    ob.begin("m5-r0", 0, lambda _: None)
    assert ob.finish(2).poses.tolist() == [[1.5, 2.5, 3.5], [4, 5, 6]]
    ob.close()

    plain = tmp_path / "short.txt"  # a regular file ends: the stream closed
    plain.write_text("POSE 1 5 1 1 2 3\n")
    ob = TrackerObserver(open_pipe(str(plain), "pipe:short"), timeout=1)
    ob.begin("r", 0, lambda _: None)
    with pytest.raises(ObserverError, match="pipe:short: the stream closed"):
        ob.finish(2)


def test_manual_entry_asks_again_until_it_gets_numbers():
    replies = iter(["seven", "3 2", "4 5 1", "", "4, 2, 3"])
    prompts = []

    def ask(p: str) -> str:
        prompts.append(p)
        return next(replies)

    ob = ManualObserver(ask, "figures")
    seen = []
    ob.begin("g0-t1", 0, seen.append)
    obs = ob.finish(200)
    assert obs.figures["blocks_covered"] == 4 and obs.figures["fitness"] == 3
    assert obs.figures["repeat_visits"] == 2 and obs.figures["repeat_visits_estimated"]
    assert "'seven' is not 3 whole numbers" in prompts[1]
    assert "cannot exceed blocks covered" in prompts[3]  # once 5 > covered 4: asked again
    assert seen == [{"type": "figures", "run_id": "g0-t1", **obs.figures}]

    replies = iter(["57.1 thirty 88", "57.1 30.5 88.7"])
    ob = ManualObserver(lambda p: next(replies), "pose")
    ob.begin("m12-r0", 0, lambda _: None)
    assert ob.finish(1).final_pose == (57.1, 30.5, 88.7)


@pytest.mark.parametrize("spec", ["camera", "tracker:localhost", "tracker:h:99999", "pipe:"])
def test_bad_observer_specs(spec):
    with pytest.raises(InputError, match="--observer"):
        open_observer(spec)


def test_unreachable_tracker_and_missing_pipe(tmp_path):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nobody listens there now
    with pytest.raises(InputError, match=f"cannot connect to 127.0.0.1:{port}"):
        open_observer(f"tracker:127.0.0.1:{port}")
    with pytest.raises(InputError, match="cannot open"):
        open_observer(f"pipe:{tmp_path / 'none'}")
    with pytest.raises(InputError, match="needs an operator"):
        open_observer("manual")
