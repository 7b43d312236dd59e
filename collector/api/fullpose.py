"""``lasercal.calibrate_fullpose``: full-pose calibration from circle points or measured poses (``lasercal
fullpose``, docs/fullpose.md).

Circle points (``config,q1..qN,angle_index,x,y,z``): 'ml' fits every measured point (maximum likelihood,
:func:`~lasercal.solver.identify.fullpose_ml.calibrate_points`; the circle-point poses are its start),
'circle' the Sensors 2013 method (one frame per configuration, then a pose fit,
:func:`~lasercal.solver.identify.fullpose.calibrate_fullpose`). Measured poses (``q1..qN,r11..r33,x,y,z``)
are fitted as poses.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: numpy and the solver load when a calibration runs
    from lasercal.solver.identify.fullpose import FullPoseCalibration
    from lasercal.solver.identify.fullpose_ml import PointCalibration
    from lasercal.solver.kinematics.model import RobotModel

# the statistics a full-pose model file records under ``identification``
_RECORDED = (
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


@dataclass(frozen=True)
class FullPoseResult:
    """A full-pose calibration with its evidence.

    Attributes
    ----------
    model : RobotModel, the model file's content (:meth:`save`): the identified geometry, ``identification``
        and the ``nominal`` it calibrates
    calibration : FullPoseCalibration or PointCalibration, the fit and the accuracy before and after
    cross_validation : the K-fold result or None
    statistics : dict, what ``lasercal fullpose --json`` prints
    poses : int, configurations measured
    from_points : bool, fitted from every circle point (method 'ml' on circle points)
    """

    model: RobotModel
    calibration: FullPoseCalibration | PointCalibration
    cross_validation: object
    statistics: dict
    poses: int
    from_points: bool

    def save(self, path) -> Path:
        """Write the model file (``lasercal-robot/1`` YAML, mm and rad): the one ``lasercal fullpose -o``
        writes."""
        self.model.save(path)
        return Path(path)

    def to_json(self) -> str:
        """:attr:`statistics` as the JSON ``lasercal fullpose --json`` prints."""
        return json.dumps(self.statistics, indent=2)

    def summary(self) -> str:
        """The text ``lasercal fullpose`` prints (without its closing ``wrote FILE``)."""
        from lasercal.solver.identify.fullpose import format_table

        cal, cv, rep = self.calibration, self.cross_validation, self.statistics
        f = cal.fit
        idf = f.identifiability
        what = f"{self.poses} poses, {rep['points']} points" if self.from_points else f"{self.poses} poses"
        lines = [
            f"{what}; {'converged' if f.converged else 'NOT converged'} after {f.iterations} iterations, "
            f"{rep['seconds']:.2f} s",
            f"identifiable: rank {idf.rank} of {idf.n_params} parameters, condition number "
            f"{idf.condition:.3g}",
        ]
        w = lines.append
        for u in idf.unidentifiable:
            w(f"  not seen by the data (held at the start value): {u}")
        if "points" in rep:
            w(f"maximum likelihood from every point; gauge: {rep['gauge']}")
            w(
                f"residual RMS per axis: {rep['sigma_mm']:.4g} mm; {len(rep['outliers'])} point(s) flagged "
                "as outliers"
            )
        else:
            w(
                f"residual RMS per component: rotation {f.sigma[0] * 1e3:.4g} mrad, position "
                f"{f.sigma[1]:.4g} mm"
            )
        if cal.alignment is not None:
            t = cal.alignment.tool[:3, 3]
            w(
                f"estimated base and tool first: tool offset ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm from "
                "the nominal end-effector frame"
            )
        w("")
        w(
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
            w("")
            w(format_table(rows, f"{cv.folds}-fold cross-validation"))
        return "\n".join(lines) + "\n"


def _header(path: Path) -> list:
    """The first non-comment line's column names (to tell circle points from poses)."""
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.checks import read_text

    for line in read_text(path).splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return [c.strip() for c in line.split(",")]
    raise FormatError(path, "the file is empty")


def fullpose_report(cal: FullPoseCalibration | PointCalibration, cv, source: str) -> dict:
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


def calibrate_fullpose(
    robot,
    measurements,
    *,
    method: str = "ml",
    folds: int = 0,
    seed: int = 0,
    estimate_frames: bool = False,
    base_link: str | None = None,
    tip_link: str | None = None,
) -> FullPoseResult:
    """Calibrate a robot's full pose (POE) from circle-point measurements or measured poses.

    Parameters
    ----------
    robot : str or Path, the nominal robot: a built-in name, a model YAML or a URDF
    measurements : str or Path, circle points (``config,q1..qN,angle_index,x,y,z``, mm, rad) or poses
        (``q1..qN,r11..r33,x,y,z``)
    method : str, circle points: 'ml' (every point, maximum likelihood) or 'circle' (the paper's method)
    folds : int, K of a K-fold cross-validation (0: none)
    seed : int, the shuffle of the folds
    estimate_frames : bool, estimate the sensor-to-base and tool transforms first (always done when the
        robot file has no ``ee.M``)
    base_link, tip_link : str, a URDF's chain ends

    Returns
    -------
    FullPoseResult

    Raises
    ------
    FormatError
        A malformed measurement file (naming file, line and column); IdentificationError for data that
        cannot be fitted.
    """
    from lasercal.solver.control.nominal import robot_reference
    from lasercal.solver.formats.fullpose_io import read_circlepoint_csv, read_pose_csv
    from lasercal.solver.formats.robots import load_model, resolve_robot_path
    from lasercal.solver.identify.fullpose import calibrate_fullpose as fit_poses
    from lasercal.solver.identify.fullpose import cross_validate
    from lasercal.solver.identify.fullpose_ml import calibrate_points, cross_validate_points

    model = load_model(robot, base_link=base_link, tip_link=tip_link)
    path = Path(measurements)
    estimate = True if estimate_frames else None
    points = None
    if "r11" in _header(path):
        d = read_pose_csv(path, model.n)
        q, T = d.q, d.T
    else:
        points = read_circlepoint_csv(path, model.n)
        q, T = points.poses()
    from_points = points is not None and method == "ml"
    if from_points:
        cal = calibrate_points(model, points, estimate)
        cv = cross_validate_points(model, points, folds, seed, estimate) if folds else None
    else:
        cal = fit_poses(model, q, T, estimate)
        cv = cross_validate(model, q, T, folds, seed, estimate) if folds else None
    rep = fullpose_report(cal, cv, str(path.resolve()))
    meta = {k: rep[k] for k in _RECORDED}
    for k in ("sigma_rad", "points", "outliers", "gauge", "frames", "cross_validation"):
        if k in rep:
            meta[k] = rep[k]
    meta["units"] = "mm, rad"
    meta["robot"] = str(resolve_robot_path(robot).resolve())
    identified = cal.model.replace(
        identification=json.loads(json.dumps(meta)), nominal=robot_reference(robot)
    )
    return FullPoseResult(identified, cal, cv, rep, len(q), from_points)
