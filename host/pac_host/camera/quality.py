"""How far a camera calibration can be trusted: each fitted quantity checked against physics
and against its own residuals, and the position error to expect over the floor area.

A check is a dict ``{"check": name, "status": "ok" | "warn" | "fail", "text": one line with
its numbers}`` (and ``"advice"``, what to do, when it is not ok). A calibration with a failed
check is refused (:func:`refuse`: InputError, exit 2); the warnings are data the CLI prints.
The same checks run when a calibration file is read, so a file the calibration would refuse
is refused too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from pac_host.camera.layout import AREA_X, AREA_Y
from pac_host.errors import InputError

# (warn above, fail above)
LENS_RMS_PX = (0.5, 1.0)  # the board corners' reprojection error
FLOOR_RMS_CM = 1.0  # refused above: the floor markers' corners through the fitted floor
# warned above: a floor marker seen this far (cm) from its place in the layout; laid by hand
# within a couple of millimetres as the how-to says, none is
MARKER_OFF_CM = 1.0
# the expected position error over the area (the error map), median: (warn above, fail above)
MAP_CM = (0.5, 1.0)
HEIGHT_GIVEN = (0.03, 0.10)  # the fitted height against --camera-height, relative
ASPECT = (0.02, 0.10)  # fx / fy against 1 (square pixels)
PRINCIPAL = (0.10, 0.25)  # the principal point's offset from the centre, share of the size
POSE_AGREE_CM = (0.3, 1.0)  # the parallax error of the lens's and the floor's camera centres
PRINT_SCALE = 0.05  # warn when the floor markers' fitted print scale is off 1 by more
# warn when the lens fits the floor markers worse than a free homography by more than chance
# gives this often (strict: the test takes every corner as precise as any other, which the
# floor's far markers, fewer pixels a cm, are not)
LENS_FLOOR_P = 1e-6
# plausible ranges
FOV_DEG = (30.0, 150.0)  # horizontal field of view
HEIGHT_CM = (30.0, 1000.0)  # the lens above the floor
BOARD_COVERAGE = 0.25  # warn when the board's corners span less of the image than this
GIVEN_HEIGHT_SIGMA = 0.03  # a given height's assumed accuracy when nothing checks it
MAP_STEP_CM = 20.0
# a smooth misfit of the camera's model counts in the error map when chance (the markers'
# laying) gives as much less often than this
SMOOTH_MISFIT_P = 0.01

LENS_ADVICE = "calibrate the lens with --lens (10-20 board images that cover the view)"
BOARD_ADVICE = ("take the board images again: flat board, sharp images, spanning a third to "
                "a half of the image's width (35-65 cm before a 75 deg webcam), "
                "tilted, covering the whole view")


def check(name: str, status: str, text: str, advice: str = "") -> dict:
    out = {"check": name, "status": status, "text": text}
    if advice and status != "ok":
        out["advice"] = advice
    return out


def grade(value: float, limits: tuple[float, float]) -> str:
    """ok, warn or fail for a value against (warn above, fail above); NaN fails."""
    if not value <= limits[1]:
        return "fail"
    return "warn" if value > limits[0] else "ok"


def failures(checks: Sequence[dict]) -> list[dict]:
    return [c for c in checks if c["status"] == "fail"]


def warnings(checks: Sequence[dict]) -> list[dict]:
    return [c for c in checks if c["status"] == "warn"]


def refuse(checks: Sequence[dict], what: str = "camera calibration refused") -> None:
    """InputError (one line: what failed, its numbers, what to do) if any check failed."""
    bad = failures(checks)
    if not bad:
        return
    advice = list(dict.fromkeys(c["advice"] for c in bad if c.get("advice")))
    raise InputError(f"{what}: " + "; ".join(c["text"] for c in bad)
                     + (" -- " + "; ".join(advice) if advice else ""))


def fov_deg(focal: float, width: float) -> float:
    """The horizontal field of view (degrees) of a focal length (pixels)."""
    return float(np.degrees(2 * np.arctan2(width / 2, focal))) if focal > 0 else float("nan")


def focal_for_fov(fov: float, width: float) -> float:
    return float(width / 2 / np.tan(np.radians(fov) / 2))


# ---- the lens --------------------------------------------------------------------------------


def radial_folds(K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> bool:
    """Whether the distortion model folds over within the image: its distorted radius stops
    growing before it reaches the image's corners (a false minimum of the fit: some pixels
    would have two rays, or none)."""
    d = np.zeros(8)
    d[:min(8, len(dist))] = np.asarray(dist, dtype=np.float64).ravel()[:8]
    k1, k2, _, _, k3, k4, k5, k6 = d
    w, h = size
    corner = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=np.float64)
    xy = (corner - K[:2, 2]) / [K[0, 0], K[1, 1]]
    r_corner = float(np.hypot(*xy.T).max())
    r = np.linspace(0, 4 * r_corner, 4001)[1:]
    r2 = r * r
    rd = r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    reach = np.nonzero(rd >= r_corner)[0]
    if len(reach) == 0:
        return True
    return bool(np.any(np.diff(rd[:reach[0] + 1]) <= 0))


def corner_shift_px(K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> float:
    """How far the distortion moves the image's corners (pixels)."""
    w, h = size
    corner = np.array([[[0.0, 0.0]], [[w - 1.0, 0]], [[0, h - 1.0]], [[w - 1.0, h - 1.0]]])
    ideal = cv2.undistortPointsIter(corner, K, dist, None, K,
                                    (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9))
    return float(np.hypot(*(ideal - corner).reshape(-1, 2).T).max())


