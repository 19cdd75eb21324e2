"""Observers: where the robot really is (the paper's "global observation").

An observer follows one run at a time: :meth:`Observer.begin` before it, :meth:`on_cycle` when
the robot reports a finished gait cycle, :meth:`finish` when it has stopped. Every observation is
handed to the ``record`` callback (the run's log, which appends and flushes it) before it is
returned or used. The kinds:

- :class:`TrackerObserver`: a stream of ``POSE seq gait power_on x y h`` lines (the emulator's
  tracker feed, or an overhead camera) from a TCP socket or a named pipe; gives the pose after
  every gait cycle.
- :class:`ManualObserver`: the operator types numbers at a prompt the caller provides; either
  the coverage figures of a run or the final pose. A reply that is not a number is asked again.
- ``camera:...``: an overhead camera read by the host itself
  (:class:`pac_host.camera.observer.CameraObserver`). A tracker stream that opens with
  :data:`ASK_HEADER` (``pac-host camera serve``) is asked for each gait cycle's pose.

The types every observer shares (:class:`Observer`, :class:`Observation`,
:class:`ObserverError`) live in :mod:`pac_host.observation`, which the camera imports without
importing this module; the tracker's lines are :mod:`pac_protocol.tracker_line`'s.

A malformed line, a closed stream or silence raises :class:`ObserverError` naming the observer;
nothing is ever filled in with zeros. A gait cycle a camera could not see (a tracker's ``LOST``
line, the ``camera:`` observer's lost window) is a gap, a NaN pose, logged; only too many of
them (:func:`pac_host.observation.too_many_lost`: more than a quarter of a test's) stop it.
"""

from __future__ import annotations

import os
import select
import socket
import stat
import time
from collections.abc import Callable

import numpy as np

from pac_host.errors import InputError
from pac_host.observation import (  # noqa: F401  (the base types, importable from here too)
    Ask,
    Observation,
    Observer,
    ObserverError,
    Record,
    too_many_lost,
)
from pac_protocol.messages import POWER_ON_MOD
from pac_protocol.tracker_line import ASK_HEADER, parse_pose_line

TRACKER_TIMEOUT_S = 3.0  # a camera's pose for a finished gait cycle should come well within this
GREETING_TIMEOUT_S = 10.0  # pac-sim's tracker greets a new client as soon as it is scheduled


# ---- tracker streams -------------------------------------------------------------------------


class LineSource:
    """Text lines from a file descriptor with a timeout (a socket or a FIFO)."""

    def __init__(self, fd: int, name: str, closer: Callable[[], None],
                 writer: Callable[[bytes], object] | None = None) -> None:
        self.fd = fd
        self.name = name
        self._close = closer
        self._write = writer
        self._buf = b""
        self.eof = False

    def _read(self) -> bytes | None:
        """One read: the bytes ready (b"" at the end of the stream), or None if none were."""
        try:
            return os.read(self.fd, 65536)
        except BlockingIOError:
            return None
        except OSError as e:
            raise ObserverError(f"observer {self.name}: read failed: {e.strerror}") from None

    def readline(self, timeout: float) -> str | None:
        """The next line, or None if none completes within ``timeout``; raises on EOF."""
        deadline = time.monotonic() + timeout
        while b"\n" not in self._buf:
            rem = deadline - time.monotonic()
            if rem <= 0:
                return None
            r, _, _ = select.select([self.fd], [], [], rem)
            if not r:
                return None
            chunk = self._read()
            if chunk is None:
                continue
            if not chunk:
                self.eof = True
                raise ObserverError(f"observer {self.name}: the stream closed")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\n", 1)
        return raw.decode(errors="replace").rstrip("\r")

    def drain(self) -> int:
        """Forget the whole lines already received (a partial last line is kept: its end is
        still coming); returns how many."""
        while select.select([self.fd], [], [], 0)[0]:
            chunk = self._read()
            if not chunk:
                break  # nothing ready, or the end of stream: readline reports that
            self._buf += chunk
        cut = self._buf.rfind(b"\n") + 1
        n = self._buf[:cut].count(b"\n")
        self._buf = self._buf[cut:]
        return n

    def write_line(self, text: str) -> None:
        """Send a line back (TCP sources only)."""
        if self._write is None:
            raise ObserverError(f"observer {self.name}: this stream is read-only")
        try:
            self._write((text + "\n").encode())
        except OSError as e:
            raise ObserverError(f"observer {self.name}: write failed: {e.strerror}") from None

    def close(self) -> None:
        self._close()


def open_tcp(host: str, port: int, name: str, timeout: float = 5.0) -> LineSource:
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as e:
        raise InputError(f"observer {name}: cannot connect to {host}:{port}: "
                         f"{e.strerror or e}") from None
    sock.setblocking(False)
    return LineSource(sock.fileno(), name, sock.close, sock.sendall)


