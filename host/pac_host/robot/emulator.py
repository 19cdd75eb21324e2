"""The built-in emulator as a robot to connect to: the one module of ``pac_host`` that reaches
``pac_sim`` (the emulated Stamp on a pseudo-terminal, its world and tracker feed).

:func:`open_emulator` checks the options and starts nothing yet: the caller connects its
observer and placer to the tracker, then calls ``start()`` on the emulator it got, opens its
``path`` as a serial port and closes it when done. The simulator is imported only here and only
when an emulator is opened, so a host talking to a real robot never loads it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pac_host.errors import InputError
from pac_host.model import Effect, GaitTable


@dataclass(frozen=True)
class EmulatorOptions:
    """The built-in emulator's world and line (see ``pac-sim --help`` for each)."""

    table: GaitTable
    effects: tuple[Effect, ...] = ()
    noise: tuple[float, float] = (0.5, 1.0)
    realtime: float = 0.0
    seed: int = 0
    drop_prob: float = 0.0
    corrupt_prob: float = 0.0
    drop_at: tuple[str, ...] = ()  # KIND:N:BYTE, see pac_sim.targeted
    corrupt_at: tuple[str, ...] = ()
    mute_after: int | None = None


def open_emulator(o: EmulatorOptions) -> Any:
    """A ``pac_sim.runner.SimStamp`` on a pseudo-terminal (``path``) with its ``world`` and a
    tracker on a free local port (``tracker.address``), not yet started; every problem with
    the options is one InputError."""
    from pac_sim.line import Faults
    from pac_sim.runner import SimConfig, SimStamp
    from pac_sim.targeted import parse_targets

    if o.realtime < 0:
        raise InputError(f"--sim-realtime must be >= 0, got {o.realtime}")
    if min(o.noise) < 0:
        raise InputError(f"--sim-noise must be >= 0, got {o.noise}")
    for name, p in (("--drop-prob", o.drop_prob), ("--corrupt-prob", o.corrupt_prob)):
        if not 0 <= p <= 1:
            raise InputError(f"{name} must be in [0, 1], got {p}")
    try:
        targets = parse_targets(o.drop_at, o.corrupt_at)
    except ValueError as e:
        raise InputError(str(e)) from None
    return SimStamp(SimConfig(
        factor=o.realtime, faults=Faults(o.drop_prob, o.corrupt_prob, targets=targets),
        seed=o.seed,
        table=o.table, effects=o.effects, tracker_noise=o.noise, tracker=("127.0.0.1", 0),
        mute_after=o.mute_after,
    ))