def lens_checks(K: np.ndarray, dist: np.ndarray, size: tuple[int, int], rms_px: float,
                images: int, model: str = "", coverage: float | None = None,
                cm_per_px: float | None = None) -> list[dict]:
    """The lens's fit against its residual and against physics (``size``: the image's)."""
    w, h = size
    fx, fy = float(K[0, 0]), float(K[1, 1])
    on_floor = f", about {rms_px * cm_per_px:.2f} cm on the floor" if cm_per_px else ""
    out = [check("lens_rms", grade(rms_px, LENS_RMS_PX),
                 f"lens: the board's corners fit to {rms_px:.3f} px RMS over {images} images"
                 f"{on_floor} ({LENS_RMS_PX[0]:g} px or less expected"
                 + (f"; model {model})" if model else ")"), BOARD_ADVICE)]
    fov = fov_deg(fx, w)
    ok = FOV_DEG[0] <= fov <= FOV_DEG[1]
    out.append(check("lens_focal", "ok" if ok else "fail",
                     f"lens: focal length {fx:.1f} px, a {fov:.0f} deg horizontal field of view "
                     f"at {w} px wide" + ("" if ok else f" (plausible: {FOV_DEG[0]:.0f}-"
                                                       f"{FOV_DEG[1]:.0f} deg)"),
                     BOARD_ADVICE))
    aspect = abs(fx / fy - 1) if fy > 0 else float("inf")
    out.append(check("lens_aspect", grade(aspect, ASPECT),
                     f"lens: fx / fy = {fx / fy if fy > 0 else float('inf'):.3f} (square "
                     "pixels: 1)", BOARD_ADVICE))
    off = max(abs(K[0, 2] - (w - 1) / 2) / w, abs(K[1, 2] - (h - 1) / 2) / h)
    out.append(check("lens_centre", grade(off, PRINCIPAL),
                     f"lens: principal point ({K[0, 2]:.0f}, {K[1, 2]:.0f}) px, "
                     f"{100 * off:.0f} % of the image from its centre", BOARD_ADVICE))
    folds = radial_folds(K, dist, size)
    shift = float("nan") if folds else corner_shift_px(K, dist, size)
    out.append(check("lens_distortion", "fail" if folds else "ok",
                     "lens: the distortion fitted folds over inside the image (a false fit: "
                     "distortion " + ", ".join(f"{v:.3g}" for v in np.ravel(dist)) + ")"
                     if folds else f"lens: the distortion moves the image's corners by "
                     f"{shift:.1f} px", BOARD_ADVICE))
    if coverage is not None:
        out.append(check("lens_coverage", "ok" if coverage >= BOARD_COVERAGE else "warn",
                         f"lens: the board's corners span {100 * coverage:.0f} % of the image"
                         + ("" if coverage >= BOARD_COVERAGE else
                            "; the distortion near the edges (where the floor markers are) "
                            "is extrapolated"),
                         "hold the board near the image's edges and corners too"))
    return out