def open_pipe(path: str, name: str) -> LineSource:
    """A named pipe (or any readable file) a camera program writes lines into. A FIFO is
    opened read-write so it neither blocks until a writer comes nor reads EOF when the writer
    restarts (Linux semantics)."""
    try:
        mode = os.stat(path).st_mode
        flags = os.O_RDWR if stat.S_ISFIFO(mode) else os.O_RDONLY
        fd = os.open(path, flags | os.O_NONBLOCK)
    except OSError as e:
        raise InputError(f"observer {name}: cannot open {path}: {e.strerror}") from None
    return LineSource(fd, name, lambda: os.close(fd))


class TrackerObserver:
    """Poses from a tracker stream, matched to gait cycles by the power-on count each line
    carries (so a CYCLE report lost on the serial line loses no pose)."""

    def __init__(self, source: LineSource, timeout: float = TRACKER_TIMEOUT_S) -> None:
        self.source = source
        self.name = source.name
        self.timeout = timeout
        self._n0 = 0
        self._poses: list[tuple[float, float, float]] = []
        self._record: Record = lambda _: None
        self._run_id = ""
        self._ask = False  # the stream answers requests (see ASK_HEADER)
        self._asked = 0
        self._lost = 0

    def begin(self, run_id: str, power_on_before: int, record: Record) -> None:
        self._run_id, self._n0, self._record = run_id, power_on_before, record
        self._poses = []
        self._asked = 0
        self._lost = 0

    def forget(self) -> None:
        """Drop the lines received so far: they belong to a test cut short, whose power-on
        counts a redone test may reuse after a reset (called before the redo)."""
        self.source.drain()

    def await_greeting(self, timeout: float = GREETING_TIMEOUT_S) -> None:
        """Wait for the tracker's first ``#`` line. pac-sim's tracker greets a client only once
        it sends it every later pose, so a run started after the greeting loses none, however
        late the tracker got round to the connection (a busy machine)."""
        deadline = time.monotonic() + timeout
        while (line := self.source.readline(max(deadline - time.monotonic(), 0.0))) is not None:
            if line.startswith(ASK_HEADER):
                self._ask = True
            if line.startswith("#"):
                return
        raise ObserverError(f"observer {self.name}: no greeting from the tracker within "
                            f"{timeout:g} s (is it pac-sim's?)")

    def on_cycle(self, power_on: int) -> None:
        self._take_until((power_on - self._n0) % POWER_ON_MOD)

    def finish(self, cycles: int) -> Observation:
        self._take_until(cycles)
        poses = np.array(self._poses[:cycles], dtype=np.float64).reshape(-1, 3)
        lost = int((~np.isfinite(poses).all(axis=1)).sum())
        if too_many_lost(lost, cycles, final=True):
            raise ObserverError(f"observer {self.name}: lost observation of {lost} of {cycles} "
                                f"gait cycles of run {self._run_id} (more than a quarter)")
        return Observation(poses=poses)

    def _take_until(self, k: int) -> None:
        """Read lines until the pose after gait cycle ``k`` of this run is in hand."""
        while len(self._poses) < k:
            want = len(self._poses) + 1
            if self._ask and self._asked < want:
                self.source.write_line(f"CYCLE {(self._n0 + want) % POWER_ON_MOD} {want}")
                self._asked = want
            line = self.source.readline(self.timeout)
            if line is None:
                raise ObserverError(
                    f"observer {self.name}: no pose for gait cycle {want} of run {self._run_id} "
                    f"within {self.timeout:g} s (is the tracker running and seeing the robot?)"
                )
            if line.startswith(ASK_HEADER):
                self._ask = True
                continue
            if not line.strip() or line.startswith("#"):
                continue
            if line.startswith("LOST"):  # a gap: logged, a NaN pose
                why = line.split(None, 2)[2] if len(line.split(None, 2)) == 3 else "lost"
                self._record({"type": "lost", "run_id": self._run_id, "cycle": want,
                              "why": why})
                self._poses.append((np.nan, np.nan, np.nan))
                self._lost += 1
                if too_many_lost(self._lost, want):
                    raise ObserverError(f"observer {self.name}: lost observation of "
                                        f"{self._lost} of {want} gait cycles of run "
                                        f"{self._run_id} (more than a quarter); the last, "
                                        f"gait cycle {want}: {why}")
                continue
            try:
                p = parse_pose_line(line)
            except ValueError as e:
                raise ObserverError(
                    f"observer {self.name}: malformed line {line.strip()[:80]!r} ({e})"
                ) from None
            if p.gait < 0:
                continue  # a snapshot of the robot at rest, not a gait cycle
            i = (p.power_on - self._n0) % POWER_ON_MOD
            if i == 0 or i > POWER_ON_MOD // 2:
                continue  # a gait cycle from before this run
            if i != want:
                raise ObserverError(
                    f"observer {self.name}: pose for gait cycle {i} of run {self._run_id} came "
                    f"where gait cycle {want} was expected (the tracker skipped a line)"
                )
            self._record({"type": "pose", "run_id": self._run_id, "cycle": i,
                          "gait": p.gait, "power_on": p.power_on, "pose": list(p.pose)})
            self._poses.append(p.pose)

    def close(self) -> None:
        self.source.close()


# ---- manual entry ----------------------------------------------------------------------------


