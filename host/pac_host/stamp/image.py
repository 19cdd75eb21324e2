"""A BASIC Stamp II download image: the tokenizer's 18-byte packets, and where they come from.

Packet layout (Parallax's BS2 download format, as the PBASIC tokenizer emits it):
``0x80 | block``, 16 EEPROM bytes of that 16-byte block, then a check byte that makes the sum of
all 18 bytes 0 modulo 256. Blocks not sent keep their old EEPROM contents.

An image is read from the tokenizer script's JSON (``servobot-image/1``), from raw packets back
to back (``.bin``/``.tok``), or made from PBASIC source by running ``firmware/tools/tokenize.js``
with Node.js. The ServoBot firmware's version is found at a fixed place: EEPROM bytes 0..3 hold
``"SB"``, the firmware version and the protocol version (DATA ``FwInfo`` in the source).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from pac_host.errors import InputError

PACKET_SIZE = 18
BLOCK_SIZE = 16
EEPROM_SIZE = 2048
ADDRESS_FLAG = 0x80
IMAGE_FORMAT = "servobot-image/1"
FW_TAG = b"SB"  # EEPROM 0..1 of the ServoBot firmware; byte 2 firmware version, 3 protocol version
TURN_CYCLE_ADDR = 4  # EEPROM 4..22 of the firmware: gene count, then 9 x (gait id, repetitions)
TURN_CYCLE_SIZE = 19


class TokenizeError(InputError):
    """The PBASIC source does not tokenize (the message is the tokenizer's, with the line)."""


def packet_check(body: bytes) -> int:
    """The 18th byte of a packet: makes the byte sum of the whole packet 0 modulo 256."""
    return (-sum(body)) & 0xFF


def make_packet(block: int, data: bytes) -> bytes:
    """One download packet for EEPROM block ``block`` (0..127) holding 16 bytes ``data``."""
    if not 0 <= block < EEPROM_SIZE // BLOCK_SIZE or len(data) != BLOCK_SIZE:
        raise ValueError(f"bad packet: block {block}, {len(data)} data bytes")
    body = bytes([ADDRESS_FLAG | block]) + bytes(data)
    return body + bytes([packet_check(body)])


def check_packet(packet: bytes) -> str | None:
    """Why ``packet`` is not a well-formed download packet, or None if it is."""
    if len(packet) != PACKET_SIZE:
        return f"{len(packet)} bytes, expected {PACKET_SIZE}"
    if not packet[0] & ADDRESS_FLAG:
        return f"address byte 0x{packet[0]:02X} lacks bit 7"
    if sum(packet) & 0xFF:
        return f"check byte 0x{packet[-1]:02X} wrong (expected 0x{packet_check(packet[:-1]):02X})"
    return None


@dataclass(frozen=True)
class StampImage:
    """The packets to send, in order, and where they came from."""

    packets: tuple[bytes, ...]
    origin: str
    resources: dict | None = None

    def eeprom(self, base: bytes | None = None) -> bytes:
        """The 2048-byte EEPROM after downloading this image over ``base`` (default all 0)."""
        mem = bytearray(base if base is not None else bytes(EEPROM_SIZE))
        for p in self.packets:
            addr = (p[0] & 0x7F) * BLOCK_SIZE
            mem[addr : addr + BLOCK_SIZE] = p[1 : 1 + BLOCK_SIZE]
        return bytes(mem)

    @property
    def firmware_version(self) -> int | None:
        """The ServoBot firmware version the image carries, or None if it is not that firmware."""
        return firmware_version_of(self.eeprom())


def firmware_version_of(eeprom: bytes) -> int | None:
    """Firmware version from an EEPROM image: byte 2 after the ``"SB"`` tag, else None."""
    return eeprom[2] if eeprom[:2] == FW_TAG else None


def _validated(packets: list[bytes], origin: str) -> tuple[bytes, ...]:
    if not packets:
        raise InputError(f"{origin}: no download packets")
    for i, p in enumerate(packets):
        why = check_packet(p)
        if why:
            raise InputError(f"{origin}: packet {i} is damaged: {why}")
    return tuple(packets)


def image_from_json(path: Path) -> StampImage:
    try:
        doc = json.loads(path.read_text())
        if doc.get("format") != IMAGE_FORMAT:
            raise ValueError(f"format is {doc.get('format')!r}, expected {IMAGE_FORMAT!r}")
        if doc.get("target") != "BS2":
            raise ValueError(f"image is for {doc.get('target')!r}, not a BS2")
        packets = [bytes.fromhex(h) for h in doc["packets"]]
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise InputError(f"image {path}: {e}") from None
    return StampImage(_validated(packets, str(path)), str(path), doc.get("resources"))


def image_from_bin(path: Path) -> StampImage:
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read {path}: {e.strerror}") from None
    if len(raw) % PACKET_SIZE:
        raise InputError(f"{path}: {len(raw)} bytes is not a whole number of 18-byte packets")
    packets = [raw[i : i + PACKET_SIZE] for i in range(0, len(raw), PACKET_SIZE)]
    return StampImage(_validated(packets, str(path)), str(path))


def tokenizer_script(source: Path) -> Path:
    """``tools/tokenize.js`` beside the source, else the repository's ``firmware/tools``."""
    for cand in (
        source.resolve().parent / "tools" / "tokenize.js",
        Path(__file__).resolve().parents[3] / "firmware" / "tools" / "tokenize.js",
    ):
        if cand.is_file():
            return cand
    raise InputError(
        f"cannot tokenize {source}: firmware/tools/tokenize.js not found; "
        "run `make firmware` in the repository and flash build/servobot.json"
    )


def tokenize(source: Path, out_dir: Path, node: str = "node", timeout: float = 120.0) -> Path:
    """Tokenize PBASIC ``source`` with Parallax's tokenizer (Node.js) into ``out_dir``; returns
    the path of the tokenizer's JSON (the packets, the EEPROM map and its flags)."""
    if not source.is_file():
        raise InputError(f"firmware source {source} does not exist")
    script = tokenizer_script(source)
    if not (script.parent.parent / "node_modules" / "pbasic-tokenizer").is_dir():
        raise InputError(
            "the tokenizer is not installed: run `make firmware` "
            f"(npm ci in {script.parent.parent})"
        )
    if shutil.which(node) is None:
        raise InputError(f"cannot tokenize {source}: Node.js ({node}) is not installed")
    try:
        res = subprocess.run(
            [node, str(script), str(source), "--out", str(out_dir), "--quiet"],
            capture_output=True, text=True, timeout=timeout, check=False,
        )
    except subprocess.TimeoutExpired:
        raise InputError(f"tokenizing {source} took over {timeout:.0f} s") from None
    if res.returncode != 0:
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        raise TokenizeError(" | ".join(ln.strip() for ln in lines) or "tokenizer failed")
    return Path(out_dir) / (source.stem + ".json")


def image_from_source(source: Path, node: str = "node", timeout: float = 120.0) -> StampImage:
    """Tokenize PBASIC ``source`` with Parallax's tokenizer (Node.js) into an image."""
    with tempfile.TemporaryDirectory(prefix="pac-fw-") as out:
        img = image_from_json(tokenize(source, Path(out), node, timeout))
    return StampImage(img.packets, str(source), img.resources)


def load_image(path: str | Path) -> StampImage:
    """An image from PBASIC source (``.bs2``/``.bse``/...), tokenizer JSON, or raw packets."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".json":
        return image_from_json(p)
    if suffix in (".bin", ".tok"):
        return image_from_bin(p)
    if suffix in (".bs2", ".pbs", ".bas", ".txt"):
        return image_from_source(p)
    raise InputError(
        f"{p}: unknown firmware file type (use .bs2 source, .json image or .bin packets)"
    )