def lens_size_check(lens_size: tuple[int, int] | None, size: tuple[int, int]) -> list[dict]:
    if lens_size is None or tuple(lens_size) == tuple(size):
        return []
    return [check("lens_size", "fail",
                  f"the lens was calibrated on {lens_size[0]}x{lens_size[1]} images, the floor "
                  f"frames are {size[0]}x{size[1]}",
                  "calibrate the lens at the floor frames' resolution")]


# ---- the floor and the camera's position -----------------------------------------------------


def floor_check(rms_cm: float, max_cm: float, rms_px: float | None, has_lens: bool,
                worst: tuple[int, float] | None = None) -> dict:
    """The floor markers' corners through the fitted floor. Refused when they fit to more
    than FLOOR_RMS_CM RMS: the camera's model does not fit them (a lens not calibrated) or
    markers lie far from their places. Warned when a marker is seen more than MARKER_OFF_CM
    from its place in the layout (``worst``: the marker farthest from its place, id and cm;
    laid off its place, or a wrong place in the layout): lay it again. A marker's own
    misplacement is no error between the markers; what it moves the floor is in the error
    map's forecast."""
    status = grade(rms_cm, (FLOOR_RMS_CM, FLOOR_RMS_CM))
    if status == "ok" and worst is not None and worst[1] > MARKER_OFF_CM:
        status = "warn"
    text = (f"floor: the markers' corners fit to {rms_cm:.2f} cm RMS ({max_cm:.2f} cm max"
            + (f", {rms_px:.2f} px RMS)" if rms_px is not None else ")"))
    if worst is not None:
        text += (f"; marker {worst[0]} is seen {worst[1]:.2f} cm from its place in the "
                 "layout, the farthest")
    if status == "warn":
        text += (f" (more than {MARKER_OFF_CM:g} cm: laid off its place, or a wrong place in "
                 "the layout?)")
    elif status == "fail":
        text += (f"; more than {FLOOR_RMS_CM:g} cm RMS is refused: the camera's model does not "
                 "fit the floor, or markers lie far from their places")
    far = worst is not None and worst[1] > MARKER_OFF_CM
    advice = "; ".join(
        ([f"lay marker {worst[0]} again where the layout puts it"] if far else [])
        + ([] if status != "fail" else [LENS_ADVICE] if not has_lens else
           ["check that the floor markers lie flat where the layout puts them and that the "
            "lens file is this camera's"]))
    return check("floor_error", status, text, advice)


def print_scale_check(scale: float) -> dict:
    """The floor markers' print scale, fitted with the floor (the positions do not depend on
    it: each marker's centre is where the layout puts it, whatever its size)."""
    off = scale - 1
    text = (f"floor: the markers are printed at {100 * scale:.1f} % of the layout's size "
            "(fitted; the floor uses their centres' places, whatever their size)")
    if abs(off) > PRINT_SCALE:
        text += (f"; more than {100 * PRINT_SCALE:g} % off: a print fitted to the page, or "
                 "sizes in the layout that are not the printed ones? A robot marker printed "
                 "alike is seen as much off its size")
    return check("print_scale", "warn" if abs(off) > PRINT_SCALE else "ok", text,
                 "print at 100 % (no fit to page) and measure the 10 cm bar on each sheet; "
                 "give the printed sizes in the layout")


