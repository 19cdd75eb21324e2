"""The built-in emulator seen through virtual cameras (``--observer camera:sim``), each
calibrated the way a user calibrates a real one (lens board images, then the floor markers),
rendering the emulated robot at the pose its world recorded for each gait cycle:

- ``cameras=1``: the reference set-up of :func:`pac_host.camera.render.standard_camera`
  (one camera, the area's first 300 cm);
- ``cameras=CxR`` (by default :data:`HALL`): a rig of C x R such webcams hung straight down
  2.5 m up (:mod:`pac_host.camera.plan`), from :data:`HALL_ORIGIN` up and to the right, over
  the floor a default ``evolve`` walks (its first, untrained tests included), the floor
  markers on a lattice over it. The cameras share the reference webcam's lens (calibrated
  once); each camera's floor is calibrated from its own frames.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pac_host.camera.calibrate import Calibration, calibrate_floor, calibrate_lens
from pac_host.camera.layout import Board, Layout
from pac_host.camera.plan import RigPlan, grid_watched, plan_rig
from pac_host.camera.render import Imaging, Renderer, board_poses, standard_camera
from pac_host.camera.sources import RenderSource
from pac_host.errors import InputError

LENS_IMAGES = 10
# the virtual rig's grid (columns across x, rows along y) and its lowest corner (cm): 12
# webcams over x -20..648, y 0..1239, where a default run's robot walks (seed 0: its untrained
# first tests to x 627, y 1214; its later sweeps within x -3..173, y 30..870)
HALL = (3, 4)
HALL_ORIGIN = (-20.0, 0.0)
KEEP_RENDERERS = 6  # a virtual rig keeps this many cameras' renderers (about 15 MB each)
_RIGS: dict[tuple, tuple[Renderer, Calibration]] = {}  # the same camera calibrates the same


def calibrate_virtual(renderer: Renderer, rng: np.random.Generator,
                      images: int = LENS_IMAGES, floor_frames: int = 3) -> Calibration:
    """Calibrate the virtual camera from its own frames: lens from board views, then floor."""
    board = Board()
    lens = calibrate_lens(renderer.board_frame(board, *p, rng)
                          for p in board_poses(renderer.camera, board, images, rng))
    return calibrate_floor([renderer.frame(None, rng) for _ in range(floor_frames)],
                           renderer.layout, lens)


def reference_rig(noise: float = 3.0, seed: int = 0) -> tuple[Renderer, Calibration]:
    """The reference camera's renderer and its calibration (made once per process)."""
    key = (float(noise), int(seed))
    if key not in _RIGS:
        renderer = Renderer(standard_camera(), Layout(), Imaging(noise=noise))
        rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
        _RIGS[key] = renderer, calibrate_virtual(renderer, rng)
    return _RIGS[key]


def world_pose(world, key: int | None) -> Sequence[float]:
    """The true pose after the gait cycle with power-on count ``key`` (the latest such), or
    the current pose."""
    if key is not None:
        for s in reversed(world.history):
            if s.power_on == key and s.gait >= 0:
                return s.true_pose
    return tuple(float(v) for v in world.pose)


def sim_source(world, opts, calib: Calibration | None = None
               ) -> tuple[RenderSource, Calibration]:
    renderer, own = reference_rig(opts.noise, opts.seed)
    return RenderSource(renderer, lambda key: world_pose(world, key), opts.seed), calib or own


def parse_cameras(text: str) -> tuple[int, int] | None:
    """``cameras=``: ``1`` (None: the reference camera) or ``CxR`` (a rig's grid)."""
    t = text.strip().lower()
    if t == "1":
        return None
    c, sep, r = t.partition("x")
    if not (sep and c.isdigit() and r.isdigit() and int(c) >= 1 and int(r) >= 1
            and int(c) * int(r) >= 2 and int(c) * int(r) <= 64):
        raise InputError(f"camera option cameras={text!r}: expected 1 (the reference camera) "
                         f"or COLUMNSxROWS (a rig of 2 to 64, e.g. {HALL[0]}x{HALL[1]})")
    return int(c), int(r)


@dataclass
class VirtualRig:
    """A grid of virtual webcams over one floor, each calibrated from its own frames; their
    renderers made when needed (the last :data:`KEEP_RENDERERS` kept)."""

    plan: RigPlan
    layout: Layout
    imaging: Imaging
    calibrations: list[Calibration] = field(default_factory=list)
    _renderers: OrderedDict = field(default_factory=OrderedDict)

    def renderer(self, i: int) -> Renderer:
        if i in self._renderers:
            self._renderers.move_to_end(i)
        else:
            dist = standard_camera().dist
            self._renderers[i] = Renderer(self.plan.camera(i, dist), self.layout, self.imaging)
            while len(self._renderers) > KEEP_RENDERERS:
                self._renderers.popitem(last=False)
        return self._renderers[i]


class _Camera:
    """Renders through the rig's renderer of camera ``i`` (made again if dropped)."""

    def __init__(self, rig: VirtualRig, i: int) -> None:
        self.rig, self.i = rig, i

    def frame(self, *args, **kw):
        return self.rig.renderer(self.i).frame(*args, **kw)


_GRIDS: dict[tuple, VirtualRig] = {}


def virtual_rig(grid: tuple[int, int] = HALL, noise: float = 3.0, seed: int = 0,
                origin: tuple[float, float] = HALL_ORIGIN) -> VirtualRig:
    """The rig of ``grid`` (columns, rows) reference webcams from ``origin``, each camera's
    floor calibrated from two of its frames with the reference lens (made once per process)."""
    key = (tuple(grid), float(noise), int(seed), tuple(origin))
    if key not in _GRIDS:
        focal = float(standard_camera().K[0, 0])
        plan = plan_rig(grid_watched(*grid, origin, focal=focal), focal=focal)
        if (len(plan.xs), len(plan.ys)) != tuple(grid):
            raise AssertionError(f"planned {len(plan.xs)}x{len(plan.ys)} for {grid}")
        lens = reference_rig(noise, seed)[1].lens
        rig = VirtualRig(plan, plan.layout(), Imaging(noise=noise))
        for i in range(plan.cameras):
            rng = np.random.default_rng(np.random.SeedSequence([seed, 2, i]))
            r = rig.renderer(i)
            rig.calibrations.append(calibrate_floor([r.frame(None, rng) for _ in range(2)],
                                                    rig.layout, lens))
        _GRIDS[key] = rig
    return _GRIDS[key]


def sim_rig(world, opts, grid: tuple[int, int] = HALL
            ) -> tuple[list[RenderSource], list[Calibration], list[str]]:
    """The virtual rig's sources (each camera's own sensor noise), calibrations and names."""
    rig = virtual_rig(grid, opts.noise, opts.seed)
    sources = [RenderSource(_Camera(rig, i), lambda key: world_pose(world, key),
                            opts.seed + i) for i in range(rig.plan.cameras)]
    return sources, list(rig.calibrations), [f"sim{i + 1}" for i in range(rig.plan.cameras)]