def ask_numbers(ask: Ask, prompt: str, names: tuple[str, ...], integer: bool) -> list[float]:
    """Ask until the reply is ``len(names)`` numbers (integers >= 0 if ``integer``)."""
    hint = ""
    while True:
        reply = ask(hint + prompt)
        parts = reply.replace(",", " ").split()
        try:
            vals = [int(p) if integer else float(p) for p in parts]
        except ValueError:
            vals = []
        ok = len(vals) == len(names) and all(np.isfinite(vals))
        if ok and integer:
            ok = all(v >= 0 for v in vals)
        if ok:
            return vals
        kind = "whole numbers >= 0" if integer else "numbers"
        hint = f"{reply.strip()!r} is not {len(names)} {kind} ({', '.join(names)}). "


class ManualObserver:
    """The operator counts and types; ``ask(prompt) -> reply`` is the caller's prompt.

    ``mode="figures"``: after a run, blocks covered, blocks covered once, and the coverage
    fitness 3R + c (R full rows from the bottom, c blocks in the next row). Repeat visits are not
    asked: they are estimated as covered - covered once (a lower bound) and marked so in the log.
    ``mode="pose"``: the final pose x y h (cm, cm, compass degrees).
    """

    FIGURES = ("blocks covered", "blocks covered once", "fitness 3R+c")
    POSE = ("x cm", "y cm", "heading deg")

    def __init__(self, ask: Ask, mode: str = "figures") -> None:
        if mode not in ("figures", "pose"):
            raise ValueError(f"mode must be figures or pose, got {mode!r}")
        self.ask = ask
        self.mode = mode
        self.name = f"manual ({mode})"
        self._record: Record = lambda _: None
        self._run_id = ""

    def begin(self, run_id: str, power_on_before: int, record: Record) -> None:
        self._run_id, self._record = run_id, record

    def on_cycle(self, power_on: int) -> None:
        pass

    def finish(self, cycles: int) -> Observation:
        if self.mode == "pose":
            vals = ask_numbers(self.ask, f"run {self._run_id}: final pose (x y heading)? ",
                               self.POSE, integer=False)
            pose = (vals[0], vals[1], vals[2])
            self._record({"type": "final_pose", "run_id": self._run_id, "pose": list(pose)})
            return Observation(final_pose=pose)
        while True:
            c, o, f = (int(v) for v in ask_numbers(
                self.ask, f"run {self._run_id}: blocks covered, covered once, fitness 3R+c? ",
                self.FIGURES, integer=True))
            if o <= c and f <= c:
                break
            self.ask(f"covered once ({o}) and fitness ({f}) cannot exceed blocks covered ({c}); "
                     "press Enter and type them again")
        figures = {"blocks_covered": c, "blocks_covered_once": o, "fitness": f,
                   "repeat_visits": c - o, "repeat_visits_estimated": True}
        self._record({"type": "figures", "run_id": self._run_id, **figures})
        return Observation(figures=figures)

    def close(self) -> None:
        pass


# ---- from a command-line spec ----------------------------------------------------------------


def check_spec(spec: str, emulated: bool = False) -> None:
    """Refuse an ``--observer`` that :func:`open_observer` cannot use, opening nothing (no
    socket, pipe or camera): ``tracker:HOST:PORT``, ``pipe:PATH``, ``camera:SOURCE[,options]``
    or ``manual``; ``emulated``: the built-in emulator plays the robot (``camera:sim``)."""
    kind, _, rest = spec.partition(":")
    if kind == "camera":
        from pac_host.camera.observer import check_spec as check_camera

        check_camera(rest, emulated)
    elif kind == "tracker":
        host, sep, port = rest.rpartition(":")
        if not sep or not port.isdigit() or not 0 < int(port) < 65536:
            raise InputError(f"--observer tracker:HOST:PORT expected, got {spec!r}")
    elif not (kind == "pipe" and rest) and spec != "manual":
        raise InputError(f"--observer: expected tracker:HOST:PORT, pipe:PATH, camera:SOURCE "
                         f"or manual, got {spec!r}")


def open_observer(spec: str, ask: Ask | None = None, manual_mode: str = "figures",
                  timeout: float = TRACKER_TIMEOUT_S, world: object | None = None) -> Observer:
    """``tracker:HOST:PORT``, ``pipe:PATH``, ``camera:SOURCE[,options]`` or ``manual`` (needs
    ``ask``); ``world`` is the built-in emulator's, for ``camera:sim``."""
    check_spec(spec, world is not None)
    kind, _, rest = spec.partition(":")
    if kind == "camera":
        from pac_host.camera.observer import open_camera

        return open_camera(rest, world)
    if kind == "tracker":
        host, _, port = rest.rpartition(":")
        return TrackerObserver(open_tcp(host or "127.0.0.1", int(port), spec), timeout)
    if kind == "pipe":
        return TrackerObserver(open_pipe(rest, spec), timeout)
    if ask is None:
        raise InputError("--observer manual needs an operator at a prompt")
    return ManualObserver(ask, manual_mode)
