"""``lasercal.calibrate``: one calibration of a session, with all that ``lasercal solve`` decides and prints.

The decisions of a calibration, in order (:func:`calibrate`):

1. refuse data that cannot identify the geometry (:func:`~lasercal.solver.identify.measurement.check_data`)
   and more folds than captures;
2. fit the geometry (``extend="none"``), or diagnose and fit the winning non-geometric effect with it
   (``"auto"``: kept if it predicts held-out captures better; an effect's name: that effect, kept whatever
   the held-out data say) -- :func:`~lasercal.solver.analysis.diagnose.diagnose` without its bootstrap;
3. name what neither the data nor the prior identifies, and refuse a partial model unless asked;
4. K-fold cross-validate the same fit (``folds``; 0 skips);
5. the statistics (:func:`~lasercal.solver.analysis.stats.solve_report`) and the model file: the model,
   its robot effects only (a session effect -- drift, a misplaced point -- was fitted so that it does not
   bend the geometry, and is reported, not applied at run time), what identified it, and the nominal it
   calibrates, named so that it is found from any folder (``lasercal correct`` needs it).

The command line's ``lasercal solve`` is this function, its :meth:`Calibration.save` and its
:meth:`Calibration.summary`; ``lasercal report`` is :meth:`Calibration.report`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from lasercal.solver.analysis import ALPHA  # a constant: loads neither numpy nor the solver

if TYPE_CHECKING:  # annotations only: numpy and the solver load when a calibration runs
    from lasercal.solver.analysis.diagnose import Diagnosis
    from lasercal.solver.analysis.stats import CrossValidation
    from lasercal.solver.formats.session import Session
    from lasercal.solver.identify.spot import Identification
    from lasercal.solver.kinematics.model import RobotModel

METHODS = ("lm", "thesis")
# the statistics a model file records under ``identification`` (beside what is added below)
_RECORDED = ("method", "converged", "iterations", "captures", "fit_rms_mm", "sigma_mm", "identifiability")


@dataclass(frozen=True)
class Calibration:
    """A calibrated session: the model, how it was identified, and the evidence.

    Attributes
    ----------
    model : RobotModel, the model file's content (what :meth:`save` writes): the identified geometry, its
        robot effects, ``identification`` (below) and the ``nominal`` it calibrates
    identification : Identification, the fit (parameters, standard errors, residuals, identifiability;
        with the extension when one was kept)
    session : Session, the calibrated session (the diagnosed one, with its torques, when ``extend`` ran)
    statistics : dict, what ``lasercal solve --json`` prints: fit, outliers, identifiability, before/after
        per point (mm), ``prior`` and ``determined_by`` (what the data and what the prior determined),
        ``cross_validation``, ``diagnosis``, ``partial``
    diagnosis : Diagnosis or None, the diagnosis that chose the extension (``extend`` not 'none')
    cross_validation : CrossValidation or None, the K-fold held-out errors (None for ``folds=0``)
    unidentifiable : tuple of Deficiency, the parameter combinations neither the data nor the prior
        identifies (empty unless ``allow_partial``)
    source : Session, the session as given to :func:`calibrate`
    method : str, 'lm' or 'thesis'
    robust : bool, whether outlier captures were flagged and dropped
    """

    model: RobotModel
    identification: Identification
    session: Session
    statistics: dict
    diagnosis: Diagnosis | None
    cross_validation: CrossValidation | None
    unidentifiable: tuple
    source: Session
    method: str
    robust: bool

    @property
    def partial(self) -> bool:
        """True when the model leaves parameter combinations unidentified (written with ``partial: true``)."""
        return bool(self.unidentifiable)

    def save(self, path) -> Path:
        """Write the model file (``lasercal-robot/1`` YAML, mm and rad): the one ``lasercal solve -o`` writes.

        Parameters
        ----------
        path : str or Path, the file (replaced if it exists)

        Returns
        -------
        Path
        """
        self.model.save(path)
        return Path(path)

    def summary(self) -> str:
        """The text ``lasercal solve`` prints (without its closing ``wrote FILE``): the fit, the
        identifiability, before/after per point, the prior, the held-out errors, what is not identified
        and the diagnosis."""
        from lasercal.collector.report.text import format_diagnosis, format_solve

        text = format_solve(self.statistics)
        text += "".join(f"PARTIAL: not identified: {d}\n" for d in self.unidentifiable)
        if self.diagnosis is not None:
            text += "\n" + format_diagnosis(self.diagnosis) + "\n"
        return text

    def to_json(self) -> str:
        """:attr:`statistics` as the JSON ``lasercal solve --json`` prints."""
        return json.dumps(self.statistics, indent=2)

    def report(
        self,
        folder,
        validations=(),
        *,
        n_boot: int = 2000,
        n_refit: int = 10,
        seed: int = 0,
        reference: dict | None = None,
        title: str | None = None,
    ) -> Path:
        """Write the HTML report (``index.html`` and its PNG plots) of a laser session's geometric
        calibration into ``folder``: the one ``lasercal report`` writes.

        The report shows the geometric fit (the calibration's method and robust loss) and a full diagnosis
        of the session, with its simulations of the experiment.

        Parameters
        ----------
        folder : str or Path, created if missing (files of the same names are replaced)
        validations : sequence of str, Path or Validation: ``lasercal validate`` folders at one point that
            is not a calibration point, shown in the order given (e.g. the nominal model's first)
        n_boot : int, the diagnosis's first-order parametric-bootstrap replicates (0 skips)
        n_refit : int, its full simulations with refits
        seed : int, the simulations' seed
        reference : dict label -> {scatter_mean, scatter_std, error_mean, error_max} (mm), optional:
            published figures shown beside the first validation point's runs (``lasercal demo``: the thesis's)
        title : str, optional, the page's heading

        Returns
        -------
        Path of index.html

        Raises
        ------
        FormatError
            A session that is not a laser session, or a validation folder that cannot be read.
        """
        from lasercal.collector.report.html import load_validation, write_report
        from lasercal.solver.analysis.diagnose import diagnose
        from lasercal.solver.identify.measurement import fit

        vals = [v if hasattr(v, "spots") else load_validation(v) for v in validations]
        geometric = self.identification
        if self.diagnosis is not None:  # the report shows the geometric fit of the session as given
            geometric = fit(self.source, method=self.method, robust=self.robust)
        d = diagnose(self.source, n_boot=n_boot, n_refit=n_refit, seed=seed, robust=self.robust)
        return write_report(folder, self.source, geometric, d, vals, reference, title)


def calibrate(
    session,
    *,
    method: str = "lm",
    extend: str = "none",
    prior=None,
    folds: int = 5,
    robust: bool = True,
    allow_partial: bool = False,
    seed: int = 0,
    alpha: float = ALPHA,
    payload=None,
    sheet_shape: str = "auto",
) -> Calibration:
    """Calibrate the robot of a capture session: the decisions of ``lasercal solve`` (module docstring).

    Parameters
    ----------
    session : Session (:func:`lasercal.load_session`), or a session folder (str or Path)
    method : str, 'lm' (ours: Levenberg-Marquardt on every parameter, under the prior) or 'thesis' (the
        thesis's Section 3.2 as written; laser sessions)
    extend : str, 'none' (the geometry alone), 'auto' (diagnose, fit the winning non-geometric effect and
        keep it if it predicts held-out captures better) or an effect's name (one of
        :data:`~lasercal.solver.kinematics.effects.JOINT_EFFECTS` or 'reference_point_offset': fitted and
        kept). Only robot effects (compliance, eccentricity) are written to the model
    prior : None (the session's, as loaded), 'none' (plain least squares), 'default' (the robot's
        manufacturing tolerances) or a ``lasercal-prior/1`` YAML file overriding some of them
    folds : int, K of the K-fold cross-validation (0: none; else 2 .. the number of captures)
    robust : bool, flag and drop outlier captures (method 'lm')
    allow_partial : bool, return a model even when neither the data nor the prior identifies every
        parameter combination it needs (marked ``partial: true``, the combinations listed)
    seed : int, which captures fall in which fold (the diagnosis's and the cross-validation's; point
        sessions leave one tool position out, whatever the seed)
    alpha : float, the diagnosis's family-wise significance level (``extend`` not 'none')
    payload : (kg, (3,) mm at q = 0), the mass the flange carries (hand, tool), for the gravity torques
        of a session that logs none (``extend`` not 'none'; e.g. the MUKCa study's)
    sheet_shape : str, a sheet session fitted by 'lm': 'auto' tests the print's shear and the paper's
        height field (eqs. S5, S6) against a flat sheet and models them when the data ask
        (:mod:`solver.identify.sheetshape`: before the diagnosis, so that every later fit holds them);
        'flat' keeps eq. S3's flat sheet

    Returns
    -------
    Calibration

    Raises
    ------
    IdentificationError
        Data that cannot identify the geometry (too few captures at a point, collinear points), more
        folds than captures, an option the method cannot take, or a partial model not allowed.
    FormatError
        A session with no captures, or a prior file that cannot be read.
    """
    from dataclasses import replace

    from lasercal.solver.analysis.diagnose import carried_payload, diagnose
    from lasercal.solver.analysis.stats import cross_validate, solve_report
    from lasercal.solver.errors import IdentificationError
    from lasercal.solver.formats.session import load_session
    from lasercal.solver.formats.tolerances import load_tolerances
    from lasercal.solver.identify.measurement import check_data, fit, refuse_partial, unidentifiable

    if not hasattr(session, "measurement"):
        session = load_session(session)
    if prior is not None:
        session = replace(session, tolerances=load_tolerances(prior, session.robot))
    if method not in METHODS:
        raise IdentificationError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    source = session
    check_data(session)
    if folds > session.m:
        raise IdentificationError(
            f"--folds {folds}: more folds than the session's {session.m} captures (expected 2 .. "
            f"{session.m}, or 0 for none)"
        )
    if extend != "none" and method != "lm":
        raise IdentificationError("--extend needs --method lm")
    shape = None
    if sheet_shape not in ("auto", "flat"):
        raise IdentificationError(f"sheet shape {sheet_shape!r}: expected auto or flat")
    sheet_lm = session.frame == "sheet" and session.measurement == "laser" and method == "lm"
    if sheet_shape == "auto" and sheet_lm:
        from lasercal.solver.identify.sheetshape import decide_sheet_shape, modelled

        shape = decide_sheet_shape(session, fit(session, robust=robust), folds, seed, alpha, robust)
        if shape is not None and shape.kept:
            session = modelled(session)  # once named, modelled: every fit below holds the sheet's shape
    diagnosis = None
    if extend != "none":
        diagnosis = diagnose(
            session,
            n_boot=0,  # the decision needs no bootstrap
            k=folds,
            effect=None if extend == "auto" else extend,
            robust=robust,
            seed=seed,
            payload=payload,
            alpha=alpha,
        )
        ident = diagnosis.extended or diagnosis.geometric
        session = diagnosis.session
    else:
        if session.measurement == "point" and method != "lm":
            raise IdentificationError("point sessions are identified by --method lm")
        ident = fit(session, method=method, robust=robust)
    missing = unidentifiable(session, ident)
    if not allow_partial:
        refuse_partial(missing)
    cv = None
    if folds > 1:
        ext = diagnosis.extension if diagnosis else None
        cv = cross_validate(
            session, method, folds, seed, inlier=ident.weights > 0, robust=robust, extension=ext
        )
    rep = solve_report(session, ident, cv)
    if shape is not None:
        rep["sheet_shape"] = shape.as_dict()
    if diagnosis is not None:
        rep["diagnosis"] = diagnosis.as_dict()
    rep["partial"] = bool(missing)
    if missing:
        rep["unidentifiable_combinations"] = [
            {"combination": d.combination, "fix": d.fix, "directions": d.directions} for d in missing
        ]
    return Calibration(
        model_file(source, session, ident, rep, carried_payload(source, payload) if diagnosis else None),
        ident,
        session,
        rep,
        diagnosis,
        cv,
        tuple(missing),
        source,
        method,
        robust,
    )


def model_file(
    source: Session, session: Session, ident: Identification, rep: dict, payload=None
) -> RobotModel:
    """The model a calibration writes: the identified geometry with its robot effects only, the record of
    its identification (``rep``'s fit statistics, prior, what determined it, cross-validation, diagnosis,
    partial, the payload its torques carried) and the nominal it calibrates (a built-in name, or an
    absolute path: found from any folder).

    Parameters
    ----------
    source : Session, as loaded (its folder and how it named its robot)
    session : Session, as calibrated (its measurement)
    ident : Identification
    rep : dict, the calibration's statistics (:attr:`Calibration.statistics`)
    payload : (kg, (3,) mm at q = 0) or None, the flange's load in the fit's gravity torques
        (``identification.payload``: ``predict`` and ``correct`` take the same torques)

    Returns
    -------
    RobotModel
    """
    from lasercal.solver.control.nominal import robot_reference
    from lasercal.solver.kinematics.effects import robot_extensions

    meta = {k: rep[k] for k in _RECORDED}
    meta.update(
        {
            "measurement": session.measurement,
            "session": str(Path(source.path).resolve()),
            "units": "mm, rad",
            "std_errors": rep.get("std_errors", {}),
            "partial": rep["partial"],
        }
    )
    for k in (
        "unidentifiable_combinations",
        "prior",
        "determined_by",
        "cross_validation",
        "diagnosis",
        "sheet_shape",
    ):
        if k in rep:
            meta[k] = rep[k]
    if payload is not None:
        meta["payload"] = {"mass": float(payload[0]), "com": [float(v) for v in payload[1]]}
    # the diagnosis's wall time is printed, not recorded: the file is a function of the data alone
    if "diagnosis" in meta:
        d = meta["diagnosis"]
        meta["diagnosis"] = {**d, "details": {k: v for k, v in d["details"].items() if k != "seconds"}}
    ref = source.robot_source or (source.meta["robot"], source.path)
    return ident.model.replace(
        identification=_defined(meta),
        extensions=robot_extensions(ident.model.extensions),
        nominal=robot_reference(*ref),
    )


def _defined(record):
    """A record with every figure that is not defined (a held-out error when every fold failed: NaN) as
    None, written ``null``: model files hold no ``.nan``, which every loader refuses as a torn file."""
    if isinstance(record, dict):
        return {k: _defined(v) for k, v in record.items()}
    if isinstance(record, list | tuple):
        return [_defined(v) for v in record]
    if isinstance(record, float) and not math.isfinite(record):
        return None
    return record
