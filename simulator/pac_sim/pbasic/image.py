"""Read the tokenizer's download image (the JSON the firmware build writes) for the interpreter:
the 2048-byte EEPROM and where the program's tokens begin, so a Stamp can start from exactly
what a real one would hold and a WRITE into the program is caught."""

from __future__ import annotations

import json
from pathlib import Path

from pac_host.errors import InputError

from .peripherals import EEPROM_SIZE

PROGRAM_FLAG = 3  # EEPROM flag kind of a program byte (1 and 2: undefined and defined DATA)


def read_image(path: str | Path) -> dict:
    """Keyword arguments for ``Stamp``: ``eeprom_image`` and ``program_start``."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
        eeprom = bytes.fromhex(doc["eeprom"])
        flags = bytes.fromhex(doc["eeprom_flags"])
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{path}: not a tokenizer image ({e})") from None
    if len(eeprom) != EEPROM_SIZE or len(flags) != EEPROM_SIZE:
        raise InputError(f"{path}: EEPROM image must be {EEPROM_SIZE} bytes")
    program = [a for a in range(EEPROM_SIZE) if flags[a] & 3 == PROGRAM_FLAG]
    return {"eeprom_image": eeprom, "program_start": min(program) if program else None}
