"""Number formatting of SEROUT/DEBUG (DEC, HEX, BIN and their S/I variants) and the digit
rules SERIN uses to parse them back."""

from __future__ import annotations

BASES = {"DEC": 10, "HEX": 16, "BIN": 2}
PREFIX = {"HEX": "$", "BIN": "%", "DEC": ""}


def split_format(name: str) -> tuple[int, bool, str]:
    """(base, signed, prefix) of a format word such as SDEC, IHEX or ISBIN."""
    signed = False
    indicated = False
    core = name
    if core.startswith("IS"):
        indicated, signed, core = True, True, core[2:]
    elif core.startswith("I") and core != "I":
        indicated, core = True, core[1:]
    elif core.startswith("S") and core[1:] in BASES:
        signed, core = True, core[1:]
    return BASES[core], signed, PREFIX[core] if indicated else ""


def format_number(name: str, digits: int | None, value: int) -> bytes:
    """The text SEROUT/DEBUG send for ``NAME[digits] value`` (value is 16-bit unsigned)."""
    base, signed, prefix = split_format(name)
    value &= 0xFFFF
    sign = ""
    if signed and value & 0x8000:
        sign, value = "-", 0x10000 - value
    if digits is not None:
        value %= base**digits
    text = _to_base(value, base)
    if digits is not None:
        text = text.zfill(digits)
    return (sign + prefix + text).encode("ascii")


def _to_base(value: int, base: int) -> str:
    if base == 10:
        return str(value)
    if base == 16:
        return format(value, "X")
    return format(value, "b")


def digit_value(b: int, base: int) -> int | None:
    """The value of an ASCII digit in base, or None if b is not such a digit."""
    c = chr(b).upper()
    if c.isdigit():
        v = ord(c) - 48
    elif "A" <= c <= "F":
        v = ord(c) - 55
    else:
        return None
    return v if v < base else None
