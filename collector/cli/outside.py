"""``lasercal new-session`` and ``lasercal configurations``: the pieces an outside robot script needs
(:mod:`sessions.outside`)."""

from __future__ import annotations

import argparse

from lasercal.collector.cli.options import LAYOUT, ROBOT, SEED, count, output_argument


def args_new_session(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal new-session``."""
    output_argument(
        p, "-o", "--output", kind="folder", required=True, metavar="SESSION", help="new session folder"
    )
    p.add_argument("--layout", type=LAYOUT, required=True, help="layout YAML (lasercal sheet's layout.yaml)")
    p.add_argument("--robot", type=ROBOT, default="panda", help="nominal robot: built-in name or YAML")
    p.add_argument(
        "--camera",
        action="store_true",
        help="the captures are measured by a camera (camera_x .. camera_note columns; docs/formats.md)",
    )
    p.add_argument(
        "--aim",
        choices=("anywhere", "cross"),
        help="with --camera: anywhere (default on a sheet lasercal sheet printed: plan plans spots anywhere "
        "on its white paper, aim_x, aim_y columns) or cross (beside each cross)",
    )
    p.add_argument(
        "--per-point", type=count(1, 10000), default=9, metavar="N", help="captures at each calibration point"
    )
    p.add_argument(
        "--no-torques",
        action="store_true",
        help="no dq1..dqN, tau1..tauN columns (a tool that reads joint positions only)",
    )


def cmd_new_session(args) -> int:
    from lasercal.collector.sessions.outside import write_empty_session
    from lasercal.collector.sessions.store import atomic_output

    if args.aim and not args.camera:
        from lasercal.collector.errors import SessionError

        raise SessionError("--aim: where a camera session's spots are planned; it needs --camera")
    with atomic_output(args.output, folder=True) as tmp:
        c = write_empty_session(
            tmp, args.layout, args.robot, args.camera, args.aim, args.per_point, not args.no_torques
        )
    cols = ", ".join(c["extra_columns"]) or "none"
    print(
        f"wrote {args.output}/session.yaml and an empty captures.csv (robot {args.robot}, aim {c['aim']}, "
        f"{args.per_point} per point; extra columns: {cols})"
    )
    print(
        f"next: lasercal plan {args.output} --next 5 -o next.csv (the poses and spots to capture); append "
        f"each capture to {args.output}/captures.csv (docs/formats.md); then lasercal solve {args.output} -o "
        "model.yaml"
    )
    return 0


def args_configurations(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal configurations``."""
    p.add_argument(
        "model", type=ROBOT, help="robot model (YAML or built-in name): the one validate would test"
    )
    p.add_argument("--layout", type=LAYOUT, required=True, help="layout YAML or built-in name")
    p.add_argument("--point", help="the point (default: the layout's first validation point)")
    p.add_argument("-n", type=count(1, 10000), default=60, help="configurations (default 60)")
    p.add_argument(
        "--seed", type=SEED, default=0, help="seed of the aiming IK (validate's --seed; default 0)"
    )
    p.add_argument(
        "--sheet-from",
        type=ROBOT,
        metavar="MODEL.yaml",
        help="sheet layout: the points where this model's calibration found the sheet (default: MODEL's own)",
    )
    output_argument(p, "-o", "--output", required=True, metavar="OUT.csv", help="the configurations, CSV")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_configurations(args) -> int:
    from lasercal.collector.sessions.outside import model_configurations
    from lasercal.collector.sessions.store import atomic_output, csv_line

    q, p, point, _ = model_configurations(
        args.model, args.layout, args.point, args.n, args.seed, args.sheet_from
    )
    sheet = (
        f", the sheet where {args.sheet_from or args.model} found it"
        if args.sheet_from or _sheet(args)
        else ""
    )
    head = [
        f"# lasercal configurations of {args.model} at {point} (what validate -n {args.n} --seed {args.seed} "
        f"would command{sheet}): q1..q{q.shape[1]} rad; point_x, point_y, point_z mm, base frame (where the "
        "model's beam meets the plane)\n"
    ]
    header = ["index"] + [f"q{j + 1}" for j in range(q.shape[1])] + ["point_x", "point_y", "point_z"]
    lines = [csv_line(header).decode()]
    lines += [csv_line([str(i), *map(float, row), *map(float, p)]).decode() for i, row in enumerate(q)]
    with atomic_output(args.output) as tmp:
        tmp.write_text("".join(head + lines))
    print(
        f"wrote {args.output}: {len(q)} configurations of {args.model} aiming at {point} "
        f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) mm"
    )
    return 0


def _sheet(args) -> bool:
    from lasercal.solver.formats.session import load_layout

    return load_layout(args.layout).frame == "sheet"
