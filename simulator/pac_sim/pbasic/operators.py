"""PBASIC 2.5 operators on 16-bit unsigned values (BS2 semantics; results wrap modulo 65536).

Comparisons and the logical operators (NOT AND OR XOR) give 1 for true and 0 for false; any
non-zero operand counts as true. Division or modulus by zero gives $FFFF (the BS2 returns all
ones; documented choice). Shifts by 16 or more give 0.
"""

from __future__ import annotations

from collections.abc import Callable
from math import isqrt

M = 0xFFFF


def _div(a: int, b: int) -> int:
    return a // b if b else M


def _mod(a: int, b: int) -> int:
    return a % b if b else M


def _dig(a: int, n: int) -> int:
    return (a // 10**n) % 10 if n < 5 else 0


def _rev(a: int, n: int) -> int:
    n &= 31
    out = 0
    for i in range(min(n, 16)):
        if a >> i & 1:
            out |= 1 << (n - 1 - i)
    return out & M


def _ncd(a: int) -> int:
    return a.bit_length()


def _abs(a: int) -> int:
    return (-a) & M if a & 0x8000 else a


BINARY: dict[str, Callable[[int, int], int]] = {
    "+": lambda a, b: (a + b) & M,
    "-": lambda a, b: (a - b) & M,
    "*": lambda a, b: (a * b) & M,
    "**": lambda a, b: (a * b) >> 16,
    "*/": lambda a, b: ((a * b) >> 8) & M,
    "/": _div,
    "//": _mod,
    "MIN": lambda a, b: a if a > b else b,
    "MAX": lambda a, b: a if a < b else b,
    "&": lambda a, b: a & b,
    "|": lambda a, b: a | b,
    "^": lambda a, b: a ^ b,
    "<<": lambda a, b: (a << b) & M if b < 16 else 0,
    ">>": lambda a, b: a >> b if b < 16 else 0,
    "DIG": _dig,
    "REV": _rev,
    "=": lambda a, b: 1 if a == b else 0,
    "<>": lambda a, b: 1 if a != b else 0,
    "<": lambda a, b: 1 if a < b else 0,
    ">": lambda a, b: 1 if a > b else 0,
    "<=": lambda a, b: 1 if a <= b else 0,
    ">=": lambda a, b: 1 if a >= b else 0,
    "AND": lambda a, b: 1 if a and b else 0,
    "OR": lambda a, b: 1 if a or b else 0,
    "XOR": lambda a, b: 1 if bool(a) != bool(b) else 0,
}

UNARY: dict[str, Callable[[int], int]] = {
    "-": lambda a: (-a) & M,
    "~": lambda a: ~a & M,
    "ABS": _abs,
    "SQR": isqrt,
    "DCD": lambda a: 1 << (a & 15),
    "NCD": _ncd,
    "NOT": lambda a: 0 if a else 1,
}
