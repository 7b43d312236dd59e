"""``lasercal demo``: the whole workflow on the built-in simulated Panda, no robot, camera or keyboard.

The story of the thesis's Panda experiment (Section 4.3), with one thing the thesis did
not model hidden in the robot:

1. Truth: the thesis's identified Panda (Table 4.3) whose joint 2 also bends under its
   gravity load (joint compliance, c_2 = 1.2e-4 rad/Nm): its encoders read the true joint
   angle minus c_2 tau_2 (:class:`EffectRobot`).
2. Capture: the simulated operator aims at P1-P3 through the collector's capture session
   (``collector.capture.run_capture``), which logs joint angles and torques.
3. Calibration by both methods (``lm`` and ``thesis``), and with ``extend="auto"``, whose diagnosis should
   name the hidden effect and fit it with the geometry: :func:`lasercal.calibrate`, as ``lasercal solve``.
4. Validation at P4 (``collector.validate.run_validation``): each model computes the
   configurations, the fake robot goes there, a fake camera photographs the true spot and
   ``vision`` measures the photo. The extended model's commands carry its correction
   (``validation_commands``: the angles whose true pose, under its compliance, is the aimed one).
5. The report: :meth:`lasercal.Calibration.report`, as ``lasercal report``.
6. The payoff: a program planned with the nominal model, commanded as planned and as ``lasercal correct``
   corrects it with the best model (:func:`correction_payoff`), measured at the true robot's flange.
"""

from __future__ import annotations

import io
import json
import time
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from lasercal.calibration import calibrate
from lasercal.collector.errors import SessionError
from lasercal.collector.hardware.base import FakeClock, JointState
from lasercal.collector.hardware.triggers import AutoTrigger
from lasercal.collector.report.html import load_validation
from lasercal.collector.sessions.capture import CaptureOptions, run_capture
from lasercal.collector.sessions.store import CaptureStore
from lasercal.collector.sessions.validate import (
    ValidateOptions,
    ValidationResult,
    measure_known_view,
    run_validation,
)
from lasercal.collector.worlds.cameras import FakeCamera, fake_view
from lasercal.collector.worlds.fake import FakeOperator, FakeRobot
from lasercal.solver.analysis.stats import spot_stats
from lasercal.solver.control.robot import Robot
from lasercal.solver.control.robot import load_model as load_robot
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Layout, load_layout, load_session, session_meta
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.effects import Extension
from lasercal.solver.kinematics.gravity import gravity_torques
from lasercal.solver.kinematics.model import RobotModel

# Thesis Section 4.3 / Figures 4.5-4.6, at P4 (mm).
THESIS_P4 = {
    "before": {"scatter_mean": 6.86, "scatter_std": 5.016, "error_mean": 9.76, "error_max": 26.993},
    "after": {"scatter_mean": 1.11, "scatter_std": 1.00, "error_mean": 1.057, "error_max": 4.92},
}
TRUTH = "panda_thesis_identified"
NOMINAL = "panda"
COMPLIANCE = Extension(
    "joint_compliance", (2,), None, np.array([1.2e-4])
)  # rad/Nm: a few mrad under the Panda's gravity load
_FIXED_POINT = 6  # iterations of the effect's fixed points: the corrections are milliradians


@dataclass(frozen=True)
class DemoOptions:
    """What the demo simulates.

    Attributes
    ----------
    seed : int, seed of the operator, the robot's motion and sensor noise, the photos and the fits
    per_point : int, captures at each of P1-P3
    aim_noise : float, the operator's aiming error per in-plane axis, mm
    n_validation : int, configurations (photos) per validated model at P4
    effect : Extension, the hidden joint effect with its true parameters
    n_boot, n_refit : int, the diagnosis's bootstrap replicates and full refits
    view_px : int, side of the square validation photos (0.1 mm per pixel, centred on P4)
    keep_photos : int, photos written per validated model (the first ones; every photo is measured):
        all 240 noisy 800 x 800 PNGs were 201 MB
    """

    seed: int = 0
    per_point: int = 30
    aim_noise: float = 0.5
    n_validation: int = 60
    effect: Extension = COMPLIANCE
    n_boot: int = 2000
    n_refit: int = 10
    view_px: int = 800
    keep_photos: int = 1

    def units(self) -> int:
        """Progress units of a run: captures, photos of four models, three fits, the report, the payoff."""
        return 3 * self.per_point + 4 * self.n_validation + 5


