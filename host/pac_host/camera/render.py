"""A virtual overhead camera: frames of the floor markers, the robot's marker plate at a pose
and the lens board, as a real camera would show them (perspective, lens distortion, blur,
sensor noise, uneven light). The tests' ground truth and the demo's camera; it shares the
camera model of :mod:`pac_host.camera.geometry` with the detection, nothing else.

What a real camera and a real lab add is optional (:class:`Imaging`, :class:`Printing`; all
off by default, so the reference frames stay as they were): motion blur along the robot's
motion, JPEG compression, a patchy light field, markers printed a little small and laid by
hand a few mm and a degree off their places.

Each pixel is drawn by casting its ray (through the distorted lens) onto the textured planes,
at ``supersample`` x ``supersample`` rays per pixel averaged (anti-aliasing); the robot's plate
is a plane at the marker's height above the floor, so parallax comes out as it would.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from pac_host.camera.geometry import Camera
from pac_host.camera.layout import (
    AREA_X,
    AREA_Y,
    BLOCK_CM,
    DEFAULT_LAYOUT,
    Board,
    Layout,
    dictionary,
    heading_rotation,
)

FLOOR_PPC = 8.0  # texture pixels per cm of the floor
FLOOR_MARGIN = 45.0  # floor drawn beyond the area, cm
PAPER = 245  # grey levels: printed white, printed black, the floor, tape lines
INK = 25
FLOOR = 150
TAPE = 110


@dataclass(frozen=True)
class Imaging:
    """What degrades the ideal image: Gaussian blur (pixels), sensor noise (grey levels),
    uneven light (the darkest corner's loss, 0..1); and, off by default, motion blur (the
    length in pixels of a line kernel along the robot's motion, applied to the robot's plate),
    JPEG compression at a quality (1..100; 0: none), and a smooth random gain field (patches of
    light and shade up to +-``light_field``, drawn from ``seed``)."""

    blur: float = 0.8
    noise: float = 3.0
    light: float = 0.35
    supersample: int = 2
    motion_blur: float = 0.0
    jpeg: int = 0
    light_field: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class Printing:
    """How the markers in the scene differ from the layout (which the calibration and the
    detection still believe): printed at ``scale`` times their size (a printer that shrinks
    the page), and each floor marker laid by hand off its place (normal, ``placement_cm`` sd
    per axis) and turned (``placement_deg`` sd), drawn from ``seed``."""

    scale: float = 1.0
    placement_cm: float = 0.0
    placement_deg: float = 0.0
    seed: int = 0

    def exact(self) -> bool:
        return self.scale == 1.0 and self.placement_cm == 0.0 and self.placement_deg == 0.0


def standard_camera(size: tuple[int, int] = (640, 480), height: float = 250.0,
                    dist: Sequence[float] = (-0.12, 0.03, 0.0005, -0.0005, 0.0)) -> Camera:
    """The project's reference set-up: a camera ``height`` cm above the floor, 50 cm before
    the area's middle, tilted to look at it (so the far end is foreshortened), the area's long
    side along the image's width; the focal length just fits the area and its floor markers."""
    mid = np.array([(AREA_X[0] + AREA_X[1]) / 2, (AREA_Y[0] + AREA_Y[1]) / 2, 0.0])
    center = mid + [0.0, -50.0, height]
    probe = Camera.looking_at(size, 1.0, center, mid, (0, 1, 0))
    corners = np.array([[x, y, 0.0] for x in (AREA_X[0] - 35, AREA_X[1] + 35)
                        for y in (AREA_Y[0] - 15, AREA_Y[1] + 15)])
    cam = (corners - probe.center) @ probe.R.T
    xy = np.abs(cam[:, :2] / cam[:, 2:])
    focal = min((size[0] / 2 - 4) / xy[:, 0].max(), (size[1] / 2 - 4) / xy[:, 1].max())
    return Camera.looking_at(size, focal, center, mid, (0, 1, 0), dist)


