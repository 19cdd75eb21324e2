"""The ``camera:`` observer: the robot's pose after each gait cycle, from an overhead camera.

When the robot reports a finished gait cycle (its CYCLE report) it stands, legs down, in its
listening window; the observer takes that window's frames, finds the robot's marker in each,
corrects its parallax (the marker is ``height`` cm above the floor) and takes the median pose
over the frames that agree. A window whose frames show the robot moving (consecutive frames'
poses farther apart than the tracker's noise, ``still``/``still_deg``, or the image around the
marker changing more than the sensor's noise explains, ``still_image``) gives no pose: a robot
still walking would pass for one standing a centimetre off.

A window that gives no pose (the marker not seen, seen moving, seen at an impossible place:
off the area, or farther from the last pose seen than the gait cycles since can move it; no
fresh frame) is looked at again, up to ``retries`` more windows, while the robot stands (a camera or
the virtual one; a recording has no frames to spare). A gait cycle still not seen is a gap: it
is logged (``lost``) and its pose is NaN, never filled in; the test goes on. Only when more
than ``max_lost`` (a quarter) of a test's gait cycles are lost
(:func:`pac_host.observation.too_many_lost`) is it stopped with :class:`ObserverError`.

Spec: ``camera:SOURCE[,key=value...]``; SOURCE a camera index, a video file, a folder of
frames, or ``sim`` (the built-in emulator seen by the virtual camera); keys ``calib=FILE``
(required except with ``sim``), ``frames=3``, ``window=0.1`` (s), ``heading0=90``, ``height``
(the marker's, cm), ``max_step=40`` (cm), ``still=0.5`` (cm), ``still_deg=5``,
``still_image=2.5``, ``retries=2``, ``max_lost=0.25``, ``noise=3`` and ``seed=0`` (``sim``
only).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import cv2
import numpy as np

from pac_host.camera.calibrate import Calibration
from pac_host.camera.detect import MarkerPose, detect, fit_square, grey, make_detector
from pac_host.errors import InputError
from pac_host.observation import MAX_LOST, Observation, ObserverError, Record, too_many_lost
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
    # the robot moved during the window: consecutive frames' positions (cm) or headings (deg)
    # farther apart, or the image around its marker changing this many times the noise (0: no
    # image check); a standing robot's frames agree within about 0.1 cm
    still: float = 0.5
    still_deg: float = 5.0
    still_image: float = 2.5
    retries: int = 2  # windows looked at again when one gives no pose (not a recording's)
    max_lost: float = MAX_LOST  # more of a test's gait cycles unseen stops it
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
        if not (self.still > 0 and self.still_deg > 0 and self.still_image >= 0):
            raise InputError("camera still and still_deg must be > 0, still_image >= 0")
        if self.retries < 0 or not 0 <= self.max_lost < 1:
            raise InputError(f"camera retries must be >= 0 and max_lost in [0, 1), got "
                             f"{self.retries} and {self.max_lost:g}")


def image_change(a: np.ndarray, b: np.ndarray, box: tuple[int, int, int, int]) -> float:
    """How much two frames differ within ``box`` (x0, y0, x1, y1 pixels), in units of the
    frames' own noise: the mean absolute difference of the slightly smoothed frames there over
    the median absolute difference of the whole frames (the noise; a change of the whole
    frame's brightness, light flickering, is taken out first). About 1.2 for frames of a
    scene that stands still; a marker moved by a pixel gives several."""
    d = (cv2.GaussianBlur(grey(a).astype(np.float32), (0, 0), 1.0)
         - cv2.GaussianBlur(grey(b).astype(np.float32), (0, 0), 1.0))
    d -= np.median(d[::4, ::4])
    d = np.abs(d)
    noise = max(float(np.median(d[::4, ::4])), 0.5)
    x0, y0, x1, y1 = box
    region = d[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)]
    return float(region.mean()) / noise if region.size else 0.0


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
        found = self._marker(frame)
        return None if found is None else found[0]

    def _marker(self, frame: np.ndarray) -> tuple[MarkerPose, np.ndarray] | None:
        """The marker's pose in a frame and its corners (pixels), if seen at its size."""
        mid = self.marker.id  # only its corners are refined: the floor's are not used here
        c = detect(self.detector, frame, refine=(mid,), find=mid).get(mid)
        if c is None:
            return None
        p = fit_square(self.calib.to_plane(c, self.height), self.marker.size)
        return (p, c) if abs(p.scale - 1) <= SCALE_TOLERANCE else None

    def moved(self, frames: Sequence[np.ndarray],
              found: Sequence[tuple[MarkerPose, np.ndarray] | None]) -> str:
        """Why the window's frames show the robot moving, or "" if they show it standing:
        consecutive sightings farther apart than ``still`` cm or ``still_deg`` degrees, or
        the image around the marker changing by more than ``still_image`` times the noise
        between consecutive frames (frames where the marker was not read count too)."""
        o = self.opts
        seen = [(k, f[0]) for k, f in enumerate(found) if f is not None]
        for (i, p), (j, q) in zip(seen, seen[1:], strict=False):
            d, dh = float(np.hypot(p.x - q.x, p.y - q.y)), abs(wrap180(p.h - q.h))
            if d > o.still or dh > o.still_deg:
                return (f"the robot moved during the window: frames {i + 1} and {j + 1} see "
                        f"it {d:.2f} cm and {dh:.1f} deg apart (still: {o.still:g} cm, "
                        f"{o.still_deg:g} deg)")
        if o.still_image > 0 and len(frames) > 1 and seen:
            pts = np.concatenate([f[1] for f in found if f is not None])
            pad = 0.25 * float(np.ptp(pts, axis=0).max())
            (x0, y0), (x1, y1) = np.floor(pts.min(0) - pad), np.ceil(pts.max(0) + pad)
            box = (int(x0), int(y0), int(x1) + 1, int(y1) + 1)
            for k in range(len(frames) - 1):
                r = image_change(frames[k], frames[k + 1], box)
                if r > o.still_image:
                    return (f"the robot moved during the window: the image around its marker "
                            f"changes between frames {k + 1} and {k + 2} ({r:.1f} times the "
                            f"noise; still: {o.still_image:g})")
        return ""

    def in_window(self, frames: Sequence[np.ndarray], ref_heading: float
                  ) -> tuple[tuple[float, float, float] | None, int, str]:
        """The median pose over the frames that show the marker and agree, its heading
        unwrapped near ``ref_heading``; the frames used; why none, if none (the marker not
        seen, or seen moving: :meth:`moved`)."""
        if not frames:
            return None, 0, f"no fresh frame within {self.opts.window:g} s (camera stalled?)"
        found = [self._marker(f) for f in frames]
        seen = [f[0] for f in found if f is not None]
        if not seen:
            return None, 0, (f"robot marker {self.marker.id} not seen in {len(frames)} "
                             "frame(s)")
        why = self.moved(frames, found)
        if why:
            return None, 0, why
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
        x0, x1, y0, _ = self.calib.layout.watched  # the area upward, or a rig's whole floor
        if not (x0 - m <= x <= x1 + m and y >= y0 - m):
            return f"robot marker seen at ({x:.1f}, {y:.1f}) cm, off the area"
        if prev is not None and np.hypot(x - prev[0], y - prev[1]) > self.opts.max_step:
            d = np.hypot(x - prev[0], y - prev[1])
            return (f"robot marker seen at ({x:.1f}, {y:.1f}) cm, {d:.0f} cm from its last "
                    f"pose (at most {self.opts.max_step:g} per gait cycle)")
        return ""


class CameraObserver:
    """Implements :class:`pac_host.robot.observers.Observer` with a frame source."""

    def __init__(self, source, calib: Calibration | None, opts: CameraOptions, name: str,
                 finder=None) -> None:
        """``finder``: what finds the pose in a window's frames (a rig's, for a rig's
        source); by default a :class:`PoseFinder` of ``calib``."""
        opts.check()
        self.source, self.opts, self.name = source, opts, name
        self.finder = finder if finder is not None else PoseFinder(calib, opts)
        self._n0 = 0
        self._run_id = ""
        self._record: Record = lambda _: None
        self._poses: list[tuple[float, float, float]] = []
        self._start: tuple[float, float, float] | None = None
        self._lost_n = 0
        self._last_lost = (0, "")
        self.sees_start = bool(getattr(source, "now", False) if opts.start is None
                               else opts.start)
        # a camera (or the virtual one) shows the robot standing again; a recording does not
        self._looks = 1 + (opts.retries if getattr(source, "now", False) else 0)

    def begin(self, run_id: str, power_on_before: int, record: Record) -> None:
        self._run_id, self._n0, self._record = run_id, power_on_before, record
        self._poses = []
        self._start = None
        self._lost_n = 0
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
        while len(self._poses) + 1 < i:
            self._gap(len(self._poses) + 1, "its CYCLE report was lost, so no frame was "
                      "taken while the robot stood")
        self._observe(i, power_on)

    def finish(self, cycles: int) -> Observation:
        if len(self._poses) == cycles - 1:  # the last CYCLE report was lost; it stands now
            self._observe(cycles, (self._n0 + cycles) % POWER_ON_MOD)
        while len(self._poses) < cycles:
            self._gap(len(self._poses) + 1, "no CYCLE report, no frame")
        poses = np.array(self._poses[:cycles], dtype=np.float64).reshape(-1, 3)
        lost = int((~np.isfinite(poses).all(axis=1)).sum())
        if too_many_lost(lost, cycles, self.opts.max_lost, final=True):
            raise ObserverError(self._too_many(lost, cycles))
        return Observation(poses=poses, start=self._start)

    def _observe(self, i: int, power_on: int) -> None:
        prev, since = self._last_seen()
        pose, why = self._look(i, power_on, power_on, prev, since)
        if why:
            self._gap(i, why)
        else:
            self._poses.append(pose)

    def _last_seen(self) -> tuple[tuple[float, float, float] | None, int]:
        """The last pose seen (the start's, if none after it) and the gait cycles since."""
        for k in range(len(self._poses) - 1, -1, -1):
            if np.all(np.isfinite(self._poses[k])):
                return self._poses[k], len(self._poses) - k
        return self._start, len(self._poses) + 1

    def _look(self, i: int, key: int | None, power_on: int,
              prev: tuple[float, float, float] | None, since: int = 1
              ) -> tuple[tuple[float, float, float] | None, str]:
        """Pose ``i`` of the run (0: its start) from the window the source gives for ``key``,
        logged if seen, checked against the last pose seen (``prev``, None: none, ``since``
        gait cycles before); else None and why not. A window that gives no pose is looked at
        again (a fresh one, the robot still standing), up to ``retries`` times."""
        ref = prev[2] if prev is not None else self.opts.heading0
        look, why = 0, "not looked"
        while why and look < self._looks:
            look += 1
            frames = self.source.window(self.opts.frames, self.opts.window, key)
            pose, used, why = self.finder.in_window(frames, ref)
            if pose is not None:
                why = self._impossible(pose, prev, since)
        if why:
            return None, why + (f" (looked {self._looks} times)" if self._looks > 1 else "")
        rec = {"type": "pose", "run_id": self._run_id, "cycle": i, "power_on": power_on,
               "pose": [round(v, 4) for v in pose], "frames": used, "observer": "camera"}
        if look > 1:
            rec["looks"] = look
        seen_by = getattr(self.finder, "last", None)  # a rig's: each camera's pose, its error
        if seen_by:
            rec["cameras"] = seen_by
        self._record(rec)
        return pose, ""

    def _impossible(self, pose: Sequence[float], prev: Sequence[float] | None,
                    since: int) -> str:
        """:meth:`PoseFinder.impossible`, the step allowed growing with the gait cycles since
        the last pose seen."""
        if since <= 1 or prev is None:
            return self.finder.impossible(pose, prev)
        why = self.finder.impossible(pose, None)
        d = float(np.hypot(pose[0] - prev[0], pose[1] - prev[1]))
        if not why and d > self.opts.max_step * since:
            why = (f"robot marker seen at ({pose[0]:.1f}, {pose[1]:.1f}) cm, {d:.0f} cm from "
                   f"its last pose seen, {since} gait cycles before (at most "
                   f"{self.opts.max_step:g} per gait cycle)")
        return why

    def _gap(self, i: int, why: str) -> None:
        """Gait cycle ``i`` not seen: logged, a NaN pose; too many so far stop the test."""
        self._record({"type": "lost", "run_id": self._run_id, "cycle": i, "why": why})
        self._poses.append((np.nan, np.nan, np.nan))
        self._lost_n += 1
        self._last_lost = (i, why)
        if too_many_lost(self._lost_n, i, self.opts.max_lost):
            raise ObserverError(self._too_many(self._lost_n, i))

    def _too_many(self, lost: int, cycles: int) -> str:
        i, why = self._last_lost
        return (f"observer {self.name}: lost observation of {lost} of {cycles} gait cycles of "
                f"run {self._run_id} (more than {self.opts.max_lost:.0%} of a test's may be "
                f"lost); the last, gait cycle {i}: {why}")

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
            val = int(v) if k in ("frames", "seed", "start", "retries") else float(v)
        except ValueError:
            raise InputError(f"camera option {k}={v!r} is not a number") from None
        out = replace(out, **{k: val})
    out.check()
    return out


def parse_rig(text: str) -> tuple[list[tuple[str, str | None]], dict[str, str]]:
    """``PART[+PART...]``, each ``SOURCE[,key=value...]``: the cameras (source, calib file or
    None) and the options they share (given in any part, one value each)."""
    cams, shared = [], {}
    for part in text.split("+"):
        source, raw = parse_spec(part)
        calib = raw.pop("calib", None)
        for k, v in raw.items():
            if shared.setdefault(k, v) != v:
                raise InputError(f"--observer camera:{text}: {k} is given as {shared[k]} and "
                                 f"{v}; the cameras of a rig share their options (give it once)")
        cams.append((source, calib))
    return cams, shared


def _sim_grid(calib: str | None, cameras: str | None) -> tuple[int, int] | None:
    """``camera:sim``'s cameras: None for the reference camera, else the rig's grid."""
    from pac_host.camera.virtual import HALL, parse_cameras

    grid = parse_cameras(cameras) if cameras is not None else None if calib else HALL
    if calib is not None and grid is not None:
        raise InputError("--observer camera:sim,calib=FILE calibrates the single reference "
                         "camera (cameras=1), not a rig")
    return grid


def check_spec(text: str, emulated: bool) -> None:
    """Refuse a ``camera:`` spec that :func:`open_camera` cannot use, opening nothing: its
    options, ``camera:sim`` without the built-in emulator (``emulated``) or joined to other
    cameras, a camera without ``calib=FILE``, a camera given twice."""
    cams, raw = parse_rig(text)
    cameras = raw.pop("cameras", None)
    options_from(raw)
    sources = [s for s, _ in cams]
    if "sim" in sources:
        if len(cams) > 1:
            raise InputError("--observer camera:sim is a whole virtual rig (cameras=1 or "
                             "COLUMNSxROWS); it joins no other camera")
        if not emulated:
            raise InputError("--observer camera:sim is the built-in emulator's virtual camera; "
                             "it does not apply with --port")
        _sim_grid(cams[0][1], cameras)
        return
    if cameras is not None:
        raise InputError("camera option cameras= is camera:sim's; a rig of real cameras joins "
                         "them with +, e.g. camera:0,calib=a.json+1,calib=b.json")
    for source, calib in cams:
        if calib is None:
            raise InputError(f"--observer camera:{source}: give calib=FILE (from `pac-host "
                             "camera calibrate`)")
    twice = sorted({s for s in sources if sources.count(s) > 1})
    if twice:
        raise InputError(f"--observer camera:{text}: camera {twice[0]} is given twice")


def open_camera(text: str, world=None) -> CameraObserver:
    """The observer a ``camera:`` spec names (several cameras joined by ``+``: a rig);
    ``world`` is the built-in emulator's world, needed by ``camera:sim``."""
    from pac_host.camera import calibrate as cal
    from pac_host.camera.sources import open_source

    check_spec(text, world is not None)
    cams, raw = parse_rig(text)
    cameras = raw.pop("cameras", None)
    opts = options_from(raw)
    name = "camera:" + "+".join(s for s, _ in cams)
    if cams[0][0] == "sim":
        calib_path = cams[0][1]
        grid = _sim_grid(calib_path, cameras)
        if grid is not None:
            from pac_host.camera.virtual import sim_rig

            return _rig(*sim_rig(world, opts, grid), opts, name)
        from pac_host.camera.virtual import sim_source

        source, calib = sim_source(world, opts, None if calib_path is None
                                   else cal.load(calib_path))
        return CameraObserver(source, calib, opts, name)
    calibs = [cal.load(c) for _, c in cams]  # every file read before a camera is opened
    if len(cams) == 1:
        return CameraObserver(open_source(cams[0][0]), calibs[0], opts, name)
    from pac_host.camera.rig import RigFinder

    names = [s for s, _ in cams]
    finder = RigFinder(calibs, opts, names)
    sources = []
    try:
        for s in names:
            sources.append(open_source(s))
    except BaseException:
        for src in sources:
            src.close()
        raise
    return _rig(sources, calibs, names, opts, name, finder)


def _rig(sources, calibs, names, opts: CameraOptions, name: str, finder=None) -> CameraObserver:
    from pac_host.camera.rig import RigFinder, RigSource

    finder = finder or RigFinder(calibs, opts, names)
    return CameraObserver(finder.attach(RigSource(sources, names)), None, opts, name, finder)
