"""The parsed program: expression and statement nodes, each statement carrying its source line."""

from __future__ import annotations

from dataclasses import dataclass, field

# ---- expressions -------------------------------------------------------------------------


@dataclass(slots=True)
class Num:
    value: int


@dataclass(slots=True)
class Ref:
    """A name with optional modifiers (``.HIGHBYTE``, ``.BIT3``) and an index ``(expr)``."""

    name: str
    line: int
    modifiers: tuple[str, ...] = ()
    index: object | None = None


@dataclass(slots=True)
class Unary:
    op: str
    operand: object


@dataclass(slots=True)
class Binary:
    op: str
    left: object
    right: object


# ---- statements --------------------------------------------------------------------------


@dataclass(slots=True)
class Stmt:
    line: int


@dataclass(slots=True)
class Directive(Stmt):
    text: str


@dataclass(slots=True)
class Label(Stmt):
    name: str


@dataclass(slots=True)
class VarDecl(Stmt):
    name: str
    size: str | None  # BIT NIB BYTE WORD, or None for an alias
    count: int | None = None  # array length
    alias: Ref | None = None


@dataclass(slots=True)
class ConDecl(Stmt):
    name: str
    expr: object


@dataclass(slots=True)
class PinDecl(Stmt):
    name: str
    expr: object


@dataclass(slots=True)
class DataDecl(Stmt):
    label: str | None
    # ("byte"|"word", expr, count_expr|None) | ("str", text) | ("at", expr) | ("reserve", n)
    items: list


@dataclass(slots=True)
class Assign(Stmt):
    target: Ref
    expr: object


@dataclass(slots=True)
class If(Stmt):
    branches: list  # [(cond, [stmts])]
    orelse: list | None


@dataclass(slots=True)
class Do(Stmt):
    pre: tuple | None  # ("WHILE"|"UNTIL", cond)
    body: list
    post: tuple | None
    end_line: int = 0


@dataclass(slots=True)
class For(Stmt):
    var: Ref
    start: object
    end: object
    step: object | None
    body: list
    end_line: int = 0


@dataclass(slots=True)
class Select(Stmt):
    expr: object
    cases: list  # [(conds, [stmts], line)]; conds: ("eq", e) | ("range", lo, hi) | ("cmp", op, e)
    orelse: list | None


@dataclass(slots=True)
class Jump(Stmt):
    kind: str  # GOTO GOSUB
    label: str


@dataclass(slots=True)
class Simple(Stmt):
    kind: str  # RETURN END STOP EXIT


@dataclass(slots=True)
class PinCmd(Stmt):
    kind: str  # HIGH LOW TOGGLE INPUT OUTPUT REVERSE
    pin: object


@dataclass(slots=True)
class TimedCmd(Stmt):
    kind: str  # PAUSE NAP SLEEP
    arg: object


@dataclass(slots=True)
class Pulsout(Stmt):
    pin: object
    width: object


@dataclass(slots=True)
class Serin(Stmt):
    pin: object
    baud: object
    timeout: object | None
    tlabel: str | None
    # ("raw", ref) | ("fmt", name, digits, ref) | ("str", ref, n, end) | ("wait", [exprs])
    # | ("waitstr", ref, n) | ("skip", n)
    items: list


@dataclass(slots=True)
class Serout(Stmt):
    pin: object
    baud: object
    pace: object | None
    items: list  # output items, see OutItem kinds in the parser


@dataclass(slots=True)
class Debug(Stmt):
    items: list


@dataclass(slots=True)
class Read(Stmt):
    addr: object
    targets: list  # [(is_word, ref)]


@dataclass(slots=True)
class Write(Stmt):
    addr: object
    values: list  # [(is_word, expr)]


@dataclass(slots=True)
class Lookup(Stmt):
    index: object
    values: list
    target: Ref


@dataclass(slots=True)
class Lookdown(Stmt):
    value: object
    op: str
    values: list
    target: Ref


@dataclass(slots=True)
class Branch(Stmt):
    kind: str  # BRANCH (goto) | ON-GOTO | ON-GOSUB
    index: object
    labels: list = field(default_factory=list)