def height_check(fitted: float | None, given: float | None, has_lens: bool,
                 marker_height: float = 12.0) -> list[dict]:
    """The camera's height fitted from the floor markers against physics and a given one."""
    out = []
    advice = LENS_ADVICE if not has_lens else "check the floor markers and the lens file"
    if fitted is not None:
        ok = HEIGHT_CM[0] <= fitted <= HEIGHT_CM[1]
        what = ("the floor's perspective" if not has_lens else "the lens and the floor markers")
        text = f"camera: {fitted / 100:.2f} m above the floor from {what}"
        if not ok:
            text += f" (plausible: {HEIGHT_CM[0] / 100:g}-{HEIGHT_CM[1] / 100:g} m)"
            if not has_lens:
                text += "; lens distortion read as tilt?"
        out.append(check("camera_height", "ok" if ok else "fail", text, advice))
    if given is not None:
        if not HEIGHT_CM[0] <= given <= HEIGHT_CM[1]:
            out.append(check("height_given", "fail",
                             f"--camera-height {given:g} cm is implausible (plausible: "
                             f"{HEIGHT_CM[0]:g}-{HEIGHT_CM[1]:g} cm)",
                             "give the lens's height above the floor in cm"))
        elif fitted is None:
            cm = parallax_error(np.array([90.0, 150.0, given]),
                                np.array([0, 0, GIVEN_HEIGHT_SIGMA * given]), marker_height)
            out.append(check("height_given", "warn",
                             f"camera: {given / 100:.2f} m above the floor as given; the view is "
                             f"too square-on to check it ({100 * GIVEN_HEIGHT_SIGMA:g} % off "
                             f"would move poses by up to {cm:.2f} cm)", LENS_ADVICE))
        else:
            rel = abs(fitted - given) / given
            cm = parallax_error(np.array([90.0, 150.0, given]),
                                np.array([0, 0, fitted - given]), marker_height)
            out.append(check("height_given", grade(rel, HEIGHT_GIVEN),
                             f"camera: {given / 100:.2f} m above the floor as given, "
                             f"{fitted / 100:.2f} m fitted ({100 * rel:.0f} % apart: up to "
                             f"{cm:.2f} cm of parallax error)",
                             "measure the height again (floor to the lens)"
                             + ("" if has_lens else f", or {LENS_ADVICE}")))
    return out


def focal_check(focal: float, width: int) -> dict:
    fov = fov_deg(focal, width)
    ok = FOV_DEG[0] <= fov <= FOV_DEG[1]
    return check("floor_focal", "ok" if ok else "fail",
                 f"focal length {focal:.0f} px from the floor's perspective: a {fov:.0f} deg "
                 "field of view" + ("" if ok else f" (plausible: {FOV_DEG[0]:.0f}-"
                                                  f"{FOV_DEG[1]:.0f} deg)"), LENS_ADVICE)


def parallax_error(c: np.ndarray, dc: np.ndarray, height: float) -> float:
    """The worst position error over the area's corners (cm) for a marker ``height`` cm up
    when the camera's centre ``c`` is off by ``dc``: the parallax correction moves a point f
    by (f - c) height / cz."""
    f = np.array([[x, y] for x in AREA_X for y in AREA_Y])
    e = height / c[2] * (dc[:2] + (f - c[:2]) * dc[2] / c[2])
    return float(np.hypot(*e.T).max())


def pose_check(c_lens: np.ndarray, c_floor: np.ndarray | None, marker_height: float,
               floor_sigma: np.ndarray | None = None) -> dict:
    """The camera's centre from the lens model (solvePnP with its intrinsics) against the one
    the floor markers alone imply (the focal length of the floor's perspective), beyond what
    the latter's own uncertainty explains (``floor_sigma``, sd per axis, cm: twice it; a
    nearly square-on view tells the focal length poorly)."""
    if c_floor is None:
        return check("camera_pose", "ok", "camera: the view is too square-on for the floor "
                     "markers alone to place it; the lens's placement is not cross-checked")
    d = np.asarray(c_lens, dtype=np.float64) - c_floor
    cm = parallax_error(c_lens, d, marker_height)
    text = (f"camera: placed {np.linalg.norm(d):.1f} cm apart by the lens model and by the "
            f"floor markers alone")
    if floor_sigma is None:
        excess = cm
    else:
        unsure = parallax_error(c_lens, 2 * np.asarray(floor_sigma, dtype=np.float64),
                                marker_height)
        excess = max(cm - unsure, 0.0)
        text += (f" (which place it to +-{np.linalg.norm(2 * floor_sigma):.1f} cm: "
                 f"{unsure:.2f} cm of parallax)")
    text += (f"; up to {excess:.2f} cm of parallax error on the area for a marker "
             f"{marker_height:g} cm up beyond that" if floor_sigma is not None else
             f"; up to {cm:.2f} cm of parallax error on the area for a marker "
             f"{marker_height:g} cm up")
    return check("camera_pose", grade(excess, POSE_AGREE_CM), text,
                 "the lens does not fit this camera (another camera, zoom, focus or "
                 "resolution?): calibrate it again")


