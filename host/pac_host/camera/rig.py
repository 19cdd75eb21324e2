"""Several cameras calibrated to the one floor frame (a rig): the robot's pose from each camera
that sees it, fused where views overlap, handed over where they do not.

Each camera has its own calibration file, made by ``camera calibrate`` from the floor markers
of one layout, so every camera gives poses in the same floor frame. In each listening window
the rig takes the frames of the cameras that can see the robot (those whose view comes within
a gait cycle's reach, ``max_step``, of its last pose; before a run, those near the start
pose), finds the robot's marker in each camera's frames as a single camera does
(:class:`PoseFinder`), and

- seen by one camera: that camera's pose (a hand-over from camera to camera needs no more);
- seen by several: their weighted mean, each weighted by the inverse square of its expected
  error at that point (its calibration's error map), the headings averaged on the circle;
  cameras that disagree by more than ``spread`` cm (or :data:`HEADING_AGREE` degrees) make the
  observation lost (a camera moved?), never a compromise;
- seen by none of the cameras near: the others are looked at too (a pose found there is too
  far from the last one, which the observer reports); seen by none at all: lost.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from pac_host.camera.calibrate import Calibration
from pac_host.camera.observer import CameraOptions, PoseFinder, wrap180
from pac_host.coverage import START_POSE
from pac_host.errors import InputError

HEADING_AGREE = 10.0  # deg: cameras whose headings differ more than this disagree

Frames = list  # per camera: its window's frames, or None where none were taken


class ExpectedError:
    """A calibration's expected position error (cm) at a floor point: its error map
    interpolated (bilinear over the grid points where the marker is in view), the map's worst
    where none is; without a map, the floor's fit error."""

    def __init__(self, calib: Calibration) -> None:
        m = calib.error_map
        self.fallback = max(float(calib.floor_error_cm["rms"]), 0.05)
        self.xs = self.ys = self.z = None
        if m is not None:
            z = np.array([[np.nan if v is None else float(v) for v in row]
                          for row in m["error_cm"]], dtype=np.float64)
            if np.isfinite(z).any():
                self.xs, self.ys, self.z = (np.asarray(m["x_cm"], dtype=np.float64),
                                            np.asarray(m["y_cm"], dtype=np.float64), z)
                self.fallback = float(np.nanmax(z))

    def __call__(self, x: float, y: float) -> float:
        if self.z is None:
            return self.fallback
        i = int(np.clip(np.searchsorted(self.xs, x) - 1, 0, max(len(self.xs) - 2, 0)))
        j = int(np.clip(np.searchsorted(self.ys, y) - 1, 0, max(len(self.ys) - 2, 0)))
        i1, j1 = min(i + 1, len(self.xs) - 1), min(j + 1, len(self.ys) - 1)
        tx = 0.0 if i1 == i else float(np.clip((x - self.xs[i]) / (self.xs[i1] - self.xs[i]),
                                               0, 1))
        ty = 0.0 if j1 == j else float(np.clip((y - self.ys[j]) / (self.ys[j1] - self.ys[j]),
                                               0, 1))
        v = np.array([self.z[j, i], self.z[j, i1], self.z[j1, i], self.z[j1, i1]])
        w = np.array([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty])
        ok = np.isfinite(v) & (w > 0)
        if not ok.any():
            return self.fallback
        return float((v[ok] * w[ok]).sum() / w[ok].sum())


def fuse(poses: Sequence[Sequence[float]], sigmas: Sequence[float], ref_heading: float
         ) -> tuple[float, float, float]:
    """The weighted mean (weights 1 / sigma^2) of poses (x, y, heading deg), the headings
    averaged on the circle and unwrapped near ``ref_heading``."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    w = 1.0 / np.maximum(np.asarray(sigmas, dtype=np.float64), 1e-6) ** 2
    x, y = (w[:, None] * p[:, :2]).sum(0) / w.sum()
    h = np.radians(p[:, 2])
    mean = float(np.degrees(np.arctan2((w * np.sin(h)).sum(), (w * np.cos(h)).sum())))
    return float(x), float(y), ref_heading + wrap180(mean - ref_heading)


def view_outline(calib: Calibration, height: float, per_side: int = 16) -> np.ndarray:
    """The floor-frame outline (n, 1, 2, float32) of what the camera sees on the plane
    ``height`` cm up: its image's border through the calibration."""
    w, h = calib.size
    t = np.linspace(0, 1, per_side, endpoint=False)
    border = np.concatenate([np.column_stack([t * (w - 1), np.zeros_like(t)]),
                             np.column_stack([np.full_like(t, w - 1), t * (h - 1)]),
                             np.column_stack([(1 - t) * (w - 1), np.full_like(t, h - 1)]),
                             np.column_stack([np.zeros_like(t), (1 - t) * (h - 1)])])
    return calib.to_plane(border, height).astype(np.float32).reshape(-1, 1, 2)