def encoder_reading(effect: Extension, q_true: np.ndarray, t: float, tau: np.ndarray) -> np.ndarray:
    """The logged angles q (n,) whose effect-corrected angles are ``q_true``: ``effect.true_q(q) = q_true``.

    Solved by :meth:`Extension.logged_q`, as in :func:`solver.simulate.simulate_captures`.
    """
    return effect.logged_q(np.asarray(q_true, dtype=float)[None], np.array([t]), tau[None], _FIXED_POINT)[0]


class EffectRobot(FakeRobot):
    """The fake arm with a hidden joint effect: the true links sit at ``effect.true_q`` of the encoder angles.

    The simulated motion, the operator and the camera act on the true links; :meth:`read`
    reports what the encoders say (the torques are the measured ones); a commanded or guided
    configuration is reached by the encoders, so the links go where the effect puts them.

    Parameters
    ----------
    truth : RobotModel, the true geometry (with link masses: compliance bends under gravity)
    clock : FakeClock
    effect : Extension, a joint effect with its true parameters
    operator : FakeOperator or None
    seed : int
    """

    def __init__(
        self,
        truth: RobotModel,
        clock: FakeClock,
        effect: Extension,
        operator: FakeOperator | None = None,
        seed: int = 0,
    ):
        super().__init__(truth, clock, operator, seed=seed)
        self.effect = effect

    def read(self) -> JointState:
        s = super().read()
        return replace(s, q=encoder_reading(self.effect, s.q, s.t, s.tau))

    def _link(self, q: np.ndarray) -> np.ndarray:
        """Where the links go when the encoders read q (the torques depend on that pose)."""
        return link_angles(self.truth, self.effect, np.asarray(q, dtype=float)[None], self.clock.now())[0]

    def move_to(self, q: np.ndarray) -> None:
        super().move_to(self._link(q))

    def prompt_configuration(self, q: np.ndarray) -> None:
        super().prompt_configuration(self._link(q))


def link_angles(truth: RobotModel, effect: Extension, q: np.ndarray, t: float = 0.0) -> np.ndarray:
    """Where the links of the hidden-effect robot go (m, n) when its encoders read q (m, n), rad: the fixed
    point link = effect.true_q(q, t, tau(link)), the torques those of the bent pose."""
    link = q
    for _ in range(_FIXED_POINT):
        link = effect.true_q(q, np.full(len(q), t), gravity_torques(truth, link))
    return link


class _Ticking(AutoTrigger):
    """The simulated operator's trigger, reporting each capture to a progress callback."""

    def __init__(self, tick):
        super().__init__()
        self.tick = tick

    def wait(self) -> str:
        self.tick()
        return super().wait()


class _TickingCamera(FakeCamera):
    """The fake camera, reporting each photo to a progress callback."""

    def __init__(self, tick, *args, **kw):
        super().__init__(*args, **kw)
        self.tick = tick

    def photo(self) -> np.ndarray:
        self.tick()
        return super().photo()


def thesis_layout() -> Layout:
    """The thesis's layout: P1-P3 for calibration, P4 for validation."""
    return load_layout(builtin_dir("layouts") / "thesis.yaml")


