"""``lasercal plan``: the next K captures that most lower the predicted error where the robot is used."""

from __future__ import annotations

import argparse
import csv
import json
import sys

import numpy as np

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
        default=1.0,
        metavar="MM",
        help="the operator's expected aiming noise per axis, mm (prior; default 1.0)",
    )
    p.add_argument("--seed", type=SEED, default=0, help="seed of the candidate sampling (default 0)")


def cmd_plan(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.analysis.design import Coach, DesignError, Prior, posterior
    from lasercal.solver.formats.session import load_layout, load_session, session_layout

    session = load_session(args.session, **session_robot(args))
    if session.measurement != "laser":
        raise DesignError("plan designs laser sessions (spot on a plane), not point sessions")
    # the session's own layout keeps its aiming hints (tilt, length), which the constraints obey
    layout = load_layout(args.layout) if args.layout else session_layout(session.meta, session.path)
    nominal = session.robot
    if session.aperture_z is not None:
        nominal = nominal.replace(aperture=np.r_[nominal.aperture[:2], session.aperture_z])
    prior = Prior(aim_mm=args.aim_noise)
    post = posterior(nominal, session.q, session.target, prior)
    ws = None if args.workspace is None else (args.workspace[:3], args.workspace[3:])
    coach = Coach(nominal, layout, args.seed, prior, workspace=ws, model=post.model, lookahead=args.next)
    coach.post = post
    st = coach.status(session.q)
    plan = st.plan
    header = ["point"] + [f"q{i}" for i in range(1, nominal.n + 1)] + ["expected_mm"]
    rows = [
        [str(nm)] + [f"{a:.6f}" for a in q] + [f"{e:.4f}"]
        for nm, q, e in zip(plan.point, plan.q, plan.expected)
    ]
    if args.output:
        with atomic_output(args.output) as tmp, open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows(rows)
    if args.json:
        print(
            json.dumps(
                {
                    "captures": session.m,
                    "identifiable": {"rank": st.rank, "of": st.n_identifiable, "parameters": st.n_params},
                    "region": st.region,
                    "predicted_mm": round(st.predicted, 4),
                    "uncertainty_mm": round(st.uncertainty, 4),
                    "sigma_mm": round(post.sigma, 4),
                    "next": [dict(zip(header, r)) for r in rows],
                },
                indent=2,
            )
        )
        return 0
    print(
        f"{session.m} captures; identifiable {st.rank} of {st.n_identifiable} ({st.n_params} parameters); "
        f"predicted error at {st.region}: {st.predicted:.2f} ± {st.uncertainty:.2f} mm"
    )
    if not args.output:
        csv.writer(sys.stdout, lineterminator="\n").writerows([header] + rows)
    else:
        print(
            f"wrote {args.output}: {len(rows)} configurations, predicted error after them "
            f"{plan.expected[-1]:.2f} mm"
        )
    return 0
