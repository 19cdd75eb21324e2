"""Printable sheets (one PDF, A4 pages, every marker at its true size when printed at 100 %):
the robot's marker on its plate, each floor marker with where its centre goes, and the lens
board. Each page carries a 10 cm bar to check the print's scale."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from pac_host.camera.layout import DEFAULT_BOARD, DEFAULT_LAYOUT, Board, Layout, dictionary

A4_CM = (21.0, 29.7)
INCH = 2.54


def _page(pdf, image: np.ndarray, size_cm: tuple[float, float], lines: list[str]) -> None:
    import matplotlib.pyplot as plt

    w, h = A4_CM
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
            "(or give that height)."])
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
            "glue it on something flat; hold it 35-65 cm before the camera, tilted,",
            "in 10-20 images that between them cover the whole view"])
        pages += 1
    return pages


def write_floor_plan(path: Path, layout: Layout = DEFAULT_LAYOUT) -> None:
    """A PNG of where the floor markers go (the area, its blocks, each marker's id)."""
    import matplotlib.pyplot as plt

    from pac_host.camera.layout import AREA_X, AREA_Y, BLOCK_CM

    fig, ax = plt.subplots(figsize=(4.5, 6.5))
    for x in np.arange(AREA_X[0], AREA_X[1] + 1, BLOCK_CM):
        ax.plot([x, x], AREA_Y, color="0.6", lw=1)
    for y in np.arange(AREA_Y[0], AREA_Y[1] + 1, BLOCK_CM):
        ax.plot(AREA_X, [y, y], color="0.6", lw=1)
    for m in layout.floor:
        ax.add_patch(plt.Rectangle((m.x - m.size / 2, m.y - m.size / 2), m.size, m.size,
                                   color="k"))
        ax.annotate(f"{m.id}\n({m.x:g}, {m.y:g})", (m.x, m.y), ha="center", va="center",
                    fontsize=6, color="w")
    ax.set_aspect("equal")
    ax.set_xlabel("x cm")
    ax.set_ylabel("y cm")
    ax.set_title("floor markers (id, centre)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
