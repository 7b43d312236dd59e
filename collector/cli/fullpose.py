"""The full-pose subcommands of ``lasercal``: fullpose and simulate-fullpose (thin handlers)."""

from __future__ import annotations

import argparse

from lasercal.collector.cli.options import (
    FOLDS,
    INFILE,
    ROBOT,
    SEED,
    chain_arguments,
    count,
    number,
    output_argument,
    unused,
)


def args_fullpose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal fullpose``."""
    p.add_argument(
        "measurements",
        type=INFILE,
        help="MEASUREMENTS.csv: config,q1..qN,angle_index,x,y,z (mm, rad); a poses.csv "
        "(q1..qN,r11..r33,x,y,z) is read as full poses",
    )
    p.add_argument(
        "--robot", type=ROBOT, required=True, help="nominal robot: model YAML, URDF or built-in name"
    )
    chain_arguments(p)
    output_argument(p, "-o", "--output", required=True, help="identified model YAML to write")
    p.add_argument(
        "--method",
        choices=["ml", "circle"],
        default="ml",
        help="circle points: ml (default) fits every measured point (maximum likelihood; the circle-point "
        "poses are its start), circle the paper's method (one frame per configuration, then a pose fit)",
    )
    p.add_argument("--folds", type=FOLDS, default=0, help="K of a K-fold cross-validation (default 0: none)")
    p.add_argument(
        "--estimate-frames",
        action="store_true",
        help="estimate the sensor-to-base and tool transforms first (always done when the robot file has no "
        "ee.M)",
    )
    p.add_argument("--seed", type=SEED, default=0, help="shuffle of the cross-validation folds")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def args_simulate_fullpose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal simulate-fullpose``."""
    p.add_argument("--robot", type=ROBOT, required=True, help="true robot: model YAML, URDF or built-in name")
    chain_arguments(p)
    p.add_argument("--configs", type=count(1, 10**5), default=30, help="robot configurations g (default 30)")
    p.add_argument(
        "--angles",
        type=count(3, 360),
        default=6,
        help="angles m of the last joint per configuration (default 6)",
    )
    p.add_argument(
        "--step",
        type=number(1, 120, "deg"),  # below 1 deg: radians, or circles too small to fit
        default=20.0,
        help="the last joint's step, deg (default 20)",
    )
    p.add_argument(
        "--noise",
        type=number(0, 100, "mm"),
        default=0.01,
        help="sensor noise std per axis, mm (default 0.01)",
    )
    p.add_argument(
        "--radius",
        type=number(0, 5000, "mm", lo_open=True, metres=True),
        default=50.0,
        help="target distance from the last axis, mm (default 50)",
    )
    p.add_argument(
        "--offset",
        type=number(-5000, 5000, "mm"),
        default=50.0,
        help="target offset along the last axis from the aperture, mm (default 50)",
    )
    p.add_argument(
        "--sensor",
        type=number(-1e5, 1e5),
        nargs=6,
        metavar=("X", "Y", "Z", "RX", "RY", "RZ"),
        help="the truth's base in the sensor frame: origin (mm) and x-y-z Euler angles (deg, extrinsic); "
        "default: the sensor frame is the base frame",
    )
    p.add_argument("--seed", type=SEED, default=0)
    output_argument(p, "-o", "--output", required=True, help="MEASUREMENTS.csv to write")
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_fullpose(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.fullpose import calibrate_fullpose

    if not args.folds:
        unused(args, "it shuffles the folds of --folds K", "seed")
    res = calibrate_fullpose(
        args.robot,
        args.measurements,
        method=args.method,
        folds=args.folds,
        seed=args.seed,
        estimate_frames=args.estimate_frames,
        base_link=args.base_link,
        tip_link=args.tip_link,
    )
    with atomic_output(args.output) as tmp:
        res.save(tmp)
    if args.json:
        print(res.to_json())
        return 0
    print(res.summary(), end="")
    print(f"\nwrote {args.output}")
    return 0


def cmd_simulate_fullpose(args) -> int:
    import numpy as np

    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.formats.fullpose_io import write_circlepoint_csv
    from lasercal.solver.formats.robots import load_model, resolve_robot_path
    from lasercal.solver.identify.fullpose import default_target, simulate_circlepoint

    X = np.eye(4)
    if args.sensor is not None:
        from scipy.spatial.transform import Rotation

        X[:3, :3] = Rotation.from_euler("xyz", args.sensor[3:], degrees=True).as_matrix()
        X[:3, 3] = args.sensor[:3]
    path = resolve_robot_path(args.robot)
    truth = load_model(path, base_link=args.base_link, tip_link=args.tip_link)
    target = default_target(truth, args.radius, args.offset)
    d = simulate_circlepoint(
        truth,
        args.configs,
        args.angles,
        np.radians(args.step),
        args.noise,
        np.random.default_rng(args.seed),
        target,
        X,
    )
    notes = (
        f"simulated circle-point measurements (lasercal simulate-fullpose); truth {path.resolve()}",
        f"configs {args.configs}, angles {args.angles}, step {args.step} deg, noise {args.noise} mm, seed "
        f"{args.seed}",
        f"target at q = 0 (truth base frame): {target[0]:.6f} {target[1]:.6f} {target[2]:.6f} mm",
        "sensor frame ^S T_base: " + " ".join(f"{v:.9g}" for v in X[:3].ravel()) + " (rows 1-3, mm)",
    )
    with atomic_output(args.output) as tmp:
        write_circlepoint_csv(tmp, d, notes)
    print(
        f"wrote {args.output}: {args.configs} configurations x {args.angles} angles (truth {truth.name}, "
        f"noise {args.noise} mm)"
    )
    return 0
