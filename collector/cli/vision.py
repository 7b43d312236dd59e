"""The vision subcommands: ``spots``, ``beam-check``, ``camera-calibrate``.

Handlers print results to stdout and per-photo problems to stderr while the batch goes on; they
return 0, or 2 when a photo was lost (one error line names it: a batch reports its failures in its
exit code) or nothing could be measured. Errors that stop the
whole command are raised as :class:`~lasercal.vision.errors.VisionError` for the main
program to report.

Units: pixels (OpenCV convention unless ``--convention imagej``: +0.5 px), mm on
the plane in the layout's frame (the robot base frame, or a printed sheet's own frame with
``frame: sheet``; ``spots --model`` adds base-frame mm through the model's sheet pose), tilt in
mrad and degrees.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from lasercal.collector.cli.options import (
    INFILE,
    LAYOUT,
    count,
    number,
    output_argument,
    unused,
    view_arguments,
    view_options,
)

if TYPE_CHECKING:  # annotations only: the modules load when a command runs
    from lasercal.vision.measure import Options


def _warn(msg: str) -> None:
    print(f"lasercal: warning: {msg}", file=sys.stderr)


def _expect(text: str) -> int | None:
    if text == "any":
        return None
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of spots or 'any', got '{text}'") from None
    if n < 1:
        raise argparse.ArgumentTypeError("expected at least 1 spot (or 'any')")
    return n


def _reference(text: str) -> str:
    return text if text == "median" else INFILE(text)


def _pattern_size(text: str) -> tuple[int, int]:
    try:
        cols, rows = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected COLSxROWS like 9x6, got '{text}'") from None
    if cols < 2 or rows < 2:
        raise argparse.ArgumentTypeError("COLS and ROWS must be at least 2")
    return cols, rows


def _add_measure_args(p: argparse.ArgumentParser, expect_default: str = "1") -> None:
    p.add_argument(
        "--layout",
        type=LAYOUT,
        metavar="LAYOUT.yaml",
        help="layout with a 'markers' section: report x_mm, y_mm",
    )
    p.add_argument(
        "--camera",
        metavar="CAMERA.yaml",
        help="camera YAML from camera-calibrate: undo lens distortion",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    output_argument(
        p,
        "--overlay",
        kind="into",
        metavar="DIR",
        help="write annotated PNGs to DIR",
        writes=lambda args: [overlay_name(path) for path in args.images],
    )
    p.add_argument(
        "--method",
        choices=("precise", "imagej"),
        default="precise",
        help="centroid method (default precise: background-subtracted weighted centroid)",
    )
    p.add_argument(
        "--imagej-mode",
        choices=("centroid", "com"),
        default="centroid",
        help="imagej: Measure's Centroid or Center of Mass (default centroid)",
    )
    p.add_argument(
        "--imagej-threshold",
        choices=("default", "otsu"),
        default="default",
        help="imagej: auto-threshold method (default: ImageJ's Default, modified IsoData)",
    )
    p.add_argument(
        "--imagej-box",
        type=count(0, 100000),
        default=64,
        metavar="PX",
        help="imagej: side of the box drawn around each spot, px; 0: the whole photo (default 64)",
    )
    p.add_argument(
        "--convention",
        choices=("opencv", "imagej"),
        default="opencv",
        help="pixel coordinates: opencv (pixel centres at integers) or imagej (+0.5 px)",
    )
    p.add_argument(
        "--reference",
        type=_reference,
        metavar="OFF.jpg|median",
        help="laser-off photo of the same view, or 'median' of the photos given",
    )
    p.add_argument(
        "--expect",
        type=_expect,
        default=_expect(expect_default),
        metavar="N|any",
        help=f"spots expected per photo; more is an error for that photo (default {expect_default})",
    )
    p.add_argument(
        "--color",
        dest="colour",
        choices=("auto", "red", "green"),
        default="auto",
        help="laser colour (default auto: decided from each photo, reported per spot)",
    )
    p.add_argument(
        "--gamma",
        type=number(0.5, 4),
        default=2.2,
        help="encoding gamma of the photos, in [0.5, 4] (2.2 camera JPEG, 1 linear data)",
    )
    p.add_argument(
        "--channel",
        choices=("auto", "laser", "luma"),
        default="auto",
        help="precise centroid on the laser's colour channel or the luma; auto: luma for JPEGs "
        "with subsampled colour, else the laser's channel",
    )


def args_spots(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal spots``."""
    p.add_argument("images", nargs="+", metavar="IMAGE")
    _add_measure_args(p)
    p.add_argument(
        "--model",
        metavar="MODEL.yaml",
        help="with a 'frame: sheet' layout: an identified model whose 'sheet' pose (from solve) adds "
        "base-frame mm (bx_mm, by_mm)",
    )


