"""A reader for the PBASIC 2.5 subset the ServoBot firmware's gait code uses, for the tests.

It takes the firmware source as written: CON constants (expressions evaluated left to right,
as PBASIC does), VAR declarations and their aliases (``gid.BIT4``, ``gid.LOWNIB``), DATA
statements (labels, ``@address``, numbers, strings, ``(n)`` reservations), and it executes the
``GaitCycle`` subroutine between the ``' <gait-cycle>`` and ``' </gait-cycle>`` markers
statement by statement (FOR/NEXT, READ, assignments, single-line IF ... THEN a : b, PULSOUT),
recording each activation's pulses and the number of PBASIC statements it executed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

SIZES = {"WORD": 16, "BYTE": 8, "NIB": 4, "BIT": 1}
MODIFIERS = {
    "LOWBYTE": (0, 8), "HIGHBYTE": (8, 8), "BYTE0": (0, 8), "BYTE1": (8, 8),
    "LOWNIB": (0, 4), "HIGHNIB": (4, 4), "NIB0": (0, 4), "NIB1": (4, 4),
    "NIB2": (8, 4), "NIB3": (12, 4), "LOWBIT": (0, 1), "HIGHBIT": (15, 1),
    **{f"BIT{i}": (i, 1) for i in range(16)},
}
BINARY = ("//", "+", "-", "*", "/", "&", "|", "^", "MIN", "MAX", "<<", ">>")
COMPARE = ("<>", "<=", ">=", "=", "<", ">")
TOKEN = re.compile(r"\s*(\$[0-9A-Fa-f]+|%[01]+|\d+|//|<<|>>|<>|<=|>=|[A-Za-z_][\w.]*|\S)")


def strip_comment(line: str) -> str:
    out, in_str = [], False
    for ch in line:
        if ch == '"':
            in_str = not in_str
        if ch == "'" and not in_str:
            break
        out.append(ch)
    return "".join(out).strip()


def split_top(text: str, sep: str) -> list[str]:
    """Split at ``sep`` outside parentheses and strings."""
    parts, depth, cur, in_str = [], 0, "", False
    for ch in text:
        if ch == '"':
            in_str = not in_str
        elif not in_str and ch == "(":
            depth += 1
        elif not in_str and ch == ")":
            depth -= 1
        if ch == sep and depth == 0 and not in_str:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    parts.append(cur.strip())
    return parts


def binop(op: str, v: int, w: int) -> int:
    """One PBASIC binary operator on 16-bit values (division by 0 gives $FFFF, as on a BS2)."""
    if op == "/":
        r = v // w if w else 0xFFFF
    elif op == "//":
        r = v % w if w else 0
    elif op == "MIN":
        r = max(v, w)
    elif op == "MAX":
        r = min(v, w)
    else:
        r = {"+": v + w, "-": v - w, "*": v * w, "&": v & w, "|": v | w, "^": v ^ w,
             "<<": v << w, ">>": v >> w}[op]
    return r & 0xFFFF


@dataclass
class Activation:
    pulses: list[tuple[int, int]] = field(default_factory=list)  # (pin, PULSOUT units)
    statements: int = 0


class Program:
    """Constants, variables and DATA of a PBASIC source, and an executor for its gait cycle."""

    def __init__(self, source: str) -> None:
        self.lines = [strip_comment(ln) for ln in source.splitlines()]
        self.raw = source.splitlines()
        self.consts: dict[str, int] = {}
        self.vars: dict[str, int] = {}  # base variable -> width in bits
        self.alias: dict[str, tuple[str, int, int]] = {}  # name -> (base, shift, width)
        self.labels: dict[str, int] = {}  # DATA labels -> EEPROM address
        self.data: dict[int, int] = {}  # EEPROM address -> defined byte
        self._parse_declarations()

    # ---- declarations ----------------------------------------------------------------------
    def _parse_declarations(self) -> None:
        ptr = 0
        for ln in self.lines:
            m = re.match(r"^(\w+)\s+CON\s+(.+)$", ln, re.I)
            if m:
                self.consts[m.group(1).upper()] = self.eval(m.group(2)) & 0xFFFF
                continue
            m = re.match(r"^(\w+)\s+VAR\s+(\w+)(?:\.(\w+))?$", ln, re.I)
            if m:
                name, base, mod = m.group(1).upper(), m.group(2).upper(), m.group(3)
                if base in SIZES and not mod:
                    self.vars[name] = SIZES[base]
                else:
                    b, shift, width = self.resolve(base)
                    if mod:
                        s2, w2 = MODIFIERS[mod.upper()]
                        shift, width = shift + s2, w2
                    self.alias[name] = (b, shift, width)
                continue
            m = re.match(r"^(?:(\w+)\s+)?DATA\s+(.+)$", ln, re.I)
            if m:
                items = split_top(m.group(2), ",")
                if items and items[0].startswith("@"):
                    first = items[0][1:].split(None, 1)
                    ptr = self.eval(first[0])
                    items = items[1:] if len(first) == 1 else [first[1], *items[1:]]
                if m.group(1):
                    self.labels[m.group(1).upper()] = ptr
                for item in items:
                    if item.startswith('"'):
                        for ch in item.strip('"'):
                            self.data[ptr] = ord(ch)
                            ptr += 1
                    elif item.startswith("("):
                        ptr += self.eval(item[1:-1])
                    else:
                        self.data[ptr] = self.eval(item) & 0xFF
                        ptr += 1

    def resolve(self, name: str) -> tuple[str, int, int]:
        name = name.upper()
        if name in self.vars:
            return name, 0, self.vars[name]
        if name in self.alias:
            return self.alias[name]
        if "." in name:
            base, mod = name.split(".", 1)
            b, shift, _ = self.resolve(base)
            s2, w2 = MODIFIERS[mod]
            return b, shift + s2, w2
        raise KeyError(f"unknown variable {name}")

    # ---- values ------------------------------------------------------------------------------
    def get(self, name: str, ram: dict[str, int]) -> int:
        name = name.upper()
        if name in self.consts:
            return self.consts[name]
        if name in self.labels:
            return self.labels[name]
        base, shift, width = self.resolve(name)
        return (ram.get(base, 0) >> shift) & ((1 << width) - 1)

    def set(self, name: str, value: int, ram: dict[str, int]) -> None:
        base, shift, width = self.resolve(name)
        mask = ((1 << width) - 1) << shift
        full = (1 << self.vars[base]) - 1
        ram[base] = ((ram.get(base, 0) & ~mask) | ((value << shift) & mask)) & full

    def eval(self, text: str, ram: dict[str, int] | None = None) -> int:
        """A PBASIC expression: strictly left to right, parentheses first, 16-bit results."""
        toks = TOKEN.findall(text)
        pos = 0

        def operand() -> int:
            nonlocal pos
            t = toks[pos]
            pos += 1
            if t == "(":
                v = expr()
                pos += 1  # ')'
                return v
            if t == "~":
                return ~operand() & 0xFFFF
            if t == "-":
                return -operand() & 0xFFFF
            if t.startswith("$"):
                return int(t[1:], 16)
            if t.startswith("%"):
                return int(t[1:], 2)
            if t.isdigit():
                return int(t)
            return self.get(t, ram if ram is not None else {})

        def expr() -> int:
            nonlocal pos
            v = operand()
            while pos < len(toks) and toks[pos].upper() in BINARY:
                op = toks[pos].upper()
                pos += 1
                w = operand()
                v = binop(op, v, w)
            return v

        return expr()

    def condition(self, text: str, ram: dict[str, int]) -> bool:
        ors = re.split(r"\s+OR\s+", text, flags=re.I)
        return any(
            all(self._compare(c, ram) for c in re.split(r"\s+AND\s+", part, flags=re.I))
            for part in ors
        )

    def _compare(self, text: str, ram: dict[str, int]) -> bool:
        depth = 0
        for i, ch in enumerate(text):
            depth += ch == "("
            depth -= ch == ")"
            if depth == 0:
                for op in COMPARE:
                    if text.startswith(op, i):
                        a, b = self.eval(text[:i], ram), self.eval(text[i + len(op):], ram)
                        return {"<>": a != b, "<=": a <= b, ">=": a >= b, "=": a == b,
                                "<": a < b, ">": a > b}[op]
        raise ValueError(f"not a comparison: {text}")

    # ---- execution ------------------------------------------------------------------------
    def gait_cycle(self, gait_id: int, gid_var: str = "gid") -> list[Activation]:
        """Execute the GaitCycle subroutine for ``gait_id``; one Activation per FOR pass."""
        m = Machine(self)
        m.set(gid_var, gait_id)
        m.run("GaitCycle", until_return=True)
        return m.activations


class Stop(Exception):
    """The program ended, or the host has nothing more to say."""


class Host:
    """What is on the other end of SERIN/SEROUT. Override :meth:`serin`."""

    def __init__(self) -> None:
        self.received = bytearray()

    def serout(self, data: bytes) -> None:
        self.received += data

    def serin(self, timeout_ms: int) -> bytes | None:
        raise Stop


class Machine:
    """Runs a :class:`Program` statement by statement: RAM, EEPROM (DATA, then WRITEs), a
    GOSUB stack, FOR loops. Counts executed statements (an IF and each statement its THEN
    runs count one each) and records each FOR pass as an :class:`Activation`."""

    def __init__(self, prog: Program, host: Host | None = None) -> None:
        self.prog = prog
        self.host = host or Host()
        self.ram: dict[str, int] = {}
        self.eeprom = bytearray(2048)
        for addr, v in prog.data.items():
            self.eeprom[addr] = v
        self.writes = 0
        self.statements = 0
        self.activations: list[Activation] = []
        self._act_start = 0
        self.stmts: list[str] = []
        self.labels: dict[str, int] = {}
        decl = re.compile(r"^(\w+\s+(CON|VAR|DATA)\b|DATA\b)", re.I)
        for ln in prog.lines:
            if not ln or decl.match(ln):
                continue
            m = re.match(r"^(\w+):$", ln)
            if m:
                self.labels[m.group(1).upper()] = len(self.stmts)
            else:
                self.stmts.append(ln)
        self.stack: list[int] = []
        self.loops: list[tuple[int, str, int]] = []

    def get(self, name: str) -> int:
        return self.prog.get(name, self.ram)

    def set(self, name: str, value: int) -> None:
        self.prog.set(name, value, self.ram)

    def eval(self, text: str) -> int:
        return self.prog.eval(text, self.ram)

    def run(self, label: str, until_return: bool = False, max_statements: int = 10**7) -> None:
        """Run from ``label``; with ``until_return``, until that subroutine returns."""
        self.pc = self.labels[label.upper()]
        depth = len(self.stack)
        if until_return:
            self.stack.append(-1)
        limit = self.statements + max_statements
        while self.statements < limit:
            if self.pc >= len(self.stmts):
                raise Stop
            s = self.stmts[self.pc]
            self.pc += 1
            self.exec(s)
            if until_return and self.pc == -1:
                del self.stack[depth:]
                return
        raise RuntimeError("statement budget exhausted")

    def jump(self, label: str) -> None:
        self.pc = self.labels[label.strip().upper()]

    def exec(self, s: str) -> None:
        self.statements += 1
        m = re.match(r"^IF\s+(.+?)\s+THEN\s+(.+)$", s, re.I)
        if m:
            if self.prog.condition(m.group(1), self.ram):
                then = m.group(2).strip()
                if then.upper() in self.labels:
                    self.jump(then)
                else:
                    for part in split_top(then, ":"):
                        self.statements += 1
                        self._do(part)
            return
        self._do(s)

    def _do(self, s: str) -> None:
        word = s.split(None, 1)[0].upper()
        rest = s[len(word):].strip()
        if word == "FOR":
            m = re.match(r"^(\w+)\s*=\s*(.+?)\s+TO\s+(.+)$", rest, re.I)
            self.set(m.group(1), self.eval(m.group(2)))
            self.loops.append((self.pc, m.group(1), self.eval(m.group(3))))
            self._act_start = self.statements - 1
            self.activations.append(Activation())
        elif word == "NEXT":
            start, var, stop = self.loops[-1]
            self.activations[-1].statements = self.statements - self._act_start
            v = self.get(var) + 1
            if v <= stop:
                self.set(var, v)
                self.pc = start
                self._act_start = self.statements
                self.activations.append(Activation())
            else:
                self.loops.pop()
        elif word == "GOTO":
            self.jump(rest)
        elif word == "GOSUB":
            self.stack.append(self.pc)
            self.jump(rest)
        elif word == "RETURN":
            self.pc = self.stack.pop()
        elif word == "ON":
            m = re.match(r"^(.+?)\s+GOTO\s+(.+)$", rest, re.I)
            targets = split_top(m.group(2), ",")
            i = self.eval(m.group(1))
            if i < len(targets):
                self.jump(targets[i])
        elif word == "PULSOUT":
            pin, width = split_top(rest, ",")
            self.activations[-1].pulses.append((self.eval(pin), self.eval(width)))
        elif word == "READ":
            addr, *targets = split_top(rest, ",")
            a = self.eval(addr)
            for k, t in enumerate(targets):
                self.set(t, self.eeprom[a + k])
        elif word == "WRITE":
            addr, *values = split_top(rest, ",")
            a = self.eval(addr)
            for k, v in enumerate(values):
                self.eeprom[a + k] = self.eval(v) & 0xFF
                self.writes += 1
        elif word == "SEROUT":
            items = rest[rest.index("[") + 1 : rest.rindex("]")]
            self.host.serout(bytes(self.eval(x) & 0xFF for x in split_top(items, ",")))
        elif word == "SERIN":
            self._serin(rest)
        elif word in ("END", "STOP"):
            raise Stop
        else:
            m = re.match(r"^([\w.]+)\s*=\s*(.+)$", s)
            if not m:
                raise ValueError(f"statement outside the subset: {s}")
            self.set(m.group(1), self.eval(m.group(2)))

    def _serin(self, rest: str) -> None:
        head, items = rest[: rest.index("[")], rest[rest.index("[") + 1 : rest.rindex("]")]
        _pin, _baud, timeout, label = (x for x in split_top(head.rstrip().rstrip(","), ","))
        data = self.host.serin(self.eval(timeout))
        parts = split_top(items, ",")
        wait = b""
        if parts[0].upper().startswith("WAIT("):
            wait = bytes(self.eval(x) for x in split_top(parts[0][5:-1], ","))
            parts = parts[1:]
        pos = data.find(wait) if data is not None else -1
        if pos < 0 or len(data) - pos - len(wait) < len(parts):
            self.jump(label)
            return
        body = data[pos + len(wait) :]
        for k, var in enumerate(parts):
            self.set(var, body[k])
