"""The ``camera:`` observer: the robot's pose after each gait cycle, from an overhead camera.

When the robot reports a finished gait cycle (its CYCLE report) it stands, legs down, in its
listening window; the observer takes that window's frames, finds the robot's marker in each,
corrects its parallax (the marker is ``height`` cm above the floor) and takes the median pose
over the frames that agree. A window where the marker is not seen, is seen at an impossible
place (off the area, or farther from the last pose than a gait cycle moves), or holds no fresh
frame is a lost observation: logged, then raised as :class:`ObserverError`, never filled in.

Spec: ``camera:SOURCE[,key=value...]``; SOURCE a camera index, a video file, a folder of
frames, or ``sim`` (the built-in emulator seen by the virtual camera); keys ``calib=FILE``
(required except with ``sim``), ``frames=3``, ``window=0.1`` (s), ``heading0=90``, ``height``
(the marker's, cm), ``max_step=40`` (cm), ``noise=3`` and ``seed=0`` (``sim`` only).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from pac_host.camera.calibrate import Calibration
from pac_host.camera.detect import MarkerPose, detect, fit_square, make_detector
from pac_host.camera.layout import AREA_X, AREA_Y
from pac_host.errors import InputError
from pac_host.observation import Observation, ObserverError, Record
from pac_protocol.messages import POWER_ON_MOD

SCALE_TOLERANCE = 0.15  # a marker seen this much bigger or smaller than printed is not it


@dataclass(frozen=True)
class CameraOptions:
    frames: int = 3  # frames per listening window
    window: float = 0.1  # s: the firmware's listening window (T_RUN)
    heading0: float = 90.0  # a run's first heading is taken within +-180 of this
    height: float | None = None  # the robot marker's height (default: the calibration's)
    max_step: float = 40.0  # cm: farther from the last pose than this is impossible
    margin: float = 40.0  # cm: how far off the area a pose may lie (about the view's edge)
    spread: float = 2.0  # cm: frames farther than this from the window's median are dropped
    noise: float = 3.0  # sim: sensor noise (grey levels)
    seed: int = 0  # sim: seeds the sensor noise
    # 1: a window before each run sees the start pose the robot was put at; 0: not; None: when
    # the source shows the robot as it is now (a camera, the virtual one; not a recording)
    start: int | None = None

    def check(self) -> None:
        if self.frames < 1:
            raise InputError(f"camera frames must be >= 1, got {self.frames}")
        if not self.window > 0:
            raise InputError(f"camera window must be > 0 s, got {self.window}")
        if self.max_step <= 0 or self.spread <= 0 or self.margin < 0 or self.noise < 0:
            raise InputError("camera max_step and spread must be > 0, margin and noise >= 0")
        if self.start not in (None, 0, 1):
            raise InputError(f"camera start must be 0 or 1, got {self.start}")


def wrap180(d: float) -> float:
    return (d + 180.0) % 360.0 - 180.0


class PoseFinder:
    """The robot's pose in the frames of one window (shared by the observer and the server)."""

    def __init__(self, calib: Calibration, opts: CameraOptions) -> None:
        self.calib, self.opts = calib, opts
        self.marker = calib.layout.robot
        self.height = opts.height if opts.height is not None else self.marker.height
        self.detector = make_detector(calib.layout.dictionary)

    def in_frame(self, frame: np.ndarray) -> MarkerPose | None:
        c = detect(self.detector, frame).get(self.marker.id)
        if c is None:
            return None
        p = fit_square(self.calib.to_plane(c, self.height), self.marker.size)
        return p if abs(p.scale - 1) <= SCALE_TOLERANCE else None

    def in_window(self, frames: Sequence[np.ndarray], ref_heading: float
                  ) -> tuple[tuple[float, float, float] | None, int, str]:
        """The median pose over the frames that show the marker and agree, its heading
        unwrapped near ``ref_heading``; the frames used; why none, if none."""
        if not frames:
            return None, 0, f"no fresh frame within {self.opts.window:g} s (camera stalled?)"
        seen = [p for p in map(self.in_frame, frames) if p is not None]
        if not seen:
            return None, 0, (f"robot marker {self.marker.id} not seen in {len(frames)} "
                             "frame(s)")
        xy = np.array([[p.x, p.y] for p in seen])
        h = np.array([ref_heading + wrap180(p.h - ref_heading) for p in seen])
        med = np.median(xy, axis=0)
        keep = np.hypot(*(xy - med).T) <= self.opts.spread
        if keep.sum() * 2 < len(seen):
            return None, 0, (f"robot marker {self.marker.id} jumps between the window's "
                             "frames (the robot moved?)")
        x, y = np.median(xy[keep], axis=0)
        hh = float(np.median(h[keep]))
        return (float(x), float(y), hh), int(keep.sum()), ""

    def impossible(self, pose: Sequence[float], prev: Sequence[float] | None) -> str:
        x, y, _ = pose
        m = self.opts.margin
        if not (AREA_X[0] - m <= x <= AREA_X[1] + m and y >= AREA_Y[0] - m):
            return f"robot marker seen at ({x:.1f}, {y:.1f}) cm, off the area"
        if prev is not None and np.hypot(x - prev[0], y - prev[1]) > self.opts.max_step:
            d = np.hypot(x - prev[0], y - prev[1])
            return (f"robot marker seen at ({x:.1f}, {y:.1f}) cm, {d:.0f} cm from its last "
                    f"pose (at most {self.opts.max_step:g} per gait cycle)")
        return ""