def capture_session(folder, truth: RobotModel, layout: Layout, opts: DemoOptions, tick=lambda: None) -> Path:
    """An automatic capture session of the hidden-effect robot at the layout's calibration points.

    Returns
    -------
    Path of the session folder (session.yaml, captures.csv with joint angles, speeds and torques)
    """
    points = {k: layout.points[k] for k in layout.calibration}
    operator = FakeOperator(truth, points, opts.per_point, opts.aim_noise, opts.seed, layout.aim_kwargs())
    robot = EffectRobot(truth, FakeClock(), opts.effect, operator, seed=opts.seed)
    hidden = {"name": opts.effect.effect, **opts.effect.to_dict()}
    meta = session_meta(
        NOMINAL,
        layout,
        truth.aperture[2],
        simulated={"truth": truth.name, "aim_noise_mm": opts.aim_noise, "seed": opts.seed, "effect": hidden},
    )
    store = CaptureStore.create(folder, meta, truth.n, robot.extra_columns)
    try:
        run_capture(
            store,
            robot,
            _Ticking(tick),
            load_model(NOMINAL),
            CaptureOptions(opts.per_point, auto_discard=True),
            out=io.StringIO(),
        )
    finally:
        store.close()
    return store.folder


def validate_model(
    folder,
    model: RobotModel,
    model_ref: str,
    truth: RobotModel,
    layout: Layout,
    opts: DemoOptions,
    tick=lambda: None,
) -> ValidationResult:
    """A validation session at the layout's validation point on the hidden-effect robot, photos measured by
    ``vision``.

    Parameters
    ----------
    folder : new folder (validation.yaml, validation.csv, photos/)
    model : RobotModel under test (its robot effects applied by the validation's commands,
    :func:`collector.sessions.validate.validation_commands`)
    model_ref : str, how validation.yaml names the model
    truth, layout, opts : as for :func:`capture_session`
    """
    point = layout.validation[0]
    robot = EffectRobot(truth, FakeClock(), opts.effect, seed=opts.seed)
    view = fake_view(layout.points[point][:2], layout.plane_z, size=(opts.view_px, opts.view_px))
    camera = _TickingCamera(tick, robot, view, layout.plane_z, seed=opts.seed)
    return run_validation(
        folder,
        model,
        model_ref,
        layout,
        point,
        robot,
        camera,
        ValidateOptions(opts.n_validation, opts.seed, keep_photos=opts.keep_photos),
        measure=lambda img, name: measure_known_view(img, name, view),
        out=io.StringIO(),
        confirm_moves=False,  # the simulated arm
    )


def correction_payoff(
    model_path, truth: RobotModel, layout: Layout, opts: DemoOptions, per_point: int = 15
) -> dict:
    """The flange error of a program planned with the nominal model, commanded as planned and corrected.

    The program: ``per_point`` configurations aiming the nominal laser at each layout point (the work the
    calibration was for). Its goals are the nominal model's flange poses; the true robot (with its hidden
    effect) goes to the link angles of each command; the error is the distance of its flange (the nominal
    flange carried by the true last joint, :mod:`solver.control.tools`) from the goal, mm.

    Returns
    -------
    dict: 'configurations', 'nominal_mm' and 'corrected_mm' (mean errors), 'model' (the file that corrected)
    """
    robot = load_robot(model_path)
    rng = np.random.default_rng(opts.seed)
    program = np.vstack(
        [aim(robot.nominal, p, per_point, rng, **layout.aim_kwargs()) for p in layout.points.values()]
    )
    goal = robot.fk(program, nominal=True)[:, :3, 3]
    true_robot = Robot(truth, robot.nominal)

    def error(q):
        return np.linalg.norm(true_robot.fk(link_angles(truth, opts.effect, q))[:, :3, 3] - goal, axis=1)

    corrected = robot.correct(q=program)
    return {
        "configurations": len(program),
        "nominal_mm": round(float(error(program).mean()), 3),
        "corrected_mm": round(float(error(corrected.q).mean()), 3),
        "all_ok": bool(corrected.ok.all()),
        "model": Path(model_path).name,
    }


