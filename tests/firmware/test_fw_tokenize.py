"""The firmware tokenizes with Parallax's tokenizer and fits the BS2; broken source is rejected."""

from __future__ import annotations

from fw_build import SOURCE, run_tokenizer

from pac_host.stamp.image import EEPROM_SIZE, check_packet

RAM_BYTES = 26


def test_firmware_tokenizes_for_a_bs2(built):
    assert built.returncode == 0, built.stderr
    img = built.image
    assert img["target"] == "BS2"
    assert img["pbasic_version"] == 2.5
    assert "RAM" in built.stdout and "EEPROM" in built.stdout


def test_ram_within_the_stamps_26_bytes(built):
    ram = built.image["resources"]["ram"]
    bits = ram["words"] * 16 + ram["bytes"] * 8 + ram["nibbles"] * 4 + ram["bits"]
    assert ram["bytes_used"] == -(-bits // 8)
    assert ram["bytes_used"] <= RAM_BYTES


def test_eeprom_within_2048_bytes_and_packets_match_the_map(built):
    img = built.image
    ee = img["resources"]["eeprom"]
    assert ee["program"] > 0 and ee["data"] > 0
    assert ee["program"] + ee["data"] + ee["free"] == EEPROM_SIZE
    eeprom = bytes.fromhex(img["eeprom"])
    flags = bytes.fromhex(img["eeprom_flags"])
    assert len(eeprom) == len(flags) == EEPROM_SIZE
    # program grows down from 2047, DATA up from 0: they must not meet
    program = [a for a in range(EEPROM_SIZE) if flags[a] & 3 == 3]
    data = [a for a in range(EEPROM_SIZE) if flags[a] & 3 in (1, 2)]
    assert max(data) < min(program)
    sent_blocks = set()
    for h in img["packets"]:
        p = bytes.fromhex(h)
        assert check_packet(p) is None
        block = p[0] & 0x7F
        sent_blocks.add(block)
        assert p[1:17] == eeprom[block * 16 : block * 16 + 16]
    # every block holding program or defined DATA is downloaded
    needed = {a // 16 for a in range(EEPROM_SIZE) if flags[a] & 3 in (2, 3)}
    assert needed <= sent_blocks


def test_firmware_version_at_its_documented_place(built, source_text):
    import re

    eeprom = bytes.fromhex(built.image["eeprom"])
    fw = int(re.search(r"^FW_VERSION\s+CON\s+(\d+)", source_text, re.M).group(1))
    proto = int(re.search(r"^PROTO_VER\s+CON\s+(\d+)", source_text, re.M).group(1))
    assert eeprom[:4] == b"SB" + bytes([fw, proto])


def test_broken_copy_is_rejected_with_the_tokenizers_message(tmp_path, source_text):
    lines = source_text.split("\n")
    target = next(i for i, ln in enumerate(lines) if ln.strip().startswith("PULSOUT HIP1,"))
    lines[target] = lines[target].replace("PULSOUT HIP1,", "PULSOUT HIP1 HIP_BACK_L,", 1)
    broken = tmp_path / "servobot.bs2"
    broken.write_text("\n".join(lines), encoding="latin-1")
    out = tmp_path / "out"
    res = run_tokenizer(broken, out)
    assert res.returncode == 1
    first = res.stderr.splitlines()[0]
    # FILE:LINE:COL: error CODE: MESSAGE, then the offending line itself
    assert f"servobot.bs2:{target + 1}:" in first
    assert "error" in first and "Expected" in first
    assert "PULSOUT HIP1 HIP_BACK_L" in res.stderr
    assert not out.exists() or not any(out.iterdir())


def test_running_out_of_ram_is_the_tokenizers_error(tmp_path, source_text):
    extra = "\n".join(f"spare{i} VAR Byte" for i in range(6))
    src = source_text.replace("' Aliases (no RAM of their own):", extra + "\n' Aliases:")
    f = tmp_path / "servobot.bs2"
    f.write_text(src, encoding="latin-1")
    res = run_tokenizer(f, tmp_path / "out")
    assert res.returncode == 1
    assert "Out of variable space" in res.stderr


def test_source_is_the_one_tokenized(built):
    import hashlib

    assert built.image["source_sha256"] == hashlib.sha256(SOURCE.read_bytes()).hexdigest()


def test_readme_quotes_todays_resource_report(built):
    """The figures firmware/README.md quotes are the ones the tokenizer reports now."""
    from fw_build import FIRMWARE

    readme = (FIRMWARE / "README.md").read_text()
    for line in built.stdout.splitlines()[:3]:
        shown = line.strip().replace(str(SOURCE.parent.parent) + "/", "")
        assert shown.split(": ", 1)[-1] in readme, shown
    program = built.image["resources"]["eeprom"]["program"]
    assert f"| {2048 - program}-2047 | the program" in readme
