"""Robot hardware: backends behind one small interface
(:class:`~lasercal.collector.hardware.base.RobotAdapter`), and the factories that build them from settings.

``fake`` (simulated Panda and operator), ``mujoco`` (a MuJoCo world file, its arm and camera driven
as hardware is), ``franky`` (franky-control), ``panda-py`` (panda-python), ``ros`` (rosbridge
/joint_states). Each backend module imports its SDK only when used; a missing SDK is a one-line error
with the pip command.
"""

from __future__ import annotations

import os

BACKENDS = ("fake", "mujoco", "franky", "panda-py", "ros")
SIMULATED = ("fake", "mujoco")  # backends whose arm is simulated: their moves need no confirmation


def _desk(cfg: dict):
    """Franka Desk credentials: the user from the settings, the password only from the environment."""
    if not cfg.get("desk_user"):
        return None
    return cfg["desk_user"], os.environ.get("LASERCAL_DESK_PASSWORD", "")


def fake_truth(cfg: dict, nominal, base=None):
    """The fake backend's true robot of the settings ``cfg``: ``perturb_seed`` (a seeded perturbation of
    ``nominal``) or ``truth`` (a robot file or name; a relative path tried in the folder ``base`` first).

    Returns
    -------
    RobotModel

    Raises
    ------
    FormatError
        A truth whose ``extensions`` the fake arm cannot simulate, naming its file and the field
        (:func:`collector.hardware.fakeeffects.arm_effects`).
    """
    from lasercal.collector.hardware.fake import perturbed_model
    from lasercal.collector.hardware.fakeeffects import arm_effects
    from lasercal.solver.formats.robots import load_model

    if cfg.get("perturb_seed") is not None:
        return perturbed_model(nominal, cfg["perturb_seed"])
    truth = load_model(cfg["truth"], base=base)
    arm_effects(truth, truth_file(cfg["truth"], base))  # refused now, naming the file
    return truth


def truth_file(ref, base=None) -> str:
    """How errors name the truth ``ref``: its file (a built-in name resolved), else ``ref`` as given."""
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.robots import resolve_robot_path

    if str(ref).lower().endswith(".urdf"):
        return str(ref)
    try:
        return str(resolve_robot_path(ref, base))
    except FormatError:
        return str(ref)


def make_robot(
    cfg: dict,
    nominal,
    layout,
    per_point: int = 0,
    truth=None,
    points=None,
    repeat_sigma=0.0,
    place=None,
    placement=None,
    printed: bool = False,
):
    """The robot adapter a settings mapping asks for.

    Parameters
    ----------
    cfg : dict, the capture/validate settings (``backend``, ``host``, ``dynamics``, ``seed``, ...)
    nominal : RobotModel, the robot the session names
    layout : Layout, the reference points (the simulated operator aims at the calibration points)
    per_point : int, captures per point the simulated operator takes (0: no operator)
    truth : RobotModel or None, the fake robot's true geometry (None: the settings' ``truth`` or
        ``perturb_seed``; a validation on a sheet passes its simulated world's, :mod:`sessions.world`)
    points : dict or None, where the simulated operator aims, name -> (3,) mm in the true robot's frame
        (None: the layout's calibration points; :func:`fakeworld.table_points`)
    repeat_sigma : float, the fake arm's repeatability, rad (:mod:`collector.hardware.fakeworld`)
    place : callable or None, where the layout's spots truly are on the fake table (:class:`FakeRobot`)
    placement : SheetPose or None, the layout's placement of its sheet (mujoco: the operator finds a point on
        the world's sheet through it)
    printed : bool, the layout is a printed sheet (its crosses lie where it says: a truth's point offset
        is refused)

    Returns
    -------
    RobotAdapter
    """
    from lasercal.solver.errors import LasercalError

    backend = cfg["backend"]
    if cfg.get("world") and backend != "mujoco":
        raise LasercalError(f"--world is a MuJoCo world file: it needs --backend mujoco (not {backend})")
    if backend == "mujoco":
        from lasercal.collector.hardware.mujoco import make_mujoco_robot

        return make_mujoco_robot(cfg, nominal, layout, per_point, placement)
    if backend == "fake":
        from lasercal.collector.hardware.base import FakeClock
        from lasercal.collector.hardware.fake import FakeOperator, FakeRobot
        from lasercal.collector.hardware.fakeeffects import arm_effects

        truth = fake_truth(cfg, nominal) if truth is None else truth
        source = truth_file(cfg["truth"]) if cfg.get("truth") and cfg.get("perturb_seed") is None else None
        effects = arm_effects(truth, source, layout.points if per_point else None, printed and per_point > 0)
        pts = {k: (layout.points if points is None else points)[k] for k in layout.calibration}
        operator = (
            FakeOperator(
                truth,
                effects.aimed_points(pts),
                per_point,
                cfg["aim_noise"],
                cfg["seed"],
                layout.aim_kwargs(),
            )
            if per_point
            else None
        )
        return FakeRobot(
            truth,
            FakeClock(),
            operator,
            seed=cfg["seed"],
            repeat_sigma=repeat_sigma,
            place=place,
            effects=effects,
        )
    if not cfg.get("host"):
        raise LasercalError(f"--backend {backend} needs --host (the robot's or rosbridge's address)")
    if backend == "franky":
        from lasercal.collector.hardware.franky import FrankyRobot

        return FrankyRobot(cfg["host"], cfg["dynamics"], _desk(cfg))
    if backend == "panda-py":
        from lasercal.collector.hardware.pandapy import PandaPyRobot

        return PandaPyRobot(cfg["host"], cfg["dynamics"], _desk(cfg))
    from lasercal.collector.hardware.ros import RosRobot

    joints = cfg["ros_joints"].split(",") if cfg.get("ros_joints") else None
    return RosRobot(cfg["host"], cfg["ros_port"], nominal.n, joints)


def make_rangefinder(cfg: dict, robot, plane_z: float):
    """The laser rangefinder the settings ask for (``rangefinder``: ``fake``, a serial URL, or none)."""
    from lasercal.collector.hardware.rangefinder import FakeRangefinder, SerialRangefinder
    from lasercal.solver.errors import LasercalError

    if cfg.get("rangefinder") == "fake":
        if cfg["backend"] != "fake":
            raise LasercalError("--rangefinder fake needs --backend fake")
        return FakeRangefinder(robot, plane_z, seed=cfg["seed"])
    if cfg.get("rangefinder"):
        query = (cfg.get("rangefinder_query") or "").encode().decode("unicode_escape").encode()
        return SerialRangefinder.from_url(cfg["rangefinder"], query)
    return None
