"""Symbol tables of one program: constants, pins, variables (with RAM layout), DATA and labels.

Built from the parsed statements before any code is generated, so labels and DATA addresses
may be used before the line that defines them.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import syntax as S
from .errors import PbasicSyntaxError
from .memory import SIZE_BITS, USER_BITS, Loc, allocate, modifier, predefined_locations
from .operators import BINARY, UNARY
from .peripherals import EEPROM_SIZE

PREDEFINED_CONSTANTS = {
    "CLS": 0, "HOME": 1, "CRSRXY": 2, "CRSRLF": 3, "CRSRRT": 4, "CRSRUP": 5, "CRSRDN": 6,
    "BELL": 7, "BKSP": 8, "TAB": 9, "LF": 10, "CLREOL": 11, "CLRDN": 12, "CR": 13, "CRSRX": 14,
    "CRSRY": 15,
}
RAM_BITS_TOTAL = 16 * 16


@dataclass
class CodeLabel:
    """A jump target; pos is its instruction index once code is generated."""

    name: str
    line: int
    pos: int | None = None


def walk(stmts: list):
    """Every statement, entering the bodies of IF, DO, FOR and SELECT."""
    for s in stmts:
        yield s
        if isinstance(s, S.If):
            for _, body in s.branches:
                yield from walk(body)
            if s.orelse:
                yield from walk(s.orelse)
        elif isinstance(s, (S.Do, S.For)):
            yield from walk(s.body)
        elif isinstance(s, S.Select):
            for _, body, _ in s.cases:
                yield from walk(body)
            if s.orelse:
                yield from walk(s.orelse)


class Symbols:
    """Names of one program and what each denotes."""

    def __init__(self, stmts: list, filename: str) -> None:
        self.filename = filename
        self.kind: dict[str, str] = {}  # name -> con | pin | var | data | label
        self.where: dict[str, int] = {}
        self.con_expr: dict[str, tuple[object, int]] = {}
        self.con_value: dict[str, int] = dict(PREDEFINED_CONSTANTS)
        self.pin_expr: dict[str, tuple[object, int]] = {}
        self.pins: dict[str, int] = {}
        self.vars: dict[str, Loc] = dict(predefined_locations())
        self.var_count: dict[str, int] = {}
        self.labels: dict[str, CodeLabel] = {}
        self.data_addr: dict[str, int] = {}
        self.data_image = bytearray(EEPROM_SIZE)
        self.data_used: set[int] = set()
        self._busy: set[str] = set()
        for name in PREDEFINED_CONSTANTS:
            self.kind[name] = "con"
        for name in self.vars:
            self.kind[name] = "var"
        self.ram_bits = 0
        self.var_counts: dict[str, int] = {}
        self._collect(stmts)

    def error(self, line: int, msg: str) -> PbasicSyntaxError:
        return PbasicSyntaxError(self.filename, line, msg)

    def _define(self, name: str, kind: str, line: int) -> None:
        if name in self.kind:
            prev = self.where.get(name)
            at = f" (line {prev})" if prev else " (a built-in name)"
            raise self.error(line, f"{name} is already defined{at}")
        self.kind[name] = kind
        self.where[name] = line

    # ---- collection ----
    def _collect(self, stmts: list) -> None:
        decls: list[tuple[str, int, int]] = []
        aliases: list[S.VarDecl] = []
        datas: list[S.DataDecl] = []
        last_var_line = 0
        for s in walk(stmts):
            if isinstance(s, S.Label):
                self._define(s.name, "label", s.line)
                self.labels[s.name] = CodeLabel(s.name, s.line)
            elif isinstance(s, S.ConDecl):
                self._define(s.name, "con", s.line)
                self.con_expr[s.name] = (s.expr, s.line)
            elif isinstance(s, S.PinDecl):
                self._define(s.name, "pin", s.line)
                self.pin_expr[s.name] = (s.expr, s.line)
            elif isinstance(s, S.VarDecl):
                self._define(s.name, "var", s.line)
                if s.size is None:
                    aliases.append(s)
                else:
                    decls.append((s.name, SIZE_BITS[s.size], s.count or 1))
                    self.var_count[s.name] = s.count or 1
                    last_var_line = s.line
            elif isinstance(s, S.DataDecl):
                if s.label:
                    self._define(s.label, "data", s.line)
                datas.append(s)
        locs, used = allocate(decls)
        if used > USER_BITS:
            w = sum(c for _, sz, c in decls if sz == 16)
            b = sum(c for _, sz, c in decls if sz == 8)
            n = sum(c for _, sz, c in decls if sz == 4)
            bits = sum(c for _, sz, c in decls if sz == 1)
            raise self.error(
                last_var_line,
                f"out of variable space: {w} words, {b} bytes, {n} nibs and {bits} bits need "
                f"{(used + 7) // 8} bytes; the BS2 has 26",
            )
        self.ram_bits = used
        self.var_counts = {name: sum(c for _, sz, c in decls if sz == size)
                           for name, size in (("words", 16), ("bytes", 8), ("nibbles", 4),
                                              ("bits", 1))}
        self.vars.update(locs)
        pending = {a.name: a for a in aliases}
        for a in aliases:
            self._resolve_alias(a, pending, 0)
        self._layout_data(datas)
        for name in list(self.con_expr):
            self.constant(name, self.con_expr[name][1])
        for name, (expr, line) in self.pin_expr.items():
            v = self.fold(expr, line, need=True)
            if v > 15:
                raise self.error(line, f"PIN {name} = {v}: the BS2 has pins 0 to 15")
            self.pins[name] = v

    def _resolve_alias(self, a: S.VarDecl, pending: dict, depth: int) -> Loc:
        if a.name in self.vars and a.name not in pending:
            return self.vars[a.name]
        if depth > 32:
            raise self.error(a.line, f"alias {a.name} refers to itself")
        ref = a.alias
        if ref.name in pending and ref.name not in self.vars:
            self._resolve_alias(pending[ref.name], pending, depth + 1)
        kind = self.kind.get(ref.name)
        if kind == "pin":
            base = self.vars[f"IN{self.pin_number(ref.name, a.line)}"]
        elif kind != "var" or ref.name not in self.vars:
            raise self.error(a.line, f"{a.name} VAR {ref.name}: {ref.name} is not a variable")
        else:
            base = self.vars[ref.name]
        off, size = self.apply_modifiers(base, ref, a.line)
        if ref.index is not None:
            idx = self.fold(ref.index, a.line, need=True)
            off += idx * size
        if off + size > RAM_BITS_TOTAL:
            raise self.error(a.line, f"alias {a.name} lies outside RAM")
        loc = Loc(off, size)
        self.vars[a.name] = loc
        pending.pop(a.name, None)
        self.var_count[a.name] = self.var_count.get(ref.name, 1) if not ref.modifiers else 1
        return loc

    def apply_modifiers(self, base: Loc, ref: S.Ref, line: int) -> tuple[int, int]:
        off, size = base.off, base.size
        for mod in ref.modifiers:
            m = modifier(size, mod)
            if m is None:
                raise self.error(line, f".{mod} does not fit in a {size}-bit variable ({ref.name})")
            off, size = off + m[0], m[1]
        return off, size

    # ---- constants ----
    def constant(self, name: str, line: int) -> int:
        if name in self.con_value:
            return self.con_value[name]
        if name in self._busy:
            raise self.error(line, f"constant {name} is defined in terms of itself")
        self._busy.add(name)
        expr, dline = self.con_expr[name]
        v = self.fold(expr, dline, need=True)
        self._busy.discard(name)
        self.con_value[name] = v
        return v

    def pin_number(self, name: str, line: int) -> int:
        if name not in self.pins:
            expr, dline = self.pin_expr[name]
            self.pins[name] = self.fold(expr, dline, need=True)
        return self.pins[name]

    def fold(self, node, line: int, need: bool = False, pins_as_numbers: bool = True) -> int | None:
        """The constant value of an expression, or None (error if need) when it uses a variable."""
        if isinstance(node, S.Num):
            return node.value & 0xFFFF
        if isinstance(node, S.Ref):
            kind = self.kind.get(node.name)
            if node.modifiers or node.index is not None:
                if kind in ("con", "data", "pin", "label"):
                    raise self.error(node.line, f"{node.name} is not a variable")
            if kind == "con":
                return self.constant(node.name, node.line)
            if kind == "data":
                if node.name not in self.data_addr:
                    raise self.error(node.line,
                                     f"DATA label {node.name} is used before its address is known")
                return self.data_addr[node.name]
            if kind == "pin" and pins_as_numbers:
                return self.pin_number(node.name, node.line)
            if kind == "label":
                raise self.error(node.line, f"label {node.name} is not a value")
            if kind is None:
                raise self.error(node.line, f"undefined symbol {node.name}")
            if need:
                raise self.error(line, f"{node.name} is a variable; a constant is needed here")
            return None
        if isinstance(node, S.Unary):
            v = self.fold(node.operand, line, need, pins_as_numbers)
            return None if v is None else UNARY[node.op](v) & 0xFFFF
        if isinstance(node, S.Binary):
            a = self.fold(node.left, line, need, pins_as_numbers)
            b = self.fold(node.right, line, need, pins_as_numbers)
            if a is None or b is None:
                return None
            return BINARY[node.op](a, b) & 0xFFFF
        raise self.error(line, "unsupported expression")

    # ---- DATA ----
    def _layout_data(self, datas: list[S.DataDecl]) -> None:
        ptr = 0
        placed: list[tuple[int, S.DataDecl, list]] = []
        for d in datas:  # pass 1: addresses
            items = []
            for item in d.items:
                if item[0] == "at":
                    ptr = self.fold(item[1], d.line, need=True)
                    continue
                if d.label and d.label not in self.data_addr:
                    self.data_addr[d.label] = ptr
                items.append((ptr, item))
                ptr += self._item_size(item, d.line)
            if d.label and d.label not in self.data_addr:
                self.data_addr[d.label] = ptr
            placed.append((ptr, d, items))
        for _, d, items in placed:  # pass 2: values
            for addr, item in items:
                self._place(addr, item, d.line)

    def _item_size(self, item, line: int) -> int:
        kind = item[0]
        if kind == "str":
            return len(item[1])
        if kind == "reserve":
            return self.fold(item[1], line, need=True)
        count = self.fold(item[2], line, need=True) if item[2] is not None else 1
        return count * (2 if kind == "word" else 1)

    def _put(self, addr: int, value: int, line: int) -> None:
        if addr >= EEPROM_SIZE:
            raise self.error(line, f"DATA beyond the {EEPROM_SIZE}-byte EEPROM (address {addr})")
        if addr in self.data_used:
            raise self.error(line, f"DATA location {addr} is already occupied")
        self.data_used.add(addr)
        self.data_image[addr] = value & 0xFF

    def _place(self, addr: int, item, line: int) -> None:
        kind = item[0]
        if kind == "str":
            for i, ch in enumerate(item[1]):
                self._put(addr + i, ord(ch), line)
            return
        if kind == "reserve":
            n = self.fold(item[1], line, need=True)
            if addr + n > EEPROM_SIZE:
                raise self.error(line, f"DATA beyond the {EEPROM_SIZE}-byte EEPROM ({addr + n})")
            return
        value = self.fold(item[1], line, need=True)
        count = self.fold(item[2], line, need=True) if item[2] is not None else 1
        for k in range(count):
            if kind == "word":
                self._put(addr + 2 * k, value & 0xFF, line)
                self._put(addr + 2 * k + 1, value >> 8, line)
            else:
                self._put(addr + k, value, line)