class CameraObserver:
    """Implements :class:`pac_host.robot.observers.Observer` with a frame source."""

    def __init__(self, source, calib: Calibration, opts: CameraOptions, name: str) -> None:
        opts.check()
        self.source, self.opts, self.name = source, opts, name
        self.finder = PoseFinder(calib, opts)
        self._n0 = 0
        self._run_id = ""
        self._record: Record = lambda _: None
        self._poses: list[tuple[float, float, float]] = []
        self._start: tuple[float, float, float] | None = None
        self.sees_start = bool(getattr(source, "now", False) if opts.start is None
                               else opts.start)

    def begin(self, run_id: str, power_on_before: int, record: Record) -> None:
        self._run_id, self._n0, self._record = run_id, power_on_before, record
        self._poses = []
        self._start = None
        begin_run = getattr(self.source, "begin_run", None)
        if begin_run is not None:
            begin_run(run_id)
        if self.sees_start:
            self._observe_start()

    def _observe_start(self) -> None:
        """The pose the robot stands at before its first gait cycle (the start a person or the
        emulator put it at): the same instrument as every later pose, where a hand placement
        is only nominal. Not seen, the run goes on from the placement's start pose."""
        self._start, why = self._look(0, None, self._n0, None)
        if why:
            self._record({"type": "start_unseen", "run_id": self._run_id, "why": why})

    def on_cycle(self, power_on: int) -> None:
        i = (power_on - self._n0) % POWER_ON_MOD
        if i == 0 or i > POWER_ON_MOD // 2 or i <= len(self._poses):
            return  # not this run's, or seen already
        if i != len(self._poses) + 1:
            self._lost(len(self._poses) + 1, "its CYCLE report was lost, so no frame was "
                       "taken while the robot stood")
        self._observe(i, power_on)

    def finish(self, cycles: int) -> Observation:
        if len(self._poses) == cycles - 1:  # the last CYCLE report was lost; it stands now
            self._observe(cycles, (self._n0 + cycles) % POWER_ON_MOD)
        if len(self._poses) < cycles:
            self._lost(len(self._poses) + 1, "no CYCLE report, no frame")
        return Observation(poses=np.array(self._poses[:cycles], dtype=np.float64).reshape(-1, 3),
                           start=self._start)

    def _observe(self, i: int, power_on: int) -> None:
        pose, why = self._look(i, power_on, power_on,
                               self._poses[-1] if self._poses else self._start)
        if why:
            self._lost(i, why)
        self._poses.append(pose)

    def _look(self, i: int, key: int | None, power_on: int,
              prev: tuple[float, float, float] | None
              ) -> tuple[tuple[float, float, float] | None, str]:
        """Pose ``i`` of the run (0: its start) from the window the source gives for ``key``,
        logged if seen, checked against the pose before it (``prev``, None: none); else None
        and why not."""
        ref = prev[2] if prev is not None else self.opts.heading0
        frames = self.source.window(self.opts.frames, self.opts.window, key)
        pose, used, why = self.finder.in_window(frames, ref)
        if pose is not None:
            why = self.finder.impossible(pose, prev)
        if why:
            return None, why
        self._record({"type": "pose", "run_id": self._run_id, "cycle": i, "power_on": power_on,
                      "pose": [round(v, 4) for v in pose], "frames": used,
                      "observer": "camera"})
        return pose, ""

    def _lost(self, i: int, why: str) -> None:
        self._record({"type": "lost", "run_id": self._run_id, "cycle": i, "why": why})
        raise ObserverError(f"observer {self.name}: lost observation of gait cycle {i} of run "
                            f"{self._run_id}: {why}")

    def close(self) -> None:
        self.source.close()


