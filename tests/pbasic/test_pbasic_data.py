"""DATA layout in EEPROM, READ/WRITE (with Word), write costs and wear counts."""

from __future__ import annotations

import json

import pytest

from pac_sim.pbasic import PbasicRuntimeError, PbasicSyntaxError, Stamp


def test_data_labels_and_bytes(programs):
    s = Stamp.from_file(programs / "data_layout.bs2")
    img = s.eeprom.mem
    assert list(img[0:6]) == [1, 2, 1000 & 0xFF, 1000 >> 8, ord("H"), ord("i")]
    assert list(img[6:9]) == [0, 0, 0]
    assert list(img[9:13]) == [0x34, 0x12, 0x34, 0x12]
    assert img[100] == 7
    assert list(img[101:104]) == [0, 100, 0]  # Table = 0, Word After = 100
    sym = s.program.symbols
    assert (sym.data_addr["ZEROS"], sym.data_addr["GAP"], sym.data_addr["LINK"]) == (6, 13, 101)
    assert sym.con_value["SIZE"] == 6


def test_read_and_write_words(programs):
    s = Stamp.from_file(programs / "data_layout.bs2")
    assert s.run_for(1) == "ended"
    assert (s.var("a"), s.var("b"), s.var("w"), s.var("v")) == (1, 2, 1000, 54321)
    assert s.eeprom.mem[202] == 9
    assert s.eeprom.writes[200] == s.eeprom.writes[201] == 1


def test_write_costs_eeprom_time(run):
    s = run("x VAR Byte\nFOR x = 1 TO 3\n  WRITE 10, x\nNEXT\nEND\n")
    assert s.eeprom.writes[10] == 3
    assert s.now_us >= 3 * 5000  # 5 ms per EEPROM write, in Stamp time


def test_overlapping_data_is_an_error(stamp):
    with pytest.raises(PbasicSyntaxError, match=r"t\.bs2:4: DATA location 1 is already occupied"):
        stamp("DATA 1, 2\nDATA @1, 5\n")


def test_data_past_eeprom_is_an_error(stamp):
    with pytest.raises(PbasicSyntaxError, match=r"t\.bs2:3: DATA beyond the 2048-byte EEPROM"):
        stamp("DATA @2047, Word 5\n")


def test_tokenizer_image_must_agree_with_data():
    src = "' {$STAMP BS2}\n' {$PBASIC 2.5}\nDATA 5, 6\nEND\n"
    good = bytearray(2048)
    good[0:2] = b"\x05\x06"
    good[2000] = 0xAB  # program tokens live at the top; they are kept
    s = Stamp.from_source(src, "t.bs2", eeprom_image=bytes(good))
    assert s.eeprom.mem[2000] == 0xAB
    good[1] = 7
    with pytest.raises(ValueError, match="differs from the DATA at address 1"):
        Stamp.from_source(src, "t.bs2", eeprom_image=bytes(good))


def test_write_into_the_program_is_an_error():
    src = "' {$STAMP BS2}\nx VAR Byte\nWRITE 100, 1\nWRITE 1990, 2\nEND\n"
    s = Stamp.from_source(src, "w.bs2", program_start=1900)
    with pytest.raises(PbasicRuntimeError, match=r"w\.bs2:4: WRITE to EEPROM address 1990 overwr"):
        s.run_for(1)
    assert s.eeprom.mem[100] == 1 and s.eeprom.mem[1990] == 0


def test_read_image_rejects_a_bad_file(tmp_path):
    from pac_host.errors import InputError
    from pac_sim.pbasic.image import read_image

    bad = tmp_path / "x.json"
    bad.write_text("{}")
    with pytest.raises(InputError, match="x.json: not a tokenizer image"):
        read_image(bad)
    bad.write_text(json.dumps({"eeprom": "00", "eeprom_flags": "00"}))
    with pytest.raises(InputError, match="must be 2048 bytes"):
        read_image(bad)
    good = bytearray(2048)
    flags = bytearray(2048)
    flags[2000:] = b"\x83" * 48
    bad.write_text(json.dumps({"eeprom": good.hex(), "eeprom_flags": flags.hex()}))
    assert read_image(bad)["program_start"] == 2000
