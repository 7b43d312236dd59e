"""The solver's subcommands of ``lasercal``: solve, predict, simulate (thin layers over the library)."""

from __future__ import annotations

import argparse
import csv
import sys

from lasercal.collector.cli.options import (
    FOLDS,
    INFILE,
    INFOLDER,
    LAYOUT,
    ROBOT,
    SEED,
    SESSION_ROBOT,
    chain_arguments,
    count,
    number,
    output_argument,
    parse_payload,
    payload_argument,
    session_robot,
    sheet_pose,
    sheet_pose_argument,
    unused,
    whole_numbers,
)
from lasercal.solver.kinematics.effects import JOINT_EFFECTS


def args_solve(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal solve``."""
    p.add_argument(
        "session",
        type=INFOLDER,
        nargs="+",
        help="session folder (session.yaml + captures.csv); several pose sessions: one robot, each session's "
        "own sensor and tool frames",
    )
    output_argument(p, "-o", "--output", required=True, help="identified model YAML to write")
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument(
        "--method",
        choices=["lm", "thesis"],
        default="lm",
        help="lm (default, ours) or thesis (Section 3.2 as written)",
    )
    p.add_argument("--folds", type=FOLDS, default=5, help="K of the K-fold cross-validation (0: skip)")
    p.add_argument("--no-robust", action="store_true", help="lm: do not flag or drop outlier captures")
    p.add_argument(
        "--extend",
        default="none",
        choices=["auto", "none"] + list(JOINT_EFFECTS) + ["joint_map", "reference_point_offset"],
        help="auto: diagnose, fit the winning non-geometric effect and keep it if it predicts held-out data "
        "better; or name one (default none; joint_map: the joint error map, pose and position sessions). "
        "Only robot effects (compliance, eccentricity, the joint map) are written to the model",
    )
    p.add_argument(
        "--sheet-shape",
        default="auto",
        choices=["auto", "flat"],
        help="a sheet session (lm): auto (default) tests the print's shear and the paper's curl against a "
        "flat sheet (F test and held-out captures) and models them when the data ask; flat: a plane",
    )
    payload_argument(p)
    p.add_argument("--json", action="store_true", help="print the statistics as JSON")
    p.add_argument(
        "--allow-partial",
        action="store_true",
        help="write a model even when neither the data nor the prior identifies every parameter combination "
        "it needs (with --prior none, or parameters without a prior; marked partial: true, the "
        "unidentifiable combinations listed)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def args_predict(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal predict``."""
    p.add_argument("model", type=ROBOT, help="robot model YAML")
    p.add_argument("configs", type=INFILE, help="configurations CSV (q1..qN; t, tau1..tauN optional)")
    p.add_argument(
        "--plane-z", type=number(-5000, 5000, "mm"), help="plane height, mm (default: the model's plane)"
    )
    payload_argument(p, recorded=True)
    output_argument(p, "-o", "--output", help="CSV to write (default: standard output)")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def args_simulate(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal simulate``."""
    p.add_argument(
        "truth", type=ROBOT, help="true robot model YAML, URDF (position sessions) or built-in name"
    )
    p.add_argument(
        "--layout", type=LAYOUT, help="layout YAML with the reference points (laser and point sessions)"
    )
    p.add_argument(
        "--measurement",
        choices=["laser", "position"],
        default="laser",
        help="position: targets on the tool measured by a 3-D sensor (default laser)",
    )
    p.add_argument("--configs", type=count(1, 10**5), default=60, help="position: robot poses (default 60)")
    p.add_argument(
        "--targets", type=count(1, 100), default=3, help="position: targets on the tool (default 3)"
    )
    p.add_argument(
        "--noise", type=number(0, 100, "mm"), default=0.02, help="position: sensor noise std per axis, mm"
    )
    p.add_argument("--per-point", type=count(1, 10**4), default=15, help="captures per calibration point")
    p.add_argument(
        "--aim-noise", type=number(0, 100, "mm"), default=1.0, help="aiming noise std per axis, mm"
    )
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument(
        "--robot",
        type=ROBOT,
        help="nominal robot the session names (default: the truth file's 'nominal' key)",
    )
    sheet_pose_argument(
        p,
        "laser: the points lie on a sheet at this true pose (mm, mm, deg: p_base = Rz(YAW) p_sheet + "
        "[X, Y, plane z]) in the true robot's own frame (joint 1 as the nominal's); the session says "
        "frame: sheet and gives the layout's placement (where the layout says the points are)",
    )
    chain_arguments(p)
    p.add_argument(
        "--effect",
        choices=list(JOINT_EFFECTS) + ["reference_point_offset"],
        help="hide a non-geometric effect in the data",
    )
    p.add_argument(
        "--effect-joints",
        type=whole_numbers(1, 64),
        default="2",
        help="1-based joints of a joint effect, comma-separated (default 2)",
    )
    p.add_argument("--effect-point", help="the reference point of a reference_point_offset")
    p.add_argument(
        "--effect-size",
        type=number(-100, 100),
        help="c (rad/Nm), eccentricity amplitude (rad), drift r (rad/s) or offset (mm)",
    )
    p.add_argument(
        "--measured",
        type=number(0, 1),
        default=0.0,
        help="laser: the share of captures whose spot a camera measured (0..1, default 0: every capture "
        "aimed by eye); the rest are aimed with --aim-noise",
    )
    p.add_argument(
        "--spot-sigma",
        type=number(1e-4, 10, "mm"),
        default=0.03,
        help="laser: the camera's noise on a measured spot, mm per axis (default 0.03)",
    )
    p.add_argument(
        "--aim-radius",
        type=number(0, 150, "mm"),
        help="laser: each capture aims at a random spot within this radius of its point, mm (default 40 "
        "with --measured, else 0: at the points)",
    )
    output_argument(p, "-o", "--output", kind="folder", required=True, help="session folder to write")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def simulated_sheet(folder, session, model) -> str:
    """A simulated sheet session's truth beside ``solve``'s sheet pose (a line), or '' for any other session:
    the figure a user cannot check against a truth says what it is relative to."""
    from lasercal.collector.hardware import session_world, true_sheet_pose
    from lasercal.collector.report.text import format_true_sheet

    if model.sheet is None:
        return ""
    world = session_world(folder)
    if world is None or world.sheet is None:
        return ""
    true, G = true_sheet_pose(world, session.robot, session.plane_z)
    found = model.sheet.as_dict() | {"std": model.sheet_std}
    return format_true_sheet(found, true, world.sheet, G)


def cmd_solve(args) -> int:
    from lasercal.calibration import calibrate
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.errors import LasercalError, warn
    from lasercal.solver.formats.poses import is_pose_session
    from lasercal.solver.formats.session import load_session

    if any(is_pose_session(s) for s in args.session):
        from lasercal.collector.cli.poses import solve_poses

        unused(
            args,
            "pose sessions",
            "method",
            "payload",
            "allow_partial",
            "base_link",
            "tip_link",
            "sheet_shape",
        )
        return solve_poses(args)
    if len(args.session) > 1:
        raise LasercalError(
            f"{len(args.session)} sessions: only pose sessions (measurement: pose) are solved together"
        )
    args.session = args.session[0]
    if args.extend == "none":
        unused(args, "the diagnosis of --extend takes it", "payload")
    session = load_session(args.session, **session_robot(args))
    cal = calibrate(
        session,
        method=args.method,
        extend=args.extend,
        folds=args.folds,
        robust=not args.no_robust,
        allow_partial=args.allow_partial,
        payload=parse_payload(args.payload),
        sheet_shape=args.sheet_shape,
    )
    if "warning" in cal.statistics:  # on stderr, where a script (and the outside check) looks for it
        warn(f"{args.session}: {cal.statistics['warning']}")
    truth = simulated_sheet(args.session, session, cal.model)  # before writing: a bad truth file is exit 2
    with atomic_output(args.output) as tmp:
        cal.save(tmp)
    if args.json:
        print(cal.to_json())
    else:
        sys.stdout.write(cal.summary())
        sys.stdout.write(truth)
        print(f"\nwrote {args.output}")
    return 0


def cmd_predict(args) -> int:
    if args.output is None:
        return _predict(args)
    from contextlib import redirect_stdout

    from lasercal.collector.sessions.store import atomic_output

    with atomic_output(args.output) as tmp, open(tmp, "w", newline="") as f, redirect_stdout(f):
        code = _predict(args)
    print(predicted_line(args.configs, args.output))
    return code


def predicted_line(configs, output) -> str:
    """What ``predict -o`` wrote, one line: its rows and the columns it added after the input's (every
    kind of model passes the input's columns through first, renamed where a predicted one takes a name)."""
    from lasercal.solver.formats.table import read_csv

    n_in = len(read_csv(configs)[0])
    header, rows = read_csv(output)
    return f"wrote {output}: {len(rows)} rows, the input's columns and {', '.join(header[n_in:])}"


def _predict(args) -> int:
    """``lasercal predict``, writing to standard output."""
    import numpy as np

    from lasercal.solver.control.nominal import gravity_robot
    from lasercal.solver.errors import FormatError, warn
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import header_beside, load_configs
    from lasercal.solver.identify.point import tips
    from lasercal.solver.identify.spot import predict_spots
    from lasercal.solver.kinematics.effects import extension_from_model
    from lasercal.solver.kinematics.gravity import gravity_torques

    model = load_model(args.model)
    if model.identification.get("measurement") == "pose":
        from lasercal.collector.cli.poses import cmd_predict_pose

        unused(args, "a pose model's effects take its robot's own gravity torques", "payload")
        return cmd_predict_pose(model, args)
    if model.identification.get("measurement") == "position":
        from lasercal.collector.cli.position import cmd_predict_position

        return cmd_predict_position(model, args)
    cfg = load_configs(args.configs, model)
    point = model.identification.get("measurement") == "point"
    z = args.plane_z if args.plane_z is not None else model.plane_z
    if z is None and not point:
        raise FormatError(args.model, "the model has no plane; pass --plane-z", field="plane")
    if point and model.tool_point is None:
        raise FormatError(args.model, "a point model needs a tool point (tool: {point: [...]})", field="tool")
    ext = extension_from_model(model.extensions, args.model, model.n)
    q = cfg.q
    if ext is None or "tau" not in ext.needs() or cfg.tau is not None:
        unused(args, "no torques are computed: no compliance, or the CSV's", "payload")
    if ext is not None:
        tau = cfg.tau
        if "tau" in ext.needs() and tau is None:  # none logged: the fit's torques (and its payload)
            tau = gravity_torques(gravity_robot(model, args.model, payload=parse_payload(args.payload)), q)
        if "t" in ext.needs() and cfg.t is None:
            raise FormatError(
                args.configs, f"the model's {ext.effect} extension needs a 't' column (s)", line=1, field="t"
            )
        q = ext.true_q(q, cfg.t, tau)
    w = csv.writer(sys.stdout, lineterminator="\n")
    if point:
        w.writerow(header_beside(cfg.header, ["tip_x", "tip_y", "tip_z"]))
        for row, p in zip(cfg.rows, tips(model, q)):
            w.writerow(row + [f"{c:.6f}" for c in p])
        return 0
    spots, length = predict_spots(model, q, z)
    valid = np.isfinite(length) & (length >= 0)  # a beam away from the plane or along it has no spot
    w.writerow(header_beside(cfg.header, ["spot_x", "spot_y", "laser_length", "valid"]))
    for row, s, t, ok in zip(cfg.rows, spots, length, valid):
        xy = [f"{s[0]:.6f}", f"{s[1]:.6f}"] if ok else ["", ""]
        w.writerow(row + xy + [f"{t:.6f}" if np.isfinite(t) else "", "true" if ok else "false"])
    if not valid.all():
        where = "--plane-z" if args.plane_z is not None else f"{args.model}, field 'plane.z'"
        warn(
            f"{where}: {int((~valid).sum())} of {len(valid)} configurations have no spot: the beam points "
            f"away from the plane z = {z:g} mm or runs along it (valid = false, spot left empty)"
        )
    return 0


def cmd_simulate(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.simulation import simulate
    from lasercal.solver.formats.session import load_layout

    if args.measurement == "position":
        unused(
            args,
            "a position session has no reference points",
            "layout",
            "per_point",
            "aim_noise",
            "sheet_pose",
            "measured",
            "aim_radius",
        )
    elif args.layout:  # (without a layout the simulation refuses to run)
        unused(args, "an option of --measurement position", "configs", "targets", "noise")
    pose = None
    if args.sheet_pose is not None and args.measurement == "laser" and args.layout:
        # a sheet layout's pose is where the sheet lies (at the base: metres), a base layout's a displacement
        pose = sheet_pose(args.sheet_pose, "--sheet-pose", absolute=load_layout(args.layout).frame == "sheet")
    with atomic_output(args.output, folder=True) as tmp:
        sim = simulate(
            args.truth,
            tmp,
            layout=args.layout,
            measurement=args.measurement,
            per_point=args.per_point,
            aim_noise=args.aim_noise,
            seed=args.seed,
            robot=args.robot,
            sheet_pose=pose,
            effect=args.effect,
            effect_joints=args.effect_joints,
            effect_point=args.effect_point,
            effect_size=args.effect_size,
            configs=args.configs,
            targets=args.targets,
            noise=args.noise,
            base_link=args.base_link,
            tip_link=args.tip_link,
            measured=args.measured,
            spot_sigma=args.spot_sigma,
            aim_radius=args.aim_radius,
        )
    print(f"wrote {args.output}: {sim.summary}")
    return 0
