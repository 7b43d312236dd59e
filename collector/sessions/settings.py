"""The settings a capture or validation session runs with, for a new session or a resumed one.

A new session takes its settings from the caller (the command line) over :data:`DEFAULTS`. A
resumed one takes them from its own folder (``session.yaml`` or ``validation.yaml``, under
``collector``), which the caller may override except for the :data:`FIXED` ones: those decide what
the captures already on disk mean.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from lasercal.collector.errors import SessionError
from lasercal.collector.sessions.motion import MAX_STEP
from lasercal.collector.sessions.store import check_output
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.data import builtin_dir, reference
from lasercal.solver.formats.robots import load_yaml
from lasercal.solver.formats.session import Layout, load_layout, session_layout

THESIS_LAYOUT = builtin_dir("layouts") / "thesis.yaml"
DEFAULTS = {
    "robot": "panda",
    "trigger": "enter",
    "truth": "panda_thesis_identified",
    "aim_noise": 1.0,
    "seed": 0,
    "speed_threshold": 0.005,
    "hold": 0.5,
    "dynamics": 0.1,
    "ros_port": 9090,
}
# Settings a resumed session must keep: they decide what its captures mean.
FIXED = (
    "backend",
    "robot",
    "per_point",
    "truth",
    "perturb_seed",
    "aim_noise",
    "seed",
    "rangefinder",
    "effects",
    "aim",
    "world",
)
SETTINGS = FIXED + (
    "camera",
    "speed_threshold",
    "hold",
    "trigger",
    "host",
    "dynamics",
    "desk_user",
    "ros_port",
    "ros_joints",
    "rangefinder_query",
    "aperture_z",
    "photos",  # which photos are kept and how: no measurement depends on it (sessions.photos)
    "photo_format",
    "view",  # --view: a resumed session brings its live view back (on 127.0.0.1 unless told again)
    "view_port",
    "plan_effects",  # --plan-effects: the coach plans for the joint compliances too (a resume keeps it)
)


def given_settings(values: Mapping) -> dict:
    """The session settings among ``values`` (e.g. the command line's), leaving out those not given.

    Parameters
    ----------
    values : mapping, name -> value; None means not given, names other than :data:`SETTINGS` are ignored

    Returns
    -------
    dict, setting -> value, only those given
    """
    return {k: values[k] for k in SETTINGS if values.get(k) is not None}


def _stored(settings: dict, given: dict, message) -> dict:
    """The settings of a resumed folder: :data:`DEFAULTS`, then its stored ones, then those given.

    Parameters
    ----------
    settings : dict, the folder's stored settings
    given : dict, settings given by the caller; they may change none of the :data:`FIXED` ones
    message : callable (option name, stored value) -> str, the error's text (each command words its own)

    Returns
    -------
    dict, the merged settings
    """
    for k in FIXED:
        if k in given and given[k] != settings.get(k):
            raise SessionError(message(k.replace("_", "-"), settings.get(k)))
    return {**DEFAULTS, **settings, **given}


@dataclass(frozen=True)
class CaptureSettings:
    """What a capture session runs with.

    Attributes
    ----------
    cfg : dict, the settings: :data:`DEFAULTS`, then a resumed session's stored ones, then those given
    layout : Layout, the reference points
    layout_path : Path or None, the layout file of a new session (None on resume: the session holds it)
    folder : Path, the session folder
    resume : bool, the folder is an interrupted session to continue
    """

    cfg: dict
    layout: Layout
    layout_path: Path | None
    folder: Path
    resume: bool


def capture_settings(
    given: dict, layout: str | None = None, output: str | None = None, resume: str | None = None
) -> CaptureSettings:
    """The settings and layout of a new capture session (``output``) or a resumed one (``resume``).

    Parameters
    ----------
    given : dict, settings given by the caller (see :func:`given_settings`)
    layout : str or None, the layout file of a new session
    output : str or None, the folder of a new session
    resume : str or None, the folder of an interrupted session (then ``layout`` and ``output`` stay None)

    Returns
    -------
    CaptureSettings

    Raises
    ------
    SessionError
        A new session lacks a layout, ``per_point``, an output or a backend, or its folder is kept; or
        the folder to resume is no capture session, or ``given`` changes a :data:`FIXED` setting.
    """
    if not resume:
        missing = [
            f
            for f, v in (
                ("--layout", layout),
                ("--per-point", given.get("per_point")),
                ("-o", output),
                ("--backend", given.get("backend")),
            )
            if v is None
        ]
        if missing:
            raise SessionError(f"a new session needs {', '.join(missing)} (or --resume SESSION)")
        cfg = {**DEFAULTS, **given}
        if cfg["backend"] == "fake":  # the simulated world's effects, as a list (stored: a resume keeps them)
            from lasercal.collector.hardware.simulated import parse_effects

            cfg["effects"] = list(parse_effects(cfg.get("effects"), cfg.get("camera") == "fake"))
        elif cfg.get("effects") is not None:
            raise SessionError("--effects switches the simulated world's effects: it needs --backend fake")
        if cfg["backend"] == "mujoco" and not cfg.get("world"):
            raise SessionError("--backend mujoco needs --world SCENE.xml (lasercal mujoco-scene writes one)")
        if cfg["backend"] != "fake":  # the fake arm's true robot: another backend's session records none
            if given.get("truth") or given.get("perturb_seed") is not None:
                raise SessionError(
                    "--truth and --perturb-seed make the fake arm's true robot: they need --backend fake"
                )
            cfg.pop("truth")
        folder = check_output(output, folder=True, instead=f"resume it with --resume {output}")
        return CaptureSettings(cfg, load_layout(layout), Path(layout), folder, False)
    if output or layout:
        raise SessionError("--resume SESSION continues that folder with its own layout: drop --layout and -o")
    folder = Path(resume)
    if not (folder / "session.yaml").is_file():
        raise SessionError(f"{folder} is not a session folder (no session.yaml): nothing to resume")
    meta = load_yaml(folder / "session.yaml")
    stored = meta.get("collector") if isinstance(meta, dict) else None
    if not stored:
        raise SessionError(f"{folder} was not started by lasercal capture: nothing to resume")
    cfg = _stored(
        stored, given, lambda k, v: f"{folder} was started with {k} {v}: it cannot change on resume"
    )
    return CaptureSettings(cfg, session_layout(meta, folder / "session.yaml"), None, folder, True)


@dataclass(frozen=True)
class ValidateSettings:
    """What a validation run runs with.

    Attributes
    ----------
    cfg : dict, the robot settings: :data:`DEFAULTS`, then a resumed run's stored ones, then those given
    run : dict, what the run measures: ``model``, ``layout`` and ``sheet_from`` (built-in names, or paths
        relative to ``folder``: :meth:`file`), ``point`` (None: the
        layout's first validation point), ``n``, ``camera``, ``guide``, ``max_step``
    folder : str, the run's folder
    resume : bool, the folder is an interrupted run to continue
    """

    cfg: dict
    run: dict
    folder: str
    resume: bool

    def file(self, key: str) -> str | None:
        """The file (or built-in name) ``run[key]`` names, as a path from the working folder: a relative
        path is relative to the run's folder (as validation.yaml stores it), an absolute one (older runs)
        stays."""
        ref = self.run.get(key)
        if ref is None:
            return None
        inside = os.path.normpath(os.path.join(self.folder, str(ref)))  # lexically: the folder may be new
        return inside if not Path(str(ref)).is_absolute() and Path(inside).exists() else str(ref)


def validate_settings(
    given: dict,
    model: str | None = None,
    output: str | None = None,
    resume: str | None = None,
    *,
    layout: str | None = None,
    point: str | None = None,
    n: int = 60,
    camera: str | None = None,
    guide: bool = False,
    max_step: float = MAX_STEP,
    sheet_from: str | None = None,
    sheet_pose=None,
) -> ValidateSettings:
    """The settings of a new validation run (``output``) or a resumed one (``resume``: its own are kept).

    Parameters
    ----------
    given : dict, robot settings given by the caller (see :func:`given_settings`)
    model : str or None, the robot model under test (file or built-in name) of a new run
    output : str or None, the folder of a new run
    resume : str or None, the folder of an interrupted run (then model, output, layout and point stay None)
    layout : str or None, layout file or built-in name (None: the thesis layout, fake backend only)
    point, n, camera, guide, max_step : the run's validation point, configurations, camera, whether to
        guide the operator, largest joint step (rad); a resumed run keeps its own
    sheet_from : str or None, on a sheet layout: the model (file or name) whose identified sheet pose the
        model under test is validated with (None: the model's own)
    sheet_pose : SheetPose or None, on the fake backend: where the simulated sheet truly lies, in the true
        robot's own frame (None: the sheet's session, or the layout's placement)

    Returns
    -------
    ValidateSettings

    Raises
    ------
    SessionError
        A new run lacks a model, an output or a backend, or a layout on a real robot, or its folder is
        kept; or ``given`` changes a :data:`FIXED` setting of the run resumed.
    FormatError
        The folder to resume holds no validation.yaml with the settings to resume.
    """
    if resume is None:
        backend = given.get("backend")
        missing = [f for f, v in (("MODEL", model), ("-o", output), ("--backend", backend)) if not v]
        if missing:
            raise SessionError(f"validate needs {', '.join(missing)} (or --resume DIR)")
        if layout is None and backend != "fake":
            raise SessionError(
                f"--layout: a real robot (--backend {backend}) needs the layout of the points on your "
                "table (there is no default for real robots)"
            )
        check_output(output, folder=True, instead=f"resume it with --resume {output}")
        run = {  # files by their path relative to the run's folder (built-ins by name): the folder can move
            "model": reference("robots", model, output),
            "layout": reference("layouts", layout or THESIS_LAYOUT, output),
            "point": point,
            "n": n,
            "camera": camera,
            "guide": guide,
            "max_step": max_step,
            "sheet_from": reference("robots", sheet_from, output) if sheet_from else None,
            "sheet_pose": None if sheet_pose is None else list(sheet_pose.as_dict().values()),
        }
        return ValidateSettings({**DEFAULTS, **given}, run, output, False)
    if output or model or layout or point or sheet_from or sheet_pose is not None:
        raise SessionError(
            "--resume DIR continues that run with its own model, layout, point and sheet: drop them"
        )
    folder = Path(resume)
    if not (folder / "validation.yaml").is_file():
        raise SessionError(
            f"--resume {folder}: not a validation folder (no validation.yaml): nothing to resume"
        )
    meta = load_yaml(folder / "validation.yaml")
    stored = meta.get("collector") if isinstance(meta, dict) else None
    if not isinstance(stored, dict) or "settings" not in stored:
        raise FormatError(folder / "validation.yaml", "written without resume settings", field="collector")
    cfg = _stored(stored["settings"], given, lambda k, v: f"--resume {folder}: started with {k} {v}")
    return ValidateSettings(cfg, stored["run"], resume, True)
