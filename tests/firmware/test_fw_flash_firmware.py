"""`pac-host flash` into `pac-sim --firmware`: the firmware developer's loop without a robot.

The interpreter runs PBASIC source, so after a download the emulated Stamp runs the firmware's
source as it now reads if that source's program is what was flashed (an edited, rebuilt and
flashed source is picked up), and answers nothing after any other program.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from fw_build import SOURCE, run_tokenizer, set_version, source_with_version

from pac_host.cli.main import main
from pac_protocol.errors import NoAnswer
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.runner import SimConfig, SimStamp

BIN = Path(sys.executable).parent


@pytest.fixture
def firmware_v7(tmp_path):
    """A copy of the firmware announcing version 7, and its tokenized image."""
    src = source_with_version(tmp_path, 7)
    built = run_tokenizer(src, tmp_path / "v7")
    assert built.returncode == 0, built.stderr
    return src, built.path


@pytest.fixture
def sim(firmware_v7):
    s = SimStamp(SimConfig(factor=0.0, echo=True, firmware=str(firmware_v7[0]))).start()
    yield s
    s.close()


def flash(port: str, image: Path):
    return CliRunner().invoke(main, ["flash", "--port", port, str(image)])


def with_link(port: str, fn, **kw):
    p = open_port(port)
    try:
        return fn(StampLink(p, name=port, **kw))
    finally:
        p.close()


def test_flashing_its_own_image_restarts_the_firmware_on_the_images_eeprom(sim, firmware_v7):
    _, image = firmware_v7

    def load(link):
        link.hello()
        link.load([(12, 3), (3, 2)])
        return link.status().count

    assert with_link(sim.path, load) == 2
    boots = sim.stamp.boots
    res = flash(sim.path, image)
    assert res.exit_code == 0, res.output
    assert "robot reports firmware 7" in res.output
    dl = sim.stamp.downloads[-1]
    assert dl.finished and sim.stamp.flash_note is None
    assert sim.stamp.boots == boots + 1  # the program started again and sent BOOT
    # the image's TcCount DATA is 0: the flash replaced the stored turn cycle, in the Stamp
    # and in the emulator's EEPROM model (what --eeprom persists)
    assert with_link(sim.path, lambda link: (link.hello(), link.status().count)[1]) == 0
    assert sim.eeprom.image[0] == 0


def test_an_edited_and_rebuilt_source_is_what_runs_after_the_flash(sim, firmware_v7, tmp_path):
    src, _ = firmware_v7
    set_version(src, 8)
    built = run_tokenizer(src, tmp_path / "v8")
    assert built.returncode == 0, built.stderr
    res = flash(sim.path, built.path)
    assert res.exit_code == 0, res.output
    assert "robot reports firmware 8" in res.output
    assert with_link(sim.path, lambda link: link.hello().firmware) == 8


def test_another_program_is_flashed_but_answers_nothing_until_reflashed(sim, firmware_v7,
                                                                        tmp_path):
    src, image = firmware_v7
    other = run_tokenizer(SOURCE, tmp_path / "stock")  # firmware 1: not this source's program
    assert other.returncode == 0, other.stderr
    res = flash(sim.path, other.path)
    assert res.exit_code != 0
    lines = res.output.strip().splitlines()
    assert lines[-1].startswith("pac-host: error:") and "Traceback" not in res.output
    assert sim.stamp.downloads[-1].finished  # the download itself went through
    assert f"not {src}'s" in sim.stamp.flash_note
    with pytest.raises(NoAnswer, match="no READY"):
        with_link(sim.path, lambda link: link.hello(), ready_timeout=1.5, attempts=1)
    res = flash(sim.path, image)
    assert res.exit_code == 0, res.output
    assert with_link(sim.path, lambda link: link.hello().firmware) == 7


def test_the_pac_sim_process_says_what_each_flash_did(firmware_v7, tmp_path):
    src, image = firmware_v7
    other = run_tokenizer(SOURCE, tmp_path / "stock")
    proc = subprocess.Popen(
        [str(BIN / "pac-sim"), "--realtime", "0", "--firmware", str(src)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        port = proc.stdout.readline().split()[-1]
        assert flash(port, image).exit_code == 0
        assert flash(port, other.path).exit_code != 0
    finally:
        os.kill(proc.pid, signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    err = proc.stderr.read().splitlines()
    flashed = [ln for ln in err if ln.startswith("pac-sim: flashed")]
    n = len(other.image["packets"])
    assert flashed[0].startswith("pac-sim: flashed ") and flashed[0].endswith(
        ": the ServoBot firmware 7")
    assert flashed[1] == (f"pac-sim: flashed {n} packets: the ServoBot firmware 1; the flashed "
                          f"program is not {src}'s: pac-sim runs only that source, so the Stamp "
                          "answers nothing")
