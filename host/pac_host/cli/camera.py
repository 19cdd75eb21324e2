"""`pac-host camera`: print the markers, calibrate, check, and serve an overhead camera."""

from __future__ import annotations

import json
from pathlib import Path

import click

from pac_host import limits
from pac_host.cli.options import Bounded
from pac_host.errors import InputError
from pac_host.files import read_text


def _need_cv2() -> None:
    try:
        import cv2  # noqa: F401
    except ImportError:
        raise InputError("the camera needs OpenCV: pip install 'pac-servobot[camera]'") from None


def _layout(path: Path | None):
    from pac_host.camera.layout import Layout

    if path is None:
        return Layout()
    try:
        doc = json.loads(read_text(path, "--layout"))
    except json.JSONDecodeError as e:
        raise InputError(f"--layout {path}: cannot read it as JSON ({e})") from None
    return Layout.from_json(doc.get("layout", doc) if isinstance(doc, dict) else {})


def _frames(source: str, n: int | None) -> list:
    """All images of a folder (or the first ``n``), or ``n`` frames of a camera or video."""
    from pac_host.camera.sources import FolderSource, open_source
    from pac_host.robot.observers import ObserverError

    src = open_source(source)
    try:
        if isinstance(src, FolderSource) and n is None:
            n = src.count
        try:
            frames = src.window(n or 1, 2.0)
        except ObserverError as e:
            raise InputError(str(e)) from None
    finally:
        src.close()
    if not frames:
        raise InputError(f"{src.name}: gave no frame within 2 s")
    return frames


def _pose(text: str) -> tuple[float, float, float]:
    try:
        x, y, h = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--pose: expected X,Y,H, got {text!r}") from None
    return x, y, h


layout_option = click.option("--layout", "layout_path", type=click.Path(dir_okay=False,
                             path_type=Path), help="Marker layout JSON (default: the built-in "
                             "one; `camera sheets` writes it as layout.json).")


@click.group("camera")
def camera() -> None:
    """An overhead camera with fiducial markers (docs/how-to/camera.md): sheets to print, plan
    the cameras of a long area, grab frames, calibrate, check, serve poses, render a virtual
    camera's frames; `--observer camera:...` (several cameras joined by +) for evolve and
    measure."""
    _need_cv2()


def _resolution(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    w, sep, h = text.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
        raise InputError(f"--resolution: expected WIDTHxHEIGHT pixels, e.g. 640x480, got "
                         f"{text!r}")
    return int(w), int(h)


@camera.command("sheets")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path))
@layout_option
@click.option("--resolution", default=None, metavar="WxH",
              help="The camera's image size (with --camera-height and --fov: the robot "
                   "marker's size is suggested for it, and printed at it).")
@click.option("--camera-height", default=None, type=float, metavar="CM",
              help="The lens's height above the floor.")
@click.option("--fov", default=None, type=float, metavar="DEG",
              help="The camera's horizontal field of view.")
@click.option("--robot-size", default=None, type=float, metavar="CM",
              help="Print the robot's marker this size (its white plate 4 cm wider).")
