"""``lasercal plan``: the next K captures that most lower the predicted error where the robot is used."""

from __future__ import annotations

import argparse
import sys

from lasercal.collector.cli.options import (
    INFOLDER,
    LAYOUT,
    SEED,
    SESSION_ROBOT,
    chain_arguments,
    count,
    number,
    output_argument,
    session_robot,
)


def args_plan(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal plan``."""
    p.add_argument(
        "session", type=INFOLDER, help="session folder (session.yaml + captures.csv; no captures yet is fine)"
    )
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument(
        "--layout",
        type=LAYOUT,
        help="layout YAML (default: the points, calibration and validation lists of the session)",
    )
    p.add_argument(
        "--next", type=count(1, 1000), default=10, metavar="K", help="captures to plan (default 10)"
    )
    output_argument(p, "-o", "--output", metavar="NEXT.csv", help="write point,q1..qN,expected_mm here")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    p.add_argument("--json", action="store_true", help="print the plan and the prediction as JSON")
    p.add_argument(
        "--workspace",
        type=number(-1e5, 1e5, "mm", metres=True),
        nargs=6,
        metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
        help="predict the error at points in this box (mm) instead of the layout's validation points",
    )
    p.add_argument(
        "--aim-noise",
        type=number(0, 100, "mm", lo_open=True),
        metavar="MM",
        help="the operator's expected aiming noise per axis, mm (the noise prior; default the prior's "
        "noise_mm.laser, 1.0 unless --prior says otherwise)",
    )
    p.add_argument("--seed", type=SEED, default=0, help="seed of the candidate sampling (default 0)")


def cmd_plan(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.planning import plan
    from lasercal.solver.formats.session import load_session

    ws = None if args.workspace is None else (args.workspace[:3], args.workspace[3:])
    p = plan(
        load_session(args.session, **session_robot(args)),
        next=args.next,
        layout=args.layout,
        workspace=ws,
        aim_noise=args.aim_noise,
        seed=args.seed,
    )
    if args.output:
        with atomic_output(args.output) as tmp:
            p.save(tmp)
    if args.json:
        print(p.to_json())
        return 0
    print(p.summary())
    if not args.output:
        sys.stdout.write(p.csv())
    else:
        print(
            f"wrote {args.output}: {len(p.rows)} configurations, predicted error after them "
            f"{p.plan.expected[-1]:.2f} mm"
        )
    return 0
