"""Split PBASIC 2.5 source into tokens: names (upper-cased), numbers, strings, operators, newlines.

Case-insensitive like the Stamp editor: every name is upper-cased. Numbers are decimal, ``$hex``
or ``%binary``. ``'`` starts a comment. A line that ends with a comma continues on the next line
(PBASIC 2.5 allows this in lists). Directives, ``{$STAMP BS2}`` or in the editor's comment
form ``' {$STAMP BS2}``, become ``dir`` tokens.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .errors import PbasicSyntaxError


@dataclass(frozen=True, slots=True)
class Token:
    """One token: kind is name, num, str, op, dir, nl or eof; line is 1-based."""

    kind: str
    value: object
    line: int
    text: str = ""  # the source spelling (names are upper-cased in value)

    def is_op(self, *ops: str) -> bool:
        return self.kind == "op" and self.value in ops

    def is_name(self, *names: str) -> bool:
        return self.kind == "name" and self.value in names


_TOKEN = re.compile(
    r"""
    (?P<ws>[ \t\f\r]+)
  | (?P<cdir>'[ \t]*\{\$[^}\n]*\}[^\n]*)
  | (?P<comment>'[^\n]*)
  | (?P<nl>\n)
  | (?P<dir>\{\$[^}\n]*\})
  | (?P<hex>\$[0-9A-Fa-f_]+)
  | (?P<bin>%[01_]+)
  | (?P<dec>[0-9][0-9_]*)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<str>"[^"\n]*")
  | (?P<op>//|\*\*|\*/|<<|>>|<=|>=|<>|[-+*/&|^~=<>(),:\[\]\\.?@#])
    """,
    re.VERBOSE,
)


def tokenize(text: str, filename: str = "<source>") -> list[Token]:
    """Tokens of the whole source, ending with an ``eof`` token."""
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # the Stamp editor may save CR only
    out: list[Token] = []
    line = 1
    pos = 0
    n = len(text)
    while pos < n:
        m = _TOKEN.match(text, pos)
        if m is None:
            ch = text[pos]
            if ch == '"':
                raise PbasicSyntaxError(filename, line, "unterminated string")
            raise PbasicSyntaxError(filename, line, f"unexpected character {ch!r}")
        kind = m.lastgroup
        s = m.group()
        pos = m.end()
        if kind in ("ws", "comment"):
            continue
        if kind == "nl":
            if out and out[-1].is_op(","):
                pass  # a trailing comma continues the statement on the next line
            elif not out or out[-1].kind != "nl":
                out.append(Token("nl", None, line))
            line += 1
        elif kind == "hex":
            out.append(Token("num", int(s[1:].replace("_", ""), 16), line, s))
        elif kind == "bin":
            out.append(Token("num", int(s[1:].replace("_", ""), 2), line, s))
        elif kind == "dec":
            out.append(Token("num", int(s.replace("_", "")), line, s))
        elif kind == "name":
            out.append(Token("name", s.upper(), line, s))
        elif kind == "str":
            out.append(Token("str", s[1:-1], line))
        elif kind == "dir":
            out.append(Token("dir", s[2:-1].strip(), line))
        elif kind == "cdir":  # the editor's usual form: a directive in a comment
            inner = s[s.index("{$") + 2:s.index("}")]
            out.append(Token("dir", inner.strip(), line))
        else:
            out.append(Token("op", s, line, s))
    if out and out[-1].kind != "nl":
        out.append(Token("nl", None, line))
    out.append(Token("eof", None, line))
    return out
