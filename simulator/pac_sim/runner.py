"""Assemble and run an emulated Stamp (line, EEPROM, world, tracker) in a background thread.

Two backends plug into the same line, EEPROM, world and tracker: the protocol-level model of the
firmware (:class:`pac_sim.stamp.StampEmulator`, the default) and the firmware itself, a PBASIC
source run by the interpreter (:class:`pac_sim.firmware.FirmwareEmulator`, ``firmware=PATH``).

Used by the ``pac-sim`` CLI, by tests, and by host code that wants a robot without hardware::

    with SimStamp(SimConfig(factor=0)) as sim:
        port = open_port(sim.path)
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from pac_host.errors import TOOLKIT_ERRORS, InputError
from pac_host.model import Effect, GaitTable, resolve_table
from pac_protocol.messages import PROTOCOL_VERSION
from pac_sim.eeprom import Eeprom
from pac_sim.firmware import FirmwareEmulator
from pac_sim.line import IDLE_FLOOR_S, WINDOW_FLOOR_S, Faults, PtyLine
from pac_sim.stamp import FIRMWARE_VERSION, StampEmulator
from pac_sim.tracker import TrackerServer
from pac_sim.world import START_POSE, World


@dataclass(frozen=True)
class SimConfig:
    factor: float = 0.0  # wall time = simulated time x factor; 0 = as fast as possible
    echo: bool = False  # emulate the pin-16 programming port's echo
    faults: Faults = Faults()
    reset_after: int | None = None
    mute_after: int | None = None  # stop answering after this many gait cycles
    seed: int = 0
    eeprom: str | None = None  # persist the turn cycle to this file
    table: GaitTable | str = "shifted"  # the robot's true gait table
    effects: tuple[Effect, ...] = ()
    start: tuple[float, float, float] = START_POSE
    tracker_noise: tuple[float, float] = (0.0, 0.0)  # cm on x and y, degrees on h
    tracker: tuple[str, int] | None = None  # (host, port); port 0 picks a free one
    protocol_version: int = PROTOCOL_VERSION
    firmware_version: int = FIRMWARE_VERSION
    window_floor_s: float = WINDOW_FLOOR_S  # shortest real run window
    idle_floor_s: float = IDLE_FLOOR_S  # shortest real idle window
    firmware: str | None = None  # run this PBASIC source instead of the protocol-level model
    image: str | None = None  # the tokenizer's image of that source (its EEPROM)


class SimStamp:
    """An emulated Stamp on a fresh pseudo-terminal; :attr:`path` is the port to open."""

    def __init__(self, config: SimConfig = SimConfig()) -> None:
        self.config = config
        for name in ("reset_after", "mute_after"):
            v = getattr(config, name)
            if v is not None and v < 1:
                raise InputError(f"{name.replace('_', '-')} must be >= 1 gait cycle, got {v}")
        faults_rng, world_rng = np.random.default_rng(config.seed).spawn(2)
        table = config.table if isinstance(config.table, GaitTable) else resolve_table(config.table)
        self.world = World(table, config.effects, config.start, config.tracker_noise, world_rng)
        self.eeprom = Eeprom(config.eeprom)
        self.line = PtyLine(
            config.factor,
            echo=config.echo,
            faults=config.faults,
            rng=faults_rng,
            window_floor_s=config.window_floor_s,
            idle_floor_s=config.idle_floor_s,
        )
        try:
            self.stamp = self._backend(config)
        except TOOLKIT_ERRORS:
            self.line.close()
            raise
        self.tracker: TrackerServer | None = None
        if config.tracker is not None:
            try:
                self.tracker = TrackerServer(self.world, *config.tracker)
            except OSError as e:
                self.line.close()
                raise InputError(
                    f"cannot open tracker socket {config.tracker}: {e.strerror}"
                ) from None
        self._thread = threading.Thread(target=self.stamp.run, name="pac-sim-stamp", daemon=True)

    def _backend(self, config: SimConfig) -> StampEmulator | FirmwareEmulator:
        if config.firmware is None:
            if config.image is not None:
                raise InputError("an image is run with its source: give --firmware SOURCE too")
            return StampEmulator(
                self.line,
                self.eeprom,
                self.world,
                protocol_version=config.protocol_version,
                firmware_version=config.firmware_version,
                reset_after=config.reset_after,
                mute_after=config.mute_after,
            )
        if (config.protocol_version, config.firmware_version) != (
            PROTOCOL_VERSION,
            FIRMWARE_VERSION,
        ):
            raise InputError("with --firmware the versions are the firmware's own constants")
        return FirmwareEmulator(
            self.line,
            self.eeprom,
            self.world,
            config.firmware,
            image=config.image,
            reset_after=config.reset_after,
            mute_after=config.mute_after,
        )

    @property
    def error(self) -> Exception | None:
        """Why the emulated Stamp stopped serving (a firmware that stopped listening), if so."""
        return self.stamp.error

    @property
    def path(self) -> str:
        return self.line.path

    def start(self) -> SimStamp:
        self._thread.start()
        return self

    def wait(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)

    def close(self) -> None:
        self.line.stop()
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        if self.tracker is not None:
            self.tracker.close()
        self.line.close()

    def __enter__(self) -> SimStamp:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
