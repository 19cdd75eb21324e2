"""RAM layout as the tokenizer makes it: words, bytes, nibs, bits; aliases, modifiers, arrays."""

from __future__ import annotations

import pytest

from pac_sim.pbasic import PbasicRuntimeError, PbasicSyntaxError


def test_words_are_placed_before_bytes_nibs_bits(run):
    # declared in the "wrong" order on purpose: the allocator sorts by size
    s = run("bt VAR Bit\nn VAR Nib\nb VAR Byte\nw VAR Word\n"
            "w = $1234\nb = $56\nn = 7\nbt = 1\nEND\n")
    assert s.var("W0") == 0x1234  # the word takes W0
    assert s.var("B2") == 0x56  # then the byte
    assert s.var("B3") == 0x17  # nib in the low half of B3, the bit right after it


def test_aliases_and_modifiers_overlap(run):
    s = run("w VAR Word\nlo VAR w.LOWBYTE\nhi VAR w.HIGHBYTE\nn3 VAR w.NIB3\ntop VAR w.BIT15\n"
            "same VAR w\n"
            "w = $A5C3\nx VAR Byte\nx = hi\nsame = same + 1\nEND\n")
    assert (s.var("lo"), s.var("hi"), s.var("n3"), s.var("top")) == (0xC4, 0xA5, 0xA, 1)
    assert s.var("x") == 0xA5


def test_modifier_in_expression_and_assignment(run):
    s = run("w VAR Word\nr VAR Word\nw = $00FF\nw.HIGHBYTE = $12\nw.BIT0 = 0\n"
            "r = w.HIGHNIB + w.LOWNIB\nEND\n")
    assert s.var("w") == 0x12FE
    assert s.var("r") == 0x1 + 0xE  # a Word's HIGHNIB is its NIB3 (as the tokenizer encodes it)


def test_arrays_index_and_overrun_into_next_variable(run):
    s = run("arr VAR Byte(3)\nnxt VAR Byte\ni VAR Nib\nFOR i = 0 TO 3\n  arr(i) = 10 + i\nNEXT\n"
            "END\n")
    assert [s.var("B0"), s.var("B1"), s.var("B2")] == [10, 11, 12]
    assert s.var("nxt") == 13  # PBASIC does not check bounds: arr(3) is the next byte


def test_bit_array_through_modifier(run):
    s = run("flags VAR Byte\ni VAR Nib\nFOR i = 0 TO 7 STEP 2\n  flags.BIT0(i) = 1\nNEXT\nEND\n")
    assert s.var("flags") == 0b01010101


def test_predefined_names_alias_user_ram(run):
    s = run("a VAR Word\nb VAR Word\nW1 = 500\nB0 = 7\nEND\n")
    assert (s.var("a"), s.var("b")) == (7, 500)


def test_26_bytes_fit_27_do_not(stamp):
    stamp("w VAR Word(12)\nb VAR Byte(2)\n")  # 26 bytes exactly
    with pytest.raises(PbasicSyntaxError, match=r"t\.bs2:5: out of variable space"):
        stamp("w VAR Word(12)\nb VAR Byte(2)\nextra VAR Bit\n")


def test_index_past_ram_is_a_runtime_error(stamp):
    s = stamp("arr VAR Word(2)\ni VAR Byte\ni = 20\narr(i) = 1\nEND\n")
    with pytest.raises(PbasicRuntimeError, match=r"t\.bs2:6: array index reaches past"):
        s.run_for(1)


def test_modifier_must_fit(stamp):
    with pytest.raises(PbasicSyntaxError, match=r"t\.bs2:4: .HIGHBYTE does not fit"):
        stamp("b VAR Byte\nb.HIGHBYTE = 1\n")


def test_pins_outs_dirs_ins(run):
    s = run("Led PIN 5\nr VAR Bit\nq VAR Bit\nHIGH 3\nLOW 4\nTOGGLE 3\nTOGGLE 3\n"
            "Led = 1\nr = Led\nINPUT 9\nq = IN9\nEND\n")
    assert s.var("DIRS") == (1 << 3) | (1 << 4)  # "Led = 1" writes OUT5 and leaves DIR5 alone
    assert s.var("OUTS") == (1 << 3) | (1 << 5)
    assert s.var("r") == 0  # Led as a value reads IN5, an input pin nobody drives
    assert s.var("q") == 0


def test_external_input_levels(stamp):
    s = stamp("Btn PIN 7\nr VAR Bit\nr = Btn\nEND\n")
    s.set_input(7, 1)
    s.run_for(1)
    assert s.var("r") == 1


@pytest.mark.parametrize(
    ("decl", "alias", "same_as"),
    [("Word", "HIGHNIB", "NIB3"), ("Byte", "HIGHNIB", "NIB1"), ("Word", "HIGHBIT", "BIT15"),
     ("Byte", "HIGHBIT", "BIT7"), ("Nib", "HIGHBIT", "BIT3"), ("Word", "HIGHBYTE", "BYTE1")],
)
def test_high_modifiers_are_relative_to_the_variable(stamp, decl, alias, same_as):
    s = stamp(f"v VAR {decl}\na VAR v.{alias}\nb VAR v.{same_as}\n")
    assert s.program.symbols.vars["A"] == s.program.symbols.vars["B"]


@pytest.mark.parametrize(("decl", "mod"), [("Byte", "LOWBYTE"), ("Nib", "LOWNIB"),
                                           ("Nib", "HIGHNIB"), ("Bit", "BIT0"), ("Byte", "BIT8")])
def test_modifier_must_name_a_smaller_part(stamp, decl, mod):
    with pytest.raises(PbasicSyntaxError, match=rf"t\.bs2:4: .{mod} does not fit"):
        stamp(f"v VAR {decl}\na VAR v.{mod}\n")
