"""The solver's subcommands of ``lasercal``: solve, predict, simulate (thin layers over the library)."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

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
    session_robot,
    sheet_pose,
    unused,
    whole_numbers,
)
from lasercal.solver.kinematics.effects import JOINT_EFFECTS

if TYPE_CHECKING:  # annotations only: the modules load when a command runs
    import numpy as np

    from lasercal.solver.kinematics.effects import Extension


def args_solve(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal solve``."""
    p.add_argument("session", type=INFOLDER, help="session folder (session.yaml + captures.csv)")
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
        choices=["auto", "none"] + list(JOINT_EFFECTS) + ["reference_point_offset"],
        help="auto: diagnose, fit the winning non-geometric effect and keep it if it predicts held-out data "
        "better; or name one (default none). Only robot effects (compliance, eccentricity) are written to "
        "the model",
    )
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
    p.add_argument(
        "--sheet-pose",
        type=number(-1e4, 1e4),
        nargs=3,
        metavar=("X", "Y", "YAW"),
        help="laser: the points lie on a sheet at this true pose (mm, mm, deg: p_base = Rz(YAW) p_sheet + "
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
    output_argument(p, "-o", "--output", kind="folder", required=True, help="session folder to write")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_solve(args) -> int:
    from lasercal.collector.report.text import format_diagnosis, format_solve
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.analysis.diagnose import diagnose
    from lasercal.solver.analysis.stats import cross_validate, solve_report
    from lasercal.solver.control.nominal import robot_reference
    from lasercal.solver.errors import IdentificationError
    from lasercal.solver.formats.session import load_session
    from lasercal.solver.identify.measurement import check_data, fit, refuse_partial, unidentifiable
    from lasercal.solver.kinematics.effects import robot_extensions

    session = load_session(args.session, **session_robot(args))
    check_data(session)
    if args.folds > session.m:
        raise IdentificationError(
            f"--folds {args.folds}: more folds than the session's {session.m} captures (expected 2 .. "
            f"{session.m}, or 0 for none)"
        )
    diagnosis = None
    robust = not args.no_robust
    if args.extend != "none" and args.method != "lm":
        raise IdentificationError("--extend needs --method lm")
    if args.extend != "none":
        diagnosis = diagnose(
            session,
            n_boot=0,  # the decision needs no bootstrap
            k=args.folds,
            effect=None if args.extend == "auto" else args.extend,
            robust=robust,
        )
        ident = diagnosis.extended or diagnosis.geometric
        session = diagnosis.session
    else:
        if session.measurement == "point" and args.method != "lm":
            raise IdentificationError("point sessions are identified by --method lm")
        ident = fit(session, method=args.method, robust=robust)
    missing = unidentifiable(session, ident)
    if not args.allow_partial:
        refuse_partial(missing)
    cv = (
        cross_validate(
            session,
            args.method,
            args.folds,
            inlier=ident.weights > 0,
            robust=robust,
            extension=diagnosis.extension if diagnosis else None,
        )
        if args.folds and args.folds > 1
        else None
    )
    rep = solve_report(session, ident, cv)
    if diagnosis is not None:
        rep["diagnosis"] = diagnosis.as_dict()
    meta = {
        k: rep[k]
        for k in (
            "method",
            "converged",
            "iterations",
            "captures",
            "fit_rms_mm",
            "sigma_mm",
            "identifiability",
        )
    }
    meta.update(
        {
            "measurement": session.measurement,
            "session": str(Path(args.session).resolve()),
            "units": "mm, rad",
            "std_errors": rep.get("std_errors", {}),
        }
    )
    rep["partial"] = meta["partial"] = bool(missing)
    if missing:
        rep["unidentifiable_combinations"] = meta["unidentifiable_combinations"] = [
            {"combination": d.combination, "fix": d.fix, "directions": d.directions} for d in missing
        ]
    for k in ("prior", "determined_by", "cross_validation", "diagnosis"):
        if k in rep:
            meta[k] = rep[k]
    # MODEL.yaml carries robot effects only: a session effect (drift, a misplaced point) was fitted so that
    # it does not bend the geometry, and is reported in identification.diagnosis, not applied at run time
    # the nominal it calibrates, named so that it is found from anywhere (lasercal correct needs it)
    ref = (args.robot, None) if args.robot else (session.meta["robot"], session.path)
    nominal = robot_reference(*ref)
    with atomic_output(args.output) as tmp:
        ident.model.replace(
            identification=meta, extensions=robot_extensions(ident.model.extensions), nominal=nominal
        ).save(tmp)
    if args.json:
        print(json.dumps(rep, indent=2))
    else:
        sys.stdout.write(format_solve(rep))
        for d in missing:
            print(f"PARTIAL: not identified: {d}")
        if diagnosis is not None:
            print("\n" + format_diagnosis(diagnosis))
        print(f"\nwrote {args.output}")
    return 0


def cmd_predict(args) -> int:
    if args.output is None:
        return _predict(args)
    from contextlib import redirect_stdout

    from lasercal.collector.sessions.store import atomic_output

    with atomic_output(args.output) as tmp, open(tmp, "w", newline="") as f, redirect_stdout(f):
        return _predict(args)


def _predict(args) -> int:
    """``lasercal predict``, writing to standard output."""
    import numpy as np

    from lasercal.solver.errors import FormatError, warn
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_configs
    from lasercal.solver.identify.point import tips
    from lasercal.solver.identify.spot import predict_spots
    from lasercal.solver.kinematics.effects import extension_from_model
    from lasercal.solver.kinematics.gravity import gravity_torques

    model = load_model(args.model)
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
    if ext is not None:
        tau = cfg.tau
        if "tau" in ext.needs() and tau is None:
            tau = gravity_torques(model, q)  # no logged torques: the robot's gravity model at these poses
        if "t" in ext.needs() and cfg.t is None:
            raise FormatError(
                args.configs, f"the model's {ext.effect} extension needs a 't' column (s)", line=1, field="t"
            )
        q = ext.true_q(q, cfg.t, tau)
    w = csv.writer(sys.stdout, lineterminator="\n")
    if point:
        w.writerow(cfg.header + ["tip_x", "tip_y", "tip_z"])
        for row, p in zip(cfg.rows, tips(model, q)):
            w.writerow(row + [f"{c:.6f}" for c in p])
        return 0
    spots, length = predict_spots(model, q, z)
    valid = np.isfinite(length) & (length >= 0)  # a beam away from the plane or along it has no spot
    w.writerow(cfg.header + ["spot_x", "spot_y", "laser_length", "valid"])
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


def hidden_effect(args, layout, n: int, rng: np.random.Generator) -> Extension | None:
    """The effect ``simulate --effect`` hides, with its true parameters (random phase/direction from the
    seed)."""
    import numpy as np

    from lasercal.solver.errors import FormatError
    from lasercal.solver.kinematics.effects import Extension

    if not args.effect:
        given = [
            f for f, v in (("--effect-size", args.effect_size), ("--effect-point", args.effect_point)) if v
        ]
        if given:
            raise FormatError(
                "--effect", f"{given[0]} was given without --effect NAME (which effect to hide?)"
            )
        return None
    if args.effect_size is None:
        raise FormatError("--effect-size", "give the size of the hidden effect")
    size = args.effect_size
    if args.effect == "reference_point_offset":
        if layout is None or args.effect_point not in layout.points:
            raise FormatError(
                args.layout,
                f"--effect-point {args.effect_point!r} is not a point of the layout",
                field="points",
            )
        phi = rng.uniform(0, 2 * np.pi)
        return Extension(args.effect, (), args.effect_point, size * np.array([np.cos(phi), np.sin(phi)]))
    joints = tuple(args.effect_joints)
    if any(not 1 <= j <= n for j in joints):
        raise FormatError("--effect-joints", f"joints are numbered 1..{n}")
    if args.effect == "encoder_eccentricity":
        phi = rng.uniform(0, 2 * np.pi, len(joints))
        params = np.stack([size * np.cos(phi), size * np.sin(phi)], axis=1).ravel()
    else:
        params = np.full(len(joints), size)
    return Extension(args.effect, joints, None, params)


def sheet_world(truth, nominal, layout, pose):
    """``simulate --sheet-pose``: the true robot in its own frame (eq. S2), the layout as a sheet (a base
    layout's points become sheet coordinates, placed where the layout says), the points where the sheet
    truly lies (``pose``, a SheetPose), and what the session records of it.

    Returns
    -------
    (truth in its own frame, the sheet layout, the layout at the true pose (base frame), dict)
    """
    from dataclasses import replace

    import numpy as np

    from lasercal.solver.kinematics.sheet import SheetPose, moved, own_frame

    if layout.frame == "base":
        pts = {k: np.r_[v[:2], 0.0] for k, v in layout.points.items()}
        layout = replace(layout, points=pts, frame="sheet", sheet=SheetPose())
    own = moved(truth, own_frame(truth, nominal))
    return (
        own,
        layout,
        layout.in_base(pose),
        {
            "pose": pose.as_dict(),
            "frame": "the true robot's own (joint 1 as the nominal's, joint 2 at q = 0 in its direction)",
            "truth_in_own_frame": "truth.yaml",
        },
    )


def cmd_simulate(args) -> int:
    import numpy as np

    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.analysis.simulate import simulate_captures
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.robots import load_model, load_yaml, resolve_robot_path
    from lasercal.solver.formats.session import load_layout, session_meta, write_session

    path = Path(args.truth) if str(args.truth).lower().endswith(".urdf") else resolve_robot_path(args.truth)
    if args.measurement == "position":
        from lasercal.collector.cli.position import cmd_simulate_position

        unused(
            args,
            "a position session has no reference points",
            "layout",
            "per_point",
            "aim_noise",
            "sheet_pose",
        )

        n = load_model(path, base_link=args.base_link, tip_link=args.tip_link).n
        return cmd_simulate_position(
            args, path, hidden_effect(args, None, n, np.random.default_rng(args.seed + 1))
        )
    if not args.layout:
        raise FormatError("--layout", "a laser session needs a layout (--layout)")
    unused(args, "an option of --measurement position", "configs", "targets", "noise")
    truth = load_model(path, base_link=args.base_link, tip_link=args.tip_link)
    raw = load_yaml(path)
    nominal = args.robot or raw.get("nominal") or str(path.resolve())
    layout = load_layout(args.layout)
    rng = np.random.default_rng(args.seed)
    effect = hidden_effect(args, layout, truth.n, rng)
    sim = {"truth": str(path.resolve()), "aim_noise_mm": args.aim_noise, "seed": args.seed}
    aimed = layout
    if args.sheet_pose is not None:
        # a sheet layout's pose is where the sheet lies (at the base: metres), a base layout's a displacement
        pose = sheet_pose(args.sheet_pose, "--sheet-pose", absolute=layout.frame == "sheet")
        truth, layout, aimed, sim["sheet"] = sheet_world(truth, load_model(nominal, base=path.parent), layout,
                                                         pose)  # fmt: skip
    elif layout.frame == "sheet":
        aimed = layout.in_base()  # the sheet lies where its placement says
    c = simulate_captures(truth, aimed, args.per_point, args.aim_noise, rng, effect=effect)
    if effect is not None:
        sim["effect"] = {"name": effect.effect, **effect.to_dict()}
    meta = session_meta(nominal, layout, truth.aperture[2], simulated=sim)
    with atomic_output(args.output, folder=True) as tmp:
        write_session(tmp, meta, c.point, c.t, c.q, tau=c.tau)
        if args.sheet_pose is not None:
            truth.save(Path(tmp) / sim["sheet"]["truth_in_own_frame"])
    hidden = (
        f", hidden {effect.effect} {effect.names} = {np.round(effect.params, 9).tolist()}" if effect else ""
    )
    print(
        f"wrote {args.output}: {len(c.q)} captures at {', '.join(layout.calibration)} (truth {truth.name}, "
        f"aiming noise {args.aim_noise} mm{hidden})"
    )
    return 0
