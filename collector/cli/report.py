"""``lasercal report`` and ``lasercal export``: thin layers over collector.report and solver.export."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lasercal.collector.cli.options import (
    INFOLDER,
    ROBOT,
    SESSION_ROBOT,
    bootstrap_arguments,
    chain_arguments,
    output_argument,
    session_robot,
    unused,
)
from lasercal.solver.formats.export import FORMATS
from lasercal.solver.formats.franka import ROBOT_IDS


def args_report(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal report``."""
    p.add_argument(
        "folders",
        nargs="+",
        type=INFOLDER,
        metavar="SESSION",
        help="one capture session folder (session.yaml) and any number of lasercal validate folders "
        "(validation.yaml) at one point, shown in the order given (e.g. the nominal model's first)",
    )
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        required=True,
        metavar="DIR",
        help="folder for index.html and its PNG plots",
    )
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument(
        "--method", choices=("lm", "thesis"), default="lm", help="identification method (default lm)"
    )
    bootstrap_arguments(p)
    p.add_argument("--force", action="store_true", help="replace an existing output")


def args_export(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal export``."""
    p.add_argument(
        "model", type=ROBOT, help="robot model YAML (e.g. written by lasercal solve) or a built-in name"
    )
    p.add_argument(
        "--format",
        choices=FORMATS + ("franka",),
        default="urdf",
        help="urdf (default), dh, yaml, or franka: franka_description's robots/<id>/kinematics.yaml "
        "(docs/use.md)",
    )
    p.add_argument(
        "--robot-id",
        choices=ROBOT_IDS,
        help="--format franka: the franka_description robot (default: fer for a Panda, fr3 for an FR3)",
    )
    output_argument(p, "-o", "--output", metavar="FILE", help="write here (default: standard output)")
    output_argument(
        p,
        "--sensor-output",
        metavar="FILE",
        help="urdf of a model from a URDF: also write the sensor-to-base transform as a URDF of its own",
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_report(args) -> int:
    from lasercal.calibration import calibrate
    from lasercal.collector.errors import SessionError
    from lasercal.collector.report.html import load_validation
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.session import load_session

    sessions, validations = [], []
    for f in map(Path, args.folders):
        if (f / "session.yaml").is_file():
            sessions.append(f)
        elif (f / "validation.yaml").is_file():
            validations.append(load_validation(f))
        else:
            raise FormatError(
                f, "neither a capture session (session.yaml) nor a validation folder (validation.yaml)"
            )
    if len(sessions) != 1:
        raise SessionError(
            "report needs exactly one capture session folder (with session.yaml) among its folders, got "
            f"{len(sessions)}"
        )
    session = load_session(sessions[0], **session_robot(args))
    if session.measurement != "laser":
        raise FormatError(
            sessions[0], "the report covers laser sessions (spots on a plane)", field="measurement"
        )
    cal = calibrate(session, method=args.method, folds=0, allow_partial=True)
    with atomic_output(args.output, folder=True) as tmp:
        cal.report(tmp, validations, n_boot=args.bootstrap, n_refit=args.refits, seed=args.seed)
    print(f"wrote {Path(args.output) / 'index.html'}")
    return 0


def cmd_export(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.errors import LasercalError, ModelError
    from lasercal.solver.formats.export import export
    from lasercal.solver.formats.robots import load_model

    model = load_model(args.model)
    if args.format == "franka":
        from lasercal.solver.formats.franka import to_franka

        try:
            text = to_franka(model, args.robot_id)
        except ModelError as e:  # a model the file cannot describe: named with the option and the model
            raise LasercalError(f"argument --format franka: {args.model}: {e}") from None
        _franka_notes(model, args.robot_id)
    else:
        text = export(model, args.format)
        unused(args, "it names the robot of --format franka", "robot_id")
        if args.format == "urdf":  # a joint's origin cannot say it bends: said here, not only in a comment
            from lasercal.solver.errors import warn
            from lasercal.solver.formats.franka import effect_notes

            for s in effect_notes(model):
                warn(f"not in the URDF: {s}")
    if args.sensor_output:
        from lasercal.solver.formats.urdf import sensor_urdf

        with atomic_output(args.sensor_output) as tmp:
            tmp.write_text(sensor_urdf(model))
        print(f"wrote {args.sensor_output}", file=sys.stderr)
    if args.output:
        with atomic_output(args.output) as tmp:
            tmp.write_text(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


def _franka_notes(model, robot_id) -> None:
    """What kinematics.yaml cannot carry, one warning each with its size (never dropped in silence)."""
    from lasercal.solver.errors import warn
    from lasercal.solver.formats.franka import not_carried, robot_id_note

    if robot_id and robot_id_note(model, robot_id):
        warn(robot_id_note(model, robot_id))
    for s in not_carried(model):
        warn(f"not in kinematics.yaml: {s}")
