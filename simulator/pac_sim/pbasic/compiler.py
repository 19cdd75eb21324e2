"""Compile parsed PBASIC into Python functions, one per Stamp instruction.

Each instruction becomes a small generated Python function ``op() -> next index`` whose
expressions are inlined Python arithmetic on the RAM word list, so running a program is a tight
loop of calls (no tree walking). Instructions that touch time or peripherals (PAUSE, PULSOUT,
SERIN, SEROUT, DEBUG, WRITE, NAP, SLEEP, END, STOP) are "specials": their op returns -1 and the
machine runs the matching handler with the clock synchronised.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from math import isqrt

from . import syntax as S
from .errors import PbasicRuntimeError, PbasicSyntaxError
from .formats import digit_value, format_number, split_format
from .memory import IO_WORDS
from .operators import _abs, _dig, _rev
from .symbols import RAM_BITS_TOTAL, CodeLabel, Symbols

GOSUB_DEPTH = 4
CMP_PY = {"=": "==", "<>": "!=", "<": "<", ">": ">", "<=": "<=", ">=": ">="}
# Python source templates of the operators (16-bit unsigned results, see operators.py).
UNARY_SRC = {
    "NOT": "(not {a})", "-": "((-{a}) & 65535)", "~": "(~{a} & 65535)",
    "DCD": "(1 << ({a} & 15))", "NCD": "int({a}).bit_length()", "ABS": "_abs({a})",
    "SQR": "_isqrt({a})",
}
BINARY_SRC = {
    "AND": "(bool({a}) and bool({b}))", "OR": "(bool({a}) or bool({b}))",
    "XOR": "(bool({a}) != bool({b}))", "+": "(({a} + {b}) & 65535)", "-": "(({a} - {b}) & 65535)",
    "*": "(({a} * {b}) & 65535)", "**": "(({a} * {b}) >> 16)", "*/": "((({a} * {b}) >> 8) & 65535)",
    "&": "({a} & {b})", "|": "({a} | {b})", "^": "({a} ^ {b})", "/": "_div({a}, {b})",
    "//": "_mod({a}, {b})", "<<": "_shl({a}, {b})", ">>": "_shr({a}, {b})", "MIN": "max({a}, {b})",
    "MAX": "min({a}, {b})", "DIG": "_dig({a}, {b})", "REV": "_rev({a}, {b})",
}
BINARY_CONST_SRC = {"/": "({a} // {b})", "//": "({a} % {b})", "<<": "(({a} << {b}) & 65535)",
                    ">>": "({a} >> {b})"}


@dataclass
class SerinSpec:
    """A compiled SERIN: argument evaluators, timeout target and the byte consumer."""

    line: int
    pin: Callable[[], int]
    baud: Callable[[], int]
    timeout: Callable[[], int] | None
    tlabel: CodeLabel | None
    consumer: Callable[[], object]  # makes a generator: send(byte) until StopIteration


@dataclass
class Compiled:
    """The executable form of a program."""

    filename: str
    code: list  # op functions
    specials: dict[int, Callable[[], int]]
    lines: list[int]
    symbols: Symbols
    ram: list[int]
    data_image: bytes
    labels: dict[str, int] = field(default_factory=dict)


@dataclass
class _Entry:
    line: int
    render: Callable[[int], str] | None = None  # body source given next index
    special: Callable[[int], Callable[[], int]] | None = None


class Compiler:
    """Turns statements into instruction functions bound to one machine's state."""

    def __init__(self, stmts: list, filename: str, machine) -> None:
        self.filename = filename
        self.m = machine
        self.sym = Symbols(stmts, filename)
        self.ram = machine.ram
        self.entries: list[_Entry] = []
        self.loops: list[CodeLabel] = []
        self.for_dirs: list[int] = []
        self.ns: dict = {
            "R": self.ram, "E": machine.eeprom.mem, "ST": machine.stack, "FD": self.for_dirs,
            "_rd": self._rd, "_wr": self._wr, "_div": lambda a, b: a // b if b else 0xFFFF,
            "_mod": lambda a, b: a % b if b else 0xFFFF, "_dig": _dig, "_rev": _rev, "_abs": _abs,
            "_isqrt": isqrt, "_shl": lambda a, b: (a << b) & 0xFFFF if b < 16 else 0,
            "_shr": lambda a, b: a >> b if b < 16 else 0, "_iosync": machine.io_sync,
            "_fail": self._fail,
        }
        self.stmts = stmts

    # ---- runtime helpers referenced by generated code ----
    def _fail(self, line: int, msg: str):
        raise PbasicRuntimeError(self.filename, line, msg)

    def _rd(self, off: int, size: int, line: int) -> int:
        if off + size > RAM_BITS_TOTAL:
            self._fail(line, f"array index reaches past the end of RAM (bit {off})")
        reg, sh = divmod(off, 16)
        return (self.ram[reg] >> sh) & ((1 << size) - 1)

    def _wr(self, off: int, size: int, v: int, line: int) -> None:
        if off + size > RAM_BITS_TOTAL:
            self._fail(line, f"array index reaches past the end of RAM (bit {off})")
        reg, sh = divmod(off, 16)
        mask = (1 << size) - 1
        self.ram[reg] = (self.ram[reg] & ~(mask << sh) & 0xFFFF) | ((int(v) & mask) << sh)
        if reg in IO_WORDS:
            self.m.io_sync()

    def error(self, line: int, msg: str) -> PbasicSyntaxError:
        return PbasicSyntaxError(self.filename, line, msg)

    # ---- emission ----
    def here(self) -> int:
        return len(self.entries)

    def emit(self, line: int, render: Callable[[int], str]) -> None:
        self.entries.append(_Entry(line, render=render))

    def emit_special(self, line: int, make: Callable[[int], Callable[[], int]]) -> None:
        self.entries.append(_Entry(line, special=make))

    def new_label(self, line: int) -> CodeLabel:
        return CodeLabel("", line)

    def mark(self, label: CodeLabel) -> None:
        label.pos = self.here()

    def label(self, name: str, line: int) -> CodeLabel:
        if self.sym.kind.get(name) != "label":
            what = self.sym.kind.get(name)
            raise self.error(line, f"{name} is not a label" if what else f"undefined label {name}")
        return self.sym.labels[name]

    # ---- expressions ----
    def ref_location(self, ref: S.Ref, line: int, for_write: bool = False):
        """(off, size, index_src|None) of a variable reference; pins map to INn / OUTn."""
        kind = self.sym.kind.get(ref.name)
        if kind == "pin":
            n = self.sym.pin_number(ref.name, line)
            base = self.sym.vars[f"{'OUT' if for_write else 'IN'}{n}"]
        elif kind == "var":
            base = self.sym.vars[ref.name]
        elif kind is None:
            raise self.error(ref.line, f"undefined symbol {ref.name}")
        else:
            raise self.error(ref.line, f"{ref.name} is a {_KIND_NAMES[kind]}, not a variable")
        off, size = self.sym.apply_modifiers(base, ref, ref.line)
        if ref.index is None:
            return off, size, None
        c = self.sym.fold(ref.index, line)
        if c is not None:
            off += c * size
            if off + size > RAM_BITS_TOTAL:
                raise self.error(ref.line, f"{ref.name}({c}) lies outside RAM")
            return off, size, None
        return off, size, self.gv(ref.index, line)

    def read_src(self, ref: S.Ref, line: int) -> str:
        off, size, idx = self.ref_location(ref, line)
        if idx is not None:
            return f"_rd({off} + ({idx}) * {size}, {size}, {line})"
        reg, sh = divmod(off, 16)
        if size == 16:
            return f"R[{reg}]"
        mask = (1 << size) - 1
        return f"(R[{reg}] & {mask})" if sh == 0 else f"((R[{reg}] >> {sh}) & {mask})"

    def write_src(self, ref: S.Ref, value: str, line: int) -> str:
        """Python statement(s) storing value (an int expression) into ref."""
        kind = self.sym.kind.get(ref.name)
        if kind in ("con", "data", "label"):
            raise self.error(ref.line, f"cannot assign to {_KIND_NAMES[kind]} {ref.name}")
        off, size, idx = self.ref_location(ref, line, for_write=True)
        if idx is not None:
            return f"_wr({off} + ({idx}) * {size}, {size}, {value}, {line})"
        reg, sh = divmod(off, 16)
        if size == 16:
            src = f"R[{reg}] = ({value}) & 65535"
        else:
            mask = (1 << size) - 1
            keep = ~(mask << sh) & 0xFFFF
            src = f"R[{reg}] = (R[{reg}] & {keep}) | ((({value}) & {mask}) << {sh})"
        if reg in IO_WORDS:
            src += "; _iosync()"
        return src

    def gx(self, node, line: int) -> tuple[str, bool]:
        """Python source of an expression and whether it yields a bool (comparison/logic)."""
        c = self.sym.fold(node, line, pins_as_numbers=False)
        if c is not None:
            return str(c), False
        if isinstance(node, S.Ref):
            return self.read_src(node, line), False
        if isinstance(node, S.Unary):
            a, _ = self.gx(node.operand, line)
            return UNARY_SRC[node.op].format(a=a), node.op == "NOT"
        if isinstance(node, S.Binary):
            return self.binary_src(node, line)
        raise self.error(line, "unsupported expression")

    def binary_src(self, node: S.Binary, line: int) -> tuple[str, bool]:
        op = node.op
        a, _ = self.gx(node.left, line)
        b, _ = self.gx(node.right, line)
        rc = self.sym.fold(node.right, line, pins_as_numbers=False)
        if op in CMP_PY:
            return f"({a} {CMP_PY[op]} {b})", True
        if rc is not None and (op in ("<<", ">>") or (op in ("/", "//") and rc)):
            template = BINARY_CONST_SRC[op] if op in ("/", "//") or rc < 16 else "0"
            return template.format(a=a, b=rc), False
        return BINARY_SRC[op].format(a=a, b=b), op in ("AND", "OR", "XOR")

    def gv(self, node, line: int) -> str:
        """Source of an expression as an int (bools become 1/0)."""
        src, is_bool = self.gx(node, line)
        return f"(1 if {src} else 0)" if is_bool else src

    def gc(self, node, line: int) -> str:
        """Source of an expression used as a condition (truthy)."""
        return self.gx(node, line)[0]

    def pin_src(self, node, line: int, serial: bool = False) -> str:
        """A pin argument: a PIN name is its number here, not the value on the pin. Pins are
        0-15; serial commands may also use 16, the programming port."""
        c = self.sym.fold(node, line, pins_as_numbers=True)
        if c is not None:
            if c > (16 if serial else 15):
                ports = "0-15, 16 = programming port" if serial else "0-15"
                raise self.error(line, f"pin {c} does not exist (BS2 pins: {ports})")
            return str(c)
        return self.gv(node, line)

    def fn(self, src: str) -> Callable[[], int]:
        return eval(f"lambda R=R, E=E: {src}", self.ns)  # noqa: S307 - generated from parsed code

    def writer(self, ref: S.Ref, line: int) -> Callable[[int], None]:
        body = self.write_src(ref, "v", line)
        loc: dict = {}
        exec(f"def _w(v, R=R):\n    {body}\n", self.ns, loc)  # noqa: S102 - generated
        return loc["_w"]

    # ---- statements ----
    def compile(self) -> Compiled:
        self.block(self.stmts)
        self.emit_special(0, lambda nxt: lambda: self.m.halt("END", nxt - 1))  # ran off the end
        self.emit_special(0, lambda nxt: lambda: self.m.halt("CALL", nxt - 1))  # Stamp.call returns
        lines = [e.line for e in self.entries]
        code: list = [None] * len(self.entries)
        specials: dict[int, Callable[[], int]] = {}
        src_parts = []
        for pc, e in enumerate(self.entries):
            if e.special is not None:
                specials[pc] = e.special(pc + 1)
                code[pc] = _special_marker
            else:
                body = e.render(pc + 1)
                src_parts.append(f"def _op{pc}(R=R, E=E, ST=ST, FD=FD):\n    " +
                                 body.replace("\n", "\n    ") + "\n")
        if src_parts:
            exec("\n".join(src_parts), self.ns)  # noqa: S102 - generated from parsed code
        for pc in range(len(code)):
            if code[pc] is None:
                code[pc] = self.ns[f"_op{pc}"]
        labels = {n: lab.pos for n, lab in self.sym.labels.items()}
        return Compiled(self.filename, code, specials, lines, self.sym, self.ram,
                        bytes(self.sym.data_image), labels=labels)

    def block(self, stmts: list) -> None:
        for s in stmts:
            handler = getattr(self, "c_" + type(s).__name__.lower(), None)
            if handler is None:
                raise self.error(s.line, f"unsupported statement {type(s).__name__}")
            handler(s)

    def c_directive(self, s) -> None:
        return None

    c_vardecl = c_condecl = c_pindecl = c_datadecl = c_directive

    def c_label(self, s: S.Label) -> None:
        self.mark(self.sym.labels[s.name])

    def c_assign(self, s: S.Assign) -> None:
        src = self.write_src(s.target, self.gv(s.expr, s.line), s.line)
        self.emit(s.line, lambda nxt: f"{src}\nreturn {nxt}")

    def jump(self, line: int, target: CodeLabel) -> None:
        self.emit(line, lambda nxt: f"return {target.pos}")

    def branch(self, line: int, cond: str, if_true: CodeLabel | None, if_false: CodeLabel | None):
        """Conditional jump; a None target means fall through to the next instruction."""
        def render(nxt: int) -> str:
            t = if_true.pos if if_true else nxt
            f = if_false.pos if if_false else nxt
            return f"return {t} if {cond} else {f}"
        self.emit(line, render)

    def c_if(self, s: S.If) -> None:
        end = self.new_label(s.line)
        n = len(s.branches)
        for i, (cond, body) in enumerate(s.branches):
            skip = self.new_label(s.line)
            self.branch(s.line, self.gc(cond, s.line), None, skip)
            self.block(body)
            if i < n - 1 or s.orelse:
                self.jump(s.line, end)
            self.mark(skip)
        if s.orelse:
            self.block(s.orelse)
        self.mark(end)

    def c_do(self, s: S.Do) -> None:
        top = self.new_label(s.line)
        out = self.new_label(s.line)
        self.mark(top)
        if s.pre:
            cond = self.gc(s.pre[1], s.line)
            if s.pre[0] == "WHILE":
                self.branch(s.line, cond, None, out)
            else:
                self.branch(s.line, cond, out, None)
        self.loops.append(out)
        self.block(s.body)
        self.loops.pop()
        if s.post:
            cond = self.gc(s.post[1], s.end_line)
            if s.post[0] == "WHILE":
                self.branch(s.end_line, cond, top, None)
            else:
                self.branch(s.end_line, cond, None, top)
        else:
            self.jump(s.end_line, top)
        self.mark(out)

    def c_for(self, s: S.For) -> None:
        k = len(self.for_dirs)
        self.for_dirs.append(0)
        start = self.gv(s.start, s.line)
        end = self.gv(s.end, s.line)
        step = self.gv(s.step, s.line) if s.step is not None else "1"
        store = self.write_src(s.var, "v", s.line)
        self.emit(s.line, lambda nxt: f"v = {start}\n{store}\nFD[{k}] = v > {end}\nreturn {nxt}")
        top = self.new_label(s.line)
        out = self.new_label(s.line)
        self.mark(top)
        self.loops.append(out)
        self.block(s.body)
        self.loops.pop()
        cur = self.read_src(s.var, s.end_line)
        store_end = self.write_src(s.var, "v", s.end_line)

        def render_next(nxt: int) -> str:
            return (f"if FD[{k}]:\n    v = {cur} - {step}\n    {store_end}\n"
                    f"    return {top.pos} if {cur} >= {end} else {nxt}\n"
                    f"v = {cur} + {step}\n{store_end}\n"
                    f"return {top.pos} if {cur} <= {end} else {nxt}")

        self.emit(s.end_line, render_next)
        self.mark(out)

    def c_select(self, s: S.Select) -> None:
        subject = self.gv(s.expr, s.line)
        end = self.new_label(s.line)
        for conds, body, line in s.cases:
            parts = []
            for c in conds:
                if c[0] == "eq":
                    parts.append(f"x == {self.gv(c[1], line)}")
                elif c[0] == "cmp":
                    parts.append(f"x {CMP_PY[c[1]]} {self.gv(c[2], line)}")
                else:
                    lo, hi = self.gv(c[1], line), self.gv(c[2], line)
                    parts.append(f"min({lo}, {hi}) <= x <= max({lo}, {hi})")
            cond = " or ".join(f"({p})" for p in parts)
            skip = self.new_label(line)

            def render(nxt: int, cond=cond, skip=skip) -> str:
                return f"x = {subject}\nreturn {nxt} if {cond} else {skip.pos}"

            self.emit(line, render)
            self.block(body)
            self.jump(line, end)
            self.mark(skip)
        if s.orelse:
            self.block(s.orelse)
        self.mark(end)

    def c_jump(self, s: S.Jump) -> None:
        target = self.label(s.label, s.line)
        if s.kind == "GOTO":
            self.jump(s.line, target)
            return
        msg = f"GOSUB nested more than {GOSUB_DEPTH} deep (the BS2's limit)"
        self.emit(s.line, lambda nxt: (f"if len(ST) >= {GOSUB_DEPTH}: _fail({s.line}, {msg!r})\n"
                                       f"ST.append({nxt})\nreturn {target.pos}"))

    def c_simple(self, s: S.Simple) -> None:
        if s.kind == "RETURN":
            self.emit(s.line, lambda nxt: (f"if not ST: _fail({s.line}, 'RETURN without GOSUB')\n"
                                           "return ST.pop()"))
        elif s.kind == "EXIT":
            if not self.loops:
                raise self.error(s.line, "EXIT outside a DO or FOR loop")
            self.jump(s.line, self.loops[-1])
        else:
            kind = s.kind
            self.emit_special(s.line, lambda nxt: lambda: self.m.halt(kind, nxt - 1))

    def c_branch(self, s: S.Branch) -> None:
        targets = [self.label(n, s.line) for n in s.labels]
        idx = self.gv(s.index, s.line)
        msg = f"GOSUB nested more than {GOSUB_DEPTH} deep (the BS2's limit)"

        def render(nxt: int) -> str:
            table = "(" + ", ".join(str(t.pos) for t in targets) + ",)"
            if s.kind == "GOSUB":
                return (f"i = {idx}\nif i >= {len(targets)}: return {nxt}\n"
                        f"if len(ST) >= {GOSUB_DEPTH}: _fail({s.line}, {msg!r})\n"
                        f"ST.append({nxt})\nreturn {table}[i]")
            return f"i = {idx}\nreturn {table}[i] if i < {len(targets)} else {nxt}"

        self.emit(s.line, render)

    def c_pincmd(self, s: S.PinCmd) -> None:
        p = self.pin_src(s.pin, s.line)
        body = {
            "HIGH": "R[2] |= b; R[1] |= b",
            "LOW": "R[2] |= b; R[1] &= ~b & 65535",
            "TOGGLE": "R[2] |= b; R[1] ^= b",
            "INPUT": "R[2] &= ~b & 65535",
            "OUTPUT": "R[2] |= b",
            "REVERSE": "R[2] ^= b",
        }[s.kind]
        self.emit(s.line, lambda nxt: f"b = 1 << ({p} & 15)\n{body}\n_iosync()\nreturn {nxt}")

    def c_lookup(self, s: S.Lookup) -> None:
        values = "(" + ", ".join(self.gv(v, s.line) for v in s.values) + ",)"
        store = self.write_src(s.target, f"{values}[i]", s.line)
        idx = self.gv(s.index, s.line)
        n = len(s.values)
        self.emit(s.line, lambda nxt: f"i = {idx}\nif i < {n}:\n    {store}\nreturn {nxt}")

    def c_lookdown(self, s: S.Lookdown) -> None:
        values = "(" + ", ".join(self.gv(v, s.line) for v in s.values) + ",)"
        store = self.write_src(s.target, "i", s.line)
        value = self.gv(s.value, s.line)
        cmp = CMP_PY[s.op]
        self.emit(s.line, lambda nxt: (f"x = {value}\nfor i, y in enumerate({values}):\n"
                                       f"    if x {cmp} y:\n        {store}\n        break\n"
                                       f"return {nxt}"))

    def c_read(self, s: S.Read) -> None:
        lines = [f"a = {self.gv(s.addr, s.line)}"]
        for is_word, ref in s.targets:
            if is_word:
                lines.append(self.write_src(ref, "E[a & 2047] | (E[(a + 1) & 2047] << 8)", s.line))
                lines.append("a += 2")
            else:
                lines.append(self.write_src(ref, "E[a & 2047]", s.line))
                lines.append("a += 1")
        body = "\n".join(lines)
        self.emit(s.line, lambda nxt: f"{body}\nreturn {nxt}")

    # ---- specials: time and peripherals ----
    def c_timedcmd(self, s: S.TimedCmd) -> None:
        arg = self.fn(self.gv(s.arg, s.line))
        kind = s.kind
        self.emit_special(s.line, lambda nxt: lambda: self.m.timed(kind, arg(), nxt))

    def c_pulsout(self, s: S.Pulsout) -> None:
        pin = self.fn(self.pin_src(s.pin, s.line))
        width = self.fn(self.gv(s.width, s.line))
        self.emit_special(s.line, lambda nxt: lambda: self.m.pulsout(pin() & 15, width(), nxt))

    def c_write(self, s: S.Write) -> None:
        addr = self.fn(self.gv(s.addr, s.line))
        vals = [(w, self.fn(self.gv(v, s.line))) for w, v in s.values]

        def run(nxt: int) -> int:
            data = bytearray()
            for is_word, f in vals:
                v = f()
                data.append(v & 0xFF)
                if is_word:
                    data.append((v >> 8) & 0xFF)
            return self.m.eeprom_write(addr(), bytes(data), nxt)

        self.emit_special(s.line, lambda nxt: lambda: run(nxt))

    def out_renderer(self, items: list, line: int) -> Callable[[], bytes]:
        parts: list[Callable[[], bytes]] = []
        for item in items:
            kind = item[0]
            if kind == "text":
                data = item[1].encode("latin-1")
                parts.append(lambda data=data: data)
            elif kind == "raw":
                f = self.fn(self.gv(item[1], line))
                parts.append(lambda f=f: bytes((f() & 0xFF,)))
            elif kind == "fmt":
                _, name, digits, expr, shown = item
                f = self.fn(self.gv(expr, line))
                if shown is not None:
                    head = f"{shown} = ".encode("latin-1")
                    parts.append(lambda f=f, n=name, d=digits, h=head:
                                 h + format_number(n, d, f()) + b"\r")
                else:
                    parts.append(lambda f=f, n=name, d=digits: format_number(n, d, f()))
            elif kind == "rep":
                f = self.fn(self.gv(item[1], line))
                n = self.fn(self.gv(item[2], line))
                parts.append(lambda f=f, n=n: bytes((f() & 0xFF,)) * n())
            elif kind == "strvar":
                get = self.element_reader(item[1], line)
                n = self.fn(self.gv(item[2], line)) if item[2] is not None else None
                parts.append(lambda get=get, n=n: _str_out(get, n))
        return lambda: b"".join(p() for p in parts)

    def element_reader(self, ref: S.Ref, line: int) -> Callable[[int], int]:
        """Reads element i of an array (counting from the reference's own index)."""
        off, size, idx = self.ref_location(ref, line)
        start = self.fn(idx) if idx is not None else (lambda: 0)
        return lambda i: self._rd(off + (start() + i) * size, size, line)

    def element_writer(self, ref: S.Ref, line: int) -> Callable[[int, int], None]:
        off, size, idx = self.ref_location(ref, line, for_write=True)
        start = self.fn(idx) if idx is not None else (lambda: 0)
        return lambda i, v: self._wr(off + (start() + i) * size, size, v, line)

    def c_serout(self, s: S.Serout) -> None:
        pin = self.fn(self.pin_src(s.pin, s.line, serial=True))
        baud = self.fn(self.gv(s.baud, s.line))
        pace = self.fn(self.gv(s.pace, s.line)) if s.pace is not None else (lambda: 0)
        render = self.out_renderer(s.items, s.line)
        self.emit_special(s.line, lambda nxt: lambda: self.m.serout(pin(), baud(), pace(),
                                                                     render(), nxt))

    def c_debug(self, s: S.Debug) -> None:
        render = self.out_renderer(s.items, s.line)
        self.emit_special(s.line, lambda nxt: lambda: self.m.debug(render(), nxt))

    def c_serin(self, s: S.Serin) -> None:
        steps = [self.serin_step(item, s.line) for item in s.items]

        def consumer():
            for step in steps:
                yield from step()

        spec = SerinSpec(
            s.line, self.fn(self.pin_src(s.pin, s.line, serial=True)),
            self.fn(self.gv(s.baud, s.line)),
            self.fn(self.gv(s.timeout, s.line)) if s.timeout is not None else None,
            self.label(s.tlabel, s.line) if s.tlabel else None, consumer)
        self.emit_special(s.line, lambda nxt: lambda: self.m.serin(spec, nxt))

    def serin_step(self, item, line: int) -> Callable[[], object]:
        """A generator function consuming the bytes of one SERIN item (each ``yield`` takes one)."""
        kind = item[0]
        if kind == "raw":
            store = self.writer(item[1], line)

            def raw():
                b = yield
                store(b)

            return raw
        if kind == "wait":
            vals = [self.fn(self.gv(v, line)) for v in item[1]]
            return lambda: _wait_for([f() & 0xFF for f in vals])
        if kind == "skip":
            n = self.fn(self.gv(item[1], line))

            def skip():
                for _ in range(n()):
                    yield

            return skip
        if kind == "str":
            put = self.element_writer(item[1], line)
            n = self.fn(self.gv(item[2], line))
            end = self.fn(self.gv(item[3], line)) if item[3] is not None else None

            def string():
                stop = end() & 0xFF if end is not None else None
                for i in range(n()):
                    b = yield
                    if b == stop:
                        put(i, 0)
                        return
                    put(i, b)

            return string
        if kind == "waitstr":
            get = self.element_reader(item[1], line)
            n = self.fn(self.gv(item[2], line)) if item[2] is not None else None

            def waitstr():
                yield from _wait_for(list(_str_out(get, n)))

            return waitstr
        # formatted number
        _, name, digits, ref = item
        store = self.writer(ref, line)
        base, signed, prefix = split_format(name)
        return lambda: _read_number(store, base, signed, prefix, digits)


