"""The interpreter agrees with Parallax's tokenizer (npm pbasic-tokenizer, via the firmware's
tools/tokenize.js): same programs accepted, same errors on the same lines, same RAM counts and
the same DATA bytes in EEPROM. Skipped where node or the tokenizer is not installed."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from pac_sim.pbasic import PbasicSyntaxError, Stamp
from pac_sim.pbasic.image import read_image

ROOT = Path(__file__).resolve().parents[2]
TOKENIZE = ROOT / "firmware" / "tools" / "tokenize.js"
PROGRAMS = sorted((Path(__file__).parent / "programs").glob("*.bs2"))
FIRMWARE = ROOT / "firmware" / "servobot.bs2"
HEADER = "' {$STAMP BS2}\n' {$PBASIC 2.5}\n"

pytestmark = pytest.mark.skipif(
    shutil.which("node") is None or not TOKENIZE.exists()
    or not (ROOT / "firmware" / "node_modules" / "pbasic-tokenizer").exists(),
    reason="node or the pbasic-tokenizer package is not installed (make firmware installs it)",
)


def tokenize(source: Path, out: Path) -> dict:
    """The tokenizer's image JSON, or {"error_line": n, "message": ...} when it rejects."""
    r = subprocess.run(["node", str(TOKENIZE), str(source), "--out", str(out), "--quiet"],
                       capture_output=True, text=True, timeout=60)
    if r.returncode != 0:
        m = re.search(r":(\d+):\d+: error \S+: (.*)", r.stderr)
        assert m, r.stderr
        return {"error_line": int(m.group(1)), "message": m.group(2)}
    return json.loads((out / (source.stem + ".json")).read_text())


def defined_data(image: dict) -> dict[int, int]:
    eeprom = bytes.fromhex(image["eeprom"])
    flags = bytes.fromhex(image["eeprom_flags"])
    return {a: eeprom[a] for a in range(len(eeprom)) if flags[a] & 3 == 2}


def check_same(path: Path, tmp_path: Path) -> None:
    image = tokenize(path, tmp_path)
    assert "error_line" not in image, image
    s = Stamp.from_file(path)
    ram = image["resources"]["ram"]
    mine = s.program.symbols.var_counts
    assert {k: ram[k] for k in mine} == mine
    ours = {a: s.program.data_image[a] for a in s.program.symbols.data_used}
    assert ours == defined_data(image)


@pytest.mark.parametrize("path", PROGRAMS, ids=[p.name for p in PROGRAMS])
def test_test_programs_agree(path, tmp_path):
    check_same(path, tmp_path)


def test_firmware_agrees(tmp_path):
    if not FIRMWARE.exists():
        pytest.skip("no firmware/servobot.bs2 in this checkout")
    check_same(FIRMWARE, tmp_path)
    kw = read_image(tmp_path / "servobot.json")
    s = Stamp.from_file(FIRMWARE, **kw)  # checks the image holds the same DATA bytes
    assert max(s.program.symbols.data_used) < kw["program_start"] < 2048
    assert s.eeprom.mem[kw["program_start"]:] == kw["eeprom_image"][kw["program_start"]:]
    s.run_until_serin(2.0)


def test_error_lines_agree(tmp_path, error_cases):
    """Where the tokenizer rejects a program of the error tests, we reject it on the same line."""
    compared = 0
    for i, (body, _, _) in enumerate(error_cases):
        src = tmp_path / f"e{i}.bs2"
        src.write_text(HEADER + body)
        theirs = tokenize(src, tmp_path)
        if "error_line" not in theirs:
            continue  # valid PBASIC that this emulator does not support (FREQOUT, RANDOM...)
        with pytest.raises(PbasicSyntaxError) as exc:
            Stamp.from_file(src)
        assert exc.value.line == theirs["error_line"], (body, theirs["message"])
        compared += 1
    assert compared >= 20


def program_tokens(image: dict) -> bytes:
    eeprom = bytes.fromhex(image["eeprom"])
    flags = bytes.fromhex(image["eeprom_flags"])
    return bytes(eeprom[a] for a in range(len(eeprom)) if flags[a] & 3 == 3)


@pytest.mark.parametrize(("decl", "high", "same", "other"),
                         [("Word", "HIGHNIB", "NIB3", "NIB1"), ("Byte", "HIGHBIT", "BIT7", "BIT6")])
def test_high_modifiers_compile_like_the_tokenizer(tmp_path, decl, high, same, other):
    """The tokenizer emits the same tokens for v.HIGHNIB as for the part we resolve it to."""
    tokens = {}
    for mod in (high, same, other):
        src = tmp_path / f"m_{mod}.bs2"
        src.write_text(HEADER + f"v VAR {decl}\nh VAR v.{mod}\nh = 1\n")
        tokens[mod] = program_tokens(tokenize(src, tmp_path))
        Stamp.from_file(src)
    assert tokens[high] == tokens[same] != tokens[other]


