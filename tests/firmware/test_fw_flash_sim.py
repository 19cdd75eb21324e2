"""`pac-host flash` against `pac-sim` on a real pseudo-terminal: the emulator learns the download,
then answers HELLO with the flashed firmware's version; every bad input is one error line."""

from __future__ import annotations

import pytest
import serial
from click.testing import CliRunner
from fw_build import SOURCE, run_tokenizer, source_with_version

from pac_host.cli.main import main
from pac_host.stamp.image import image_from_json
from pac_host.stamp.loader import StampLoader
from pac_protocol.errors import NoAnswer
from pac_protocol.link import StampLink
from pac_protocol.port import open_port
from pac_sim.line import Faults
from pac_sim.runner import SimConfig, SimStamp


@pytest.fixture(scope="module")
def image_v7(tmp_path_factory):
    d = tmp_path_factory.mktemp("fw7")
    built = run_tokenizer(source_with_version(d, 7), d / "out")
    assert built.returncode == 0, built.stderr
    return built.path


@pytest.fixture
def sim():
    s = SimStamp(SimConfig(factor=0.0, echo=True)).start()
    yield s
    s.close()


def hello(path: str) -> int:
    port = open_port(path)
    try:
        return StampLink(port, name=path).hello().firmware
    finally:
        port.close()


class RecordingSerial(serial.Serial):
    """A real pyserial port that keeps a copy of every byte written and read."""

    def __init__(self, *a, **kw) -> None:
        self.wrote, self.got = bytearray(), bytearray()
        super().__init__(*a, **kw)

    def write(self, data):
        self.wrote += data
        return super().write(data)

    def read(self, size=1):
        data = super().read(size)
        self.got += data
        return data


def test_flash_cli_into_pac_sim_then_hello_reports_the_new_version(sim, image_v7):
    assert hello(sim.path) == 1
    res = CliRunner().invoke(main, ["flash", "--port", sim.path, str(image_v7)])
    assert res.exit_code == 0, res.output
    assert "robot reports firmware 7" in res.stdout
    assert hello(sim.path) == 7
    assert sim.stamp.downloads[-1].finished


def test_download_into_pac_sim_is_byte_exact(sim, image_v7):
    image = image_from_json(image_v7)
    port = RecordingSerial(sim.path, 9600, timeout=0.05)
    try:
        report = StampLoader(port).flash(image)
    finally:
        port.close()
    assert bytes(port.wrote) == b"BS2\x00" + b"".join(image.packets) + b"\x00"
    expected = b"B\xbeS\xad2\xce\x00\x10" + b"".join(p + b"\x00" for p in image.packets) + b"\x00"
    assert bytes(port.got) == expected
    assert report.packets == len(image.packets)


def test_flashing_clears_the_stored_turn_cycle_and_resets(sim, image_v7):
    port = open_port(sim.path)
    try:
        link = StampLink(port, name=sim.path)
        link.hello()
        link.load([(12, 3), (3, 2)])
        assert link.status().count == 2
    finally:
        port.close()
    boots = sim.stamp.boots
    res = CliRunner().invoke(main, ["flash", "--port", sim.path, str(image_v7)])
    assert res.exit_code == 0, res.output
    assert sim.stamp.boots == boots + 1
    port = open_port(sim.path)
    try:
        link = StampLink(port, name=sim.path)
        link.hello()
        assert link.status().count == 0  # the image's TcCount DATA is 0
    finally:
        port.close()


def test_flash_from_source_tokenizes_first(sim, tmp_path):
    res = CliRunner().invoke(main, ["flash", "--port", sim.path,
                                    str(source_with_version(tmp_path, 9))])
    assert res.exit_code == 0, res.output
    assert hello(sim.path) == 9


def test_download_cut_short_leaves_no_firmware_until_reflashed(sim, image_v7):
    image = image_from_json(image_v7)
    port = serial.Serial(sim.path, 9600, timeout=0.05)
    try:
        loader = StampLoader(port)
        loader.reset()
        loader.identify()
        for i, p in enumerate(image.packets[:3]):
            loader.send_packet(i, len(image.packets), p)
    finally:
        port.close()  # the host dies mid-download
    port = open_port(sim.path)
    try:
        with pytest.raises(NoAnswer, match="no READY"):
            StampLink(port, name=sim.path, ready_timeout=1.5, attempts=1).hello()
    finally:
        port.close()
    res = CliRunner().invoke(main, ["flash", "--port", sim.path, str(image_v7)])
    assert res.exit_code == 0, res.output
    assert hello(sim.path) == 7


def one_error_line(res, code: int) -> str:
    assert res.exit_code == code, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("pac-host: error:")]
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.output
    return lines[0]


def test_source_that_does_not_tokenize_is_one_line_exit_2(sim, tmp_path):
    bad = tmp_path / "servobot.bs2"
    bad.write_text(SOURCE.read_text(encoding="latin-1").replace("NEXT", "NEXTT", 1),
                   encoding="latin-1")
    line = one_error_line(CliRunner().invoke(main, ["flash", "--port", sim.path, str(bad)]), 2)
    assert "servobot.bs2:" in line and "error" in line
    assert sim.stamp.downloads == []  # nothing was sent


def test_port_with_no_stamp_is_one_line(image_v7):
    with SimStamp(SimConfig(factor=0.0, faults=Faults(silent=True))) as quiet:
        line = one_error_line(
            CliRunner().invoke(main, ["flash", "--port", quiet.path, str(image_v7)]), 1)
    assert "no BASIC Stamp" in line


def test_missing_port_and_unknown_file_type_exit_2(tmp_path, image_v7):
    one_error_line(CliRunner().invoke(main, ["flash", "--port", str(tmp_path / "nope"),
                                             str(image_v7)]), 2)
    weird = tmp_path / "firmware.hex"
    weird.write_text("x")
    line = one_error_line(CliRunner().invoke(main, ["flash", "--port", "x", str(weird)]), 2)
    assert "unknown firmware file type" in line
