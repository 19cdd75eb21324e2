"""Timing constants of PROTOCOL.md 4.1, shared by the host link, the emulator and the benchmark."""

BAUD = 9600
BITS_PER_BYTE = 10  # start + 8 data + stop
BYTE_S = BITS_PER_BYTE / BAUD  # 1.042 ms on the wire

T_IDLE_S = 0.5  # SERIN timeout when idle
T_RUN_S = 0.1  # SERIN timeout between gait cycles of a RUN or STEP
T_REPLY_S = 0.1  # the Stamp starts its reply within this long after a request

ACTIVATIONS_PER_CYCLE = 58
ACTIVATION_S = 0.020  # one servo activation: a round of pulses, ~20 ms (DESIGN.md 5)
T_CYCLE_S = ACTIVATIONS_PER_CYCLE * ACTIVATION_S  # 1.16 s per gait cycle

T_PROCESS_S = 0.002  # the Stamp checks and dispatches a request (estimate: ~8 statements)
T_EEPROM_WRITE_S = 0.005  # one EEPROM byte write


def wire_time(n_bytes: int, baud: int = BAUD) -> float:
    """Seconds ``n_bytes`` take on the line at ``baud``, 8N1."""
    return n_bytes * BITS_PER_BYTE / baud