class RigSource:
    """The frames of several sources, window by window. A window takes frames from the
    cameras in :attr:`wanted` (None: all), and always from a recording (its frames go in
    order, one window each, so it is read whether looked at or not). Live cameras are read
    at once, each in its own thread (their windows are the same 0.1 s)."""

    def __init__(self, sources: Sequence, names: Sequence[str]) -> None:
        self.sources, self.names = list(sources), list(names)
        self.name = "rig of " + ", ".join(getattr(s, "name", str(n))
                                          for s, n in zip(self.sources, self.names, strict=True))
        self.live = any(getattr(s, "live", False) for s in self.sources)
        self.now = all(getattr(s, "now", False) for s in self.sources)
        self.first: frozenset[int] | None = None  # the cameras looked at before a run
        self.wanted: frozenset[int] | None = None
        self._last: tuple = (1, 0.1, None)

    def begin_run(self, run_id: str) -> None:
        for s in self.sources:
            if hasattr(s, "begin_run"):
                s.begin_run(run_id)
        self.wanted = self.first

    def window(self, n: int, seconds: float, key: int | None = None) -> Frames:
        self._last = (n, seconds, key)
        take = [k for k, s in enumerate(self.sources)
                if self.wanted is None or k in self.wanted or not getattr(s, "now", False)]
        return self._take(take, [None] * len(self.sources))

    def rest(self, frames: Frames) -> Frames:
        """``frames`` with the cameras the last window skipped taken too (their frames now)."""
        return self._take([k for k, f in enumerate(frames) if f is None], list(frames))

    def _take(self, take: Sequence[int], out: Frames) -> Frames:
        n, seconds, key = self._last
        live = [k for k in take if getattr(self.sources[k], "live", False)]
        if len(live) > 1:
            with ThreadPoolExecutor(len(live)) as pool:
                got = {k: pool.submit(self.sources[k].window, n, seconds, key) for k in live}
                for k, f in got.items():
                    out[k] = f.result()
        for k in take:
            if out[k] is None:
                out[k] = self.sources[k].window(n, seconds, key)
        return out

    def close(self) -> None:
        for s in self.sources:
            s.close()


class RigFinder:
    """The robot's pose in one window of a rig's frames (the interface of
    :class:`PoseFinder`): each camera's pose, fused or handed over."""

    def __init__(self, calibs: Sequence[Calibration], opts: CameraOptions,
                 names: Sequence[str]) -> None:
        if len(calibs) < 2:
            raise InputError("a rig needs two cameras or more")
        first = calibs[0].layout
        for name, c in zip(names[1:], calibs[1:], strict=True):
            if c.layout != first:
                raise InputError(f"camera {name}'s calibration has another marker layout than "
                                 f"camera {names[0]}'s: calibrate every camera of a rig with "
                                 "the same --layout")
        self.opts, self.names = opts, list(names)
        self.source: RigSource | None = None
        self.finders = [PoseFinder(c, opts) for c in calibs]
        self.calib = calibs[0]
        self.marker = self.finders[0].marker
        self.height = self.finders[0].height
        self.errors = [ExpectedError(c) for c in calibs]
        self.views = [view_outline(c, self.height) for c in calibs]
        self.last: dict = {}  # the last pose's cameras: name -> [x, y, h, expected error]

    def attach(self, source: RigSource) -> RigSource:
        """Choose ``source``'s cameras window by window: before a run those near the start
        pose, then those near the last pose seen."""
        self.source = source
        source.first = self.near(START_POSE[:2])
        return source

    def near(self, xy: Sequence[float]) -> frozenset[int]:
        """The cameras that could see the marker whole once it has moved ``max_step`` from
        the floor point ``xy``: its plate (half its side at least from the view's edge) then
        inside their view."""
        pt = (float(xy[0]), float(xy[1]))
        reach = self.opts.max_step - self.marker.plate / 2
        return frozenset(k for k, v in enumerate(self.views)
                         if cv2.pointPolygonTest(v, pt, True) >= -reach)

    def in_window(self, frames: Frames, ref_heading: float
                  ) -> tuple[tuple[float, float, float] | None, int, str]:
        pose, used, why = self._fused(frames, ref_heading)
        if pose is None and self.source is not None and any(f is None for f in frames):
            frames = self.source.rest(frames)  # seen by none of those near: look everywhere
            pose, used, why = self._fused(frames, ref_heading)
        if pose is not None and self.source is not None:
            self.source.wanted = self.near(pose)
        return pose, used, why

    def _fused(self, frames: Frames, ref: float
               ) -> tuple[tuple[float, float, float] | None, int, str]:
        self.last = {}
        looked = [k for k, f in enumerate(frames) if f is not None]
        res = {k: self.finders[k].in_window(frames[k], ref) for k in looked}
        seen = [k for k in looked if res[k][0] is not None]
        if not seen:
            return None, 0, self._unseen(looked, res)
        poses = [res[k][0] for k in seen]
        sig = [self.errors[k](p[0], p[1]) for k, p in zip(seen, poses, strict=True)]
        for a in range(len(seen)):
            for b in range(a + 1, len(seen)):
                d = float(np.hypot(poses[a][0] - poses[b][0], poses[a][1] - poses[b][1]))
                dh = abs(wrap180(poses[a][2] - poses[b][2]))
                if d > self.opts.spread or dh > HEADING_AGREE:
                    return None, 0, (
                        f"cameras {self.names[seen[a]]} and {self.names[seen[b]]} see robot "
                        f"marker {self.marker.id} {d:.1f} cm and {dh:.1f} deg apart (more than "
                        f"{self.opts.spread:g} cm or {HEADING_AGREE:g} deg: has a camera "
                        "moved? calibrate it again)")
        self.last = {self.names[k]: [round(v, 4) for v in (*p, s)]
                     for k, p, s in zip(seen, poses, sig, strict=True)}
        return fuse(poses, sig, ref), int(sum(res[k][1] for k in seen)), ""

    def _unseen(self, looked: Sequence[int], res: dict) -> str:
        if not looked:
            return "no camera looked (none near)"
        whys = {res[k][2] for k in looked}
        if len(whys) == 1:
            names = ", ".join(self.names[k] for k in looked)
            return f"{whys.pop()} of camera(s) {names}"
        return "; ".join(f"camera {self.names[k]}: {res[k][2]}" for k in looked)

    def impossible(self, pose: Sequence[float], prev: Sequence[float] | None) -> str:
        return self.finders[0].impossible(pose, prev)