def parse_spec(text: str) -> tuple[str, dict[str, str]]:
    """``SOURCE[,key=value...]`` into the source and the options (strings)."""
    source, *rest = text.split(",")
    opts = {}
    for part in rest:
        k, sep, v = part.partition("=")
        if not sep or not k.strip():
            raise InputError(f"--observer camera:{text}: expected key=value, got {part!r}")
        opts[k.strip()] = v.strip()
    if not source:
        raise InputError("--observer camera:SOURCE[,key=value...]: no SOURCE given")
    return source, opts


def options_from(raw: dict[str, str]) -> CameraOptions:
    types = {f.name: f.type for f in fields(CameraOptions)}
    out = CameraOptions()
    for k, v in raw.items():
        if k not in types:
            raise InputError(f"camera option {k!r} unknown (calib, {', '.join(types)})")
        try:
            val = int(v) if k in ("frames", "seed", "start") else float(v)
        except ValueError:
            raise InputError(f"camera option {k}={v!r} is not a number") from None
        out = replace(out, **{k: val})
    out.check()
    return out


def check_spec(text: str, emulated: bool) -> None:
    """Refuse a ``camera:`` spec that :func:`open_camera` cannot use, opening nothing: its
    options, ``camera:sim`` without the built-in emulator (``emulated``), a camera without
    ``calib=FILE``."""
    source_text, raw = parse_spec(text)
    calib_path = raw.pop("calib", None)
    options_from(raw)
    if source_text == "sim" and not emulated:
        raise InputError("--observer camera:sim is the built-in emulator's virtual camera; "
                         "it does not apply with --port")
    if source_text != "sim" and calib_path is None:
        raise InputError(f"--observer camera:{source_text}: give calib=FILE (from `pac-host "
                         "camera calibrate`)")


def open_camera(text: str, world=None) -> CameraObserver:
    """The observer a ``camera:`` spec names; ``world`` is the built-in emulator's world,
    needed by ``camera:sim``."""
    from pac_host.camera import calibrate as cal
    from pac_host.camera.sources import open_source

    check_spec(text, world is not None)
    source_text, raw = parse_spec(text)
    calib_path = raw.pop("calib", None)
    opts = options_from(raw)
    name = f"camera:{source_text}"
    if source_text == "sim":
        from pac_host.camera.virtual import sim_source

        source, calib = sim_source(world, opts, None if calib_path is None
                                   else cal.load(calib_path))
        return CameraObserver(source, calib, opts, name)
    calib = cal.load(calib_path)
    return CameraObserver(open_source(source_text), calib, opts, name)
