"""Paths of the firmware, and Parallax's tokenizer run through Node.js, for the tests."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
SOURCE = FIRMWARE / "servobot.bs2"
TOKENIZE = FIRMWARE / "tools" / "tokenize.js"


def set_version(source: Path, version: int) -> None:
    """Rewrite the firmware source's FW_VERSION constant in place."""
    text = re.sub(r"^(FW_VERSION\s+CON\s+)\d+", rf"\g<1>{version}",
                  source.read_text(encoding="latin-1"), count=1, flags=re.M)
    source.write_text(text, encoding="latin-1")


def source_with_version(directory: Path, version: int) -> Path:
    """A copy of the firmware in ``directory`` announcing ``version``."""
    path = directory / "servobot.bs2"
    path.write_text(SOURCE.read_text(encoding="latin-1"), encoding="latin-1")
    set_version(path, version)
    return path


@dataclass
class Tokenized:
    returncode: int
    stdout: str
    stderr: str
    image: dict | None
    path: Path | None


def run_tokenizer(source: Path, out: Path) -> Tokenized:
    if shutil.which("node") is None:
        pytest.fail("Node.js is required to tokenize the firmware")
    if not (FIRMWARE / "node_modules" / "pbasic-tokenizer").is_dir():
        pytest.fail("the tokenizer is not installed: run `make firmware` (npm ci in firmware/)")
    res = subprocess.run(
        ["node", str(TOKENIZE), str(source), "--out", str(out)],
        capture_output=True, text=True, timeout=120, check=False,
    )
    path = out / (source.stem + ".json")
    image = json.loads(path.read_text()) if res.returncode == 0 and path.exists() else None
    return Tokenized(res.returncode, res.stdout, res.stderr, image, path if image else None)
