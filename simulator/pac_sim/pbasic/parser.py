"""Parse PBASIC 2.5 tokens into statements (see ``syntax``): declarations, control blocks, commands.

Expressions follow the Stamp: arithmetic strictly left to right with no precedence (unary
operators bind to the operand that follows them), parentheses group; in conditions the
comparisons bind looser than arithmetic, NOT applies to one comparison, and AND, OR, XOR
combine them left to right with no precedence among them (checked against the tokenizer).
Any keyword outside the supported subset is an error naming the line.
"""

from __future__ import annotations

from . import syntax as S
from .errors import PbasicSyntaxError
from .lexer import Token, tokenize

BINARY_OPS = {"+", "-", "*", "/", "//", "**", "*/", "&", "|", "^", "<<", ">>", "MIN", "MAX",
              "DIG", "REV"}
UNARY_OPS = {"-", "~", "ABS", "SQR", "DCD", "NCD", "SIN", "COS"}
COMPARE_OPS = {"=", "<>", "<", ">", "<=", ">="}
MODIFIERS = {"LOWBYTE", "HIGHBYTE", "BYTE0", "BYTE1", "LOWNIB", "HIGHNIB", "NIB0", "NIB1",
             "NIB2", "NIB3", "LOWBIT", "HIGHBIT"} | {f"BIT{i}" for i in range(16)}
SIZES = {"BIT", "NIB", "BYTE", "WORD"}
OUT_FORMATS = {"DEC", "SDEC", "HEX", "SHEX", "IHEX", "ISHEX", "BIN", "SBIN", "IBIN", "ISBIN"}
IN_FORMATS = {"DEC", "SDEC", "HEX", "SHEX", "IHEX", "ISHEX", "BIN", "SBIN", "IBIN", "ISBIN"}

# PBASIC words this emulator does not implement: using one is an error, never ignored.
UNSUPPORTED = {
    "BUTTON", "COUNT", "DEBUGIN", "DTMFOUT", "FREQOUT", "I2CIN", "I2COUT", "LCDCMD", "LCDIN",
    "LCDOUT", "OWIN", "OWOUT", "POLLIN", "POLLMODE", "POLLOUT", "POLLRUN", "POLLWAIT", "PULSIN",
    "PWM", "RANDOM", "RCTIME", "SHIFTIN", "SHIFTOUT", "XOUT", "GET", "PUT", "RUN", "STORE",
    "IOTERM", "AUXIO", "MAINIO", "SOUND", "LET", "POT", "SERTXD", "SERRXD", "#IF", "ATN", "HYP",
    "COMPARE", "CONFIGPIN",
}
STATEMENT_WORDS = {
    "IF", "ELSEIF", "ELSE", "ENDIF", "THEN", "DO", "LOOP", "WHILE", "UNTIL", "FOR", "TO", "STEP",
    "NEXT", "SELECT", "CASE", "ENDSELECT", "GOTO", "GOSUB", "RETURN", "EXIT", "END", "STOP",
    "PAUSE", "PULSOUT", "HIGH", "LOW", "TOGGLE", "INPUT", "OUTPUT", "REVERSE", "SERIN", "SEROUT",
    "DEBUG", "READ", "WRITE", "LOOKUP", "LOOKDOWN", "BRANCH", "ON", "NAP", "SLEEP", "DATA", "VAR",
    "CON", "PIN", "AND", "OR", "XOR", "NOT", "WAIT", "STR", "SKIP", "WAITSTR", "REP",
}
RESERVED = STATEMENT_WORDS | UNSUPPORTED | SIZES | OUT_FORMATS | UNARY_OPS | BINARY_OPS


def _is_reserved(name: str) -> bool:
    if name in RESERVED:
        return True
    # DEC1..DEC5, HEX1..HEX4, BIN1..BIN16 and friends
    stripped = name.rstrip("0123456789")
    return stripped != name and stripped in OUT_FORMATS


