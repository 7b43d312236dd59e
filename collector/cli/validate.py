"""``lasercal validate``: a thin layer over :mod:`sessions.settings` and :mod:`sessions.start`."""

from __future__ import annotations

import argparse
import sys

from lasercal.collector.cli.options import (
    INFOLDER,
    LAYOUT,
    ROBOT,
    backend_arguments,
    count,
    motion_arguments,
    output_argument,
    photo_arguments,
    sheet_pose,
    sheet_pose_argument,
    view_arguments,
    view_options,
)


def args_validate(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal validate``."""
    p.add_argument("model", nargs="?", type=ROBOT, help="robot model YAML under test (nominal or identified)")
    p.add_argument("--point", help="validation point (default: the layout's first validation point)")
    p.add_argument("-n", type=count(1, 10000), default=60, help="configurations (default 60)")
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        instead="resume it with --resume {path}",
        metavar="DIR",
        help="new folder: validation.yaml, validation.csv, photos/",
    )
    p.add_argument(
        "--resume",
        type=INFOLDER,
        metavar="DIR",
        help="continue an interrupted validation run (its settings are kept)",
    )
    p.add_argument(
        "--layout",
        type=LAYOUT,
        help="layout YAML (required for a real robot; default with --backend fake: the thesis layout)",
    )
    p.add_argument(
        "--sheet-from",
        type=ROBOT,
        metavar="MODEL.yaml",
        help="sheet layout: place the points where this model's calibration found the sheet, for the model "
        "under test (e.g. the nominal: the 'before'; default: the model's own sheet pose)",
    )
    sheet_pose_argument(
        p,
        "--backend fake, sheet layout: the simulated sheet truly lies here (mm, mm, deg, in the true "
        "robot's own frame, as simulate --sheet-pose; default: where the sheet model's simulated session "
        "put it, else the layout's placement)",
    )
    motion_arguments(p)
    photo_arguments(p)
    view_arguments(p)
    p.add_argument(
        "--camera",
        help="fake, or an OpenCV device: index, URL or frames/%%04d.png (default: fake with --backend fake)",
    )
    p.add_argument(
        "--guide",
        action="store_true",
        help="guide the operator to each configuration even where the backend can move",
    )
    backend_arguments(p)


def cmd_validate(args) -> int:
    from lasercal.collector.sessions.settings import given_settings, validate_settings
    from lasercal.collector.sessions.start import start_validation
    from lasercal.solver.analysis.stats import spot_stats

    settings = validate_settings(
        given_settings(vars(args)),
        args.model,
        args.output,
        args.resume,
        layout=args.layout,
        point=args.point,
        n=args.n,
        camera=args.camera,
        guide=args.guide,
        max_step=args.max_step,
        sheet_from=args.sheet_from,
        sheet_pose=sheet_pose(args.sheet_pose, "--sheet-pose") if args.sheet_pose else None,
    )
    started = start_validation(settings, yes=args.yes)
    res = started.run(sys.stdout, view_options(args, settings.cfg))
    print(f"wrote {res.path} ({res.photos} photos this run; {res.summary()})")
    if not res.complete:
        print(f"continue with: lasercal validate --resume {settings.folder}")
    if len(res.spots) > 1:
        s = spot_stats(res.spots, started.layout.points[started.point])
        print(
            f"{started.point}: {s.n} spots measured: scatter mean {s.scatter_mean:.3f} mm "
            f"(std {s.scatter_std:.3f}), error mean {s.error_mean:.3f} mm (max {s.error_max:.3f})"
        )
    elif res.spots.size == 0 and res.photos:
        print(
            "photos kept, not measured (the layout has no markers): the report needs measured spots -- "
            "validate with a layout with markers (lasercal sheet prints one); lasercal spots "
            f"{res.path.parent}/photos/*.png prints the spots in pixels"
        )
    if res.failed:  # a batch reports its failures in its exit code (1: the run is written, and resumable)
        print(
            f"lasercal: warning: {res.failed} configuration(s) of this run gave no spot (not measured, or "
            "the arm did not come to rest: the lines above say which)",
            file=sys.stderr,
        )
        return 1
    return 0
