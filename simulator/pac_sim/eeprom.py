"""The Stamp's turn-cycle EEPROM (PROTOCOL.md 5.1): a count byte and 9 (gait id, repetitions).

Optionally persisted to a JSON file, written through on every byte write (atomic replace), so
restarting the emulator is a power cycle that keeps the stored turn cycle.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

from pac_host.errors import InputError
from pac_host.stamp.image import TURN_CYCLE_ADDR
from pac_protocol.messages import MAX_GENES

FORMAT = "pac-sim-eeprom/1"
SIZE = 1 + 2 * MAX_GENES  # TC_COUNT then 9 x (gait id, repetitions)


class Eeprom:
    """19 bytes of turn-cycle storage. ``writes`` counts byte writes (EEPROM wear)."""

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = Path(path) if path else None
        self.image = bytearray(SIZE)  # the firmware's DATA initialises TC_COUNT to 0
        self.writes = 0
        self._lock = threading.Lock()
        if self.path and self.path.exists():
            self.image = self._load(self.path)

    @staticmethod
    def _load(path: Path) -> bytearray:
        try:
            doc = json.loads(path.read_text())
            if doc.get("format") != FORMAT:
                raise ValueError(f"format is {doc.get('format')!r}, expected {FORMAT!r}")
            image = bytearray.fromhex(doc["image"])
        except (OSError, ValueError, KeyError, AttributeError, TypeError) as e:
            raise InputError(f"EEPROM file {path}: {e}") from None
        if len(image) != SIZE:
            raise InputError(f"EEPROM file {path}: image has {len(image)} bytes, expected {SIZE}")
        return image

    def _save(self) -> None:
        if not self.path:
            return
        genes = [list(self.gene(i)) for i in range(self.count)]
        doc = {"format": FORMAT, "image": self.image.hex(), "turn_cycle": genes}
        tmp = self.path.with_name(self.path.name + ".tmp")
        tmp.write_text(json.dumps(doc) + "\n")
        os.replace(tmp, self.path)

    @property
    def count(self) -> int:
        """The stored gene count; a value above 9 (never written by the firmware) reads as 0."""
        c = self.image[0]
        return c if c <= MAX_GENES else 0

    def gene(self, i: int) -> tuple[int, int]:
        return self.image[1 + 2 * i], self.image[2 + 2 * i]

    def write(self, addr: int, value: int) -> None:
        with self._lock:
            self.image[addr] = value
            self.writes += 1
            self._save()

    def write_flashed(self, eeprom: bytes) -> None:
        """Take the turn-cycle bytes of a downloaded 2 KB EEPROM image, writing only the bytes
        that differ (a flash rewrites the turn cycle the robot stored)."""
        for addr, b in enumerate(eeprom[TURN_CYCLE_ADDR : TURN_CYCLE_ADDR + len(self.image)]):
            if self.image[addr] != b:
                self.write(addr, b)

    def write_count(self, n: int) -> None:
        self.write(0, n)

    def write_gene(self, i: int, gait: int, reps: int) -> None:
        self.write(1 + 2 * i, gait)
        self.write(2 + 2 * i, reps)

    def turn_cycle(self) -> list[tuple[int, int]]:
        return [self.gene(i) for i in range(self.count)]
