"""Robot hardware: backends behind one small interface
(:class:`~lasercal.collector.hardware.base.RobotAdapter`), and the factories that build them from settings.

``fake`` (simulated Panda and operator), ``mujoco`` (a MuJoCo world file, its arm and camera driven
as hardware is), ``franky`` (franky-control), ``panda-py`` (panda-python), ``ros`` (rosbridge
/joint_states). Each backend module imports its SDK only when used; a missing SDK is a one-line error
with the pip command.
"""

from __future__ import annotations

import os

from lasercal.collector.hardware.simulated import SIMULATED as SIMULATED

BACKENDS = ("fake", "mujoco", "franky", "panda-py", "ros")


def _desk(cfg: dict):
    """Franka Desk credentials: the user from the settings, the password only from the environment."""
    if not cfg.get("desk_user"):
        return None
    return cfg["desk_user"], os.environ.get("LASERCAL_DESK_PASSWORD", "")


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
        ``perturb_seed``; a validation on a sheet passes its simulated world's, :mod:`worlds.record`)
    points : dict or None, where the simulated operator aims, name -> (3,) mm in the true robot's frame
        (None: the layout's calibration points; :func:`fakeworld.table_points`)
    repeat_sigma : float, the fake arm's repeatability, rad (:mod:`collector.worlds.fakeworld`)
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
        from lasercal.collector.worlds.mujoco import make_mujoco_robot

        return make_mujoco_robot(cfg, nominal, layout, per_point, placement)
    if backend == "fake":
        from lasercal.collector.hardware.base import FakeClock
        from lasercal.collector.worlds.fake import FakeOperator, FakeRobot, fake_truth, truth_file
        from lasercal.collector.worlds.fakeeffects import arm_effects

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


# -- the simulated worlds, reached only through here (collector.worlds: tests/test_architecture.py) --------


def draw_world(effects, seed: int, layout):
    """A fake world's table effects (``capture --effects``) drawn once from the session's ``seed`` for the
    layout's sheet (:meth:`collector.worlds.fakeworld.World.draw`); ``effects`` () draws none."""
    from lasercal.collector.worlds.fakeworld import World, paper_half_length

    return World.draw(effects or (), seed, paper_half_length(layout))


def no_effects():
    """A fake world without table effects (a validation off a sheet)."""
    from lasercal.collector.worlds.fakeworld import World

    return World()


def recorded_world(folder):
    """The fake world a session folder recorded (session.yaml's ``simulated.world``), for its resume."""
    from lasercal.collector.worlds.record import stored_effects

    return stored_effects(folder)


def fake_table(layout, world, beside=(0.0, 0.0)):
    """Where the fake operator aims on the world's table, and where a layout's (x, y) truly lies on it.

    Returns
    -------
    (points, place): name -> (3,) mm in the true robot's frame, and ``place(xy (2,) mm) -> (3,) mm``
    """
    from lasercal.collector.worlds.fakeworld import on_table, table_points

    return table_points(layout, world, beside), lambda xy: on_table(layout, world, xy)


def sheet_camera(cfg: dict, robot, layout, markers, world):
    """A capture session's fake camera (``--camera fake``): the printed sheet at its placement on the world's
    table, photographed through the world's lens (:class:`collector.worlds.cameras.SheetCamera`). Off the
    fake backend it photographs the nominal ``cfg["robot"]``'s beam at the joint angles the robot reports
    (:class:`collector.worlds.cameras.StatedTruth`), and says so on stderr."""
    import sys

    import numpy as np

    from lasercal.collector.worlds.cameras import SheetCamera, StatedTruth
    from lasercal.solver.formats.robots import load_model

    arm = robot
    if cfg["backend"] != "fake":
        arm = StatedTruth(load_model(cfg["robot"]), robot)
        sys.stderr.write(
            f"--camera fake on --backend {cfg['backend']}: the photos show where the nominal "
            f"{arm.truth.name}'s laser beam (the stated truth, as a simulator's arm is) meets the sheet "
            f"at its placement, at the joint angles the robot reports; world effects: "
            f"{', '.join(world.effects) or 'none'}\n"
        )
    crosses = np.array([p[:2] for p in layout.points.values()])
    paper = world.paper(layout.sheet, layout.plane_z)
    return SheetCamera(arm, markers, crosses, paper, world, cfg["seed"])


def top_camera(robot, centre, plane_z: float, seed: int, paper=None, world=None):
    """A validation's fake camera looking down at ``centre`` (2,) mm: on the world's true ``paper`` (its
    printed mm; :class:`collector.worlds.cameras.PaperTopCamera`), else on a blank sheet at ``plane_z``
    (base frame; :class:`collector.worlds.cameras.FakeCamera`). Its ``view`` maps a photo to mm."""
    from lasercal.collector.worlds.cameras import (
        FAKE_MM_PER_PX,
        FAKE_VIEW_PX,
        FakeCamera,
        PaperTopCamera,
        fake_view,
    )

    if paper is not None:
        return PaperTopCamera(robot, paper, centre, world, seed, FAKE_VIEW_PX, FAKE_MM_PER_PX)
    return FakeCamera(robot, fake_view(centre, plane_z, FAKE_VIEW_PX, FAKE_MM_PER_PX), plane_z, seed=seed)


def mujoco_camera(robot):
    """The MuJoCo world's camera (``--camera mujoco``) of a robot on the mujoco backend."""
    from lasercal.collector.worlds.mujoco import mujoco_camera as camera

    return camera(robot)


def session_world(folder):
    """The simulated world a session folder was made in (its true robot and sheet), or None."""
    from lasercal.collector.worlds.record import session_world as world

    return world(folder)


def validation_world(cfg: dict, nominal, sheet_session=None, pose=None, placement=None):
    """The fake backend's world for a validation on a sheet
    (:func:`collector.worlds.record.validation_world`)."""
    from lasercal.collector.worlds.record import validation_world as world

    return world(cfg, nominal, sheet_session, pose, placement)


def true_sheet_pose(world, nominal, z: float):
    """A simulated world's true sheet pose in the nominal's frame, and its map
    (:func:`collector.worlds.record.true_sheet_pose`)."""
    from lasercal.collector.worlds.record import true_sheet_pose as pose

    return pose(world, nominal, z)


def world_joints(truth):
    """The simulated world's joints of a true robot (its gravity torques and joint effects, eqs. W4-W6:
    :class:`collector.worlds.truejoints.TrueJoints`), the flange's load it records included."""
    from lasercal.collector.worlds.truejoints import true_joints
    from lasercal.solver.control.nominal import recorded_payload

    return true_joints(truth, recorded_payload(truth))


def simulated_arm(robot) -> bool:
    """The adapter is a fake world's arm (its true pose can be read: ``true_q``)."""
    from lasercal.collector.worlds.fake import FakeRobot

    return isinstance(robot, FakeRobot)


def write_mujoco_scene(
    folder, layout, pdf, seed, passive=(), light=1.0, shadows=False, curl=0.0, camera_at=None
) -> dict:
    """``lasercal mujoco-scene``: a MuJoCo world for a printed sheet written into ``folder``
    (:func:`collector.worlds.mujoco_scene.write_scene`); ``passive``: dicts of
    :class:`collector.worlds.mujoco_scene.Passive`'s fields; ``camera_at``: (3,) mm from the sheet's centre
    (None: the default). Returns what it drew (scene.yaml's content)."""
    from lasercal.collector.worlds.mujoco_scene import CAMERA_OFFSET_MM, Passive, SceneOptions, write_scene

    passive = tuple(Passive(**p) for p in passive)
    at = CAMERA_OFFSET_MM if camera_at is None else tuple(camera_at)
    options = SceneOptions(seed, passive=passive, light=light, shadows=shadows, curl=curl, camera_at=at)
    return write_scene(folder, layout, pdf, options)