_RAYS: dict[bytes, np.ndarray] = {}  # cameras alike but for where they hang share their rays


def _dense_rays(camera: Camera, s: int, step: int = 4) -> np.ndarray:
    """The floor-frame ray of every supersampled pixel (h s, w s, 3, read-only): exact on a
    grid every ``step`` rays, interpolated between (the lens's distortion is smooth). Cameras
    of the same lens turned the same way (a rig's) share one array."""
    key = b"".join(np.ascontiguousarray(a, dtype=np.float64).tobytes()
                   for a in (camera.K, camera.dist, camera.R, camera.size, (s, step)))
    if key not in _RAYS:
        if len(_RAYS) >= 8:
            _RAYS.pop(next(iter(_RAYS)))
        rays = _rays_of(camera, s, step)
        rays.flags.writeable = False
        _RAYS[key] = rays
    return _RAYS[key]


def _rays_of(camera: Camera, s: int, step: int) -> np.ndarray:
    w, h = camera.size
    gu = np.arange(0, w * s + step, step)
    gv = np.arange(0, h * s + step, step)
    u, v = np.meshgrid((gu + 0.5) / s - 0.5, (gv + 0.5) / s - 0.5)
    coarse = camera.rays(np.column_stack([u.ravel(), v.ravel()])).reshape(
        len(gv), len(gu), 3).astype(np.float32)
    mu, mv = np.meshgrid(np.arange(w * s, dtype=np.float32) / step,
                         np.arange(h * s, dtype=np.float32) / step)
    return cv2.remap(coarse, mu, mv, cv2.INTER_LINEAR)


def _marker_image(dict_name: str, marker_id: int, px: int) -> np.ndarray:
    img = cv2.aruco.generateImageMarker(dictionary(dict_name), marker_id, px, borderBits=1)
    return np.where(img > 127, PAPER, INK).astype(np.uint8)


def _cells(dict_name: str) -> int:
    return dictionary(dict_name).markerSize + 2


def _scaled(img: np.ndarray, side: int) -> np.ndarray:
    """A marker image resampled to ``side`` pixels (a print at another scale)."""
    if side == img.shape[0]:
        return img
    return cv2.resize(img, (side, side), interpolation=cv2.INTER_AREA)