def lens_floor_check(posed: np.ndarray, free: np.ndarray, group: int = 4) -> dict:
    """Whether the floor markers' corners fit the camera's pose through the lens (residuals
    ``posed``, (n, 2) cm; 6 parameters) about as well as a free homography (``free``; 8): an
    F-test of the two more parameters, its statistic divided by the design effect of the
    corners erring together by ``group`` (a marker laid off its place moves its four).
    Warned when a fit that much worse comes by chance less than once in LENS_FLOOR_P."""
    rss6, rss8 = float((posed ** 2).sum()), float((free ** 2).sum())
    dof = posed.size - 8
    n6, n8 = math.sqrt(rss6 / len(posed)), math.sqrt(rss8 / len(free))
    if dof <= 0 or rss8 <= 0:
        return check("lens_floor", "ok", "camera: too few floor markers to test the lens "
                     "against them")
    sums = free.reshape(-1, group, 2).sum(axis=1) if len(free) % group == 0 else free
    deff = max(float((sums ** 2).sum()) / rss8, 1.0)
    f = max(rss6 - rss8, 0.0) / 2 / (rss8 / dof) / deff
    p = (1 + 2 * f / dof) ** (-dof / 2)  # the F(2, dof) distribution's tail
    bad = p < LENS_FLOOR_P
    text = (f"camera: through the lens, the floor markers' corners fit the camera's pose to "
            f"{n6:.2f} cm RMS, a free homography to {n8:.2f} cm"
            + (f" (chance gives that less than once in {1 / LENS_FLOOR_P:,.0f}: the lens "
               "does not fit the floor's perspective)" if bad else ""))
    return check("lens_floor", "warn" if bad else "ok", text,
                 "the lens does not fit this camera (another camera, zoom, focus or "
                 "resolution?): calibrate it again")


def no_lens_check() -> dict:
    return check("lens", "warn", "no lens calibration: distortion is not corrected and the "
                 "focal length comes from the floor's perspective", LENS_ADVICE)


def pose_from_homography(H: np.ndarray, K: np.ndarray) -> np.ndarray:
    """The camera's centre (floor frame, cm) from the homography ``H`` (ideal pixels -> floor
    cm) and intrinsics ``K``: the columns of K^-1 H^-1 as the rotation's first two columns and
    the translation (made a rotation by SVD)."""
    M = np.linalg.inv(K) @ np.linalg.inv(H)
    s = 2.0 / (np.linalg.norm(M[:, 0]) + np.linalg.norm(M[:, 1]))
    if M[2, 2] * s < 0:  # the floor in front of the camera
        s = -s
    r1, r2, t = s * M[:, 0], s * M[:, 1], s * M[:, 2]
    u, _, vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    R = u @ vt
    c = -R.T @ t
    return c if c[2] > 0 else -c


# ---- the expected pose error over the area ---------------------------------------------------


def _h_params(H: np.ndarray) -> np.ndarray:
    return (H / H[2, 2]).ravel()[:8]


def _h_of(p: np.ndarray) -> np.ndarray:
    return np.append(p, 1.0).reshape(3, 3)


def _jacobian(fun, p: np.ndarray) -> np.ndarray:
    """d fun / d p by central differences (fun: params -> vector)."""
    cols = []
    for i in range(len(p)):
        e = 1e-6 * max(abs(p[i]), 1e-9)
        a, b = p.copy(), p.copy()
        a[i] += e
        b[i] -= e
        cols.append((fun(a) - fun(b)) / (2 * e))
    return np.column_stack(cols)