class Parser:
    """Recursive-descent parser over the token list of one source file."""

    def __init__(self, tokens: list[Token], filename: str) -> None:
        self.toks = tokens
        self.i = 0
        self.filename = filename

    # ---- token helpers ----
    @property
    def tok(self) -> Token:
        return self.toks[self.i]

    def peek(self, k: int = 1) -> Token:
        return self.toks[min(self.i + k, len(self.toks) - 1)]

    def advance(self) -> Token:
        t = self.toks[self.i]
        self.i += 1
        return t

    def error(self, msg: str, line: int | None = None) -> PbasicSyntaxError:
        return PbasicSyntaxError(self.filename, line if line is not None else self.tok.line, msg)

    def describe(self, t: Token) -> str:
        if t.kind == "nl":
            return "end of line"
        if t.kind == "eof":
            return "end of file"
        if t.kind == "str":
            return f'"{t.value}"'
        return repr(str(t.value))

    def expect_op(self, op: str) -> Token:
        if not self.tok.is_op(op):
            raise self.error(f"expected '{op}', found {self.describe(self.tok)}")
        return self.advance()

    def expect_name(self, *names: str) -> Token:
        if not self.tok.is_name(*names):
            raise self.error(f"expected {' or '.join(names)}, found {self.describe(self.tok)}")
        return self.advance()

    def accept_op(self, op: str) -> bool:
        if self.tok.is_op(op):
            self.i += 1
            return True
        return False

    def accept_name(self, *names: str) -> str | None:
        if self.tok.is_name(*names):
            return self.advance().value
        return None

    def ident(self, what: str = "a name") -> str:
        t = self.tok
        if t.kind != "name":
            raise self.error(f"expected {what}, found {self.describe(t)}")
        if t.value in UNSUPPORTED:
            raise self.error(f"{t.value} is not supported by this PBASIC emulator")
        if _is_reserved(t.value):
            raise self.error(f"expected {what}, found reserved word {t.value}")
        self.i += 1
        return t.value

    def at_end_of_statement(self) -> bool:
        t = self.tok
        return t.kind in ("nl", "eof") or t.is_op(":")

    # ---- expressions ----
    def condition(self):
        """Logical operators AND, OR, XOR: one level, left to right (as the tokenizer groups
        them: ``a OR b AND c`` is ``(a OR b) AND c``)."""
        left = self.not_expr()
        while self.tok.is_name("AND", "OR", "XOR"):
            op = self.advance().value
            left = S.Binary(op, left, self.not_expr())
        return left

    def not_expr(self):
        if self.accept_name("NOT"):
            return S.Unary("NOT", self.not_expr())
        left = self.expr()
        if self.tok.kind == "op" and self.tok.value in COMPARE_OPS:
            op = self.advance().value
            left = S.Binary(op, left, self.expr())
        return left

    def expr(self):
        """Arithmetic: operands and binary operators strictly left to right."""
        left = self.unary()
        while True:
            t = self.tok
            if (t.kind == "op" or t.kind == "name") and t.value in BINARY_OPS:
                self.advance()
                left = S.Binary(t.value, left, self.unary())
            else:
                return left

    def unary(self):
        t = self.tok
        if (t.kind == "op" or t.kind == "name") and t.value in UNARY_OPS:
            self.advance()
            if t.value in ("SIN", "COS"):
                raise self.error(f"{t.value} is not supported by this PBASIC emulator", t.line)
            return S.Unary(t.value, self.unary())
        if t.is_name("NOT"):
            self.advance()
            return S.Unary("NOT", self.unary())
        return self.primary()

    def primary(self):
        t = self.tok
        if t.kind == "num":
            self.advance()
            return S.Num(t.value)
        if t.kind == "str":
            self.advance()
            if len(t.value) != 1:
                raise self.error("a string in an expression must be one character", t.line)
            return S.Num(ord(t.value))
        if t.is_op("("):
            self.advance()
            e = self.condition()
            self.expect_op(")")
            return e
        if t.kind == "name":
            return self.ref()
        raise self.error(f"expected a value, found {self.describe(t)}")

    def ref(self) -> S.Ref:
        line = self.tok.line
        name = self.ident("a name")
        mods: list[str] = []
        index = None
        while True:
            if self.tok.is_op(".") and self.peek().kind == "name":
                mod = self.peek().value
                if mod not in MODIFIERS:
                    raise self.error(f"unknown variable modifier .{mod}")
                self.i += 2
                mods.append(mod)
            elif self.tok.is_op("(") and index is None:
                self.advance()
                index = self.expr()
                self.expect_op(")")
            else:
                break
        return S.Ref(name, line, tuple(mods), index)

    def target(self) -> S.Ref:
        if self.tok.kind != "name":
            raise self.error(f"expected a variable, found {self.describe(self.tok)}")
        return self.ref()

    # ---- program structure ----
    def program(self) -> list:
        stmts, term = self.block(set())
        if term is not None:
            raise self.error(f"{term.value} without a matching opening statement", term.line)
        if not any(isinstance(s, S.Directive) and s.text.startswith("STAMP") for s in stmts):
            raise self.error("$STAMP directive not found (the program needs ' {$STAMP BS2})", 1)
        return stmts

    def block(self, terminators: set[str]) -> tuple[list, Token | None]:
        """Statements up to one of the terminator words at a statement start (or end of file)."""
        out: list = []
        while True:
            t = self.tok
            if t.kind == "eof":
                return out, None
            if t.kind == "nl" or t.is_op(":"):
                self.advance()
                continue
            if t.kind == "name" and t.value in terminators:
                return out, t
            if t.kind == "name" and t.value in ("ELSEIF", "ELSE", "ENDIF", "LOOP", "NEXT",
                                                  "CASE", "ENDSELECT"):
                raise self.error(f"{t.value} without a matching opening statement")
            self.statement(out)
            self.end_statement()

    def end_statement(self) -> None:
        if not self.at_end_of_statement():
            raise self.error(f"unexpected {self.describe(self.tok)} after the statement")

    def statement(self, out: list) -> None:
        """Parse one statement (or a label and its statement) and append it to out."""
        t = self.tok
        line = t.line
        if t.kind == "dir":
            self.advance()
            out.append(self.directive(t))
            return
        if t.kind != "name":
            raise self.error(f"expected a statement, found {self.describe(t)}")
        word = t.value
        nxt = self.peek()
        if word in UNSUPPORTED:
            raise self.error(f"{word} is not supported by this PBASIC emulator")
        if nxt.is_op(":") and not _is_reserved(word):
            self.i += 2
            out.append(S.Label(line, word))
            if self.tok.kind not in ("nl", "eof"):
                self.statement(out)
            return
        if nxt.is_name("VAR", "CON", "PIN", "DATA") and not _is_reserved(word):
            self.advance()
            kind = self.advance().value
            out.append(getattr(self, "decl_" + kind.lower())(word, line))
            return
        if word == "DATA":
            self.advance()
            out.append(self.decl_data(None, line))
            return
        handler = getattr(self, "stmt_" + word.lower(), None)
        if handler is not None and word in STATEMENT_WORDS:
            self.advance()
            out.append(handler(line))
            return
        if _is_reserved(word):
            raise self.error(f"unexpected {word}")
        target = self.target()
        if not self.tok.is_op("="):
            raise self.error(f"unknown statement {word} (expected '=' for an assignment)")
        self.advance()
        out.append(S.Assign(line, target, self.expr()))

    def directive(self, t: Token) -> S.Directive:
        text = " ".join(str(t.value).upper().split())
        parts = text.replace(",", " ").split() or [""]
        if parts[0] == "STAMP":
            if len(parts) < 2 or parts[1] != "BS2":
                raise self.error(f"only {{$STAMP BS2}} is supported, found {{${text}}}", t.line)
        elif parts[0] == "PBASIC":
            if len(parts) < 2 or parts[1] != "2.5":
                raise self.error(f"only {{$PBASIC 2.5}} is supported, found {{${text}}}", t.line)
        elif parts[0] != "PORT":
            raise self.error(f"unknown directive {{${text}}}", t.line)
        return S.Directive(t.line, text)

    # ---- declarations ----
    def decl_var(self, name: str, line: int) -> S.VarDecl:
        if self.tok.kind == "name" and self.tok.value in SIZES:
            size = self.advance().value
            count = None
            if self.accept_op("("):
                c = self.tok
                if c.kind != "num" or c.value < 1:
                    raise self.error("an array length must be a positive number")
                self.advance()
                count = c.value
                self.expect_op(")")
            return S.VarDecl(line, name, size, count)
        return S.VarDecl(line, name, None, None, self.target())

    def decl_con(self, name: str, line: int) -> S.ConDecl:
        return S.ConDecl(line, name, self.expr())

    def decl_pin(self, name: str, line: int) -> S.PinDecl:
        return S.PinDecl(line, name, self.expr())

    def decl_data(self, label: str | None, line: int) -> S.DataDecl:
        items: list = []
        if self.at_end_of_statement():
            return S.DataDecl(line, label, items)
        while True:
            if self.accept_op("@"):
                items.append(("at", self.expr()))
            elif self.tok.kind == "str" and len(self.tok.value) != 1:
                items.append(("str", self.advance().value))
            elif self.tok.is_op("("):
                self.advance()
                items.append(("reserve", self.expr()))
                self.expect_op(")")
            else:
                kind = "word" if self.accept_name("WORD") else "byte"
                if kind == "byte":
                    self.accept_name("BYTE")
                if self.tok.kind == "str" and len(self.tok.value) != 1:
                    if kind == "word":
                        raise self.error("Word needs a number, not a string")
                    items.append(("str", self.advance().value))
                else:
                    value = self.expr()
                    count = None
                    if self.accept_op("("):
                        count = self.expr()
                        self.expect_op(")")
                    items.append((kind, value, count))
            if not self.accept_op(","):
                break
        return S.DataDecl(line, label, items)

    # ---- control structures ----
    def stmt_if(self, line: int):
        cond = self.condition()
        self.expect_name("THEN")
        if self.tok.kind in ("nl", "eof"):
            return self.block_if(line, cond)
        # single-line forms: IF c THEN label / IF c THEN stmt(s) [ELSE stmt(s)]
        if (self.tok.kind == "name" and not _is_reserved(self.tok.value)
                and (self.peek().kind in ("nl", "eof") or self.peek().is_name("ELSE"))):
            body: list = [S.Jump(self.tok.line, "GOTO", self.advance().value)]
        else:
            body = self.inline_statements()
        orelse = None
        if self.accept_name("ELSE"):
            if (self.tok.kind == "name" and not _is_reserved(self.tok.value)
                    and self.peek().kind in ("nl", "eof")):
                orelse = [S.Jump(self.tok.line, "GOTO", self.advance().value)]
            else:
                orelse = self.inline_statements()
        return S.If(line, [(cond, body)], orelse)

    def inline_statements(self) -> list:
        out: list = []
        while True:
            self.statement(out)
            if self.accept_op(":"):
                if self.tok.kind in ("nl", "eof") or self.tok.is_name("ELSE"):
                    break
                continue
            break
        if not (self.tok.kind in ("nl", "eof") or self.tok.is_name("ELSE")):
            raise self.error(f"unexpected {self.describe(self.tok)} in a single-line IF")
        return out

    def block_if(self, line: int, cond) -> S.If:
        branches = []
        orelse = None
        body, term = self.block({"ELSEIF", "ELSE", "ENDIF"})
        branches.append((cond, body))
        while True:
            if term is None:
                raise self.error(f"IF at line {line} has no ENDIF", line)
            self.advance()
            if term.value == "ELSEIF":
                c = self.condition()
                self.expect_name("THEN")
                body, term = self.block({"ELSEIF", "ELSE", "ENDIF"})
                branches.append((c, body))
            elif term.value == "ELSE":
                orelse, term = self.block({"ENDIF", "ELSEIF", "ELSE"})
                if term is not None and term.value != "ENDIF":
                    what = "ELSEIF after ELSE" if term.value == "ELSEIF" else "a second ELSE"
                    raise self.error(what, term.line)
            else:
                return S.If(line, branches, orelse)

    def loop_condition(self) -> tuple | None:
        kind = self.accept_name("WHILE", "UNTIL")
        return (kind, self.condition()) if kind else None

    def stmt_do(self, line: int) -> S.Do:
        pre = self.loop_condition()
        body, term = self.block({"LOOP"})
        if term is None:
            raise self.error(f"DO at line {line} has no LOOP", line)
        self.advance()
        post = self.loop_condition()
        if pre and post:
            raise self.error("a DO loop may test its condition at one end only", term.line)
        return S.Do(line, pre, body, post, term.line)

    def stmt_for(self, line: int) -> S.For:
        var = self.target()
        self.expect_op("=")
        start = self.expr()
        self.expect_name("TO")
        end = self.expr()
        step = self.expr() if self.accept_name("STEP") else None
        body, term = self.block({"NEXT"})
        if term is None:
            raise self.error(f"FOR at line {line} has no NEXT", line)
        self.advance()
        if self.tok.kind == "name" and not _is_reserved(self.tok.value):
            nv = self.ref()
            if nv.name != var.name:
                raise self.error(f"NEXT {nv.name} does not match FOR {var.name}", term.line)
        return S.For(line, var, start, end, step, body, term.line)

    def stmt_select(self, line: int) -> S.Select:
        subject = self.expr()
        cases: list = []
        orelse = None
        body, term = self.block({"CASE", "ENDSELECT"})
        if body:
            raise self.error("statements between SELECT and its first CASE", body[0].line)
        while True:
            if term is None:
                raise self.error(f"SELECT at line {line} has no ENDSELECT", line)
            self.advance()
            if term.value == "ENDSELECT":
                return S.Select(line, subject, cases, orelse)
            if orelse is not None:
                raise self.error("CASE after CASE ELSE", term.line)
            if self.accept_name("ELSE"):
                orelse, term = self.block({"CASE", "ENDSELECT"})
                continue
            conds = []
            while True:
                if self.tok.kind == "op" and self.tok.value in COMPARE_OPS:
                    op = self.advance().value
                    conds.append(("cmp", op, self.expr()))
                else:
                    lo = self.expr()
                    if self.accept_name("TO"):
                        conds.append(("range", lo, self.expr()))
                    else:
                        conds.append(("eq", lo))
                if not self.accept_op(","):
                    break
            body, nterm = self.block({"CASE", "ENDSELECT"})
            cases.append((conds, body, term.line))
            term = nterm

    def label_name(self) -> str:
        return self.ident("a label")

    def stmt_goto(self, line: int) -> S.Jump:
        return S.Jump(line, "GOTO", self.label_name())

    def stmt_gosub(self, line: int) -> S.Jump:
        return S.Jump(line, "GOSUB", self.label_name())

    def stmt_return(self, line: int) -> S.Simple:
        return S.Simple(line, "RETURN")

    def stmt_end(self, line: int) -> S.Simple:
        return S.Simple(line, "END")

    def stmt_stop(self, line: int) -> S.Simple:
        return S.Simple(line, "STOP")

    def stmt_exit(self, line: int) -> S.Simple:
        return S.Simple(line, "EXIT")

    def stmt_branch(self, line: int) -> S.Branch:
        index = self.expr()
        self.expect_op(",")
        return S.Branch(line, "GOTO", index, self.label_list())

    def stmt_on(self, line: int) -> S.Branch:
        index = self.expr()
        kind = self.expect_name("GOTO", "GOSUB").value
        return S.Branch(line, kind, index, self.label_list(brackets=False))

    def label_list(self, brackets: bool = True) -> list[str]:
        if brackets:
            self.expect_op("[")
        labels = [self.label_name()]
        while self.accept_op(","):
            labels.append(self.label_name())
        if brackets:
            self.expect_op("]")
        return labels

    # ---- commands ----
    def _pin_cmd(self, kind: str, line: int) -> S.PinCmd:
        return S.PinCmd(line, kind, self.expr())

    def stmt_high(self, line: int):
        return self._pin_cmd("HIGH", line)

    def stmt_low(self, line: int):
        return self._pin_cmd("LOW", line)

    def stmt_toggle(self, line: int):
        return self._pin_cmd("TOGGLE", line)

    def stmt_input(self, line: int):
        return self._pin_cmd("INPUT", line)

    def stmt_output(self, line: int):
        return self._pin_cmd("OUTPUT", line)

    def stmt_reverse(self, line: int):
        return self._pin_cmd("REVERSE", line)

    def stmt_pause(self, line: int):
        return S.TimedCmd(line, "PAUSE", self.expr())

    def stmt_nap(self, line: int):
        return S.TimedCmd(line, "NAP", self.expr())

    def stmt_sleep(self, line: int):
        return S.TimedCmd(line, "SLEEP", self.expr())

    def stmt_pulsout(self, line: int) -> S.Pulsout:
        pin = self.expr()
        self.expect_op(",")
        return S.Pulsout(line, pin, self.expr())

    def stmt_serin(self, line: int) -> S.Serin:
        pin = self.expr()
        if self.tok.is_op("\\"):
            raise self.error("SERIN flow-control pins are not supported by this emulator")
        self.expect_op(",")
        baud = self.expr()
        self.expect_op(",")
        timeout = tlabel = None
        if not self.tok.is_op("["):
            first = self.expr()
            self.expect_op(",")
            if self.tok.is_op("["):
                raise self.error("SERIN parity-error label is not supported; give timeout, label")
            timeout = first
            tlabel = self.label_name()
            self.expect_op(",")
        self.expect_op("[")
        items = [self.serin_item()]
        while self.accept_op(","):
            items.append(self.serin_item())
        self.expect_op("]")
        return S.Serin(line, pin, baud, timeout, tlabel, items)

    def serin_item(self):
        t = self.tok
        if t.is_name("WAIT"):
            self.advance()
            self.expect_op("(")
            values = self.byte_list()
            self.expect_op(")")
            if len(values) > 6:
                raise self.error("WAIT takes at most 6 bytes on the BS2", t.line)
            return ("wait", values)
        if t.is_name("STR"):
            self.advance()
            ref = self.target()
            self.expect_op("\\")
            n = self.expr()
            end = self.expr() if self.accept_op("\\") else None
            return ("str", ref, n, end)
        if t.is_name("WAITSTR"):
            self.advance()
            ref = self.target()
            n = self.expr() if self.accept_op("\\") else None
            return ("waitstr", ref, n)
        if t.is_name("SKIP"):
            self.advance()
            return ("skip", self.expr())
        fmt = self.format_word(IN_FORMATS)
        if fmt:
            return ("fmt", fmt[0], fmt[1], self.target())
        return ("raw", self.target())

    def format_word(self, formats: set[str]) -> tuple[str, int | None] | None:
        t = self.tok
        if t.kind != "name":
            return None
        base = t.value.rstrip("0123456789")
        if base not in formats:
            return None
        digits = int(t.value[len(base):]) if len(base) < len(t.value) else None
        self.advance()
        return base, digits

    def byte_list(self) -> list:
        """Values for WAIT(...) / LOOKUP [...]: strings expand to their characters."""
        values: list = []
        while True:
            if self.tok.kind == "str":
                values.extend(S.Num(ord(c)) for c in self.advance().value)
            else:
                values.append(self.expr())
            if not self.accept_op(","):
                return values

    def stmt_serout(self, line: int) -> S.Serout:
        pin = self.expr()
        if self.tok.is_op("\\"):
            raise self.error("SEROUT flow-control pins are not supported by this emulator")
        self.expect_op(",")
        baud = self.expr()
        self.expect_op(",")
        pace = None
        if not self.tok.is_op("["):
            pace = self.expr()
            self.expect_op(",")
        self.expect_op("[")
        items = self.out_items()
        self.expect_op("]")
        return S.Serout(line, pin, baud, pace, items)

    def stmt_debug(self, line: int) -> S.Debug:
        return S.Debug(line, self.out_items())

    def out_items(self) -> list:
        items = [self.out_item()]
        while self.accept_op(","):
            items.append(self.out_item())
        return items

    def out_item(self):
        t = self.tok
        if t.kind == "str":
            self.advance()
            return ("text", t.value)
        if t.is_name("STR"):
            self.advance()
            ref = self.target()
            n = self.expr() if self.accept_op("\\") else None
            return ("strvar", ref, n)
        if t.is_name("REP"):
            self.advance()
            value = self.expr()
            self.expect_op("\\")
            return ("rep", value, self.expr())
        fmt = self.format_word(OUT_FORMATS)
        if fmt:
            show = self.accept_op("?")
            if show:
                start = self.i
                e = self.expr()
                text = " ".join(tok.text or str(tok.value) for tok in self.toks[start:self.i])
                return ("fmt", fmt[0], fmt[1], e, text)
            return ("fmt", fmt[0], fmt[1], self.expr(), None)
        return ("raw", self.expr())

    def stmt_read(self, line: int) -> S.Read:
        addr = self.expr()
        targets = []
        while self.accept_op(","):
            word = bool(self.accept_name("WORD"))
            targets.append((word, self.target()))
        if not targets:
            raise self.error("READ needs a variable")
        return S.Read(line, addr, targets)

    def stmt_write(self, line: int) -> S.Write:
        addr = self.expr()
        values = []
        while self.accept_op(","):
            word = bool(self.accept_name("WORD"))
            values.append((word, self.expr()))
        if not values:
            raise self.error("WRITE needs a value")
        return S.Write(line, addr, values)

    def stmt_lookup(self, line: int) -> S.Lookup:
        index = self.expr()
        self.expect_op(",")
        self.expect_op("[")
        values = self.byte_list()
        self.expect_op("]")
        self.expect_op(",")
        return S.Lookup(line, index, values, self.target())

    def stmt_lookdown(self, line: int) -> S.Lookdown:
        value = self.expr()
        self.expect_op(",")
        op = "="
        if self.tok.kind == "op" and self.tok.value in COMPARE_OPS:
            op = self.advance().value
        self.expect_op("[")
        values = self.byte_list()
        self.expect_op("]")
        self.expect_op(",")
        return S.Lookdown(line, value, op, values, self.target())


def parse(text: str, filename: str = "<source>") -> list:
    """The statements of a PBASIC 2.5 source text; raises PbasicSyntaxError naming the line."""
    return Parser(tokenize(text, filename), filename).program()
