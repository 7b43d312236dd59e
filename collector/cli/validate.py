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
    photo_options_used,
    resume_or_another,
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
        instead=resume_or_another(
            "validate", "validation.yaml", "a validation run", {"session.yaml": "a capture session"}
        ),
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
    from lasercal.collector.errors import InputEnded
    from lasercal.collector.sessions.settings import given_settings, validate_settings
    from lasercal.collector.sessions.start import start_validation
    from lasercal.solver.analysis.stats import spot_stats
    from lasercal.solver.errors import LasercalError

    photo_options_used(args, True)  # a validation always photographs
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
    if args.sheet_pose:
        try:
            stated_sheet_check(started, args.sheet_pose)
        except LasercalError:
            started.camera.close()
            raise
    try:
        res = started.run(sys.stdout, view_options(args, settings.cfg))
    except InputEnded as e:  # the operator's trigger (a real robot guided by hand) read standard input
        raise LasercalError(
            f"{e}; what was measured is in {settings.folder}: continue with: lasercal validate --resume "
            f"{settings.folder}"
        ) from None
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


SHEET_WARN_MM = 10.0  # a sheet found by solve lies within ~1 mm of the truth (0.3 mm sigma, docs/sessions.md)
SHEET_OFF_MM = 100.0  # half an A4 sheet's short side: beyond, the model's spot falls off the stated sheet


def stated_sheet_check(started, values) -> None:
    """``--sheet-pose`` (where the simulated sheet truly lies) against where the model aims: the validation
    point laid by the stated pose, seen from the model's spot at it (eq. S1, in the sheet's frame, mm).
    Farther than :data:`SHEET_OFF_MM`, the validation would measure where the sheet was put, not the model:
    refused; farther than :data:`SHEET_WARN_MM`, a warning (a sheet moved since the calibration, or a
    typing slip).

    Raises
    ------
    LasercalError
        Naming the option, the point and both places.
    """
    import numpy as np

    from lasercal.solver.errors import LasercalError, warn
    from lasercal.solver.formats.session import load_layout

    stated = started.world.sheet
    aimed = started.layout.points[started.point]  # base frame, where the model's sheet pose puts the point
    on_sheet = load_layout(started.settings.file("layout")).points[started.point][:2]
    off = float(np.linalg.norm(stated.from_base(aimed[None])[0] - on_sheet))
    if off <= SHEET_WARN_MM:
        return
    given = " ".join(f"{v:g}" for v in values)
    true = stated.to_base(on_sheet[None], started.layout.plane_z)[0]
    what = (
        f"argument --sheet-pose {given}: lays {started.point} at ({true[0]:.1f}, {true[1]:.1f}) mm, "
        f"{off:.1f} mm from where the model aims at it ({aimed[0]:.1f}, {aimed[1]:.1f}) mm"
    )
    if off > SHEET_OFF_MM:
        raise LasercalError(
            f"{what}: its spot would miss the sheet (expected the sheet's true pose, within mm of the one "
            "the model's calibration found)"
        )
    warn(f"{what}: the validation measures the sheet's displacement, not the model")
