"""`StampLoader` against a module on a real pty: byte-exact download, and every failure mode."""

from __future__ import annotations

import re

import pytest
import serial
from fw_build import SOURCE
from fw_fake_stamp import FakeStamp

from pac_host.stamp.image import image_from_json
from pac_host.stamp.loader import (
    FlashError,
    NoStampError,
    PacketNotAcknowledged,
    StampLoader,
    WrongModuleError,
)
from pac_protocol.messages import Ready, State
from pac_sim.stamp_download import DownloadFaults


@pytest.fixture(scope="module")
def image(built):
    assert built.path is not None, built.stderr
    return image_from_json(built.path)


def flash_into(fake: FakeStamp, image, **kw):
    port = serial.Serial(fake.path, 9600, timeout=0.05)
    try:
        return StampLoader(port, answer_timeout=0.15, ack_timeout=0.3, **kw).flash(image)
    finally:
        port.close()


def test_download_is_byte_exact_with_the_documented_protocol(image):
    events = []
    with FakeStamp() as fake:
        report = flash_into(fake, image, progress=lambda *e: events.append(e))
        host, module = bytes(fake.from_host), bytes(fake.to_host)
        eeprom, version = fake.download.eeprom, fake.download.firmware_version
        assert fake.download.finished
    packets = b"".join(image.packets)
    assert host == b"BS2\x00" + packets + b"\x00"
    expected = b"B\xbeS\xad2\xce\x00\x10"
    expected += b"".join(p + b"\x00" for p in image.packets) + b"\x00"
    assert module == expected
    assert eeprom == image.eeprom()
    fw = int(re.search(r"^FW_VERSION\s+CON\s+(\d+)", SOURCE.read_text(), re.M).group(1))
    assert version == image.firmware_version == fw
    assert report.interpreter == "1.0" and report.packets == len(image.packets)
    assert report.reset_line is False  # a pty has no DTR
    n = len(image.packets)
    assert events[0][0] == "reset" and events[-1] == ("done", n, n)
    counts = [e[1] for e in events if e[0] == "packet"]
    assert counts == list(range(1, len(image.packets) + 1))


def test_frames_the_firmware_sent_before_the_download_are_skipped(image):
    # no reset line on a pty: the running firmware's READY can precede the echo of 'B'
    ready = Ready(State.IDLE).encode(0)
    with FakeStamp(before=ready + ready) as fake:
        report = flash_into(fake, image)
        assert fake.download.finished and bytes(fake.to_host).startswith(ready + ready + b"B")
    assert report.packets == len(image.packets)


def test_bytes_before_the_echo_that_are_no_whole_frame_are_a_damaged_line(image):
    with FakeStamp(before=b"\xa5\x00") as fake, pytest.raises(FlashError, match="echo .* differs"):
        flash_into(fake, image)


def test_silent_port_is_no_stamp(image):
    with FakeStamp(mode="silent") as fake, pytest.raises(NoStampError, match=re.escape(fake.path)):
        flash_into(fake, image)


def test_module_answering_differently_is_not_a_bs2(image):
    faults = DownloadFaults(id_answers=bytes([0x65, 0xAD, 0xCE]))
    with FakeStamp(faults) as fake, pytest.raises(WrongModuleError) as e:
        flash_into(fake, image)
    assert "not a BS2" in str(e.value) and "0x65" in str(e.value) and "0xBE" in str(e.value)
    assert fake.from_host == b"B"  # nothing sent after the wrong answer


def test_echo_without_identification_is_not_a_bs2_in_download_mode(image):
    with FakeStamp(mode="echo") as fake, pytest.raises(WrongModuleError, match="did not answer"):
        flash_into(fake, image)


def test_refused_packet_stops_the_download(image):
    with FakeStamp(DownloadFaults(refuse_packet=3)) as fake:
        with pytest.raises(PacketNotAcknowledged) as e:
            flash_into(fake, image)
        assert not fake.download.finished
        sent_packets = (len(fake.from_host) - 4) // 18
    msg = str(e.value)
    assert f"packet 4 of {len(image.packets)}" in msg and "0x02" in msg
    assert "3 packet(s) before it were written" in msg
    assert sent_packets == 4  # nothing after the refused packet, no end byte


def test_unacknowledged_packet_times_out(image):
    with FakeStamp(DownloadFaults(mute_packet=0)) as fake, pytest.raises(
        PacketNotAcknowledged, match="not acknowledged within"
    ):
        flash_into(fake, image)
