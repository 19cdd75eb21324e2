"""Download images: the tokenizer's JSON and raw packets read alike; damage is refused."""

from __future__ import annotations

import json

import pytest

from pac_host.errors import InputError
from pac_host.stamp.image import check_packet, load_image, make_packet


def test_json_and_bin_images_hold_the_same_packets(built):
    from_json = load_image(built.path)
    from_bin = load_image(built.path.with_suffix(".bin"))
    assert from_json.packets == from_bin.packets
    # the blocks the download sends hold the tokenizer's EEPROM; nothing else is written
    tokenized = bytes.fromhex(built.image["eeprom"])
    flags = bytes.fromhex(built.image["eeprom_flags"])
    written = from_json.eeprom()
    for a in range(2048):
        assert written[a] == (tokenized[a] if flags[a] & 0x80 else 0), a
    assert from_json.firmware_version == from_bin.firmware_version == 1


def test_make_packet_is_what_the_tokenizer_makes(built):
    for h in built.image["packets"]:
        p = bytes.fromhex(h)
        assert make_packet(p[0] & 0x7F, p[1:17]) == p


def test_damaged_packet_is_refused_naming_it(built, tmp_path):
    raw = bytearray(built.path.with_suffix(".bin").read_bytes())
    raw[18 * 5 + 7] ^= 0x10
    bad = tmp_path / "bad.bin"
    bad.write_bytes(raw)
    with pytest.raises(InputError, match="packet 5 is damaged: check byte"):
        load_image(bad)
    assert check_packet(bytes(raw[:17])) == "17 bytes, expected 18"
    (tmp_path / "short.bin").write_bytes(raw[:20])
    with pytest.raises(InputError, match="not a whole number of 18-byte packets"):
        load_image(tmp_path / "short.bin")


def test_image_for_another_module_is_refused(built, tmp_path):
    doc = dict(built.image, target="BS2e")
    f = tmp_path / "other.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="not a BS2"):
        load_image(f)