def args_beam_check(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal beam-check``."""
    p.add_argument("images", nargs="*", metavar="IMAGE")
    p.add_argument(
        "--device",
        help="take the photos live instead (an OpenCV device index, URL or frames/%%04d.png): Enter at each "
        "joint-7 angle, q when done; with --save",
    )
    p.add_argument("--save", metavar="FOLDER", help="with --device: a new or empty folder for the photos")
    view_arguments(p)
    p.add_argument(
        "--laser-length",
        type=number(0, 1e4, "mm", lo_open=True, metres=True),
        metavar="MM",
        help="distance from where the beam meets the joint-7 axis to the plane, mm (for the tilt)",
    )
    _add_measure_args(p)


def args_camera_calibrate(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal camera-calibrate``."""
    p.add_argument("photos", nargs="+", metavar="PHOTO")
    output_argument(p, "-o", "--output", required=True, metavar="CAMERA.yaml")
    p.add_argument("--force", action="store_true", help="replace an existing camera YAML")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--chessboard", type=_pattern_size, metavar="COLSxROWS", help="inner corners, e.g. 9x6")
    g.add_argument("--charuco", type=_pattern_size, metavar="COLSxROWS", help="squares, e.g. 7x5")
    p.add_argument(
        "--square",
        type=number(0, 1000, "mm", lo_open=True, metres=True),
        required=True,
        metavar="MM",
        help="square side, mm",
    )
    p.add_argument(
        "--marker",
        type=number(0, 1000, "mm", lo_open=True, metres=True),
        metavar="MM",
        help="ChArUco marker side, mm",
    )
    p.add_argument("--dictionary", default="DICT_4X4_50", help="ChArUco dictionary (default DICT_4X4_50)")


def _options(args) -> Options:
    from lasercal.vision.measure import Options

    if args.method != "imagej":
        unused(args, "an option of --method imagej", "imagej_mode", "imagej_threshold", "imagej_box")

    return Options(
        args.method,
        args.imagej_mode,
        args.imagej_threshold,
        args.imagej_box,
        args.colour,
        args.expect,
        args.gamma,
        args.channel,
    )


def _context(args):
    """Layout, camera and reference photo shared by a batch (errors stop the command)."""
    from lasercal.vision.camera import load_camera
    from lasercal.vision.images import read_image
    from lasercal.vision.measure import median_reference
    from lasercal.vision.plane import load_markers

    layout = load_markers(args.layout) if args.layout else None
    if args.layout and layout is None:
        _warn(f"{args.layout} has no 'markers' section: positions in px only")
    camera = load_camera(args.camera) if args.camera else None
    if args.reference == "median":
        reference = median_reference(args.images)
    else:
        reference = read_image(args.reference) if args.reference else None
    return layout, camera, reference


def _measure_all(args):
    """Measure every photo; a lost photo becomes an entry with ``error`` (the batch goes on) and is
    named by :func:`lost_photos`. The overlays are written only when no photo was lost (a bad input
    leaves no file behind).

    Returns
    -------
    (list of (JSON entry, PhotoResult or None), MarkerLayout or None)
    """
    from lasercal.vision.images import exif_orientation, read_image
    from lasercal.vision.measure import measure_file
    from lasercal.vision.overlay import draw, write

    layout, camera, reference = _context(args)
    opts = _options(args)
    how = opts.method if opts.method == "precise" else f"imagej {opts.imagej_threshold} {opts.imagej_mode}"
    results = []
    for path in args.images:
        res = measure_file(path, opts, layout, camera, reference)
        if res.error is None:
            for w in res.warnings:
                _warn(f"{path}: {w}")
        entry = res.to_dict(opts.method, args.convention, layout.plane_z if layout else None)
        if layout is not None:
            entry["frame"] = layout.frame
        results.append((entry, None if res.error else res))
    if args.overlay and all(r is not None for _, r in results):
        for path, (_, res) in zip(args.images, results):
            up = exif_orientation(path)
            image = draw(read_image(path), res.spots, res.plane, f"{path}  [{how}]", args.convention, up)
            write(Path(args.overlay) / overlay_name(path), image)
    return results, layout


def lost_photos(entries: list) -> int:
    """0 when every photo of a batch was measured; else one error line naming the lost ones (why, for
    the first three) on stderr, and 2: a batch reports its failures in its exit code."""
    lost = [e for e in entries if e["error"]]
    if not lost:
        return 0
    why = "; ".join(e["error"] if e["error"].startswith(e["image"]) else f"{e['image']}: {e['error']}"
                    for e in lost[:3])  # fmt: skip
    more = f"; and {len(lost) - 3} more" if len(lost) > 3 else ""
    print(
        f"lasercal: error: {len(lost)} of {len(entries)} photos not measured ({why}{more})", file=sys.stderr
    )
    return 2


def overlay_name(photo: str) -> str:
    """The name of a photo's annotated copy in ``--overlay DIR``."""
    return Path(photo).stem + ".overlay.png"


def _fmt(x, spec):
    return "-" if x is None else format(x, spec)


def _sheet_pose(model_path: str, layout):
    """The identified sheet pose (eq. S1) of ``--model``, for a ``frame: sheet`` layout.

    Raises
    ------
    LasercalError
        No sheet layout, or a model without a ``sheet`` pose.
    """
    from lasercal.solver.errors import LasercalError
    from lasercal.solver.formats.robots import load_model

    if layout is None or layout.frame != "sheet":
        raise LasercalError(
            "--model turns sheet mm into base-frame mm: it needs --layout with 'frame: sheet' (the mm of a "
            "base-frame layout already are)"
        )
    pose = getattr(load_model(model_path), "sheet", None)
    if pose is None:
        raise LasercalError(
            f"{model_path}: no 'sheet' pose; solve a session whose layout says 'frame: sheet' to identify "
            "where the sheet lies"
        )
    return pose


def _add_base_mm(entries: list, pose) -> None:
    """Each spot's base-frame ``x_base_mm, y_base_mm`` from its sheet mm (eq. S1), in place."""
    import numpy as np

    spots = [s for e in entries for s in e["spots"] if s["x_mm"] is not None]
    if spots:
        xy = pose.to_base(np.array([[s["x_mm"], s["y_mm"]] for s in spots]), 0.0)  # x, y only
        for s, p in zip(spots, xy):
            s["x_base_mm"], s["y_base_mm"] = round(float(p[0]), 4), round(float(p[1]), 4)
    for e in entries:
        e["sheet_pose"] = pose.as_dict()


def spots_command(args) -> int:
    """``lasercal spots``: print spots per photo; 2 when no photo gave a spot."""
    from lasercal.vision.plane import load_markers

    base = args.model is not None
    pose = _sheet_pose(args.model, load_markers(args.layout) if args.layout else None) if base else None
    results, layout = _measure_all(args)
    entries = [e for e, _ in results]
    if base:
        _add_base_mm(entries, pose)
    frame = layout.frame if layout is not None else "base"
    if args.json:
        print(json.dumps(entries, indent=2))
    else:
        mm = f"{frame} frame on the plane"
        mm += f"; bx_mm, by_mm: base frame through {args.model}" if base else ""
        print(f"# pixels: {args.convention} convention; mm: {mm}; method: {args.method}")
        head = (
            "image",
            "#",
            "u_px",
            "v_px",
            "sd_u",
            "sd_v",
            "x_mm",
            "y_mm",
            "sd_x",
            "sd_y",
            "peak",
            "sat",
            "area",
        ) + (("bx_mm", "by_mm") if base else ())
        print(
            "{:<28} {:>2} {:>10} {:>10} {:>6} {:>6} {:>10} {:>10} {:>6} {:>6} {:>6} {:>3} {:>6}".format(*head)
            + "".join(f" {h:>10}" for h in head[13:])
        )
        for e in entries:
            if e["error"]:
                print(f"{e['image']:<28}  error: {e['error']}")
            for n, s in enumerate(e["spots"], 1):
                print(
                    f"{e['image']:<28} {n:>2} {s['u']:>10.3f} {s['v']:>10.3f} "
                    f"{_fmt(s['sigma_u'], '6.3f'):>6} "
                    f"{_fmt(s['sigma_v'], '6.3f'):>6} {_fmt(s['x_mm'], '10.3f'):>10} "
                    f"{_fmt(s['y_mm'], '10.3f'):>10} "
                    f"{_fmt(s['sigma_x_mm'], '6.3f'):>6} {_fmt(s['sigma_y_mm'], '6.3f'):>6} "
                    f"{s['peak']:>6.0f} "
                    f"{'yes' if s['saturated'] else 'no':>3} {s['area']:>6}"
                    + "".join(f" {_fmt(s.get(k), '10.3f'):>10}" for k in ("x_base_mm", "y_base_mm") if base)
                )
            if e["plane"]:
                p = e["plane"]
                print(
                    f"{'':<28}    plane: {len(p['markers'])} markers, {p['charuco_corners']} ChArUco "
                    "corners, "
                    f"fit RMS {p['rms_mm']:.3f} mm, {p['mm_per_px']:.4f} mm/px"
                )
    return lost_photos(entries) or (0 if any(e["spots"] for e in entries) else 2)


def beam_check_command(args) -> int:
    """``lasercal beam-check``: circle through the spots of a joint-7 turn."""
    import numpy as np

    from lasercal.vision.beamcheck import fit_circle, tilt
    from lasercal.vision.errors import CalibrationError, VisionError

    if args.expect != 1:
        raise VisionError("beam-check takes one spot per photo (--expect 1)")
    if args.device:  # the photos taken live (sessions.beamphotos), then measured as given ones
        args.images = _beam_photos(args)
    elif not args.images:
        raise VisionError("beam-check needs IMAGE... (or --device with --save to take them live)")
    measured, layout = _measure_all(args)
    results = [(e, r) for e, r in measured if r is not None]
    photo_warnings = [f"{e['image']}: {w}" for e, _ in results for w in e["warnings"]]  # already printed
    warnings = []
    if len(results) < 3:
        raise CalibrationError(
            f"beam-check needs at least 3 photos with a spot, {len(results)} of {len(args.images)} had one"
        )
    uv = np.array([[r.spots[0].u, r.spots[0].v] for _, r in results])
    d = np.linalg.norm(uv[:, None] - uv[None], axis=2) + np.eye(len(uv))
    if d.min() < 1e-3:  # a photo given twice (or taken twice at one angle) is no second point of the circle
        i, j = sorted(np.unravel_index(np.argmin(d), d.shape))
        raise CalibrationError(
            f"{results[i][0]['image']} and {results[j][0]['image']} show the same spot ({uv[i, 0]:.2f}, "
            f"{uv[i, 1]:.2f}) px: the same photo twice? (expected one photo per joint-7 angle)"
        )
    c_px = fit_circle(uv)
    mm = all(r.plane is not None for _, r in results)
    c_mm = fit_circle(np.array([[r.spots[0].x_mm, r.spots[0].y_mm] for _, r in results])) if mm else None
    t = None
    if args.laser_length is not None:
        if c_mm is None:
            warnings.append("tilt needs the radius in mm: give --layout with markers")
        else:
            t = tilt(c_mm.radius, args.laser_length)
    if len(results) == 3:
        warnings.append("3 spots define a circle exactly: no check of the fit (take more photos)")
    if c_px.arc_deg < 90:
        warnings.append(
            f"the spots span only {c_px.arc_deg:.0f} deg of the circle: radius and centre are "
            "poorly determined (turn joint 7 further)"
        )
    for w in warnings:
        _warn(w)
    shift = 0.5 if args.convention == "imagej" else 0.0

    def r4(x):
        return None if x is None or not np.isfinite(x) else round(float(x), 4)

    out = {
        "images": [e["image"] for e, _ in results],
        "spots": [{"image": e["image"], **e["spots"][0]} for e, _ in results],
        "convention": args.convention,
        "centre_px": [r4(c_px.centre[0] + shift), r4(c_px.centre[1] + shift)],
        "radius_px": r4(c_px.radius),
        "radius_sigma_px": r4(c_px.radius_sigma),
        "rms_px": r4(c_px.rms),
        "centre_mm": None if c_mm is None else [r4(c_mm.centre[0]), r4(c_mm.centre[1])],
        "radius_mm": None if c_mm is None else r4(c_mm.radius),
        "radius_sigma_mm": None if c_mm is None else r4(c_mm.radius_sigma),
        "rms_mm": None if c_mm is None else r4(c_mm.rms),
        "arc_deg": r4(c_px.arc_deg),
        "laser_length_mm": args.laser_length,
        "tilt_mrad": None if t is None else r4(t * 1e3),
        "tilt_deg": None if t is None else r4(np.degrees(t)),
        "warnings": photo_warnings + warnings,
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"beam-check: {len(results)} spots, arc {c_px.arc_deg:.0f} deg")
        print(
            f"  circle (px): centre ({out['centre_px'][0]:.2f}, {out['centre_px'][1]:.2f}), radius "
            f"{c_px.radius:.3f} px, fit RMS {c_px.rms:.3f} px"
        )
        if c_mm is not None:
            print(
                f"  circle (mm): centre = joint-7 axis on the plane ({c_mm.centre[0]:.3f}, "
                f"{c_mm.centre[1]:.3f}) mm ({layout.frame} frame), "
                f"radius {c_mm.radius:.3f} +- {_fmt(out['radius_sigma_mm'], '.3f')} mm, fit RMS "
                f"{c_mm.rms:.3f} mm"
            )
        if t is not None:
            print(
                f"  beam tilt from the joint-7 axis: {t * 1e3:.3f} mrad = {np.degrees(t):.4f} deg "
                f"(laser length {args.laser_length:g} mm; an upper bound if the beam misses the axis)"
            )
    return lost_photos([e for e, _ in measured])


def _beam_photos(args) -> list[str]:
    """``beam-check --device``: the photos taken live, with the live view if asked."""
    from lasercal.collector.errors import SessionError
    from lasercal.collector.hardware.cameras import OpenCVCamera
    from lasercal.collector.hardware.triggers import EnterTrigger
    from lasercal.collector.sessions.beamphotos import take_beam_photos

    if args.images or not args.save:
        raise SessionError("beam-check --device takes its photos live: drop IMAGE..., give --save FOLDER")
    view = view_options(args)
    camera = OpenCVCamera(int(args.device) if args.device.isdigit() else args.device)
    return take_beam_photos(camera, Path(args.save), EnterTrigger(), view, args.layout)


def camera_calibrate_command(args) -> int:
    """``lasercal camera-calibrate``: write a camera YAML."""
    import numpy as np

    from lasercal.collector.sessions.store import atomic_output
    from lasercal.vision.camera import calibrate, save_camera
    from lasercal.vision.errors import CalibrationError, VisionError
    from lasercal.vision.images import read_image, to_gray

    if args.charuco:
        if args.marker is None or not 0 < args.marker < args.square:
            raise VisionError("--charuco needs --marker MM, smaller than --square")
        pattern = {
            "type": "charuco",
            "cols": args.charuco[0],
            "rows": args.charuco[1],
            "square": args.square,
            "marker": args.marker,
            "dictionary": args.dictionary,
        }
    else:
        unused(args, "a chessboard has no markers", "marker", "dictionary")
        pattern = {
            "type": "chessboard",
            "cols": args.chessboard[0],
            "rows": args.chessboard[1],
            "square": args.square,
        }
    images, lost = [], []
    for path in args.photos:
        try:
            images.append((path, to_gray(read_image(path))))
        except VisionError as exc:
            lost.append(str(exc))
    if lost:  # a photo named and not read is a failure of the batch, before anything is written
        more = f"; and {len(lost) - 3} more" if len(lost) > 3 else ""
        raise CalibrationError(
            f"{len(lost)} of {len(args.photos)} photos unreadable ({'; '.join(lost[:3])}{more})"
        )
    cam, used = calibrate(images, pattern, _warn)
    with atomic_output(args.output) as tmp:
        save_camera(tmp, cam, pattern, used)
    print(
        f"camera: {cam.size[0]}x{cam.size[1]} px, fx {cam.K[0, 0]:.2f} fy {cam.K[1, 1]:.2f} px, "
        f"centre ({cam.K[0, 2]:.2f}, {cam.K[1, 2]:.2f}) px, dist {np.round(cam.dist[:5], 5).tolist()}, "
        f"RMS reprojection {cam.rms_px:.3f} px from {used} photos -> {args.output}"
    )
    return 0
