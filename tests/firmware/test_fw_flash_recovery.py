"""A flash that fails mid-way: tried again from the reset; if it still fails, the Stamp's state
is said and a new `pac-host flash` recovers it (pac-sim with a download packet's byte dropped)."""

from __future__ import annotations

from click.testing import CliRunner
from fw_build import SOURCE

from pac_host.cli.main import main
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.line import Faults
from pac_sim.runner import SimConfig, SimStamp
from pac_sim.targeted import parse_targets


def sim_dropping(*specs: str) -> SimStamp:
    return SimStamp(SimConfig(factor=0.0, echo=True,
                              faults=Faults(targets=parse_targets(specs))))


def flash(path: str, *args: str):
    return CliRunner().invoke(main, ["flash", "--port", path, str(SOURCE), *args])


def answers_hello(path: str) -> bool:
    port = open_port(path)
    try:
        StampLink(port, name=path, ready_timeout=0.5, attempts=1, resyncs=0).hello()
        return True
    except Exception:
        return False
    finally:
        port.close()


def test_a_download_damaged_once_is_tried_again_and_completes():
    with sim_dropping("PACKET:3:5") as sim:
        res = flash(sim.path)
        assert res.exit_code == 0, res.output
        assert "trying again from the reset (2 of 3)" in res.output
        assert "packet 3 of" in res.output and "(after 1 failed download(s))" in res.output
        assert sim.line.aimed_packets.hit == ["drop PACKET:3:5"]
        dls = sim.stamp.downloads
        assert [d.packets for d in dls][0] == 2 and dls[-1].finished
        assert answers_hello(sim.path)


def test_a_flash_that_fails_says_what_the_stamp_holds_and_flash_again_recovers():
    with sim_dropping("PACKET:3:5") as sim:
        res = flash(sim.path, "--attempts", "1")
        assert res.exit_code == 1
        last = res.output.strip().splitlines()[-1]
        assert last.startswith("pac-host: error:") and "Traceback" not in res.output
        assert "2 of" in last and "holds no whole program" in last
        assert "Run `pac-host flash` again" in last
        assert not answers_hello(sim.path)  # the state it said: nothing answers
        res = flash(sim.path, "--attempts", "1")
        assert res.exit_code == 0, res.output
        assert answers_hello(sim.path)
