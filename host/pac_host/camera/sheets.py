"""Printable sheets (one PDF, A4 pages, every marker at its true size when printed at 100 %;
the robot's page A3 if its plate is wider than 20 cm):
the robot's marker on its plate, each floor marker with where its centre goes, and the lens
board. Each page carries a 10 cm bar to check the print's scale.

And how big the robot's marker must be for a camera (:func:`suggest_marker_size`): at least
:data:`MARKER_PX` pixels across. Measured on rendered frames of the reference camera (640x480,
2.5 m up, 3 px of motion blur, JPEG, noise, patchy light), a marker lost its decoding below
about 21 px; 30 px leaves room for the far end of a tilted view and the lens's edges.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from pac_host.camera.layout import DEFAULT_BOARD, DEFAULT_LAYOUT, Board, Layout, dictionary
from pac_host.errors import InputError

A4_CM = (21.0, 29.7)
A3_CM = (29.7, 42.0)  # the robot's page when its plate is wider than A4 leaves room for
INCH = 2.54
MARKER_PX = 30  # the robot marker's side, pixels: the least a camera should see it at


def floor_px_per_cm(resolution: tuple[int, int], height: float, fov: float,
                    z: float = 0.0) -> float:
    """Pixels per cm on a plane ``z`` cm above the floor for a camera ``height`` cm up looking
    straight down, ``resolution`` (w, h) pixels, a horizontal field of view of ``fov`` deg:
    its focal length (w / 2 / tan(fov / 2) pixels) over the distance to the plane. A tilted
    view sees its far end smaller, a barrel lens its edges.

    >>> round(floor_px_per_cm((640, 480), 250, 74.6, z=12), 2)
    1.76
    """
    if not (height > z and 0 < fov < 180 and resolution[0] > 0):
        raise InputError(f"a camera {height:g} cm up with a {fov:g} deg field of view cannot "
                         f"see a plane {z:g} cm up")
    focal = resolution[0] / 2 / math.tan(math.radians(fov) / 2)
    return focal / (height - z)


def suggest_marker_size(resolution: tuple[int, int], height: float, fov: float,
                        z: float = 12.0, px: float = MARKER_PX, step: float = 0.5) -> float:
    """The smallest robot marker side (cm, a multiple of ``step``) that a camera of
    :func:`floor_px_per_cm` sees ``px`` pixels across at the marker's height ``z``.

    >>> suggest_marker_size((640, 480), 250, 74.6), suggest_marker_size((1280, 720), 250, 74.6)
    (17.0, 8.5)
    """
    return math.ceil(px / floor_px_per_cm(resolution, height, fov, z) / step - 1e-9) * step


def _page(pdf, image: np.ndarray, size_cm: tuple[float, float], lines: list[str],
          page: tuple[float, float] = A4_CM) -> None:
    import matplotlib.pyplot as plt

    w, h = page
    fig = plt.figure(figsize=(w / INCH, h / INCH))
    left, bottom = (w - size_cm[0]) / 2, h - 4.0 - size_cm[1]
    ax = fig.add_axes((left / w, bottom / h, size_cm[0] / w, size_cm[1] / h))
    ax.imshow(image, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    ax.set_axis_off()
    fig.text(0.5, 1 - 1.5 / h, "\n".join(lines), ha="center", va="top", fontsize=11)
    bar = fig.add_axes((2.0 / w, 1.5 / h, 10.0 / w, 0.3 / h))
    bar.imshow(np.zeros((1, 10)), cmap="gray", aspect="auto")
    bar.set_axis_off()
    fig.text(12.5 / w, 1.65 / h, "10 cm: measure this bar; print at 100 %, no fit to page",
             va="center", fontsize=9)
    pdf.savefig(fig)
    plt.close(fig)


def _framed(img: np.ndarray, pad: int) -> np.ndarray:
    """The marker on white with a thin grey cutting line around the white."""
    out = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
    out[[0, -1], :] = 160
    out[:, [0, -1]] = 160
    return out


def write_sheets(path: Path, layout: Layout = DEFAULT_LAYOUT, board: Board = DEFAULT_BOARD) -> int:
    """Write the PDF; returns the number of pages."""
    from matplotlib.backends.backend_pdf import PdfPages

    d = dictionary(layout.dictionary)
    cells = d.markerSize + 2
    ppc = 40  # image pixels per cm (nearest-neighbour scaled in the PDF: sharp at any size)
    pages = 0
    with PdfPages(path) as pdf:
        r = layout.robot
        px = cells * round(r.size * ppc / cells)
        pad = round((r.plate - r.size) / 2 * ppc)
        img = _framed(cv2.aruco.generateImageMarker(d, r.id, px), pad)
        _page(pdf, img, (r.plate, r.plate), [
            f"ROBOT marker id {r.id}: black square {r.size:g} cm, plate {r.plate:g} cm",
            "Cut along the grey line; fix it flat on the robot's top, centred over the body,",
            f"its top edge towards the robot's front, {r.height:g} cm above the floor "
            "(or give that height)."], A4_CM if r.plate <= A4_CM[0] - 1 else A3_CM)
        pages += 1
        for m in layout.floor:
            px = cells * round(m.size * ppc / cells)
            img = _framed(cv2.aruco.generateImageMarker(d, m.id, px), round(2 * ppc))
            _page(pdf, img, (m.size + 4, m.size + 4), [
                f"FLOOR marker id {m.id}: black square {m.size:g} cm",
                f"centre at x = {m.x:g} cm, y = {m.y:g} cm; top edge towards +y (up the area)",
                "flat on the floor, taped at the white margin"])
            pages += 1
        cols, rows = board.squares
        size = (cols * board.square, rows * board.square)
        img = board.charuco().generateImage((round(size[0] * ppc), round(size[1] * ppc)))
        _page(pdf, img, size, [
            f"LENS board: {cols} x {rows} squares of {board.square:g} cm "
            f"(markers {board.marker:g} cm)",
            "glue it on something flat; hold it 35-65 cm before the camera (a wider lens:",
            "closer, the board a third to a half of the view's width), tilted,",
            "in 10-20 images that between them cover the whole view"])
        pages += 1
    return pages


def write_floor_plan(path: Path, layout: Layout = DEFAULT_LAYOUT, plan=None) -> None:
    """A PNG of where the floor markers go (the watched floor, the area's blocks, each
    marker's id) and, given a :class:`pac_host.camera.plan.RigPlan`, what each camera sees."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from pac_host.camera.layout import AREA_X, AREA_Y, BLOCK_CM

    x0, x1, y0, y1 = layout.watched
    xs = [m.x for m in layout.floor] + [x0, x1]
    ys = [m.y for m in layout.floor] + [y0, y1]
    wide, tall = max(xs) - min(xs) + 40, max(ys) - min(ys) + 40
    scale = min((6.5 if tall < 500 else 10.0) / tall, 8.0 / wide)  # inches per cm
    fig, ax = plt.subplots(figsize=(max(wide * scale, 2.5) + 1.4, max(tall * scale, 2.5) + 0.8))
    ty0, ty1 = max(AREA_Y[0], y0), max(AREA_Y[0], y1)
    for x in np.arange(AREA_X[0], AREA_X[1] + 1, BLOCK_CM):
        ax.plot([x, x], [ty0, ty1], color="0.6", lw=1)
    for y in np.arange(AREA_Y[0], ty1 + 1, BLOCK_CM):
        if y >= ty0:
            ax.plot(AREA_X, [y, y], color="0.6", lw=1)
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", ec="0.4", lw=0.8))
    if plan is not None:
        fx, fy = plan.footprint(0.0)
        for i, (cx, cy) in enumerate(plan.centres()):
            ax.add_patch(Rectangle((cx - fx / 2, cy - fy / 2), fx, fy, fill=False,
                                   ec=f"C{i % 10}", lw=1.2))
            ax.annotate(f"camera {i + 1}", (cx, cy), ha="center", va="center", fontsize=6,
                        color=f"C{i % 10}")
    small = scale < 0.015  # too small for the centres' numbers
    for m in layout.floor:
        ax.add_patch(plt.Rectangle((m.x - m.size / 2, m.y - m.size / 2), m.size, m.size,
                                   color="k"))
        ax.annotate(f"{m.id}" if small else f"{m.id}\n({m.x:g}, {m.y:g})", (m.x, m.y),
                    ha="center", va="center", fontsize=4 if small else 6, color="w")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x cm")
    ax.set_ylabel("y cm")
    ax.set_title("camera views and floor markers" if plan else
                 "floor markers (id)" if small else "floor markers (id, centre)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