_KIND_NAMES = {"con": "constant", "data": "DATA label", "label": "label", "pin": "pin",
               "var": "variable"}


def _special_marker() -> int:
    return -1


def _str_out(get: Callable[[int], int], n: Callable[[], int] | None) -> bytes:
    out = bytearray()
    if n is not None:
        for i in range(n()):
            out.append(get(i) & 0xFF)
        return bytes(out)
    i = 0
    while i < 26:
        b = get(i) & 0xFF
        if b == 0:
            break
        out.append(b)
        i += 1
    return bytes(out)


def _wait_for(seq: list[int]):
    """Consume bytes until seq has arrived in a row."""
    if not seq:
        return
    k = 0
    while k < len(seq):
        b = yield
        if b == seq[k]:
            k += 1
        else:
            k = 1 if b == seq[0] else 0


def _read_number(store, base: int, signed: bool, prefix: str, digits: int | None):
    """DEC/HEX/BIN input: skip to the first digit (after the prefix, if one is required),
    read digits until a non-digit (consumed) or the digit count is reached."""
    neg = False
    while True:
        b = yield
        if prefix:
            if b == ord(prefix):
                b = yield
                if digit_value(b, base) is not None:
                    break
            continue
        if signed and b == ord("-"):
            b = yield
            if digit_value(b, base) is not None:
                neg = True
                break
            continue
        if digit_value(b, base) is not None:
            break
    value = 0
    count = 0
    while True:
        d = digit_value(b, base)
        if d is None:
            break
        value = (value * base + d) & 0xFFFF
        count += 1
        if digits is not None and count >= digits:
            break
        b = yield
    store((-value) & 0xFFFF if neg else value)
