"""What the camera looks for: floor markers at known places, the robot's marker, the board
that calibrates the lens. Every length is in cm in the floor frame of DESIGN.md 2.2 (x 0..180
across the area, y up the area, z up from the floor); a marker's "up" edge (its first two
corners in OpenCV's order) points to +y on the floor and to the robot's heading on the robot.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from pac_host.coverage import BLOCK_CM  # noqa: F401  (the blocks the camera draws)
from pac_host.errors import InputError

DICTIONARY = "DICT_4X4_50"  # few, large bits: robust at ~20 px per marker
# the same 4x4 markers with more ids (the first 50 are DICT_4X4_50's), for a floor of many
DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000")
BOARD_DICTIONARY = "DICT_5X5_100"  # the lens board's own ids, never mistaken for floor markers
AREA_X = (0.0, 180.0)
AREA_Y = (0.0, 300.0)  # the part of the (upward unbounded) area a camera is set up to see
# cm between the floor markers' rows (at most): the markers define the floor frame, and the
# more of them, the better their hand-laying errors average out
MARKER_SPACING = 30.0


def dictionary(name: str) -> cv2.aruco.Dictionary:
    code = getattr(cv2.aruco, name, None)
    if not name.startswith("DICT_") or code is None:
        raise InputError(f"unknown marker dictionary {name!r} (e.g. {DICTIONARY})")
    return cv2.aruco.getPredefinedDictionary(code)


@dataclass(frozen=True)
class FloorMarker:
    id: int
    x: float  # centre, cm
    y: float
    size: float  # side of the black square, cm


@dataclass(frozen=True)
class RobotMarker:
    id: int = 0
    size: float = 12.0  # side of the black square, cm (10 cm is lost at some headings)
    height: float = 12.0  # above the floor, cm (the robot's top)
    plate: float = 16.0  # the white plate it is printed on (its quiet zone), cm


@dataclass(frozen=True)
class Board:
    """The ChArUco board for the lens: squares x squares of ``square`` cm."""

    squares: tuple[int, int] = (7, 5)
    square: float = 3.8  # fills an A4 sheet
    marker: float = 2.8

    def charuco(self) -> cv2.aruco.CharucoBoard:
        return cv2.aruco.CharucoBoard(self.squares, self.square, self.marker,
                                      dictionary(BOARD_DICTIONARY))


def default_floor(size: float = 12.0, margin: float = 10.0, y_range=AREA_Y,
                  spacing: float = MARKER_SPACING) -> tuple[FloorMarker, ...]:
    """Markers just outside the area's long sides, in rows at most ``spacing`` cm apart from
    ``y_range``'s start to its end (22, every 30 cm from y = 0 to 300, by default): the robot
    never covers them and a camera that sees the area sees them."""
    xs = (AREA_X[0] - margin - size / 2, AREA_X[1] + margin + size / 2)
    ys = np.linspace(y_range[0], y_range[1], int(np.ceil((y_range[1] - y_range[0]) / spacing
                                                         - 1e-9)) + 1)
    return tuple(FloorMarker(1 + i * 2 + j, float(x), float(y), size)
                 for i, y in enumerate(ys) for j, x in enumerate(xs))


def grid_floor(watched: tuple[float, float, float, float], spacing: float,
               size: float = 12.0) -> tuple[FloorMarker, ...]:
    """Markers on a lattice at most ``spacing`` cm apart over the floor ``watched`` (x0, x1,
    y0, y1), for cameras set in a grid over it (each sees several wherever it hangs)."""
    x0, x1, y0, y1 = watched
    xs = np.linspace(x0, x1, int(np.ceil((x1 - x0) / spacing - 1e-9)) + 1)
    ys = np.linspace(y0, y1, int(np.ceil((y1 - y0) / spacing - 1e-9)) + 1)
    return tuple(FloorMarker(1 + i * len(xs) + j, float(x), float(y), size)
                 for i, y in enumerate(ys) for j, x in enumerate(xs))


def dictionary_for(ids: int) -> str:
    """The smallest 4x4 dictionary with ``ids`` markers (ids 0 .. ids - 1)."""
    for name in DICTIONARIES:
        if ids <= int(name.rsplit("_", 1)[1]):
            return name
    raise InputError(f"{ids} markers are more than the largest 4x4 dictionary holds "
                     f"({DICTIONARIES[-1]}); space the floor markers farther apart")


@dataclass(frozen=True)
class Layout:
    floor: tuple[FloorMarker, ...] = field(default_factory=default_floor)
    robot: RobotMarker = RobotMarker()
    dictionary: str = DICTIONARY
    # the floor the camera (or the cameras of a rig) watch, x0, x1, y0, y1 cm: where the
    # robot's marker is looked for (and the error map drawn); the area's first 300 cm by default
    watched: tuple[float, float, float, float] = (*AREA_X, *AREA_Y)

    def floor_by_id(self) -> dict[int, FloorMarker]:
        return {m.id: m for m in self.floor}

    def to_json(self) -> dict:
        return {"dictionary": self.dictionary,
                "floor": [vars(m) for m in self.floor], "robot": vars(self.robot),
                "watched": list(self.watched)}

    @staticmethod
    def from_json(doc: dict) -> Layout:
        try:
            watched = tuple(float(v) for v in doc.get("watched", (*AREA_X, *AREA_Y)))
            if len(watched) != 4 or not (watched[0] < watched[1] and watched[2] < watched[3]):
                raise ValueError(f"watched must be [x0, x1, y0, y1], x0 < x1, y0 < y1, got "
                                 f"{list(watched)}")
            return Layout(tuple(FloorMarker(int(m["id"]), float(m["x"]), float(m["y"]),
                                            float(m["size"])) for m in doc["floor"]),
                          RobotMarker(**{k: float(v) if k != "id" else int(v)
                                         for k, v in doc["robot"].items()}),
                          str(doc["dictionary"]), watched)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"marker layout: missing or bad field ({e})") from None


def square_corners(size: float) -> np.ndarray:
    """A marker's corners in its own frame (x right, y up), OpenCV's order: top-left,
    top-right, bottom-right, bottom-left."""
    s = size / 2
    return np.array([[-s, s], [s, s], [s, -s], [-s, -s]], dtype=np.float64)


def floor_corners(m: FloorMarker) -> np.ndarray:
    """The floor marker's four corners on the floor (4, 2), cm."""
    return square_corners(m.size) + [m.x, m.y]


def heading_rotation(h_deg: float) -> np.ndarray:
    """Maps a marker-frame vector (x right, y forward) to the floor for compass heading h."""
    h = np.radians(h_deg)
    return np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])


DEFAULT_LAYOUT = Layout()
DEFAULT_BOARD = Board()