def _timed(seconds: dict, name: str, fn, *args, **kw):
    """Call ``fn(*args, **kw)`` and note its wall time, in seconds to two places, as ``seconds[name]``.

    Parameters
    ----------
    seconds : dict
        The stages' times so far (written to).
    name : str
        The stage's name.
    fn : callable
        What the stage runs.

    Returns
    -------
    object
        What ``fn`` returns.
    """
    t0 = time.perf_counter()
    result = fn(*args, **kw)
    seconds[name] = round(time.perf_counter() - t0, 2)
    return result


def _calibrations(session, out: Path, opts: DemoOptions, step, seconds: dict) -> tuple[dict, object]:
    """``lasercal solve --method lm / thesis`` and ``lasercal solve --extend auto``: the API's calibrations.

    Parameters
    ----------
    session : Session
        The captured session.
    out : Path
        The demo's folder (the models are saved in it).
    opts : DemoOptions
        The demo's options.
    step : callable(stage: str)
        Called once per progress unit.
    seconds : dict
        The stages' times (written to).

    Returns
    -------
    cals : dict
        'lm' and 'thesis' -> their Calibration (saved as model_<method>.yaml).
    extended : Calibration
        The ``extend="auto"`` calibration, with its diagnosis.
    """
    cals = {}
    for method in ("lm", "thesis"):
        cals[method] = _timed(seconds, method, calibrate, session, method=method, folds=0)
        cals[method].save(out / f"model_{method}.yaml")
        step(f"calibrate ({method})")
    extended = _timed(seconds, "diagnose", calibrate, session, extend="auto", folds=5, seed=opts.seed)
    step("diagnose")
    return cals, extended


def _validations(session, cals: dict, extended, out: Path, truth, layout, opts: DemoOptions, step, seconds):
    """Each model validated at P4 by fresh photos: the nominal, lm, thesis and (when found) extended one.

    Parameters
    ----------
    session : Session
        The captured session (its robot is the nominal).
    cals : dict
        'lm' and 'thesis' -> their Calibration.
    extended : Calibration
        The ``extend="auto"`` calibration (saved as model_extended.yaml when it extends the geometry).
    out : Path
        The demo's folder.
    truth, layout
        The hidden robot and the reference points.
    opts, step, seconds
        As :func:`_calibrations`'s: the demo's options, its progress, the stages' times (written to).

    Returns
    -------
    list of Validation
        The validations, in the order above.
    """
    candidates = {
        "nominal": (session.robot, NOMINAL),
        "lm": (cals["lm"].model, "model_lm.yaml"),
        "thesis": (cals["thesis"].model, "model_thesis.yaml"),
    }
    if extended.diagnosis.extended is not None:
        extended.save(out / "model_extended.yaml")
        candidates["extended"] = (extended.model, "model_extended.yaml")
    validations = []
    for name, (model, ref) in candidates.items():
        folder = out / "validation" / name
        _timed(
            seconds,
            f"validate {name}",
            validate_model,
            folder,
            model,
            ref,
            truth,
            layout,
            opts,
            partial(step, f"validate {name}"),
        )
        validations.append(load_validation(folder))
    return validations


