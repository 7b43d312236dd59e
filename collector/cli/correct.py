"""``lasercal correct``: corrected joint and Cartesian commands for goals or a nominal program (a thin layer
over :mod:`solver.control` and :mod:`solver.formats.goals`)."""

from __future__ import annotations

import argparse
import sys

from lasercal.collector.cli.options import (
    INFILE,
    ROBOT,
    count,
    name,
    number,
    output_argument,
    parse_payload,
    payload_argument,
    unused,
)


def args_correct(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal correct``."""
    p.add_argument(
        "model", type=ROBOT, help="calibrated model YAML (lasercal solve), a built-in robot or a URDF"
    )
    p.add_argument(
        "goals",
        type=INFILE,
        metavar="IN.csv",
        help="goals x,y,z mm [rx,ry,rz rad] [q1..qN seeds, rad], base frame; or a program q1..qN (rad) "
        "planned with the nominal model",
    )
    output_argument(
        p,
        "-o",
        "--output",
        required=True,
        metavar="OUT.csv",
        help="the input columns, cmd_q1..cmd_qN (rad), cmd_x,cmd_y,cmd_z (mm, the nominal model's view) "
        "[cmd_rx,cmd_ry,cmd_rz], residual_mm, ok, reason",
    )
    tool = p.add_mutually_exclusive_group()
    tool.add_argument(
        "--tool",
        type=name,
        metavar="NAME",
        help="a target or tool point the model identified (default: the flange)",
    )
    tool.add_argument(
        "--tcp",
        nargs=3,
        type=number(-5000, 5000, "mm"),
        metavar=("X", "Y", "Z"),
        help="a tool centre point in the flange frame, mm",
    )
    p.add_argument(
        "--margin",
        type=number(0, 0.5, "rad"),
        default=0.01,
        help="distance every command keeps from its joint limits, rad (default 0.01)",
    )
    p.add_argument(
        "--restarts",
        type=count(0, 1000),
        default=8,
        help="further starts from random configurations for a goal not reached (default 8)",
    )
    payload_argument(p, recorded=True)
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_correct(args) -> int:
    import numpy as np

    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.control.robot import load_model
    from lasercal.solver.errors import FormatError, LasercalError
    from lasercal.solver.formats.checks import metres_hint
    from lasercal.solver.formats.goals import load_goals, write_commands
    from lasercal.solver.kinematics.ik import IKOptions

    if args.tcp is not None and metres_hint(args.tcp):
        raise LasercalError(
            f"argument --tcp: {' '.join(f'{v:g}' for v in args.tcp)}: {metres_hint(args.tcp)}"
        )
    options = IKOptions(margin=args.margin, restarts=args.restarts)
    robot = load_model(args.model, options, payload=parse_payload(args.payload))
    if robot.extension is None or "tau" not in robot.extension.needs():
        unused(args, "the model has no compliance", "payload")
    goals = load_goals(args.goals, robot.model)
    try:
        tool = robot.tool(args.tool or args.tcp)
    except FormatError as e:  # the library names its Python argument, the user typed an option
        raise LasercalError(f"argument {'--tool' if args.tool else '--tcp'}: {e.reason}") from None
    c = robot.correct(goals.goal(), q=goals.q if goals.program else None, seed=goals.q, tool=tool)
    comment = (
        f"lasercal correct {args.model} ({robot.model.name}, nominal {robot.nominal.name}), tool "
        f"{tool.name}: angles rad, positions mm, rotation vectors rad, base frame"
    )
    with atomic_output(args.output) as tmp:
        write_commands(tmp, goals, c, comment)
    off = ", ".join(f"{v:.3f}" for v in tool.offset[:3, 3])
    print(f"tool {tool.name}: ({off}) mm in the flange frame (the TCP for the Cartesian commands)")
    print(f"nominal model: {robot.nominal.name} (cmd_x, cmd_y, cmd_z are its view of each command)")
    if goals.program:
        before = robot.fk(goals.q, tool)[:, :3, 3] - robot.fk(goals.q, tool, nominal=True)[:, :3, 3]
        d = np.linalg.norm(before, axis=1)
        print(f"the program as planned misses by {d.mean():.3f} mm mean, {d.max():.3f} mm max (calibrated)")
    ok = int(c.ok.sum())
    print(reached_line(c.ok, c.residual_mm))
    print(f"wrote {args.output}")
    if ok < len(c.ok):
        bad = np.flatnonzero(~c.ok)
        for i in bad[:5]:
            print(f"lasercal: {args.goals}, line {goals.lines[i]}: {c.reason[i]}", file=sys.stderr)
        more = f" (and {len(bad) - 5} more)" if len(bad) > 5 else ""
        print(f"lasercal: {len(bad)} goal(s) not reached{more}: ok = false (see reason)", file=sys.stderr)
        return 1
    return 0


def reached_line(ok, residual_mm) -> str:
    """The summary of a run: goals reached and the largest residual over every goal, the ones not reached
    included (a goal out of reach is its miss, not 0), and over the reached ones when they differ.

    Parameters
    ----------
    ok : (m,) bool array, the goal is reached
    residual_mm : (m,) array, each command's position residual on the calibrated robot, mm
    """

    def mm(v: float) -> str:
        return f"{v:.2g}" if abs(v) < 10 else f"{v:.1f}"

    k, m = int(ok.sum()), len(ok)
    line = f"{k} of {m} goals reached; residual {mm(residual_mm.max(initial=0))} mm max"
    if 0 < k < m:
        line += f" ({mm(residual_mm[ok].max())} mm over the {k} reached)"
    return line
