"""Frames for the camera observer: a camera (index), a video file, a folder of images, or the
virtual camera of :mod:`pac_host.camera.render`.

``window(n, seconds, key)`` gives the frames of one listening window: from a live camera, the
frames captured after the call within ``seconds`` (at most ``n``; none if the camera stalled:
an older frame is stale and never used); from a recording, the next ``n`` frames; from the
virtual camera, ``n`` renderings of the robot at the pose ``key`` names (None: where it is now).

``now`` says whether a window shows the robot as it is when asked (a camera, the virtual one),
so a window before a run sees the robot standing at its start; a recording's frames come in
order, one window per gait cycle, and have none to spare for that.
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from pac_host.camera.render import Renderer
from pac_host.errors import InputError
from pac_host.observation import ObserverError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


class FrameBuffer:
    """The last frames of a live camera with their arrival times; a window takes only frames
    that arrived after it opened (older ones are stale)."""

    def __init__(self, keep: int = 64) -> None:
        self._frames: deque[tuple[float, np.ndarray]] = deque(maxlen=keep)
        self._cond = threading.Condition()

    def push(self, frame: np.ndarray, t: float | None = None) -> None:
        with self._cond:
            self._frames.append((time.monotonic() if t is None else t, frame))
            self._cond.notify_all()

    def window(self, n: int, seconds: float) -> list[np.ndarray]:
        """Up to ``n`` frames arriving within ``seconds`` from now (fewer if the camera is
        slow, none if it stalled)."""
        t0 = time.monotonic()
        deadline = t0 + seconds
        with self._cond:
            while True:
                fresh = [f for t, f in self._frames if t >= t0]
                rem = deadline - time.monotonic()
                if len(fresh) >= n or rem <= 0:
                    return fresh[:n]
                self._cond.wait(rem)


class CaptureSource:
    """A camera (``int`` index: live, captured in a background thread with arrival times) or a
    video file (read in order)."""

    def __init__(self, target: int | str) -> None:
        self.name = f"camera {target}" if isinstance(target, int) else f"video {target}"
        self.live = isinstance(target, int)
        self.now = self.live
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # FFmpeg's own lines too
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # one line, ours
        try:
            self._cap = cv2.VideoCapture(target)
        finally:
            cv2.utils.logging.setLogLevel(level)
        if not self._cap.isOpened():
            raise InputError(f"{self.name} cannot be opened")
        self._buffer = FrameBuffer()
        self._stop = threading.Event()
        self._thread = None
        if self.live:
            self._cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
            self._thread = threading.Thread(target=self._grab, name="pac-camera", daemon=True)
            self._thread.start()

    def _grab(self) -> None:
        while not self._stop.is_set():
            ok, frame = self._cap.read()
            if not ok:
                time.sleep(0.01)
                continue
            self._buffer.push(frame)

    def window(self, n: int, seconds: float, key: int | None = None) -> list[np.ndarray]:
        if not self.live:
            out = []
            for _ in range(n):
                ok, frame = self._cap.read()
                if not ok:
                    raise ObserverError(f"{self.name}: no frames left")
                out.append(frame)
            return out
        return self._buffer.window(n, seconds)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self._cap.release()


class FolderSource:
    """Image files of a folder in name order, ``n`` per window."""

    def __init__(self, folder: Path) -> None:
        self.name = f"folder {folder}"
        self.live = False
        self.now = False
        self._files = sorted(p for p in Path(folder).iterdir()
                             if p.suffix.lower() in IMAGE_SUFFIXES)
        if not self._files:
            raise InputError(f"{self.name} holds no images ({', '.join(IMAGE_SUFFIXES)})")
        self._next = 0

    @property
    def count(self) -> int:
        return len(self._files)

    def window(self, n: int, seconds: float, key: int | None = None) -> list[np.ndarray]:
        out = []
        for _ in range(n):
            if self._next >= len(self._files):
                raise ObserverError(f"{self.name}: no frames left after {len(self._files)}")
            p = self._files[self._next]
            self._next += 1
            img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
            if img is None:
                raise ObserverError(f"{self.name}: {p.name} is not an image")
            out.append(img)
        return out

    def close(self) -> None:
        pass


class RenderSource:
    """The virtual camera: ``pose_of(key)`` says where the robot is (None: not in view).
    Its sensor noise restarts for each run from ``seed`` and the run's id, so a run's frames
    depend on the run alone (a resumed run sees what an uninterrupted one saw).

    ``walking`` (0..1, off by default): how often the first window of a gait cycle opens
    while the robot still walks, its frames showing it ``speed`` cm apart along its heading,
    arriving at its pose with the window's last frame (a window looked at again for the same
    gait cycle shows it standing)."""

    def __init__(self, renderer: Renderer,
                 pose_of: Callable[[int | None], Sequence[float] | None],
                 seed: int = 0, walking: float = 0.0, speed: float = 0.7) -> None:
        self.name = "virtual camera"
        self.live = False
        self.now = True
        self.renderer, self.pose_of, self.seed = renderer, pose_of, seed
        self.walking, self.speed = walking, speed
        self.rng = np.random.default_rng(seed)
        self._walk_rng = np.random.default_rng([seed, 3])
        self._last_key: object = object()

    def begin_run(self, run_id: str) -> None:
        key = [self.seed, *run_id.encode()]
        self.rng = np.random.default_rng(np.random.SeedSequence(key))
        self._walk_rng = np.random.default_rng(np.random.SeedSequence([*key, 3]))
        self._last_key = object()

    def window(self, n: int, seconds: float, key: int | None = None) -> list[np.ndarray]:
        pose = self.pose_of(key)
        first, self._last_key = key != self._last_key, key
        if (pose is not None and self.walking > 0 and first
                and self._walk_rng.random() < self.walking):
            h = np.radians(pose[2])
            back = np.array([np.sin(h), np.cos(h), 0.0]) * self.speed
            return [self.renderer.frame(np.asarray(pose, dtype=np.float64) - (n - 1 - k) * back,
                                        self.rng) for k in range(n)]
        return [self.renderer.frame(pose, self.rng) for _ in range(n)]

    def close(self) -> None:
        pass


def open_source(text: str) -> CaptureSource | FolderSource:
    """A camera index (``0``), a folder of images or a video file."""
    if text.isdigit():
        return CaptureSource(int(text))
    p = Path(text)
    if p.is_dir():
        return FolderSource(p)
    if not p.exists():
        raise InputError(f"camera source {text!r}: no such camera index, folder or video file")
    return CaptureSource(str(p))
