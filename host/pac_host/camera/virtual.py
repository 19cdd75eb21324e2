"""The built-in emulator seen through the virtual camera (``--observer camera:sim``): the
reference set-up of :func:`pac_host.camera.render.standard_camera`, calibrated the way a user
calibrates a real one (lens board images, then the floor markers), rendering the emulated
robot at the pose its world recorded for each gait cycle."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pac_host.camera.calibrate import Calibration, calibrate_floor, calibrate_lens
from pac_host.camera.layout import Board, Layout
from pac_host.camera.render import Imaging, Renderer, board_poses, standard_camera
from pac_host.camera.sources import RenderSource

LENS_IMAGES = 10
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