def sheets_cmd(out_dir: Path, layout_path: Path | None, resolution: str | None,
               camera_height: float | None, fov: float | None,
               robot_size: float | None) -> None:
    """Write the sheets to print (markers.pdf: robot marker, floor markers, lens board, each at
    its true size at 100 %), floor_plan.png and layout.json. Given the camera (--resolution,
    --camera-height, --fov), suggests the robot marker's size: at least 30 pixels across."""
    from dataclasses import replace

    from pac_host.camera.sheets import (
        A4_CM,
        MARKER_PX,
        floor_px_per_cm,
        suggest_marker_size,
        write_floor_plan,
        write_sheets,
    )

    layout = _layout(layout_path)
    size = _resolution(resolution)
    cam = (size, camera_height, fov)
    if any(v is not None for v in cam) and any(v is None for v in cam):
        raise InputError("give the camera with all of --resolution, --camera-height and --fov")
    if robot_size is not None and not 1 <= robot_size <= 40:
        raise InputError(f"--robot-size must be 1..40 cm, got {robot_size:g}")
    suggested = None
    if size is not None:
        z = layout.robot.height
        ppc = floor_px_per_cm(size, camera_height, fov, z)
        suggested = suggest_marker_size(size, camera_height, fov, z)
        click.echo(f"camera {size[0]}x{size[1]}, {camera_height:g} cm up, {fov:g} deg across: "
                   f"{ppc:.2f} px per cm at the robot marker's height ({z:g} cm), looking "
                   f"straight down; the robot marker needs {suggested:g} cm for {MARKER_PX} px "
                   f"({layout.robot.size:g} cm: {layout.robot.size * ppc:.0f} px)")
        if robot_size is None and layout_path is None:
            robot_size = max(suggested, layout.robot.size)
    if robot_size is not None:
        r = layout.robot
        layout = replace(layout, robot=replace(r, size=robot_size,
                                               plate=robot_size + (r.plate - r.size)))
    if suggested is not None and layout.robot.size < suggested:
        click.echo(f"warning: a robot marker of {layout.robot.size:g} cm is smaller than the "
                   f"{suggested:g} cm suggested: it may be lost when blurred")
    out_dir.mkdir(parents=True, exist_ok=True)
    pages = write_sheets(out_dir / "markers.pdf", layout)
    write_floor_plan(out_dir / "floor_plan.png", layout)
    (out_dir / "layout.json").write_text(json.dumps(layout.to_json(), indent=1) + "\n")
    a3 = ", the robot's A3" if layout.robot.plate > A4_CM[0] - 1 else ""
    click.echo(f"wrote {out_dir / 'markers.pdf'} ({pages} A4 pages{a3}; print at 100 %, check the "
               f"10 cm bar), floor_plan.png and layout.json (robot marker "
               f"{layout.robot.size:g} cm on a {layout.robot.plate:g} cm plate)")


@camera.command("layout")
@click.option("--length", default=1000.0, show_default=True, type=float, metavar="CM",
              help="How much of the area (180 cm wide) to watch, from its start.")
@click.option("--height", default=250.0, show_default=True, type=float, metavar="CM",
              help="The cameras' lenses above the floor.")
@click.option("--fov", default=75.0, show_default=True, type=float, metavar="DEG",
              help="The webcams' horizontal field of view.")
@click.option("--size", "size_text", default="640x480", show_default=True, metavar="WxH",
              help="The webcams' image size, pixels.")
@click.option("--overlap", default=40.0, show_default=True, type=float, metavar="CM",
              help="Neighbouring cameras' views of the robot's marker overlap by this at least.")
@click.option("--out", "out_dir", default=None, type=click.Path(file_okay=False, path_type=Path),
              help="Write layout.json (give it to sheets and calibrate with --layout), "
                   "floor_plan.png (the markers and each camera's view) and rig_plan.json.")
def layout_cmd(length, height, fov, size_text, overlap, out_dir) -> None:
    """Plan the cameras for a long area: how many webcams, where, how high, what overlap,
    the robot marker's size in pixels, and the floor markers for them (computed from the
    field of view and the height: docs/how-to/camera.md section 7)."""
    from pac_host.camera.plan import strip_plan
    from pac_host.camera.sheets import write_floor_plan

    try:
        w, h = (int(v) for v in size_text.lower().split("x"))
    except ValueError:
        raise InputError(f"--size: expected WIDTHxHEIGHT pixels, got {size_text!r}") from None
    if min(w, h) < 16:
        raise InputError(f"--size {w}x{h} is not a webcam's image")
    plan = strip_plan(length, height=height, size=(w, h), fov=fov, overlap=overlap)
    layout = plan.layout()
    for line in plan.lines(layout):
        click.echo(line)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "layout.json").write_text(json.dumps(layout.to_json(), indent=1) + "\n")
        write_floor_plan(out_dir / "floor_plan.png", layout, plan)
        doc = {"height_cm": plan.height, "image_size": list(plan.size), "focal_px": plan.focal,
               "cameras": [{"x_cm": x, "y_cm": y} for x, y in plan.centres()],
               "lines": plan.lines(layout)}
        (out_dir / "rig_plan.json").write_text(json.dumps(doc, indent=1) + "\n")
        click.echo(f"wrote {out_dir / 'layout.json'}, floor_plan.png and rig_plan.json")