def homography_fit(H: np.ndarray, ideal: np.ndarray, floor: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The free homography's fit of the floor (``ideal`` image points onto ``floor``, cm):
    the Jacobian (2n, 8) of its residuals in its 8 parameters and the residuals (2n,)."""
    def res(q):
        return (cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), _h_of(q)).reshape(-1, 2)
                - floor).ravel()

    p = _h_params(H)
    return _jacobian(res, p), res(p)


def design_effect(r: np.ndarray, group: int) -> float:
    """How much more the summed residuals (``r``, (2n,)) of groups of ``group`` points that
    err together (a floor marker's corners) scatter than independent points' would; at least
    1, and 1 where the points do not come in such groups."""
    if group <= 1 or len(r) % (2 * group) or not r @ r > 0:
        return 1.0
    sums = r.reshape(-1, group, 2).sum(axis=1)
    return max(float((sums ** 2).sum() / (r @ r)), 1.0)


def homography_covariance(H: np.ndarray, ideal: np.ndarray, floor: np.ndarray,
                          group: int = 1) -> np.ndarray:
    """The covariance (8, 8) of the homography's parameters from its fit's residuals. With
    ``group`` > 1, the points come in groups of as many that err together (a floor marker's
    corners, when it is laid off its place): the covariance is widened by their
    :func:`design_effect`."""
    J, r = homography_fit(H, ideal, floor)
    dof = max(len(r) - 8, 1)
    return float(r @ r) / dof * np.linalg.pinv(J.T @ J) * design_effect(r, group)


def cluster_covariance(J: np.ndarray, r: np.ndarray, group: int = 4) -> np.ndarray:
    """The covariance of a least-squares fit's parameters (``J``: d residuals / d parameters
    at the fit, (n, p); ``r``: its residuals, n = 2 x points) when the points come in groups
    of ``group`` that err together: a floor marker's corners, laid off its place as one. The
    sandwich (J^T J)^-1 (sum over groups of J_g^T r_g r_g^T J_g) (J^T J)^-1 with the
    small-sample factor G / (G - 1) (n - 1) / (n - p): each marker's laying counts once,
    however many corners it has, and a marker far off its place widens it as much as it
    pulls the fit. With too few groups to tell (G <= p + 2), the residuals' variance times
    their design effect."""
    n, p = J.shape
    rows = 2 * group
    B = np.linalg.pinv(J.T @ J)
    dof = max(n - p, 1)
    if n % rows or n // rows <= p + 2:
        return float(r @ r) / dof * B * design_effect(r, group)
    g = (J * r[:, None]).reshape(-1, rows, p).sum(axis=1)
    G = len(g)
    return G / (G - 1) * (n - 1) / dof * (B @ (g.T @ g) @ B)


def marker_offsets(res: np.ndarray, group: int = 4) -> np.ndarray:
    """Each floor marker's offset from its place as the fit sees it (cm, (markers, 2)): the
    mean of its corners' residuals (``res``, (n, 2), ``group`` corners a marker)."""
    return res.reshape(-1, group, 2).mean(axis=1)


def within_marker_noise(res: np.ndarray, floor: np.ndarray, group: int = 4) -> np.ndarray:
    """The corners' residuals (cm, (n, 2); their floor places ``floor``, ``group`` corners a
    marker) less each marker's own shift and turn: what no laying explains (the corners'
    noise), 2 x group - 3 degrees of freedom a marker."""
    r = res.reshape(-1, group, 2)
    o = floor.reshape(-1, group, 2)
    o = o - o.mean(axis=1, keepdims=True)
    r = r - r.mean(axis=1, keepdims=True)
    perp = np.stack([-o[..., 1], o[..., 0]], axis=-1)
    turn = (perp * r).sum(axis=(1, 2)) / np.maximum((o ** 2).sum(axis=(1, 2)), 1e-12)
    return (r - turn[:, None, None] * perp).reshape(-1, 2)


def smooth_misfit(ideal: np.ndarray, floor: np.ndarray, res: np.ndarray, params: int,
                  size: tuple[int, int], start: np.ndarray, group: int = 4) -> dict:
    """The part of the floor's misfit that a smooth error of the camera's model explains
    beyond chance: what a richer model (a free homography after a radial distortion about the
    image's centre, 10 parameters; ``start``: a free homography to begin from) takes out of
    the corners' residuals ``res`` (cm, (n, 2); the fitted model's, ``params`` parameters)
    beyond what chance takes out with as many more parameters (the markers' laying, each
    marker's corners erring together: their design effect). Such an error lies between the
    markers as much as on them, unlike each marker's own misplacement. ``cm``: its RMS over
    the corners (cm), counted when chance gives as much less often than SMOOTH_MISFIT_P (``p``:
    how often it does); ``rms_rich_cm``, ``residuals``: the richer model's fit."""
    from scipy.optimize import least_squares
    from scipy.stats import f as f_dist

    w, h = size
    c0 = np.array([(w - 1) / 2, (h - 1) / 2])
    reach = float(np.hypot(w, h) / 2)
    u = (ideal - c0) / reach
    rho2 = (u ** 2).sum(axis=1, keepdims=True)

    def resid(x):
        bent = c0 + (ideal - c0) * (1 + x[8] * rho2 + x[9] * rho2 ** 2)
        return (cv2.perspectiveTransform(bent.reshape(-1, 1, 2), _h_of(x[:8])).reshape(-1, 2)
                - floor).ravel()

    x0 = np.append(_h_params(start), [0.0, 0.0])
    fit = least_squares(resid, x0, method="lm", x_scale="jac")
    rich = fit.x if fit.cost < 0.5 * float(resid(x0) @ resid(x0)) else x0
    r = resid(rich)
    rss, rss_rich = float((res ** 2).sum()), float(r @ r)
    extra = 10 - params
    dof = len(r) - 10
    out = {"cm": 0.0, "rms_rich_cm": round(math.sqrt(rss_rich / len(floor)), 4),
           "residuals": r.reshape(-1, 2)}
    if dof <= 0 or rss_rich <= 0 or extra <= 0:
        return out
    chance = extra * design_effect(r, group) * rss_rich / dof  # what chance takes out
    p = float(f_dist.sf((rss - rss_rich) / chance, extra, dof))
    out["p"] = p
    if p < SMOOTH_MISFIT_P:
        out["cm"] = round(math.sqrt(max(rss - rss_rich - chance, 0.0) / len(floor)), 4)
    return out


def pose_error_map(cal, cov: np.ndarray, center_sigma: np.ndarray, noise_px: float,
                   model_cm: float = 0.0, step: float = MAP_STEP_CM) -> dict:
    """The position error (cm, RMS) to expect for the robot's marker centred at each point of
    a grid over the watched floor (the layout's), at its height: the fitted floor's
    uncertainty (``cov``, the homography's parameters' covariance from its fit: the markers'
    laying averaged over them, :func:`cluster_covariance`), the noise of the marker's corners
    (``noise_px`` per corner, through the local cm per pixel), the parallax error of the
    camera centre's uncertainty (``center_sigma``, cm, per axis), and ``model_cm`` everywhere
    (a smooth misfit of the camera's model, :func:`smooth_misfit`, which no fit corrects).
    Each marker's own misplacement is not an error between the markers: only what it moves
    the fit counts. None where the marker is out of view."""
    marker = cal.layout.robot
    hm, c = marker.height, cal.center
    x0, x1, y0, y1 = cal.layout.watched
    xs = np.arange(x0, x1 + 1e-9, step)
    ys = np.arange(y0, y1 + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    n = len(pts)
    # the marker's corners in the image: all in view?
    half = marker.size / 2
    offs = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    corners = cal.from_floor((pts[:, None, :] + offs).reshape(-1, 2), hm).reshape(n, 4, 2)
    w, h = cal.size
    seen = np.all((corners >= 1) & (corners <= [w - 2, h - 2]), axis=(1, 2))
    # and not folded into the image by the lens model far outside the view it was fitted on
    back = cal.to_plane(corners.reshape(-1, 2), hm).reshape(n, 4, 2)
    seen &= np.all(np.hypot(*(back - (pts[:, None, :] + offs)).transpose(2, 0, 1)) < 0.5,
                   axis=1)
    # the local cm per pixel at the marker's centre (its pixel moved by one pixel)
    px = cal.from_floor(pts, hm)
    jx = cal.to_plane(px + [0.5, 0], hm) - cal.to_plane(px - [0.5, 0], hm)
    jy = cal.to_plane(px + [0, 0.5], hm) - cal.to_plane(px - [0, 0.5], hm)
    scale = np.sqrt((jx ** 2).sum(1) + (jy ** 2).sum(1))  # Frobenius norm of d cm / d px
    detect = noise_px * scale / 2  # four corners averaged, both axes
    # the homography's uncertainty at the marker's floor point (below it along the ray)
    shrink = (c[2] - hm) / c[2]
    f = c[:2] + (pts - c[:2]) / shrink
    ideal = cv2.perspectiveTransform(f.reshape(-1, 1, 2), np.linalg.inv(cal.H))
    p0 = _h_params(cal.H)
    J = _jacobian(lambda q: cv2.perspectiveTransform(ideal, _h_of(q)).ravel(), p0)
    var = np.einsum("ij,jk,ik->i", J, cov, J).reshape(n, 2).sum(1)
    fit = np.sqrt(np.maximum(var, 0)) * shrink
    # parallax: to_plane = f - (f - c) hm / cz, moved by the centre's error
    s = np.asarray(center_sigma, dtype=np.float64)
    par = hm / c[2] * np.sqrt(s[0] ** 2 + s[1] ** 2
                              + (np.hypot(*(f - c[:2]).T) * s[2] / c[2]) ** 2)
    total = np.sqrt(fit ** 2 + detect ** 2 + par ** 2 + model_cm ** 2)
    total = np.where(seen, total, np.nan).reshape(gy.shape)
    vals = total[np.isfinite(total)]
    worst = np.unravel_index(np.nanargmax(total), total.shape) if len(vals) else None
    return {"x_cm": xs.round(3).tolist(), "y_cm": ys.round(3).tolist(),
            "error_cm": [[None if not np.isfinite(v) else round(float(v), 3) for v in row]
                         for row in total],
            "marker_height_cm": hm, "noise_px": round(float(noise_px), 4),
            "model_cm": round(float(model_cm), 4),
            "median_cm": round(float(np.median(vals)), 3) if len(vals) else None,
            "max_cm": round(float(vals.max()), 3) if len(vals) else None,
            "worst_at_cm": None if worst is None else [float(xs[worst[1]]), float(ys[worst[0]])],
            "unseen": int(n - seen.sum()), "points": n}


def map_check(m: dict, has_lens: bool = True) -> dict:
    """The error map's forecast: warned when its median is over MAP_CM[0] or a point of the
    area is over MAP_CM[1] (poses there could be off by more than 1 cm), refused when its
    median is over MAP_CM[1]; warned when the robot's marker is out of view somewhere."""
    if m["median_cm"] is None:
        return check("pose_error_map", "fail", "the robot's marker is out of view everywhere "
                     "on the area", "aim the camera at the area")
    status = grade(m["median_cm"], MAP_CM)
    if status == "ok" and m["max_cm"] > MAP_CM[1]:
        status = "warn"
    text = (f"expected position error over the area: {m['median_cm']:.2f} cm median, "
            f"{m['max_cm']:.2f} cm max (at {m['worst_at_cm'][0]:g}, {m['worst_at_cm'][1]:g})")
    if m.get("model_cm"):
        text += f"; {m['model_cm']:.2f} cm of it a smooth misfit of the camera's model"
    if status == "warn":
        text += (f" ({MAP_CM[0]:g} cm median or less and {MAP_CM[1]:g} cm or less everywhere "
                 "expected)")
    elif status == "fail":
        text += f" (more than {MAP_CM[1]:g} cm median is refused)"
    if m["unseen"]:
        status = "warn" if status == "ok" else status
        text += (f"; the robot's marker is out of view at {m['unseen']} of {m['points']} points "
                 f"of a {MAP_STEP_CM:g} cm grid")
    advice = ["see the error map"]
    if m["unseen"]:
        advice.append("move the camera so that it sees the whole area")
    if not has_lens or m.get("model_cm"):
        advice.append(LENS_ADVICE if not has_lens else "the lens does not fit this camera "
                      "(another camera, zoom, focus or resolution?): calibrate it again")
    if status != "ok" and not m["unseen"]:
        advice.append("lay the floor markers within a couple of millimetres of their places")
    return check("pose_error_map", status, text, "; ".join(advice))