LAYOUT = """a VAR Bit
b VAR Nib
c VAR Byte(3)
d VAR Word
e VAR Bit(5)
f VAR Nib
g VAR Word(2)
h VAR Byte
al VAR g.HIGHBYTE
an VAR c.NIB1
ab VAR d.BIT9
aa VAR al
"""


def equivalent(off: int, size: int) -> str:
    """The predefined-name spelling of a RAM bit range (W/B plus a modifier)."""
    k, bit = divmod(off - 48, 8)
    if size == 16:
        return f"W{k // 2}"
    if size == 8:
        return f"B{k}"
    return f"B{k}.NIB{bit // 4}" if size == 4 else f"B{k}.BIT{bit}"


def check_layout(decls: str, tmp_path: Path) -> int:
    """Tokens of `v = 1` for every variable equal those of its W/B equivalent: the tokenizer
    put each variable where we did."""
    probe = tmp_path / "probe.bs2"
    probe.write_text(HEADER + decls)
    sym = Stamp.from_file(probe).program.symbols
    names = [n for n in sym.where if sym.kind[n] == "var"]
    ours = "".join(f"{n} = 1\n" for n in names)
    theirs = "".join(f"{equivalent(sym.vars[n].off, sym.vars[n].size)} = 1\n" for n in names)
    out = []
    for tag, body in (("ours", ours), ("theirs", theirs)):
        src = tmp_path / f"layout_{tag}.bs2"
        src.write_text(HEADER + decls + body)
        out.append(program_tokens(tokenize(src, tmp_path)))
    assert out[0] == out[1]
    return len(names)


def test_ram_layout_matches_the_tokenizer(tmp_path):
    assert check_layout(LAYOUT, tmp_path) == 12


def test_firmware_ram_layout_matches_the_tokenizer(tmp_path):
    if not FIRMWARE.exists():
        pytest.skip("no firmware/servobot.bs2 in this checkout")
    lines = FIRMWARE.read_text(encoding="latin-1").splitlines()
    decls = "".join(line.split("'")[0] + "\n" for line in lines
                    if " VAR " in line.split("'")[0].upper())
    assert check_layout(decls, tmp_path) >= 20


DECLS = "x VAR Word\ny VAR Word\na VAR Byte\nb VAR Byte\nc VAR Byte\n"
# (statement, explicit grouping): the tokenizer emits the same tokens for both
SAME = [
    ("x = y + 3 * 4", "x = (y + 3) * 4"),
    ("x = -y + 10", "x = (-y) + 10"),
    ("x = ABS y + 1", "x = (ABS y) + 1"),
    ("x = y MAX 1 * 3", "x = (y MAX 1) * 3"),
    ("IF x + 1 > 5 AND y = 2 THEN x = 1", "IF ((x + 1) > 5) AND (y = 2) THEN x = 1"),
    ("IF NOT x = 1 AND y = 2 THEN x = 1", "IF (NOT (x = 1)) AND (y = 2) THEN x = 1"),
    ("IF a = 1 OR b = 1 AND c = 1 THEN x = 1", "IF ((a = 1) OR (b = 1)) AND (c = 1) THEN x = 1"),
    ("IF a = 1 AND b = 1 XOR c = 1 THEN x = 1", "IF ((a = 1) AND (b = 1)) XOR (c = 1) THEN x = 1"),
]
# ... and different tokens for these other groupings
DIFFERENT = [
    ("x = y + 3 * 4", "x = y + (3 * 4)"),
    ("IF a = 1 OR b = 1 AND c = 1 THEN x = 1", "IF (a = 1) OR ((b = 1) AND (c = 1)) THEN x = 1"),
]


def tokens_of(body: str, tmp_path: Path, tag: str) -> bytes:
    src = tmp_path / f"g_{tag}.bs2"
    src.write_text(HEADER + DECLS + body + "\n")
    return program_tokens(tokenize(src, tmp_path))


def results(body: str) -> list[int]:
    """x after running body for a grid of a, b, c, y values, in the interpreter."""
    out = []
    for a, b, c, y in [(1, 1, 1, 4), (1, 0, 1, 2), (0, 1, 1, 7), (1, 1, 0, 0), (0, 0, 0, 9),
                       (1, 0, 0, 3), (0, 1, 0, 65535), (0, 0, 1, 1)]:
        s = Stamp.from_source(HEADER + DECLS + f"a = {a}\nb = {b}\nc = {c}\ny = {y}\n{body}\n",
                              "g.bs2")
        s.run_for(1)
        out.append(s.var("x"))
    return out


def test_grouping_agrees_with_the_tokenizer(tmp_path):
    plain = "\n".join(p for p, _ in SAME)
    grouped = "\n".join(g for _, g in SAME)
    assert tokens_of(plain, tmp_path, "plain") == tokens_of(grouped, tmp_path, "grouped")
    for i, (p, g) in enumerate(DIFFERENT):
        assert tokens_of(p, tmp_path, f"p{i}") != tokens_of(g, tmp_path, f"g{i}")
    for p, g in SAME:  # and the interpreter evaluates each pair alike
        assert results(p) == results(g), p
    p, g = DIFFERENT[1]
    assert results(p) != results(g)
