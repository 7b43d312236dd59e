"""Pose sessions on the command line: ``import-ipa``, ``register``, and the pose pieces of ``solve`` and
``predict`` (called from cli/solve.py). Thin layers over solver.identify.poses and solver.analysis.pose_cv."""

from __future__ import annotations

import argparse
import json
import sys

from lasercal.collector.cli.options import INFOLDER, ROBOT, output_argument


def args_import_ipa(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal import-ipa``."""
    p.add_argument("series", type=INFOLDER, help="one published series folder (e.g. ur10-tracker/Series_A)")
    output_argument(p, "-o", "--output", kind="folder", required=True, help="pose session folder to write")
    p.add_argument(
        "--half",
        choices=["first", "second"],
        help="only this half of the series in recording order (rows 1..m/2 or the rest): register a model on "
        "one half of a later series, predict the other",
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_import_ipa(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.formats.ipa import write_ipa_session

    with atomic_output(args.output, folder=True) as tmp:
        m = write_ipa_session(args.series, tmp, args.half)
    half = f", the {args.half} half of the series" if args.half else ""
    print(
        f"wrote {args.output}: {m} poses{half} (robot ur10; the probe in the tracker frame, mm and rotation "
        "vector)"
    )
    return 0


def args_register(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal register``."""
    p.add_argument("model", type=ROBOT, help="a model calibrated from pose sessions (lasercal solve)")
    p.add_argument(
        "session", type=INFOLDER, help="pose session measured after the move (session.yaml + captures.csv)"
    )
    output_argument(
        p, "-o", "--output", required=True, help="model YAML to write: the robot kept, the frames new"
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_register(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.analysis.pose_cv import register
    from lasercal.solver.formats.poses import load_pose_session

    model = pose_model(args.model)
    session = load_pose_session(args.session, robot=args.model)
    fit = register(model, session)
    ((pos, rot),) = fit.errors.values()
    with atomic_output(args.output) as tmp:
        fit.model.save(tmp)
    print(
        f"registered {session.name} ({session.m} poses): sensor and tool frames fitted, robot kept; "
        f"residual mean {pos.mean():.3f} mm, {1e3 * rot.mean():.3f} mrad\nwrote {args.output}"
    )
    return 0


def pose_model(path):
    """A model calibrated from pose sessions (``identification.measurement: pose``), else a one-line error."""
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.robots import load_model

    model = load_model(path)
    if (
        model.identification.get("measurement") != "pose"
        or model.sensor_pose is None
        or model.ee_pose is None
    ):
        raise FormatError(
            path,
            "not a pose model (expected one written by 'lasercal solve' of pose sessions)",
            field="identification",
        )
    return model


def solve_poses(args) -> int:
    """``lasercal solve S1 [S2 ...]`` of pose sessions: one robot, each session's own frames."""
    import numpy as np

    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.analysis.pose_cv import candidates, covering, extend_auto, held_out
    from lasercal.solver.errors import LasercalError
    from lasercal.solver.formats.poses import load_pose_session
    from lasercal.solver.identify.poses import fit_poses

    if args.extend not in POSE_EXTEND:
        raise LasercalError(f"--extend {args.extend}: pose sessions take {', '.join(POSE_EXTEND)}")
    sessions = [load_pose_session(s, robot=args.robot) for s in args.session]
    names = [s.name for s in sessions]
    if len(set(names)) != len(names):
        raise LasercalError(
            f"two sessions share the folder name {names[0]!r}: each session's frames go by it"
        )
    nominal = sessions[0].robot
    if args.prior is not None:
        from dataclasses import replace

        from lasercal.solver.formats.tolerances import load_tolerances

        tol = load_tolerances(args.prior, nominal)
        sessions = [replace(s, tolerances=tol) for s in sessions]
    table = None
    if args.extend == "auto":
        auto = extend_auto(sessions, nominal, robust=not args.no_robust)
        fit, table = auto.fit, auto.table
    else:
        ext, jm = named_extension(args.extend, candidates(nominal, sessions))
        fit = fit_poses(sessions, nominal, ext, jm, robust=not args.no_robust)
    model = fit.model.replace(nominal=str(sessions[0].meta.get("robot", nominal.name)))
    with atomic_output(args.output) as tmp:
        model.save(tmp)
    stats = pose_statistics(sessions, fit, model, args)
    out = [f"pose sessions: {', '.join(f'{s.name} ({s.m})' for s in sessions)}; {fit.seconds:.1f} s"]
    out.append(
        f"noise the data show: {fit.sigma_pos:.3f} mm, {1e3 * fit.sigma_rot:.3f} mrad per axis; "
        f"{model.identification['outliers']} outlier poses left out"
    )
    for nm, (p, r) in fit.errors.items():
        out.append(f"  {nm}: fitted poses mean {p.mean():.3f} mm, {1e3 * r.mean():.3f} mrad")
    if table:
        out.append("held out (leave one session out; frames registered on one half, the other half scored):")
        for row in table:
            out.append(
                f"  {row['label']}: {row['position_mm']:.3f} mm, {row['rotation_mrad']:.3f} mrad "
                f"(fitted {row['train_position_mm']:.3f} mm)"
            )
        out += chosen_in_folds(auto)
        out.append(f"kept: {auto.chosen}")
        stats.update(extend_auto_statistics(auto))
    elif args.folds and len(sessions) > 1:
        loso = []
        for k, held in enumerate(sessions):
            train = [s for j, s in enumerate(sessions) if j != k]
            ext, jm = fit.effects
            # each fold its own fit, from the nominal (pose_cv's module docstring)
            f = fit_poses(train, nominal, ext, covering(jm, train), robust=not args.no_robust)
            p, r = held_out(f, held)
            loso.append({"held": held.name, "position_mm": p, "rotation_mrad": 1e3 * r})
            out.append(f"  held out {held.name}: {p:.3f} mm, {1e3 * r:.3f} mrad")
        pos, rot = (float(np.mean([f[k] for f in loso])) for k in ("position_mm", "rotation_mrad"))
        out.append(f"leave one session out: {pos:.3f} mm, {rot:.3f} mrad mean")
        stats["leave_one_session_out"] = {"folds": loso, "position_mm": pos, "rotation_mrad": rot}
    if args.json:
        print(json.dumps(stats, indent=2))
    else:
        print("\n".join(out) + f"\nwrote {args.output}")
    return 0


def pose_statistics(sessions: list, fit, model, args) -> dict:
    """What ``solve --json`` prints for pose sessions: the fit (mm, mrad), each session's fitted errors and
    the model written."""
    return {
        "measurement": "pose",
        "units": {"position": "mm", "rotation": "mrad"},
        "sessions": [
            {
                "name": s.name,
                "poses": s.m,
                "fitted_position_mm": float(fit.errors[s.name][0].mean()),
                "fitted_rotation_mrad": 1e3 * float(fit.errors[s.name][1].mean()),
            }
            for s in sessions
        ],
        "extend": args.extend,
        "noise": {"position_mm": float(fit.sigma_pos), "rotation_mrad": 1e3 * float(fit.sigma_rot)},
        "outliers": int(model.identification["outliers"]),
        "seconds": float(fit.seconds),
        "output": str(args.output),
    }


def extend_auto_statistics(auto) -> dict:
    """``--extend auto``'s part of ``solve --json`` on pose sessions: every candidate's held-out row, each
    outer fold's own choice, their held-out figure and agreement, and the candidate kept (pose_cv)."""
    return {
        "held_out": auto.table,
        "fold_choices": list(auto.folds),
        "nested": auto.nested,
        "best": auto.best,
        "kept": auto.chosen,
        "folds_disagreed": auto.chosen != auto.best,
    }


def chosen_in_folds(auto) -> list:
    """The lines saying what each outer fold chose from its training sessions alone, the held-out error of
    those choices (the figure ``--extend auto`` stands by) and whether the folds agreed (pose_cv)."""
    n = auto.nested
    if n is None:
        return ["the choice inside each fold: not made (no fold's inner fits could be made)"]
    geo = n["geometric_position_mm"]
    out = [
        "the choice made inside each fold (leave one out of its training sessions alone; of one session's "
        "blocks):",
        *(f"  {f['held']} held out: {f['chose'] or 'no choice (an inner fit failed): the geometry'}, "
          f"{f['position_mm']:.3f} mm, {f['rotation_mrad']:.3f} mrad" for f in auto.folds),
        f"held out with each fold's own choice: {n['position_mm']:.3f} mm, {n['rotation_mrad']:.3f} mrad "
        f"(geometric {geo:.3f} mm: {100 * (geo - n['position_mm']) / geo:+.1f} %); "
        f"{n['agree']} of {len(auto.folds)} folds chose {auto.best} ({n['needed']} needed)",
    ]  # fmt: skip
    if auto.chosen != auto.best:
        out.append(f"{auto.best}, best held out, is not named: the folds disagreed")
    return out


POSE_EXTEND = ("none", "auto", "joint_compliance", "joint_map")  # solve --extend of pose sessions


def named_extension(name: str, cands: list) -> tuple:
    """(Extension or None, JointMap or None) of ``solve --extend NAME`` on pose sessions: 'joint_compliance'
    on the joints the gravity model loads, 'joint_map' the joint error map alone, 'none' neither."""
    from lasercal.solver.errors import LasercalError

    if name == "joint_map":
        return None, cands[-1].joint_map
    if name == "joint_compliance":
        comp = [c for c in cands if c.extension is not None and c.joint_map is None]
        if not comp:
            raise LasercalError(
                "--extend joint_compliance: no joint's gravity torque spans 5 Nm over these sessions "
                "(or the robot has no link masses)"
            )
        return comp[0].extension, None
    return None, None


def cmd_predict_pose(model, args) -> int:
    """``lasercal predict`` of a pose model: x, y, z (mm) and rx, ry, rz (rad, rotation vector) of the
    frame in the sensor frame, each input row followed by them. A pose session's measured columns carried
    from the input are renamed ``measured_x`` ... ``measured_rz`` (as a position session's): a name written
    twice would leave a CSV reader one of the two."""
    from lasercal.solver.formats.poses import POSE, write_pose_rows
    from lasercal.solver.formats.session import header_beside, load_configs
    from lasercal.solver.identify.poses import model_effects, session_frames

    pose_model(args.model)
    cfg = load_configs(args.configs, model)
    T = session_frames(model, cfg.q, model.sensor_pose, model.ee_pose, model_effects(model, args.model))
    carried = header_beside(cfg.header, list(POSE))[: len(cfg.header)]
    write_pose_rows(sys.stdout, carried, cfg.rows, T)
    return 0