def line_kernel(length: float, direction: Sequence[float]) -> np.ndarray:
    """A normalised line kernel (motion blur): ``length`` pixels along the unit image
    ``direction`` (dx, dy), centred, its ends anti-aliased."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    half = int(np.ceil(length / 2)) + 1
    k = np.zeros((2 * half + 1, 2 * half + 1), np.float32)
    n = max(int(np.ceil(length * 8)), 1)
    for t in (np.arange(n) + 0.5) / n - 0.5:
        x, y = half + t * length * d[0], half + t * length * d[1]
        x0, y0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - x0, y - y0
        k[y0, x0] += (1 - fx) * (1 - fy)
        k[y0, x0 + 1] += fx * (1 - fy)
        k[y0 + 1, x0] += (1 - fx) * fy
        k[y0 + 1, x0 + 1] += fx * fy
    return k / k.sum()


def light_field(size: tuple[int, int], amplitude: float, seed: int) -> np.ndarray:
    """A smooth random gain field (h, w) around 1, within +-``amplitude``: a coarse grid of
    random gains interpolated (bicubic) over the image, as lamps and shade light a floor."""
    w, h = size
    grid = np.random.default_rng(seed).uniform(-1, 1, (3, 4)).astype(np.float32)
    field = cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)
    return 1 + amplitude * np.clip(field, -1, 1)


def _crop(bounds: tuple[float, float, float, float],
          view: tuple[float, float, float, float] | None, margin: float = 30.0
          ) -> tuple[float, float, float, float]:
    """``bounds`` (x0, x1, y0, y1) cut to ``view`` and a margin, in whole cm beyond it (the
    texture's pixels stay where they were, wherever it is cut)."""
    if view is None:
        return bounds
    x0, x1 = max(bounds[0], np.floor(view[0] - margin)), min(bounds[1], np.ceil(view[1] + margin))
    y0, y1 = max(bounds[2], np.floor(view[2] - margin)), min(bounds[3], np.ceil(view[3] + margin))
    if x1 - x0 < 1 or y1 - y0 < 1:  # sees none of it: a token of floor
        return bounds[0], bounds[0] + 1.0, bounds[2], bounds[2] + 1.0
    return float(x0), float(x1), float(y0), float(y1)


class Renderer:
    """Frames of one camera looking at one layout; the floor's rays are computed once."""

    def __init__(self, camera: Camera, layout: Layout = DEFAULT_LAYOUT,
                 imaging: Imaging = Imaging(), printing: Printing = Printing()) -> None:
        self.camera, self.layout, self.imaging = camera, layout, imaging
        self.printing = printing
        s = imaging.supersample
        w, h = camera.size
        self._rays = _dense_rays(camera, s)
        self._floor_tex, origin = self._floor_texture()
        mx, my = self._plane_maps(self._rays, origin, (1, 0, 0), (0, -1, 0), FLOOR_PPC)
        self._floor = cv2.remap(self._floor_tex, mx, my, cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=FLOOR
                                ).astype(np.float32)
        r = layout.robot
        cells = _cells(layout.dictionary)
        mpx = cells * max(1, round(r.size * 16 / cells))
        self._plate_ppc = mpx / r.size
        ppx = round(r.plate * self._plate_ppc)
        plate = np.full((ppx, ppx), PAPER, np.uint8)
        o = (ppx - mpx) // 2
        side = round(mpx * printing.scale)
        o = (ppx - side) // 2
        plate[o:o + side, o:o + side] = _scaled(_marker_image(layout.dictionary, r.id, mpx),
                                                side)
        self._plate_tex = plate
        yy, xx = np.mgrid[0:h, 0:w]
        rr = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
        self._light = (1 - imaging.light * (0.5 * rr + 0.5 * (xx / w))).astype(np.float32)
        if imaging.light_field > 0:
            self._light *= light_field(camera.size, imaging.light_field, imaging.seed)

    def _floor_texture(self) -> tuple[np.ndarray, tuple[float, float, float]]:
        """The floor as a picture: grey, tape on the block lines, the markers on white paper;
        the layout's watched floor and a margin, as far as this camera sees it."""
        wx0, wx1, wy0, wy1 = self.layout.watched
        x0, x1, y0, y1 = _crop((wx0 - FLOOR_MARGIN, wx1 + FLOOR_MARGIN, wy0 - FLOOR_MARGIN,
                                wy1 + FLOOR_MARGIN), self._floor_view())
        k = FLOOR_PPC
        tex = np.full((round((y1 - y0) * k), round((x1 - x0) * k)), FLOOR, np.uint8)

        def px(x: float, y: float) -> tuple[int, int]:
            return round((x - x0) * k), round((y1 - y) * k)

        ty0, ty1 = max(AREA_Y[0], wy0), max(AREA_Y[0], wy1)  # the area's blocks watched
        for bx in np.arange(AREA_X[0], AREA_X[1] + 1, BLOCK_CM):
            cv2.line(tex, px(bx, ty0), px(bx, ty1), TAPE, round(1.5 * k))
        for by in np.arange(AREA_Y[0], ty1 + 1, BLOCK_CM):
            if by >= ty0:
                cv2.line(tex, px(AREA_X[0], by), px(AREA_X[1], by), TAPE, round(1.5 * k))
        cells = _cells(self.layout.dictionary)
        if not self.printing.exact():
            self._laid_by_hand(tex, k, (x0, y1))
            return tex, (x0, y1, 0.0)
        for m in self.layout.floor:
            side = cells * max(1, round(m.size * k / cells))
            paper = round((m.size + 4) * k)
            c0, r0 = px(m.x - (m.size + 4) / 2, m.y + (m.size + 4) / 2)
            if not (0 <= c0 and 0 <= r0 and c0 + paper <= tex.shape[1]
                    and r0 + paper <= tex.shape[0]):
                continue  # beyond what this camera sees
            tex[r0:r0 + paper, c0:c0 + paper] = PAPER
            c0, r0 = px(m.x - m.size / 2, m.y + m.size / 2)
            tex[r0:r0 + side, c0:c0 + side] = _marker_image(self.layout.dictionary, m.id, side)
        return tex, (x0, y1, 0.0)

    def _laid_by_hand(self, tex: np.ndarray, k: float, corner: tuple[float, float]) -> None:
        """The floor markers on their paper as :attr:`printing` says: scaled, each shifted and
        turned by its own draw, drawn into the floor texture ``tex`` (``k`` px per cm, its
        top-left at floor point ``corner``)."""
        p = self.printing
        rng = np.random.default_rng(np.random.SeedSequence([p.seed, 2]))
        cells = _cells(self.layout.dictionary)
        for m in self.layout.floor:
            dx, dy = rng.normal(0.0, p.placement_cm, 2)
            turn = float(rng.normal(0.0, p.placement_deg))
            paper = round((m.size + 4) * k)
            mpx = cells * max(1, round(m.size * k / cells))
            side = round(mpx * p.scale)
            patch = np.full((paper, paper), PAPER, np.uint8)
            o = (paper - side) // 2
            patch[o:o + side, o:o + side] = _scaled(
                _marker_image(self.layout.dictionary, m.id, mpx), side)
            cx, cy = (m.x + dx - corner[0]) * k, (corner[1] - (m.y + dy)) * k
            # patch centre -> (cx, cy), turned clockwise on the floor by ``turn`` (compass)
            A = cv2.getRotationMatrix2D(((paper - 1) / 2, (paper - 1) / 2), -turn, 1.0)
            A[:, 2] += [cx - 0.5 - (paper - 1) / 2, cy - 0.5 - (paper - 1) / 2]
            th, tw = tex.shape
            col = cv2.warpAffine(patch.astype(np.float32), A, (tw, th), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            alpha = cv2.warpAffine(np.ones(patch.shape, np.float32), A, (tw, th),
                                   flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                   borderValue=0)
            tex[:] = np.clip(np.rint(tex * (1 - alpha) + col), 0, 255).astype(np.uint8)

    def _floor_view(self) -> tuple[float, float, float, float] | None:
        """The bounding box (x0, x1, y0, y1, cm) of the floor this camera sees, None if its
        view reaches the horizon."""
        r = self._rays[::8, ::8].reshape(-1, 3).astype(np.float64)
        c = self.camera.center
        if not np.all(r[:, 2] < 0):
            return None
        p = c[:2] - r[:, :2] * (c[2] / r[:, 2])[:, None]
        return float(p[:, 0].min()), float(p[:, 0].max()), float(p[:, 1].min()), \
            float(p[:, 1].max())

    def _plane_maps(self, rays: np.ndarray, origin, ex, ey, ppc: float
                    ) -> tuple[np.ndarray, np.ndarray]:
        """remap() maps from rays onto the plane ``origin + a ex + b ey`` (a texture with
        ``ppc`` pixels per cm, a to the right, b down); rays that miss it map outside."""
        o, ex, ey = (np.asarray(v, dtype=np.float64) for v in (origin, ex, ey))
        n = np.cross(ex, ey)
        c = self.camera.center
        denom = rays @ n.astype(np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.float32(n @ (o - c)) / denom
        hit = (c - o).astype(np.float32) + t[..., None] * rays
        a = hit @ ex.astype(np.float32)
        b = hit @ ey.astype(np.float32)
        bad = ~(t > 0)
        mx = np.where(bad, -1e6, a * ppc - 0.5).astype(np.float32)
        my = np.where(bad, -1e6, b * ppc - 0.5).astype(np.float32)
        return mx, my

    def _paste(self, img: np.ndarray, tex: np.ndarray, origin, ex, ey, ppc: float,
               box: tuple[int, int, int, int] | None = None,
               kernel: np.ndarray | None = None) -> None:
        """Draw the textured plane over ``img`` (supersampled, float) within ``box``; with a
        ``kernel``, the plane moving (its colour and coverage smeared by it: motion blur)."""
        y0, y1, x0, x1 = box if box is not None else (0, img.shape[0], 0, img.shape[1])
        if y1 <= y0 or x1 <= x0:
            return
        mx, my = self._plane_maps(self._rays[y0:y1, x0:x1], origin, ex, ey, ppc)
        kw = {"borderMode": cv2.BORDER_CONSTANT, "borderValue": 0}
        col = cv2.remap(tex.astype(np.float32), mx, my, cv2.INTER_LINEAR, **kw)
        alpha = cv2.remap(np.ones(tex.shape, np.float32), mx, my, cv2.INTER_LINEAR, **kw)
        if kernel is not None:
            col = cv2.filter2D(col, -1, kernel, borderType=cv2.BORDER_CONSTANT)
            alpha = cv2.filter2D(alpha, -1, kernel, borderType=cv2.BORDER_CONSTANT)
        sub = img[y0:y1, x0:x1]
        sub *= 1 - alpha
        sub += col

    def _finish(self, ideal: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        im = self.imaging
        w, h = self.camera.size
        img = cv2.resize(ideal, (w, h), interpolation=cv2.INTER_AREA) * self._light
        if im.blur > 0:
            img = cv2.GaussianBlur(img, (0, 0), im.blur)
        if rng is not None and im.noise > 0:
            img += rng.normal(0.0, im.noise, img.shape).astype(np.float32)
        out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        if im.jpeg > 0:
            ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(im.jpeg)])
            out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE) if ok else out
        return out

    def _motion_kernel(self, centre: np.ndarray, compass: float) -> np.ndarray | None:
        """The supersampled line kernel of the motion blur for a plate moving along compass
        heading ``compass`` at floor-frame point ``centre`` (None: no motion blur)."""
        length = self.imaging.motion_blur * self.imaging.supersample
        if length <= 0:
            return None
        h = np.radians(compass)
        ends = self.camera.project(np.stack([centre, centre + [np.sin(h), np.cos(h), 0.0]]))
        d = ends[1] - ends[0]
        return line_kernel(length, d) if np.linalg.norm(d) > 1e-9 else None

    def frame(self, pose: Sequence[float] | None, rng: np.random.Generator | None = None,
              motion: float | None = None) -> np.ndarray:
        """A grey frame with the robot's marker plate centred at ``pose`` (x, y, compass h)
        at its height; None draws the floor alone. ``rng`` draws the sensor noise. With
        motion blur (:class:`Imaging`), the plate is smeared along compass heading ``motion``
        (default: the robot's heading, the way it walks)."""
        img = self._floor.copy()
        if pose is not None:
            r = self.layout.robot
            x, y, h = (float(v) for v in pose)
            rot = heading_rotation(h)
            ex = np.append(rot[:, 0], 0.0)
            ey = -np.append(rot[:, 1], 0.0)
            half = r.plate / 2
            origin = np.array([x, y, r.height]) - half * (ex + ey)
            corners = np.array([origin + a * ex + b * ey for a in (0, r.plate)
                                for b in (0, r.plate)])
            px = self.camera.project(corners) * self.imaging.supersample
            kernel = self._motion_kernel(np.array([x, y, r.height]),
                                         h if motion is None else float(motion))
            pad = 4 + (0 if kernel is None else kernel.shape[0])
            hs, ws = self._rays.shape[:2]
            lo = np.floor(px.min(axis=0)).astype(int) - pad
            hi = np.ceil(px.max(axis=0)).astype(int) + pad
            box = (max(lo[1], 0), min(hi[1], hs), max(lo[0], 0), min(hi[0], ws))
            self._paste(img, self._plate_tex, origin, ex, ey, self._plate_ppc, box, kernel)
        return self._finish(img, rng)

    def board_frame(self, board: Board, rvec: Sequence[float], tvec: Sequence[float],
                    rng: np.random.Generator | None = None) -> np.ndarray:
        """A frame of the lens board held in front of the camera: its top-left corner at
        camera-frame point ``tvec`` (cm), turned by the Rodrigues vector ``rvec``."""
        R = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))[0]
        cam = self.camera
        to_floor = cam.R.T
        origin = to_floor @ np.asarray(tvec, dtype=np.float64) + cam.center
        ex, ey = to_floor @ R[:, 0], to_floor @ R[:, 1]
        cols, rows = board.squares
        ppc = 20.0
        tex = board.charuco().generateImage((round(cols * board.square * ppc),
                                             round(rows * board.square * ppc)), marginSize=0)
        tex = np.where(tex > 127, PAPER, INK).astype(np.uint8)
        img = self._floor.copy()
        self._paste(img, tex, origin, ex, ey, ppc)
        return self._finish(img, rng)


