"""How many cameras a floor needs, where they hang and how big the robot's marker must be: a
rig planned from a webcam's image size and field of view, its height and the floor to watch.

A camera looking straight down from ``height`` cm with a focal length of ``f`` pixels sees,
on a plane ``z`` cm up, ``(height - z) / f`` cm per pixel: its image of w x h pixels covers
``w (height - z) / f`` by ``h (height - z) / f`` cm there (its footprint; the field of view
is ``2 atan(w / 2f)``). The robot's marker is seen whole where its plate, turned any way, lies
inside the footprint at the marker's height: there its centre may be anywhere but the
plate's half diagonal from the edge. Cameras hang in a grid, each image's width along y (the
area's long side), neighbours' marker regions overlapping by at least ``overlap`` cm, so the
marker is always seen whole by one camera and, where two see it, by both (the rig fuses
them). A lens's barrel distortion widens the view a little and shrinks the image's edges:
the plan is on the safe side for the view, and asks :data:`MARKER_PX` pixels of the marker
to leave room for the shrinking.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pac_host.camera.geometry import Camera
from pac_host.camera.layout import (
    AREA_X,
    AREA_Y,
    MARKER_SPACING,
    Layout,
    RobotMarker,
    default_floor,
    dictionary_for,
    grid_floor,
)
from pac_host.camera.sheets import MARKER_PX  # one definition: what `camera sheets` asks
from pac_host.errors import InputError

WEBCAM_SIZE = (640, 480)
WEBCAM_FOV = 75.0  # deg, horizontal: a common webcam's
HEIGHT = 250.0  # cm: a ceiling, or a boom on a stand
OVERLAP = 40.0  # cm: at least, between neighbours' marker regions (3 gait cycles' steps)
PAPER = 2.0  # cm of white margin around a floor marker
SIDE_MARGIN = 10.0  # cm between the area's long side and a floor marker beside it
ROBOT = RobotMarker()


def fov_deg(focal: float, pixels: float) -> float:
    """The field of view (deg) across ``pixels`` of a focal length (pixels)."""
    return math.degrees(2 * math.atan(pixels / 2 / focal))


def focal_px(fov: float, pixels: float) -> float:
    """The focal length (pixels) with a field of view of ``fov`` deg across ``pixels``."""
    return pixels / 2 / math.tan(math.radians(fov) / 2)


def footprint(size: tuple[int, int], focal: float, distance: float) -> tuple[float, float]:
    """The cm an image of ``size`` (w, h pixels) covers on a plane ``distance`` cm below the
    lens, looking straight down: (w, h) x distance / focal."""
    return size[0] * distance / focal, size[1] * distance / focal


def _axis(lo: float, hi: float, seen: float, overlap: float) -> tuple[float, ...]:
    """Centres of the fewest cameras whose ``seen`` cm, overlapping by ``overlap`` at least,
    cover lo..hi, evenly spaced."""
    if hi - lo <= seen:
        return ((lo + hi) / 2,)
    if seen <= overlap:
        raise InputError(f"a camera sees the marker over {seen:.0f} cm, not more than the "
                         f"{overlap:g} cm overlap asked: hang the cameras higher or use a "
                         "wider lens")
    n = math.ceil((hi - lo - overlap) / (seen - overlap) - 1e-9)
    step = (hi - lo - seen) / (n - 1)
    return tuple(lo + seen / 2 + i * step for i in range(n))


@dataclass(frozen=True)
class RigPlan:
    """Cameras hung straight down at ``height`` over the floor ``watched`` (x0, x1, y0, y1:
    where the robot marker's centre must be seen), at the centres ``xs`` x ``ys``."""

    watched: tuple[float, float, float, float]
    size: tuple[int, int]
    focal: float
    height: float
    overlap: float
    marker: RobotMarker
    xs: tuple[float, ...]
    ys: tuple[float, ...]

    @property
    def cameras(self) -> int:
        return len(self.xs) * len(self.ys)

    @property
    def fov(self) -> tuple[float, float]:
        """The horizontal and vertical fields of view (deg)."""
        return fov_deg(self.focal, self.size[0]), fov_deg(self.focal, self.size[1])

    def footprint(self, z: float = 0.0) -> tuple[float, float]:
        """(across x, along y) cm a camera sees on a plane ``z`` cm up (the image's width lies
        along y)."""
        along, across = footprint(self.size, self.focal, self.height - z)
        return across, along

    @property
    def seen(self) -> tuple[float, float]:
        """(across, along) cm over which one camera sees the marker whole (its centre)."""
        fx, fy = self.footprint(self.marker.height)
        d = self.marker.plate * math.sqrt(2)
        return fx - d, fy - d

    @property
    def overlaps(self) -> tuple[float | None, float | None]:
        """How far neighbours' marker regions overlap (cm; None: no neighbour that way)."""
        sx, sy = self.seen
        return tuple(None if len(c) < 2 else s - (c[1] - c[0])
                     for s, c in ((sx, self.xs), (sy, self.ys)))

    @property
    def px_per_cm(self) -> float:
        """Pixels per cm at the marker's height (the same over a straight-down view)."""
        return self.focal / (self.height - self.marker.height)

    @property
    def marker_px(self) -> float:
        return self.marker.size * self.px_per_cm

    @property
    def marker_needed(self) -> int:
        """The smallest whole-cm marker side that spans :data:`MARKER_PX` pixels."""
        return math.ceil(MARKER_PX / self.px_per_cm - 1e-9)

    def centres(self) -> list[tuple[float, float]]:
        """The cameras' (x, y), row by row from the lowest y."""
        return [(x, y) for y in self.ys for x in self.xs]

    def camera(self, i: int, dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> Camera:
        """Camera ``i`` (of :meth:`centres`) as the geometry's pinhole, looking straight
        down, its image's width along +y."""
        x, y = self.centres()[i]
        return Camera.looking_at(self.size, self.focal, (x, y, self.height), (x, y, 0.0),
                                 (0.0, 1.0, 0.0), dist)

    def layout(self) -> Layout:
        """The floor markers for this rig: beside the area's long sides (the robot never
        covers them), rows :data:`MARKER_SPACING` apart at most, when one row of cameras
        along the area sees them; else on a lattice over the watched floor, 2.5 to a camera's
        narrower view."""
        size = 12.0
        if len(self.xs) == 1 and self.sees_beside(size):
            floor = default_floor(size, SIDE_MARGIN, self.watched[2:], MARKER_SPACING)
        else:
            floor = grid_floor(self.watched, min(self.footprint(0.0)) / 2.5, size)
        return Layout(floor, self.marker, dictionary_for(len(floor) + 1), self.watched)

    def sees_beside(self, size: float = 12.0) -> bool:
        """Whether a camera over the area's middle sees the floor markers beside it (their
        paper) with room to spare."""
        half = self.footprint(0.0)[0] / 2
        need = (AREA_X[1] - AREA_X[0]) / 2 + SIDE_MARGIN + size + PAPER
        return half >= need + 5.0 and abs(self.xs[0] - sum(AREA_X) / 2) <= half - need - 5.0

    def markers_seen(self, layout: Layout) -> int:
        """The fewest floor markers (with their paper) any one camera sees whole."""
        fx, fy = self.footprint(0.0)
        least = None
        for x, y in self.centres():
            n = sum(abs(m.x - x) + m.size / 2 + PAPER <= fx / 2
                    and abs(m.y - y) + m.size / 2 + PAPER <= fy / 2 for m in layout.floor)
            least = n if least is None else min(least, n)
        return int(least or 0)

    def lines(self, layout: Layout | None = None) -> list[str]:
        """The plan in a few lines (the `camera layout` command prints them)."""
        layout = layout or self.layout()
        x0, x1, y0, y1 = self.watched
        fx, fy = self.footprint(0.0)
        sx, sy = self.seen
        ox, oy = self.overlaps
        hf, vf = self.fov
        over = " and ".join(f"{o:.0f} cm {w}" for o, w in ((oy, "along y"), (ox, "across x"))
                            if o is not None) or "none (one camera)"
        return [
            f"floor watched: x {x0:g}..{x1:g} cm, y {y0:g}..{y1:g} cm "
            f"({x1 - x0:g} x {y1 - y0:g} cm)",
            f"cameras: {self.cameras} ({len(self.xs)} across x {len(self.ys)} along y), "
            f"{self.height / 100:g} m up, looking straight down, the image's width along y",
            f"each: {self.size[0]}x{self.size[1]} px, {hf:.0f} x {vf:.0f} deg field of view "
            f"(focal {self.focal:.0f} px); sees {fy:.0f} x {fx:.0f} cm of floor, the robot's "
            f"marker whole over {sy:.0f} x {sx:.0f} cm",
            "centres (x, y) cm: " + ", ".join(f"({x:.0f}, {y:.0f})" for x, y in self.centres()),
            f"overlap of neighbours' views of the marker: {over}",
            f"robot marker: {self.marker.size:g} cm is {self.marker_px:.0f} px across "
            f"({self.px_per_cm:.2f} px/cm at its height); at least {self.marker_needed} cm "
            f"for {MARKER_PX} px",
            f"floor markers: {len(layout.floor)} ({layout.dictionary}), each camera sees "
            f"{self.markers_seen(layout)} or more",
        ]


def plan_rig(watched: tuple[float, float, float, float], height: float = HEIGHT,
             size: tuple[int, int] = WEBCAM_SIZE, focal: float | None = None,
             fov: float = WEBCAM_FOV, overlap: float = OVERLAP,
             marker: RobotMarker = ROBOT) -> RigPlan:
    """The fewest cameras (``size`` pixels, ``focal`` px or else a horizontal field of view
    of ``fov`` deg) hung ``height`` cm up, straight down, that see the robot's marker whole
    with its centre anywhere on ``watched`` (x0, x1, y0, y1 cm)."""
    x0, x1, y0, y1 = (float(v) for v in watched)
    if not (x0 < x1 and y0 < y1):
        raise InputError(f"the floor to watch must have x0 < x1 and y0 < y1, got {watched}")
    if not height > marker.height + 1:
        raise InputError(f"the cameras ({height:g} cm up) must hang above the robot's marker "
                         f"({marker.height:g} cm up)")
    if overlap < 0:
        raise InputError(f"the overlap must be >= 0 cm, got {overlap:g}")
    if focal is None:
        if not 10 <= fov <= 170:
            raise InputError(f"a field of view of {fov:g} deg is not a webcam's (10-170)")
        focal = focal_px(fov, size[0])
    probe = RigPlan((x0, x1, y0, y1), size, float(focal), float(height), float(overlap),
                    marker, (0.0,), (0.0,))
    sx, sy = probe.seen
    if min(sx, sy) <= 0:
        raise InputError(f"a camera {height:g} cm up sees {sy:.0f} x {sx:.0f} cm at the "
                         "marker's height, less than the marker's plate: hang it higher")
    return RigPlan((x0, x1, y0, y1), size, float(focal), float(height), float(overlap),
                   marker, _axis(x0, x1, sx, overlap), _axis(y0, y1, sy, overlap))


def grid_watched(columns: int, rows: int, origin: tuple[float, float], height: float = HEIGHT,
                 size: tuple[int, int] = WEBCAM_SIZE, focal: float | None = None,
                 overlap: float = OVERLAP, marker: RobotMarker = ROBOT
                 ) -> tuple[float, float, float, float]:
    """The floor (x0, x1, y0, y1) a grid of ``columns`` x ``rows`` cameras watches from
    ``origin`` (its lowest x and y), neighbours overlapping by ``overlap``: what
    :func:`plan_rig` plans that grid for."""
    if columns < 1 or rows < 1:
        raise InputError(f"a rig needs at least one camera each way, got {columns}x{rows}")
    probe = plan_rig((0.0, 1.0, 0.0, 1.0), height, size, focal, overlap=overlap, marker=marker)
    sx, sy = probe.seen
    x0, y0 = origin
    # a hair less than the grid covers, so that planning it again gives this grid
    return (x0, x0 + columns * sx - (columns - 1) * overlap - 1e-6,
            y0, y0 + rows * sy - (rows - 1) * overlap - 1e-6)


def strip_plan(length: float, **kw) -> RigPlan:
    """The plan for the area's first ``length`` cm (180 cm wide)."""
    if not length > 0:
        raise InputError(f"--length must be > 0 cm, got {length:g}")
    return plan_rig((AREA_X[0], AREA_X[1], AREA_Y[0], AREA_Y[0] + length), **kw)


def view_corners(plan: RigPlan, i: int, z: float = 0.0) -> np.ndarray:
    """Camera ``i``'s footprint on the plane ``z`` cm up (4, 2), through the geometry's own
    pinhole (a check on :meth:`RigPlan.footprint`)."""
    cam = plan.camera(i)
    w, h = plan.size
    px = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    r = cam.rays(px)
    t = (z - cam.center[2]) / r[:, 2]
    return cam.center[:2] + r[:, :2] * t[:, None]
