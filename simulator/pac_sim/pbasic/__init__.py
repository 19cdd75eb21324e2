"""A PBASIC 2.5 interpreter for the BASIC Stamp II subset the ServoBot firmware uses.

``Stamp.from_file(path)`` parses and compiles a program; the driver then runs it in Stamp time
(``run``, ``run_until_serin``, ``run_for``), feeds serial bytes (``feed``, ``advance``) and reads
the results (``output``, ``servo``, ``eeprom``, ``debug_text``, ``var``).
"""

from .errors import PbasicRuntimeError, PbasicSyntaxError, StampEnded, StampNotListening
from .machine import ENDED, READY, SERIN, SerinWait, Stamp
from .parser import parse

__all__ = [
    "ENDED", "READY", "SERIN", "PbasicRuntimeError", "PbasicSyntaxError", "SerinWait", "Stamp",
    "StampEnded", "StampNotListening", "parse",
]