def _summary(session, cals: dict, extended, validations, truth, opts: DemoOptions, payoff, report) -> dict:
    """The demo's summary (summary.json) but for its times, its report's path and the files written.

    Parameters
    ----------
    session : Session
        The captured session.
    cals : dict
        'lm' and 'thesis' -> their Calibration.
    extended : Calibration
        The ``extend="auto"`` calibration, with its diagnosis.
    validations : list of Validation
        The models' validations.
    truth : Robot
        The hidden robot.
    opts : DemoOptions
        The demo's options.
    payoff : dict
        What ``lasercal correct`` gains (:func:`correction_payoff`).
    report : Path
        The report's index.html.

    Returns
    -------
    dict
        :func:`run_demo`'s summary, its keys in their order ('seconds' and 'report' placeholders).
    """
    d = extended.diagnosis
    found = (
        d.extension is not None
        and d.effect == opts.effect.effect
        and set(d.extension.joints) == set(opts.effect.joints)
    )
    return {
        "p4": {v.label: spot_stats(v.spots, v.xyz).as_dict() for v in validations},
        "thesis": THESIS_P4,
        "methods": {
            m: {
                "iterations": c.identification.iterations,
                "converged": c.identification.converged,
                "seconds": round(c.identification.seconds, 3),
                "fit_rms_mm": round(c.identification.rms_mm, 4),
            }
            for m, c in cals.items()
        },
        "truth": {"robot": truth.name, "effect": {"name": opts.effect.effect, **opts.effect.to_dict()}},
        "options": {k: v for k, v in asdict(opts).items() if k != "effect"},
        "captures": session.m,
        "diagnosis": d.as_dict(),
        "found": bool(found),
        "correct": payoff,
        "seconds": None,
        "report": None,
    }


def run_demo(out, opts: DemoOptions = DemoOptions(), progress=None) -> dict:
    """Run the whole story, write its files under ``out`` and return the summary (also in summary.json).

    Files (``out`` must be new or empty): ``session/``, ``model_lm.yaml``, ``model_thesis.yaml``,
    ``model_extended.yaml``,
    ``validation/{nominal,lm,thesis,extended}/`` (the first ``keep_photos`` photos of each),
    ``report/index.html``, ``summary.json`` (with 'wrote': the folder, its files and bytes).

    Parameters
    ----------
    out : folder (created)
    opts : DemoOptions
    progress : callable(stage: str) or None, called once per progress unit (:meth:`DemoOptions.units`)

    Returns
    -------
    dict with 'p4' -> {'nominal', 'lm', 'thesis', 'extended'} spot statistics (mm) measured from the
    photos, 'thesis' (the published P4 figures), 'methods' (iterations, time, fit RMS), 'truth'
    (the hidden effect), 'diagnosis' (:meth:`Diagnosis.as_dict` of the ``extend="auto"`` calibration's;
    the report shows the full diagnosis with its bootstrap), 'found' (the diagnosis named the
    hidden effect and joints), 'seconds' per stage and in total, 'report' (path)
    """
    step = progress or (lambda stage: None)
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise SessionError(
            f"{out} is not empty (an earlier demo?): remove it or choose another folder with -o"
        )
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    seconds = {}
    truth, layout = load_model(TRUTH), thesis_layout()

    session = load_session(
        _timed(
            seconds,
            "capture",
            capture_session,
            out / "session",
            truth,
            layout,
            opts,
            partial(step, "capture"),
        )
    )
    cals, extended = _calibrations(session, out, opts, step, seconds)
    d = extended.diagnosis
    validations = _validations(session, cals, extended, out, truth, layout, opts, step, seconds)
    report = _timed(
        seconds,
        "report",
        cals["lm"].report,  # lasercal report: the geometric fit and the full diagnosis, with its simulations
        out / "report",
        validations,
        n_boot=opts.n_boot,
        n_refit=opts.n_refit,
        seed=opts.seed,
        reference={f"thesis paper, {k}": v for k, v in THESIS_P4.items()},
        title=f"lasercal demo: the simulated Panda with a hidden {opts.effect.effect.replace('_', ' ')}",
    )
    step("report")
    best = out / ("model_extended.yaml" if d.extended is not None else "model_lm.yaml")
    payoff = _timed(seconds, "correct", correction_payoff, best, truth, layout, opts)
    step("correct")
    summary = _summary(session, cals, extended, validations, truth, opts, payoff, report)
    summary["seconds"] = {**seconds, "total": round(time.perf_counter() - t_start, 2)}
    summary["report"] = str(report)
    summary["wrote"] = written(out)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def written(out: Path) -> dict:
    """What a run wrote in ``out`` besides summary.json: 'folder', 'files' and 'bytes'."""
    files = [f for f in Path(out).rglob("*") if f.is_file() and f != Path(out) / "summary.json"]
    return {"folder": str(out), "files": len(files), "bytes": sum(f.stat().st_size for f in files)}


