"""The full-pose subcommands of ``lasercal``: fullpose and simulate-fullpose (thin handlers)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

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

if TYPE_CHECKING:  # annotations only: the modules load when a command runs
    from lasercal.solver.identify.fullpose import FullPoseCalibration
    from lasercal.solver.identify.fullpose_ml import PointCalibration


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


def _header(path: Path) -> list:
    """The first non-comment line's column names (to tell circle points from poses)."""
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.checks import read_text

    for line in read_text(path).splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return [c.strip() for c in line.split(",")]
    raise FormatError(path, "the file is empty")


def report(cal: FullPoseCalibration | PointCalibration, cv, source: str) -> dict:
    """The JSON-ready statistics of a full-pose calibration (from poses, or from every circle point)."""
    f = cal.fit
    idf = f.identifiability
    if hasattr(cal, "circle"):  # maximum likelihood from the points
        head = {
            "method": "fullpose-ml (every circle point, position model, LM; circle-point start)",
            "measurements": source,
            "poses": int(cal.after.n),
            "points": int(len(f.residuals)),
            "outliers": list(f.outliers),
            "converged": f.converged,
            "iterations": f.iterations,
            "seconds": f.seconds + cal.circle.fit.seconds,
            "sigma_mm": float(f.sigma_mm),
            "gauge": f.extra["gauge"],
            "circle_start": {"accuracy_after": cal.circle.after.to_dict()},
        }
    else:
        head = {
            "method": "fullpose-poe (thesis eq. 2.3.29, Levenberg-Marquardt)",
            "measurements": source,
            "poses": int(len(f.residuals)),
            "converged": f.converged,
            "iterations": f.iterations,
            "seconds": f.seconds,
            "sigma_rad": float(f.sigma[0]),
            "sigma_mm": float(f.sigma[1]),
        }
    rep = {
        **head,
        "identifiability": {
            "parameters": idf.n_params,
            "rank": idf.rank,
            "condition": idf.condition,
            "unidentifiable": list(idf.unidentifiable),
        },
        "accuracy": {
            "before": cal.before.to_dict(),
            "after": cal.after.to_dict(),
            "units": "mm; Euler angles x-y-z of R_pred^T R_meas, deg",
        },
        "std_errors": f.std_errors,
        "history": list(f.history),
    }
    if cal.alignment is not None:
        rep["frames"] = {
            "base": cal.alignment.base.tolist(),
            "tool": cal.alignment.tool.tolist(),
            "ee_nominal": cal.alignment.ee_nominal.tolist(),
        }
    if cv is not None:
        rep["cross_validation"] = {
            "folds": cv.folds,
            "seed": cv.seed,
            "per_fold": list(cv.per_fold),
            **{
                k: getattr(cv, k).to_dict()
                for k in ("nominal_train", "nominal_test", "calibrated_train", "calibrated_test")
            },
        }
    return rep


def cmd_fullpose(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.control.nominal import robot_reference
    from lasercal.solver.formats.fullpose_io import read_circlepoint_csv, read_pose_csv
    from lasercal.solver.formats.robots import load_model, resolve_robot_path
    from lasercal.solver.identify.fullpose import calibrate_fullpose, cross_validate, format_table
    from lasercal.solver.identify.fullpose_ml import calibrate_points, cross_validate_points

    if not args.folds:
        unused(args, "it shuffles the folds of --folds K", "seed")
    model = load_model(args.robot, base_link=args.base_link, tip_link=args.tip_link)
    path = Path(args.measurements)
    estimate = True if args.estimate_frames else None
    points = None
    if "r11" in _header(path):
        d = read_pose_csv(path, model.n)
        q, T = d.q, d.T
    else:
        points = read_circlepoint_csv(path, model.n)
        q, T = points.poses()
    if points is not None and args.method == "ml":
        cal = calibrate_points(model, points, estimate)
        cv = cross_validate_points(model, points, args.folds, args.seed, estimate) if args.folds else None
    else:
        cal = calibrate_fullpose(model, q, T, estimate)
        cv = cross_validate(model, q, T, args.folds, args.seed, estimate) if args.folds else None
    rep = report(cal, cv, str(path.resolve()))
    meta = {
        k: rep[k]
        for k in (
            "method",
            "measurements",
            "poses",
            "converged",
            "iterations",
            "sigma_mm",
            "identifiability",
            "accuracy",
            "std_errors",
        )
    }
    for k in ("sigma_rad", "points", "outliers", "gauge", "frames", "cross_validation"):
        if k in rep:
            meta[k] = rep[k]
    meta["units"] = "mm, rad"
    meta["robot"] = str(resolve_robot_path(args.robot).resolve())
    with atomic_output(args.output) as tmp:
        nominal = robot_reference(args.robot)
        cal.model.replace(identification=json.loads(json.dumps(meta)), nominal=nominal).save(tmp)
    if args.json:
        print(json.dumps(rep, indent=2))
        return 0
    f = cal.fit
    idf = f.identifiability
    what = (
        f"{len(q)} poses"
        if points is None or args.method == "circle"
        else f"{len(q)} poses, {rep['points']} points"
    )
    print(
        f"{what}; {'converged' if f.converged else 'NOT converged'} after {f.iterations} iterations, "
        f"{rep['seconds']:.2f} s"
    )
    print(f"identifiable: rank {idf.rank} of {idf.n_params} parameters, condition number {idf.condition:.3g}")
    for u in idf.unidentifiable:
        print(f"  not seen by the data (held at the start value): {u}")
    if "points" in rep:
        print(f"maximum likelihood from every point; gauge: {rep['gauge']}")
        print(
            f"residual RMS per axis: {rep['sigma_mm']:.4g} mm; {len(rep['outliers'])} point(s) flagged as "
            "outliers"
        )
    else:
        print(
            f"residual RMS per component: rotation {f.sigma[0] * 1e3:.4g} mrad, position {f.sigma[1]:.4g} mm"
        )
    if cal.alignment is not None:
        t = cal.alignment.tool[:3, 3]
        print(
            f"estimated base and tool first: tool offset ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm from the "
            "nominal end-effector frame"
        )
    print()
    print(
        format_table(
            [("nominal", cal.before), ("calibrated", cal.after)],
            "accuracy on the measured poses (Table 4 form)",
        )
    )
    if cv is not None:
        rows = [
            ("nominal train", cv.nominal_train),
            ("nominal test", cv.nominal_test),
            ("calibrated train", cv.calibrated_train),
            ("calibrated test", cv.calibrated_test),
        ]
        print()
        print(format_table(rows, f"{cv.folds}-fold cross-validation"))
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