def random_walk(n: int, rng: np.random.Generator,
                start: tuple[float, float] = (90.0, 150.0), step: float = 10.0,
                turn: float = 30.0, edge: float = 8.0) -> np.ndarray:
    """A robot's random walk of ``n`` gait cycles over the area, for rendering a run: from
    ``start`` (x, y cm) at a random heading, each gait cycle turns by up to ``turn`` degrees
    either way and walks ``step`` cm; a step that would come closer than ``edge`` cm to the
    area's edges is walked the other way instead (the walk bounces off them).

    Draws one uniform heading from ``rng`` and one uniform turn per gait cycle, in that
    order. Returns the pose after each gait cycle, (n, 3): x, y cm and compass heading (deg,
    unwrapped: the sum of the turns)."""
    x, y = (float(v) for v in start)
    h = float(rng.uniform(-180, 180))
    out = []
    for _ in range(n):
        h += float(rng.uniform(-turn, turn))
        nx, ny = x + step * np.sin(np.radians(h)), y + step * np.cos(np.radians(h))
        if not (AREA_X[0] + edge <= nx <= AREA_X[1] - edge
                and AREA_Y[0] + edge <= ny <= AREA_Y[1] - edge):
            h += 180.0
            nx, ny = x + step * np.sin(np.radians(h)), y + step * np.cos(np.radians(h))
        x, y = nx, ny
        out.append((x, y, h))
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def board_poses(camera: Camera, board: Board, n: int, rng: np.random.Generator,
                distance: tuple[float, float] = (35.0, 65.0), spread: float = 0.6
                ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` poses (rvec, tvec) of the lens board held ``distance`` cm (35..65) before the
    camera, tilted up to 35 degrees, its centre over the middle ``spread`` of the view's width
    and height (as a person would wave it)."""
    w, h = camera.size
    K = camera.K
    bw, bh = board.squares[0] * board.square, board.squares[1] * board.square
    lo, hi = (1 - spread) / 2, (1 + spread) / 2
    out = []
    for _ in range(n):
        z = rng.uniform(*distance)
        u, v = rng.uniform(lo * w, hi * w), rng.uniform(lo * h, hi * h)
        centre = np.array([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
        rvec = rng.uniform(-1, 1, 3) * np.radians([35, 35, 20])
        R = cv2.Rodrigues(rvec)[0]
        out.append((rvec, centre - R @ [bw / 2, bh / 2, 0.0]))
    return out
