"""The virtual clock: what each PBASIC instruction costs in Stamp time (microseconds).

Figures (BS2 at 20 MHz, from Parallax's published figures, rounded):
- every instruction: INSTRUCTION_US = 250 us (about 4000 instructions per second);
- PULSOUT: plus its pulse width, width x 2 us;
- PAUSE: plus its argument in ms;
- SERIN/SEROUT/DEBUG: plus 10 bit times per byte (start, 8 data, stop), the bit time being
  (baudmode & $1FFF) + 20 us (baudmode 84 -> 104 us, 9600 baud; DEBUG goes at 9600 baud);
  SERIN also waits, in Stamp time, until its bytes arrive or its timeout (ms) expires;
- WRITE: plus WRITE_US = 5 ms per byte written (EEPROM write cycle);
- NAP n: 18 ms x 2^n; SLEEP n: n seconds.
"""

from __future__ import annotations

INSTRUCTION_US = 250
WRITE_US = 5_000
NAP_BASE_US = 18_000
DEBUG_BAUDMODE = 84
FRAME_BITS = 10


def bit_us(baudmode: int) -> int:
    """Bit time in microseconds of a BS2 baudmode."""
    return (baudmode & 0x1FFF) + 20


def byte_us(baudmode: int) -> int:
    """Time of one serial frame (start, 8 data, stop) at a BS2 baudmode."""
    return FRAME_BITS * bit_us(baudmode)
