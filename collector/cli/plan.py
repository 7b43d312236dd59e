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

MIN_SHEET_CAPTURES = 9  # captures from which a sheet session's own fit places the sheet (else its placement)


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
    from lasercal.solver.analysis.design import Coach, DesignError, posterior
    from lasercal.solver.formats.session import load_layout, load_session, session_layout
    from lasercal.solver.identify.spot import identify_lm, in_base_frame

    session = load_session(args.session, **session_robot(args))
    if session.measurement != "laser":
        raise DesignError("plan designs laser sessions (spot on a plane), not point sessions")
    # the session's own layout keeps its aiming hints (tilt, length), which the constraints obey
    layout = load_layout(args.layout) if args.layout else session_layout(session.meta, session.path)
    if session.frame == "sheet":  # the sheet where the captures so far put it (or its stated placement)
        pose = identify_lm(session).model.sheet if session.m >= MIN_SHEET_CAPTURES else layout.sheet
        layout = layout.in_base(pose)
        session = in_base_frame(session, pose)  # (a pose is known: in_base refused the layout without one)
    nominal = session.robot
    if session.aperture_z is not None:
        nominal = nominal.replace(aperture=np.r_[nominal.aperture[:2], session.aperture_z])
    if session.tolerances is None:
        raise DesignError("plan predicts from a prior: --prior none leaves no prediction to make")
    tol = session.tolerances
    if args.aim_noise is not None:
        tol = tol.with_noise("laser", args.aim_noise)
    post = posterior(nominal, session.q, session.target, tol)
    ws = None if args.workspace is None else (args.workspace[:3], args.workspace[3:])
    coach = Coach(nominal, layout, args.seed, tol, workspace=ws, model=post.model, lookahead=args.next)
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
