"""The BS2's variable RAM: 16 words (INS, OUTS, DIRS, then W0..W12 = 26 bytes of user RAM).

A variable is a bit range of that RAM: ``Loc(off, size)`` with ``off`` in bits from the start
of INS and ``size`` 1, 4, 8 or 16. The allocator places declarations as the tokenizer does,
words first, then bytes, nibbles, bits (each in declaration order) from W0 upward, so aliases
and the predefined W0..W12 / B0..B25 names overlap exactly as on the Stamp.
"""

from __future__ import annotations

from dataclasses import dataclass

USER_BASE = 3 * 16  # first bit of W0
USER_BITS = 26 * 8
SIZE_BITS = {"BIT": 1, "NIB": 4, "BYTE": 8, "WORD": 16}
IO_WORDS = {1, 2}  # writing OUTS or DIRS changes what INS reads


@dataclass(frozen=True, slots=True)
class Loc:
    """A fixed bit range of RAM."""

    off: int
    size: int


def predefined_locations() -> dict[str, Loc]:
    """The names every BS2 program has: W0..W12, B0..B25, INS/OUTS/DIRS and their parts."""
    locs: dict[str, Loc] = {}
    for i in range(13):
        locs[f"W{i}"] = Loc(USER_BASE + 16 * i, 16)
    for i in range(26):
        locs[f"B{i}"] = Loc(USER_BASE + 8 * i, 8)
    for reg, prefix in enumerate(("IN", "OUT", "DIR")):
        base = reg * 16
        locs[prefix + "S"] = Loc(base, 16)
        locs[prefix + "L"] = Loc(base, 8)
        locs[prefix + "H"] = Loc(base + 8, 8)
        for k, letter in enumerate("ABCD"):
            locs[prefix + letter] = Loc(base + 4 * k, 4)
        for b in range(16):
            locs[f"{prefix}{b}"] = Loc(base + b, 1)
    return locs


def modifier(loc_size: int, name: str) -> tuple[int, int] | None:
    """(bit offset, size) of a modifier such as HIGHBYTE or BIT3 within a variable of loc_size
    bits, or None when it does not fit. As the tokenizer has it: a modifier names a strictly
    smaller part, and HIGHBYTE/HIGHNIB/HIGHBIT are the top part of the variable they modify
    (a Word's HIGHNIB is NIB3, a Byte's is NIB1)."""
    kind = name[:3] if name.startswith(("BIT", "NIB")) and name[3:].isdigit() else name
    size = {"LOWBYTE": 8, "HIGHBYTE": 8, "BYTE0": 8, "BYTE1": 8, "LOWNIB": 4, "HIGHNIB": 4,
            "NIB": 4, "LOWBIT": 1, "HIGHBIT": 1, "BIT": 1}[kind]
    if name.startswith("HIGH"):
        delta = loc_size - size
    elif kind in ("BIT", "NIB"):
        delta = int(name[3:]) * size
    else:
        delta = 8 if name == "BYTE1" else 0
    if size >= loc_size or delta + size > loc_size:
        return None
    return delta, size


def allocate(decls: list[tuple[str, int, int]]) -> tuple[dict[str, Loc], int]:
    """Place (name, size bits, count) declarations: words, then bytes, nibs, bits.

    Returns the locations and the number of RAM bits used; the caller checks the 208-bit limit.
    """
    locs: dict[str, Loc] = {}
    off = USER_BASE
    for size in (16, 8, 4, 1):
        for name, sz, count in decls:
            if sz == size:
                locs[name] = Loc(off, size)
                off += size * count
    return locs, off - USER_BASE
