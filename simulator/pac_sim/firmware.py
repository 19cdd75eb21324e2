"""The emulator's firmware-in-the-loop backend: the real PBASIC source, run by ``pac_sim.pbasic``.

:class:`FirmwareEmulator` has the face of :class:`pac_sim.stamp.StampEmulator` (``run``,
``reset``, ``boots``, ``cycles_total``, ``executed``, ``downloads``) so :class:`SimStamp` plugs
either one into the same pty line (faults, echo, pacing floors), EEPROM file, world and tracker.
The program runs in Stamp time through :func:`pac_sim.pbasic.hostlink.serve`; after every slice
of Stamp time the servo trace is counted into gait cycles (:mod:`pac_sim.thrust`) and each one
moves the world by the table row its thrust selects, not by the id the firmware meant.

Being flashed: the download is served by :mod:`pac_sim.stamp_download`, as in the model. The
interpreter runs PBASIC source, not tokens, so what was flashed runs only if it is the
program of the firmware's source as it now reads (tokenized again to compare, so an edited and
rebuilt source is picked up): then the Stamp restarts on the recompiled source with the
flashed EEPROM. Any other program, or a download cut short, leaves a Stamp that answers
nothing until the next flash, and :attr:`FirmwareEmulator.flash_note` says why.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
import threading
from collections import deque
from pathlib import Path

from pac_host.errors import TOOLKIT_ERRORS, InputError, PacError
from pac_host.stamp.image import TURN_CYCLE_ADDR, TURN_CYCLE_SIZE, tokenize
from pac_protocol.decoder import FrameDecoder
from pac_protocol.messages import Cmd
from pac_protocol.timing import T_IDLE_S
from pac_sim.eeprom import Eeprom
from pac_sim.line import DownloadStart, PtyLine, Shutdown
from pac_sim.pbasic import (
    ENDED,
    SERIN,
    SerinWait,
    Stamp,
    StampEnded,
    StampNotListening,
    peripherals,
)
from pac_sim.pbasic.hostlink import serve
from pac_sim.pbasic.image import read_image
from pac_sim.stamp_download import StampDownload, serve_downloads
from pac_sim.thrust import ServoMap, ThrustCounter, WalkedCycle, walked_gait
from pac_sim.world import World

NOT_LISTENING_S = 10.0  # Stamp time without entering SERIN after which the Stamp is not listening
HOST_PIN = peripherals.PROGRAMMING_PORT
ACTING = (Cmd.LOAD, Cmd.RUN, Cmd.STEP)
WALKED_KEPT = 10_000  # the most recent gait cycles kept in ``walked``


def load_firmware(source: str | Path, image: str | Path | None = None) -> Stamp:
    """Compile a PBASIC source (errors name file:line); with the tokenizer's image of that same
    source, the EEPROM starts as the image holds it."""
    if Path(source).suffix.lower() in (".json", ".bin", ".tok"):
        raise InputError(f"{source}: --firmware runs PBASIC source; pass a built image with "
                         "--image next to its source")
    kw: dict = {}
    if image is not None:
        kw = read_image(image)
        try:
            want = json.loads(Path(image).read_text()).get("source_sha256")
            have = hashlib.sha256(Path(source).read_bytes()).hexdigest()
        except OSError as e:
            raise InputError(f"{source}: cannot read: {e.strerror}") from None
        if want is not None and want != have:
            raise InputError(f"{image} was not built from {source} (source_sha256 differs): "
                             "run `make firmware` again")
    return Stamp.from_file(source, **kw)


def check_listens(stamp: Stamp, limit_s: float = NOT_LISTENING_S) -> None:
    """Raise :class:`StampNotListening` unless the program enters SERIN within limit_s."""
    try:
        stamp.run_until_serin(limit_s)
    except StampEnded as e:
        raise StampNotListening(f"the Stamp is not listening: {e}") from None


class MirroredEeprom(peripherals.Eeprom):
    """The Stamp's 2 KB EEPROM, its turn-cycle bytes written through to the emulator's
    :class:`Eeprom` (so ``--eeprom`` persistence and the write count are the model's code)."""

    def __init__(self, inner: peripherals.Eeprom, turn_cycle: Eeprom,
                 flashed: bytes | None = None) -> None:
        """``flashed``: a download's EEPROM, whose turn-cycle bytes replace the stored ones."""
        self.mem, self.writes, self.turn_cycle = inner.mem, inner.writes, turn_cycle
        if flashed is not None:
            turn_cycle.write_flashed(flashed)
        self.mem[TURN_CYCLE_ADDR : TURN_CYCLE_ADDR + TURN_CYCLE_SIZE] = turn_cycle.image

    def write(self, addr: int, value: int) -> None:
        super().write(addr, value)
        a = addr % peripherals.EEPROM_SIZE - TURN_CYCLE_ADDR
        if 0 <= a < TURN_CYCLE_SIZE:
            self.turn_cycle.write(a, value & 0xFF)


class _Wire:
    """The pty line as the program's host pin sees it (a ``hostlink.ByteLink``)."""

    def __init__(self, line: PtyLine) -> None:
        self.line = line

    def write(self, data: bytes) -> None:
        self.line.deliver(data)

    def read(self, timeout_s: float) -> bytes:
        return self.line.receive(timeout_s, downloads=True)  # a download resets the Stamp


class FirmwareEmulator:
    """Runs a PBASIC firmware on a :class:`PtyLine` until the line is stopped.

    ``reset_after``: reset once, after that many gait cycles since the emulator started, halfway
    through the first frame the program sends after that cycle (its CYCLE report).
    ``mute_after``: after that many gait cycles, that first frame still sent, nothing more
    reaches the host (a pulled cable).
    ``error``: why the program stopped serving (not listening, ended, a run-time error).
    """

    def __init__(
        self,
        line: PtyLine,
        eeprom: Eeprom,
        world: World | None,
        source: str | Path,
        *,
        image: str | Path | None = None,
        reset_after: int | None = None,
        mute_after: int | None = None,
    ) -> None:
        self.line, self.eeprom, self.world = line, eeprom, world
        self.source = str(source)
        self.stamp: Stamp | None = load_firmware(source, image)
        check_listens(load_firmware(source, image))
        self.servo = ServoMap.from_constants(self.stamp.program.symbols.con_value, self.source)
        self.flash_note: str | None = None  # why the Stamp runs nothing after the last flash
        self.reset_after, self.mute_after = reset_after, mute_after
        self.boots = 0  # BOOT frames the program sent
        self.cycles_total = 0  # gait cycles walked since the emulator started, across resets
        self.executed: list[tuple[int, int]] = []  # (cmd, seq) of each LOAD/RUN/STEP acted on
        self.downloads: list[StampDownload] = []  # every download session, in order
        self.walked: deque[WalkedCycle] = deque(maxlen=WALKED_KEPT)
        self.inexact = 0  # gait cycles whose thrust matched no table row exactly
        self.error: Exception | None = None  # one of TOOLKIT_ERRORS
        self._counter = ThrustCounter(self.servo)
        self._decoder = FrameDecoder()
        self._reset_pending = threading.Event()
        self._power_on = 0
        self._prev: int | None = None
        self._cut_after_us: int | None = None
        self._mute_after_us: int | None = None
        self._mute_next = False
        self._listened_us = 0
        self._last_seq = 0

    # ---- the thread -----------------------------------------------------------------------------

    def run(self) -> None:
        """Serve the program on the line; returns when the line is stopped or the program fails
        (then :attr:`error` says why)."""
        if self.stamp is not None and not isinstance(self.stamp.eeprom, MirroredEeprom):
            self.stamp.eeprom = MirroredEeprom(self.stamp.eeprom, self.eeprom)  # as stored now
        while True:
            try:
                if self.stamp is None:
                    self._silent()
                    continue
                s = self.stamp
                state = serve(s, _Wire(self.line), pin=HOST_PIN, factor=self.line.factor,
                              floor_s=self._floor, echo=False, keep_output=False,
                              on_chunk=self._on_chunk)
            except DownloadStart as d:
                serve_downloads(self.line, d.data, self._eeprom_now, self._flashed,
                                self.line.aimed_packets)
                continue
            except Shutdown:
                return
            except TOOLKIT_ERRORS as e:
                self.error = e
                return
            if state == ENDED:
                self.error = StampNotListening(
                    f"{self.source}:{s.line_at()}: the Stamp is not listening: the program "
                    f"reached {s.halted_by} at {s.now_s:.3f} s of Stamp time")
            return

    def _silent(self) -> None:
        """A Stamp holding a program the interpreter cannot run: nothing answers, until the
        next download (which raises :class:`DownloadStart`)."""
        while True:
            self.line.receive(T_IDLE_S, downloads=True)

    # ---- being flashed ------------------------------------------------------------------------

    def _eeprom_now(self) -> bytes:
        """What the EEPROM holds: the running program's, or (a silent Stamp runs nothing only
        after a download) what the last download left."""
        if self.stamp is not None:
            return bytes(self.stamp.eeprom.mem)
        return self.downloads[-1].eeprom

    def _flashed(self, dl: StampDownload) -> None:
        """After a download: restart on the source if its program is what was flashed. The
        session is listed in :attr:`downloads` once :attr:`flash_note` tells its outcome."""
        try:
            self._boot_flashed(dl)
        finally:
            self.downloads.append(dl)

    def _boot_flashed(self, dl: StampDownload) -> None:
        if not dl.finished and not dl.packets:
            if self.stamp is not None:  # identification failed: the old program starts again
                self.flash_note = None
                self._restart(self.stamp)
            return  # (a silent Stamp stays silent, for the reason already noted)
        self.stamp, self.flash_note = None, None
        if not dl.finished:
            self.flash_note = (f"the download ended after {dl.packets} packets: the Stamp holds "
                               "no whole program")
            return
        try:
            with tempfile.TemporaryDirectory(prefix="pac-sim-fw-") as d:
                image = read_image(tokenize(Path(self.source), Path(d)))
        except PacError as e:
            self.flash_note = f"cannot tell what was flashed: {e}"
            return
        start = image["program_start"] or 0
        if dl.eeprom[start:] != image["eeprom_image"][start:]:
            self.flash_note = (f"the flashed program is not {self.source}'s: pac-sim runs only "
                               "that source, so the Stamp answers nothing")
            return
        try:
            stamp = Stamp.from_file(self.source, eeprom_image=dl.eeprom, program_start=start)
            self.servo = ServoMap.from_constants(stamp.program.symbols.con_value, self.source)
        except PacError as e:
            self.flash_note = f"cannot run {self.source}: {e}"
            return
        stamp.eeprom = MirroredEeprom(stamp.eeprom, self.eeprom, dl.eeprom)
        self._counter = ThrustCounter(self.servo)
        self._restart(stamp)
        self.stamp = stamp

    def reset(self) -> None:
        """Press the reset button: takes effect after the Stamp's current slice of time."""
        self._reset_pending.set()

    def _floor(self, w: SerinWait) -> float:
        """The pty line's idle floor for a window as long as the idle one, else its run floor."""
        idle = w.deadline_us is None or w.deadline_us - w.since_us >= T_IDLE_S * 1e6
        return self.line.idle_floor_s if idle else self.line.window_floor_s

    def _restart(self, s: Stamp) -> None:
        s.reset()
        self._counter.restart()
        self._power_on, self._prev, self._last_seq = 0, None, 0
        self._listened_us = s.now_us
        if self.world is not None:
            self.world.power_on = 0

    # ---- after every slice of Stamp time -------------------------------------------------------

    def _on_chunk(self, s: Stamp) -> None:
        if self._reset_pending.is_set():
            self._reset_pending.clear()
            del s.output.frames[:]
            self._restart(s)
            return
        if s.state == SERIN:
            self._listened_us = s.now_us
        elif s.now_us - self._listened_us > NOT_LISTENING_S * 1e6:
            raise StampNotListening(
                f"{self.source}: the Stamp is not listening: no SERIN for {NOT_LISTENING_S:g} s "
                f"of Stamp time (running line {s.line_at()})")
        if self._mute_next:
            self.line.mute()
            self._mute_next = False
        self._probe_executed(s)
        pulses = s.servo.pulses
        cycles = self._counter.feed(pulses)
        del pulses[:]
        for c in cycles:
            self._walk(c.legs, c.end_us)
        if self._cut_after_us is not None and self._cut(s):
            return
        if self._mute_after_us is not None:
            self._mute_after_frame(s)
        frames = [b for _, pin, b in s.output.frames if pin == HOST_PIN]
        for f in self._decoder.feed(bytes(frames)):
            if f.cmd == Cmd.BOOT:
                self.boots += 1
            if f.cmd in (Cmd.BOOT, Cmd.DONE):
                self._prev = None  # the next gait cycle starts a new run

    def _walk(self, thrust: tuple[int, ...], end_us: int) -> None:
        w = walked_gait(thrust)
        self.walked.append(w)
        self.inexact += not w.exact
        n0 = self._power_on
        self._power_on += 1
        self.cycles_total += 1
        if self.world is not None:
            self.world.advance(w.gait, n0, self._prev)
        self._prev = w.gait
        if self.reset_after is not None and self.cycles_total == self.reset_after:
            self._cut_after_us = end_us
        if self.mute_after is not None and self.cycles_total == self.mute_after:
            self._mute_after_us = end_us

    def _first_frame_after(self, s: Stamp, t_us: int) -> tuple[int, int] | None:
        """Where the first frame sent after t_us starts in ``s.output.frames`` and how many
        bytes it has (None until all of its header is there)."""
        fr = s.output.frames
        i = next((k for k, f in enumerate(fr) if f[0] > t_us and f[1] == HOST_PIN), None)
        if i is None or len(fr) < i + 3:
            return None
        return i, fr[i + 2][2] + 6  # LEN + 6 bytes in the frame

    def _mute_after_frame(self, s: Stamp) -> None:
        """The armed mute: that frame goes out, nothing after it (the line mutes next)."""
        found = self._first_frame_after(s, self._mute_after_us)
        if found is not None:
            i, n = found
            del s.output.frames[i + n :]
            self._mute_after_us, self._mute_next = None, True

    def _cut(self, s: Stamp) -> bool:
        """The armed reset: keep half of the first frame sent after the cycle, lose the rest."""
        found = self._first_frame_after(s, self._cut_after_us)
        if found is None:
            return False
        i, n = found
        del s.output.frames[i + n // 2 :]
        self._cut_after_us = None
        self._restart(s)
        return True

    def _probe_executed(self, s: Stamp) -> None:
        """A LOAD, RUN or STEP was acted on when the firmware's lastSeq took its SEQ."""
        try:
            last = s.var("lastSeq")
        except KeyError:
            return
        if last != self._last_seq:
            self._last_seq = last
            cmd = s.var("cmd")
            if cmd in ACTING:
                self.executed.append((Cmd(cmd), last))