@camera.command("render")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path))
@click.option("--pose", "poses", multiple=True, metavar="X,Y,H",
              help="A robot pose to render (repeatable).")
@click.option("--floor", "n_floor", default=3, show_default=True, type=int,
              help="Frames of the floor alone.")
@click.option("--board", "n_board", default=12, show_default=True, type=int,
              help="Frames of the lens board.")
@click.option("--noise", default=3.0, show_default=True, type=float, help="Grey levels.")
@click.option("--motion-blur", default=0.0, show_default=True, type=float, metavar="PX",
              help="The robot's plate smeared this many pixels along its heading.")
@click.option("--jpeg", default=0, show_default=True, type=click.IntRange(0, 100),
              help="JPEG quality each frame is compressed at (0: none).")
@click.option("--light-field", default=0.0, show_default=True, type=float, metavar="A",
              help="Patches of light and shade, gain 1 +- A.")
@click.option("--seed", default=0, show_default=True, type=Bounded(limits.SEED))
def render_cmd(out_dir: Path, poses, n_floor: int, n_board: int, noise: float,
               motion_blur: float, jpeg: int, light_field: float, seed: int) -> None:
    """Frames of the virtual camera (the reference set-up: 640x480, 2.5 m up, a distorting
    lens; optionally with a real camera's motion blur, JPEG and patchy light): OUT/floor,
    OUT/board and OUT/robot folders and OUT/truth.json, to try calibrate and check without a
    camera."""
    import cv2
    import numpy as np

    from pac_host.camera.layout import Board
    from pac_host.camera.render import Imaging, Renderer, board_poses, standard_camera

    if min(n_floor, n_board) < 0 or min(noise, motion_blur) < 0 or not 0 <= light_field < 1:
        raise InputError("--floor, --board, --noise and --motion-blur must be >= 0, "
                         "--light-field in [0, 1)")
    cam = standard_camera()
    r = Renderer(cam, imaging=Imaging(noise=noise, motion_blur=motion_blur, jpeg=jpeg,
                                      light_field=light_field, seed=seed))
    rng = np.random.default_rng(seed)
    truth = {"camera_center_cm": cam.center.tolist(), "K": cam.K.tolist(),
             "dist": cam.dist.tolist(), "robot": []}
    for sub in ("floor", "board", "robot"):
        (out_dir / sub).mkdir(parents=True, exist_ok=True)
    for i in range(n_floor):
        cv2.imwrite(str(out_dir / "floor" / f"{i:03d}.png"), r.frame(None, rng))
    board = Board()
    for i, p in enumerate(board_poses(cam, board, n_board, rng)):
        cv2.imwrite(str(out_dir / "board" / f"{i:03d}.png"), r.board_frame(board, *p, rng))
    for i, text in enumerate(poses):
        pose = _pose(text)
        cv2.imwrite(str(out_dir / "robot" / f"{i:03d}.png"), r.frame(pose, rng))
        truth["robot"].append(list(pose))
    (out_dir / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    click.echo(f"wrote {n_floor} floor, {n_board} board and {len(poses)} robot frames "
               f"to {out_dir}")


@camera.command("grab")
@click.option("--source", required=True, metavar="SOURCE", help="A camera index (or video).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path))
@click.option("--count", default=15, show_default=True, type=int)
@click.option("--every", default=1.5, show_default=True, type=float,
              help="Seconds between frames (time to move the lens board).")
def grab_cmd(source, out_dir, count, every) -> None:
    """Save COUNT frames, one every EVERY seconds, as PNGs (lens board or floor images)."""
    import time

    import cv2

    from pac_host.camera.sources import open_source
    from pac_host.robot.observers import ObserverError

    if count < 1 or every < 0:
        raise InputError("--count must be >= 1 and --every >= 0")
    out_dir.mkdir(parents=True, exist_ok=True)
    src = open_source(source)
    try:
        for i in range(count):
            time.sleep(every if i else 0.0)
            try:
                frames = src.window(1, 2.0)
            except ObserverError as e:
                raise InputError(str(e)) from None
            if not frames:
                raise InputError(f"{src.name}: gave no frame within 2 s")
            cv2.imwrite(str(out_dir / f"{i:03d}.png"), frames[0])
            click.echo(f"{out_dir / f'{i:03d}.png'}")
    finally:
        src.close()


@camera.command("calibrate")
@click.option("--floor", "floor_src", required=True, metavar="SOURCE",
              help="Frames of the floor markers: a folder, a video or a camera index.")
@click.option("--lens", "lens_src", default=None, metavar="SOURCE",
              help="Frames of the lens board (ChArUco): fits intrinsics and distortion; or an "
                   "earlier calibration file (.json) whose lens to reuse.")
@click.option("--frames", default=None, type=int,
              help="Frames to take from a camera or video (default: a folder's all, else 10).")
@click.option("--camera-height", default=None, type=float, metavar="CM",
              help="The lens's height above the floor (needed without --lens when the camera "
                   "looks straight down; checked against the fitted one otherwise).")
@layout_option
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The calibration file to write (pac-camera-calibration/1).")
@click.option("--map", "map_path", default=None, type=click.Path(dir_okay=False, path_type=Path),
              help="The PNG of the expected position error over the area (default: beside "
                   "--out, NAME_error_map.png).")
def calibrate_cmd(floor_src, lens_src, frames, camera_height, layout_path, out_path,
                  map_path) -> None:
    """Fit the floor (a homography from >= 4 floor markers at known places) and the camera's
    position, and optionally the lens; check each against physics and its residuals (a
    calibration that fails a check is refused, exit 2); write them to one file with the
    expected position error over the area, and print the quality report."""
    from pac_host.camera.calibrate import calibrate_floor, calibrate_lens, load_lens
    from pac_host.plots import camera_error_map

    if frames is not None and frames < 1:
        raise InputError(f"--frames must be >= 1, got {frames}")
    if camera_height is not None and not camera_height > 0:
        raise InputError(f"--camera-height must be > 0, got {camera_height}")
    layout = _layout(layout_path)
    n = frames if frames is not None or Path(floor_src).is_dir() else 10
    lens = None
    if lens_src is not None and Path(lens_src).suffix.lower() == ".json":
        lens = load_lens(lens_src)
        click.echo(f"lens: from {lens_src} ({lens.images} board images, {lens.error_px:.3f} px "
                   f"RMS, focal {lens.K[0, 0]:.1f} px)")
    elif lens_src is not None:
        m = frames if frames is not None or Path(lens_src).is_dir() else 10
        lens = calibrate_lens(_frames(lens_src, m))
        click.echo(f"lens: {lens.images} board images, reprojection error {lens.error_px:.3f} "
                   f"px RMS, focal {lens.K[0, 0]:.1f} px, distortion ({lens.model}) "
                   + ", ".join(f"{v:.4f}" for v in lens.dist))
    cal = calibrate_floor(_frames(floor_src, n), layout, lens, camera_height)
    map_path = map_path or out_path.with_name(out_path.stem + "_error_map.png")
    cal.save(out_path)
    camera_error_map(cal.error_map, map_path, [(m.x, m.y, m.size) for m in layout.floor])
    e = cal.floor_error_cm
    c = cal.center
    click.echo(f"floor: {len(e['markers'])} markers (ids {e['markers']}) over {e['frames']} "
               f"frame(s), reprojection error {e['rms']:.3f} cm RMS, {e['max']:.3f} cm max")
    click.echo(f"camera at ({c[0]:.1f}, {c[1]:.1f}) cm, {c[2]:.1f} cm above the floor")
    click.echo("quality:")
    for chk in cal.checks:
        line = f"  {'ok' if chk['status'] == 'ok' else 'warning'}: {chk['text']}"
        click.echo(line + (f" ({chk['advice']})" if chk.get("advice") else ""))
    click.echo(f"wrote {out_path} and {map_path}"
               + (f" ({len(cal.warnings)} warning(s))" if cal.warnings else ""))


def _camera_opts(frames: int, window: float, height: float | None):
    from pac_host.camera.observer import CameraOptions

    opts = CameraOptions(frames=frames, window=window, height=height)
    opts.check()
    return opts


@camera.command("check")
@click.option("--source", required=True, metavar="SOURCE", help="A folder, video or camera.")
@click.option("--calib", "calib_path", required=True, type=click.Path(dir_okay=False))
@click.option("--frames", default=1, show_default=True, type=int,
              help="Frames to take (the robot's pose is their median).")
@click.option("--height", default=None, type=float, help="The robot marker's height, cm.")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The PNG to write.")
def check_cmd(source, calib_path, frames, height, out_path) -> None:
    """Draw the detected markers, the area's block grid and the robot's pose on a frame."""
    import cv2

    from pac_host.camera import calibrate as cal
    from pac_host.camera.detect import detect
    from pac_host.camera.draw import check_image
    from pac_host.camera.observer import PoseFinder

    calib = cal.load(calib_path)
    finder = PoseFinder(calib, _camera_opts(frames, 2.0, height))
    for w in calib.warnings:
        click.echo(f"calibration warning: {w['text']}")
    imgs = _frames(source, frames)
    corners = detect(finder.detector, imgs[-1])
    pose, used, why = finder.in_window(imgs, finder.opts.heading0)
    floor_ids = sorted(set(corners) & set(calib.layout.floor_by_id()))
    if not cv2.imwrite(str(out_path), check_image(imgs[-1], calib, corners, pose,
                                                  finder.height)):
        raise InputError(f"cannot write {out_path}")
    click.echo(f"floor markers seen: {len(floor_ids)} of {len(calib.layout.floor)} "
               f"(ids {floor_ids})")
    if pose is None:
        click.echo(f"robot: {why}")
    else:
        click.echo(f"robot at ({pose[0]:.2f}, {pose[1]:.2f}) cm, heading {pose[2]:.2f} deg "
                   f"({used} frame(s))")
    click.echo(f"wrote {out_path}")


@camera.command("serve")
@click.option("--source", required=True, metavar="SOURCE", help="A camera index (or video, "
              "folder).")
@click.option("--calib", "calib_path", required=True, type=click.Path(dir_okay=False))
@click.option("--host", default="0.0.0.0", show_default=True)
@click.option("--port", default=7000, show_default=True, type=int)
@click.option("--frames", default=3, show_default=True, type=int,
              help="Frames per listening window.")
@click.option("--window", default=0.1, show_default=True, type=float,
              help="The listening window, s.")
@click.option("--height", default=None, type=float, help="The robot marker's height, cm.")
def serve_cmd(source, calib_path, host, port, frames, window, height) -> None:
    """Serve the camera's poses to `--observer tracker:HOST:PORT` (it asks for each gait
    cycle's pose when the robot reports it). Stop with Ctrl-C."""
    from pac_host.camera import calibrate as cal
    from pac_host.camera.observer import PoseFinder
    from pac_host.camera.serve import PoseServer
    from pac_host.camera.sources import open_source

    calib = cal.load(calib_path)
    finder = PoseFinder(calib, _camera_opts(frames, window, height))
    src = open_source(source)
    try:
        try:
            server = PoseServer(src, finder, host, port, on_event=click.echo)
        except OSError as e:
            raise InputError(f"cannot listen on {host}:{port}: {e.strerror}") from None
        click.echo(f"serving {src.name} on {server.address[0]}:{server.address[1]}")
        try:
            server.serve()
        finally:
            server.close()
    finally:
        src.close()


def register(main: click.Group) -> None:
    main.add_command(camera)