def format_summary(s: dict) -> str:
    """The demo's printed summary: P4 before/after beside the thesis, the effect, the gain, the report."""
    rows = [
        f"{'P4 (441, 160, -8) mm':26} {'scatter mean':>12} {'scatter std':>11} {'error mean':>10} "
        f"{'error max':>9}"
    ]
    labels = (
        ("nominal (before)", "nominal", None),
        ("lm (ours)", "lm", None),
        ("thesis method", "thesis", None),
        ("lm + effect (ours)", "extended", None),
        ("thesis paper, before", None, "before"),
        ("thesis paper, after", None, "after"),
    )
    for label, key, ref in labels:
        if key is not None and key not in s["p4"]:
            continue
        d = s["p4"][key] if key else s["thesis"][ref]
        rows.append(
            f"{label:26} {d['scatter_mean']:12.3f} {d['scatter_std']:11.3f} {d['error_mean']:10.3f} "
            f"{d['error_max']:9.3f}"
        )
    for m, d in s["methods"].items():
        rows.append(
            f"{m}: {d['iterations']} iterations, {d['seconds']} s, "
            f"{'converged' if d['converged'] else 'stopped at the iteration cap'}"
        )
    truth = s["truth"]["effect"]
    hidden = f"{truth['name']} at joint {', '.join(map(str, truth['joints']))}"
    true_values = {k: v for k, v in truth.items() if isinstance(v, list) and k != "joints"}
    rows.append(
        f"\nhidden in the robot: {hidden} ({', '.join(f'{k} = {v}' for k, v in true_values.items())} "
        f"{truth['units']})"
    )
    dg = s["diagnosis"]
    if dg["effect"] == "none":
        rows.append(f"effect found: none (corrected p = {dg['p_value']:.3g})")
    else:
        where = f"point {dg['point']}" if dg["point"] else "joint " + ", ".join(map(str, dg["joints"]))
        params = ", ".join(
            f"{k} = {v['value']:.3g} +- {v['std_error']:.2g} {v['units']}"
            for k, v in dg["parameters"].items()
        )
        rows.append(
            f"effect found: {dg['effect']} at {where}: {params} (corrected p = {dg['p_value']:.3g})"
            + ("" if s["found"] else "  -- not the hidden one")
        )
    h = dg["holdout_rms_mm"]
    gain = f"gain: held-out RMS {h['geometric']:.3f} -> {h['extended']:.3f} mm ({dg['gain_percent']:.1f}%)"
    if "extended" in s["p4"]:
        gain += (
            f"; P4 error mean {s['p4']['lm']['error_mean']:.3f} -> {s['p4']['extended']['error_mean']:.3f} mm"
        )
    rows.append(gain)
    c = s["correct"]
    rows.append(
        f"commanded with the nominal model: {c['nominal_mm']:.2f} mm off; with `lasercal correct`: "
        f"{c['corrected_mm']:.2f} mm (flange, {c['configurations']} configurations of a nominal program)"
    )
    rows.append(
        f"\n{s['captures']} captures, {4 * s['options']['n_validation']} photos, {s['seconds']['total']:.1f} "
        "s"
    )
    rows.append(f"report: {s['report']}")
    w, o = s["wrote"], s["options"]
    rows.append(
        f"wrote {w['folder']}: {w['bytes'] / 1e6:.1f} MB in {w['files']} files and summary.json (session, "
        f"models, validations with {o['keep_photos']} of their {o['n_validation']} photos each -- every "
        "photo measured --, report); remove it when done"
    )
    return "\n".join(rows)
