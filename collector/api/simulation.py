"""``lasercal.simulate``: a synthetic session whose truth is a given robot (``lasercal simulate``).

Laser sessions: the operator aims the true robot's beam at the layout's calibration points, ``per_point``
times each, with ``aim_noise`` mm per axis (:func:`~lasercal.solver.analysis.simulate.simulate_captures`);
the arm's hidden joint effects and its gravity torques are the simulated world's (eqs. W4-W6,
:mod:`lasercal.collector.worlds.truejoints`), not the solver's forms;
the session names the nominal robot, so that calibrating it recovers the truth. Position sessions: random
in-limit poses, every target on the tool measured by a 3-D sensor ``noise`` mm per axis
(:func:`~lasercal.solver.analysis.simulate.simulate_positions`). Either may hide a non-geometric effect.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: numpy and the solver load when a simulation runs
    import numpy as np

    from lasercal.solver.formats.session import Layout
    from lasercal.solver.kinematics.effects import Extension
    from lasercal.solver.kinematics.model import RobotModel
    from lasercal.solver.kinematics.sheet import SheetPose

SENSOR_DISTANCE = 2500.0  # mm: a tracker's usual stand-off from the robot base
TARGET_OFFSETS = ((60.0, 0, 30), (-40, 50, 20), (0, -60, 40), (50, 50, 60))  # mm, tip frame


@dataclass(frozen=True)
class Simulation:
    """A simulated session, written.

    Attributes
    ----------
    folder : Path, the session folder (session.yaml + captures.csv)
    truth : RobotModel, the true robot (a sheet session's: in its own frame)
    captures : int, rows of captures.csv
    effect : Extension or None, the hidden effect with its true parameters
    summary : str, what ``lasercal simulate`` prints after ``wrote FOLDER:``
    """

    folder: Path
    truth: RobotModel
    captures: int
    effect: Extension | None
    summary: str


def default_sensor(distance: float = SENSOR_DISTANCE) -> np.ndarray:
    """^S T_base (4, 4): the sensor ``distance`` mm from the base, rotated 40, 10, -20 deg (z, y, x)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    X = np.eye(4)
    X[:3, :3] = Rotation.from_euler("zyx", [40, 10, -20], degrees=True).as_matrix()
    X[:3, 3] = distance * np.array([0.8, -0.5, 0.33]) / np.linalg.norm([0.8, -0.5, 0.33])
    return X


def default_targets(model: RobotModel, k: int) -> dict:
    """k targets at fixed offsets in the tip frame (ee_pose) or around the model's tool point."""
    import numpy as np

    from lasercal.solver.identify.position import target_start

    M = np.asarray(model.ee_pose) if model.ee_pose is not None else np.eye(4)
    base = M[:3, 3] if model.ee_pose is not None else target_start(model)
    offsets = np.array(TARGET_OFFSETS)
    return {f"T{i + 1}": base + M[:3, :3] @ offsets[i % len(offsets)] for i in range(k)}


def hidden_effect(
    effect: str | None,
    size: float | None,
    joints,
    point: str | None,
    layout: Layout | None,
    n: int,
    rng: np.random.Generator,
    layout_name=None,
) -> Extension | None:
    """The effect a simulation hides, with its true parameters (random phase/direction from ``rng``).

    Parameters
    ----------
    effect : str or None, a joint effect's name or 'reference_point_offset'
    size : float, c (rad/Nm), eccentricity amplitude (rad), drift r (rad/s) or offset (mm)
    joints : sequence of int, the 1-based joints of a joint effect
    point : str, the layout's point of a reference_point_offset
    layout : Layout or None
    n : int, the robot's joints
    rng : numpy Generator
    layout_name : str or Path, how the layout was given (named in an error)

    Returns
    -------
    Extension or None
    """
    import numpy as np

    from lasercal.solver.errors import FormatError
    from lasercal.solver.kinematics.effects import Extension

    if not effect:
        given = [f for f, v in (("--effect-size", size), ("--effect-point", point)) if v]
        if given:
            raise FormatError(
                "--effect", f"{given[0]} was given without --effect NAME (which effect to hide?)"
            )
        return None
    if size is None:
        raise FormatError("--effect-size", "give the size of the hidden effect")
    if effect == "reference_point_offset":
        if layout is None or point not in layout.points:
            raise FormatError(
                layout_name,
                f"--effect-point {point!r} is not a point of the layout",
                field="points",
            )
        phi = rng.uniform(0, 2 * np.pi)
        return Extension(effect, (), point, size * np.array([np.cos(phi), np.sin(phi)]))
    joints = tuple(joints)
    if any(not 1 <= j <= n for j in joints):
        raise FormatError("--effect-joints", f"joints are numbered 1..{n}")
    if effect == "encoder_eccentricity":
        phi = rng.uniform(0, 2 * np.pi, len(joints))
        params = np.stack([size * np.cos(phi), size * np.sin(phi)], axis=1).ravel()
    else:
        params = np.full(len(joints), size)
    return Extension(effect, joints, None, params)


def camera_aims(layout: Layout, per_point: int, radius: float, seed: int) -> dict:
    """Where each capture of a simulated camera session aims: per calibration point, (per_point, 2) offsets
    in the layout's frame drawn uniformly in a disc of ``radius`` mm (the coach's aim anywhere), mm."""
    import numpy as np

    from lasercal.solver.streams import stream

    out = {}
    for name in layout.calibration:
        g = stream(seed, "camera aims", name)
        r, phi = radius * np.sqrt(g.uniform(0, 1, per_point)), g.uniform(0, 2 * np.pi, per_point)
        out[name] = np.c_[r * np.cos(phi), r * np.sin(phi)]
    return out


def turned(aims: dict | None, pose: SheetPose | None) -> dict | None:
    """Aim offsets in a sheet's frame turned into the base frame by its yaw (a base layout's: as they are)."""
    import numpy as np

    if aims is None or pose is None:
        return aims
    c, s = np.cos(np.radians(pose.yaw_deg)), np.sin(np.radians(pose.yaw_deg))
    return {k: v @ np.array([[c, -s], [s, c]]).T for k, v in aims.items()}


def aim_columns(layout: Layout, aims: dict) -> dict:
    """The aim_x, aim_y columns (mm, the layout's frame) of captures aimed at ``aims`` off their points."""
    import numpy as np

    xy = np.concatenate([np.asarray(layout.points[k][:2]) + v for k, v in aims.items()])
    return {"aim_x": [f"{v:.3f}" for v in xy[:, 0]], "aim_y": [f"{v:.3f}" for v in xy[:, 1]]}


def measured_columns(c, pose: SheetPose | None, share: float, sigma: float, seed: int) -> dict:
    """The camera_x .. camera_note columns of a simulated camera session: a random ``share`` of the captures
    measured, each the true spot (on the sheet at its true ``pose``, or in the base frame) plus Gaussian
    noise of ``sigma`` mm per axis; the others empty (aimed), mm."""
    import numpy as np

    from lasercal.solver.streams import stream

    g = stream(seed, "camera")
    m = len(c.q)
    meas = np.zeros(m, bool)
    meas[g.permutation(m)[: int(round(share * m))]] = True
    xy = pose.from_base(c.hit) if pose is not None else c.hit[:, :2]
    xy = xy + g.normal(0.0, sigma, xy.shape)
    cell = lambda v: [f"{x:.4f}" if ok else "" for x, ok in zip(v, meas)]  # noqa: E731
    return {
        "camera_x": cell(xy[:, 0]),
        "camera_y": cell(xy[:, 1]),
        "camera_sx": cell(np.full(m, sigma)),
        "camera_sy": cell(np.full(m, sigma)),
        "camera_note": ["" if ok else "simulated: aimed" for ok in meas],
    }


def sheet_world(truth: RobotModel, nominal: RobotModel, layout: Layout, pose: SheetPose):
    """A sheet simulation's world: the true robot in its own frame (eq. S2), the layout as a sheet (a base
    layout's points become sheet coordinates, placed where the layout says), the points where the sheet
    truly lies (``pose``), and what the session records of it.

    Returns
    -------
    (truth in its own frame, the sheet layout, the layout at the true pose (base frame), dict)
    """
    from dataclasses import replace

    import numpy as np

    from lasercal.solver.kinematics.frames import moved, own_frame
    from lasercal.solver.kinematics.sheet import SheetPose

    if layout.frame == "base":
        pts = {k: np.r_[v[:2], 0.0] for k, v in layout.points.items()}
        layout = replace(layout, points=pts, frame="sheet", sheet=SheetPose())
    own = moved(truth, own_frame(truth, nominal))
    return (
        own,
        layout,
        layout.in_base(pose),
        {
            "pose": pose.as_dict(),
            "frame": "the true robot's own (joint 1 as the nominal's, joint 2 at q = 0 in its direction)",
            "truth_in_own_frame": "truth.yaml",
        },
    )


def simulate(
    truth,
    folder,
    *,
    layout=None,
    measurement: str = "laser",
    per_point: int = 15,
    aim_noise: float = 1.0,
    seed: int = 0,
    robot=None,
    sheet_pose: SheetPose | None = None,
    effect: str | None = None,
    effect_joints=(2,),
    effect_point: str | None = None,
    effect_size: float | None = None,
    configs: int = 60,
    targets: int = 3,
    noise: float = 0.02,
    base_link: str | None = None,
    tip_link: str | None = None,
    measured: float = 0.0,
    spot_sigma: float = 0.03,
    aim_radius: float | None = None,
) -> Simulation:
    """Write a synthetic session whose truth is ``truth`` into ``folder`` (``lasercal simulate``).

    Parameters
    ----------
    truth : str or Path, the true robot: a built-in name, a model YAML or (position sessions) a URDF
    folder : str or Path, the session folder to write (created; files of the same names are replaced)
    layout : str, Path or Layout, the reference points (laser sessions): a built-in name ('thesis') or file
    measurement : str, 'laser' (spots on a plane) or 'position' (targets measured by a 3-D sensor)
    per_point : int, laser: captures per calibration point
    aim_noise : float, laser: aiming noise std per axis, mm
    seed : int
    robot : str, the nominal robot the session names (default: the truth file's ``nominal`` key, else the
        truth itself)
    sheet_pose : SheetPose, laser: the points lie on a sheet at this true pose in the true robot's own
        frame; the session says ``frame: sheet`` and gives the layout's placement
    effect : str, a non-geometric effect to hide (a joint effect's name or 'reference_point_offset')
    effect_joints : sequence of int, its 1-based joints
    effect_point : str, the layout point of a reference_point_offset
    effect_size : float, c (rad/Nm), eccentricity amplitude (rad), drift r (rad/s) or offset (mm)
    configs : int, position: robot poses
    targets : int, position: targets on the tool (when the truth has none)
    noise : float, position: sensor noise std per axis, mm
    base_link, tip_link : str, a URDF truth's chain ends
    measured : float in [0, 1], laser: the share of captures whose spot a camera measured (camera_x ..
        columns: the true spot on the sheet plus Gaussian noise of ``spot_sigma`` mm per axis); the others
        are aimed, with ``aim_noise``, as an operator aims where the camera cannot see
    spot_sigma : float, mm per axis, the camera's noise on a measured spot
    aim_radius : float, mm: each capture aims at a random spot within this radius of its point (the
        coach's aim anywhere; aim_x, aim_y columns); default 40 with measured captures, else 0 (the points)

    Returns
    -------
    Simulation

    Raises
    ------
    FormatError
        A laser session without a layout, an effect that does not fit the robot or layout, unreadable files.
    """
    from lasercal.solver.formats.robots import resolve_robot_path

    path = Path(truth) if str(truth).lower().endswith(".urdf") else resolve_robot_path(truth)
    hiding = (effect, effect_size, effect_joints, effect_point)
    if measurement == "position":
        return _simulate_positions(
            path, folder, robot, configs, targets, noise, seed, hiding, base_link, tip_link
        )
    camera = (measured, spot_sigma, aim_radius)
    aiming, chain = (per_point, aim_noise, seed), (base_link, tip_link)
    return _simulate_laser(path, folder, layout, robot, aiming, sheet_pose, hiding, camera, chain)


def _simulate_laser(
    path: Path, folder, layout, robot, aiming, sheet_pose, hiding, camera, chain
) -> Simulation:
    """A laser session (:func:`simulate`); ``aiming``: (per_point, aim_noise mm, seed); ``hiding``:
    :func:`hidden_effect`'s (effect, size, joints, point); ``camera``: (measured share, spot sigma mm, aim
    radius mm or None); ``chain``: a URDF truth's (base_link, tip_link)."""
    import numpy as np

    from lasercal.collector.hardware import world_joints
    from lasercal.solver.analysis.simulate import simulate_captures
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.data import truth_references
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout, session_meta, write_session

    if layout is None:
        raise FormatError("--layout", "a laser session needs a layout (--layout)")
    (per_point, aim_noise, seed), (measured, spot_sigma, aim_radius) = aiming, camera
    model = load_model(path, base_link=chain[0], tip_link=chain[1])
    # the session names its truth and nominal relative to itself (a temporary sibling resolves alike)
    truth_ref, nominal_ref = truth_references(path, folder, robot)
    name = layout.path if hasattr(layout, "points") else layout
    layout = layout if hasattr(layout, "points") else load_layout(layout)
    rng = np.random.default_rng(seed)
    hidden = hidden_effect(*hiding, layout, model.n, rng, name)
    sim = {"truth": truth_ref, "aim_noise_mm": aim_noise, "seed": seed}
    model, layout, aimed, true_pose = laid(model, layout, nominal_ref, folder, sheet_pose, sim)
    radius = (40.0 if measured > 0 else 0.0) if aim_radius is None else aim_radius
    aims = camera_aims(layout, per_point, radius, seed) if radius > 0 else None
    offsets = turned(aims, true_pose)
    arm = world_joints(model.replace(extensions=hidden.model_entries() if hidden else {}))
    c = simulate_captures(model, aimed, per_point, aim_noise, rng, effect=hidden, aims=offsets, arm=arm)
    if hidden is not None:
        sim["effect"] = {"name": hidden.effect, **hidden.to_dict()}
    if measured > 0:
        sim |= {"measured": measured, "spot_sigma_mm": spot_sigma}
    extra = laser_columns(c, layout, aims, true_pose, measured, spot_sigma, seed)
    meta = session_meta(nominal_ref, layout, model.aperture[2], simulated=sim)
    write_session(folder, meta, c.point, c.t, c.q, tau=c.tau, extra=extra)
    if sheet_pose is not None:
        model.save(Path(folder) / sim["sheet"]["truth_in_own_frame"])
    return Simulation(
        Path(folder), model, len(c.q), hidden, laser_summary(c, layout, model, aim_noise, hidden)
    )


def laser_columns(c, layout: Layout, aims, pose: SheetPose | None, measured: float, sigma: float, seed: int):
    """captures.csv's extra columns of a laser simulation: where each capture aimed (:func:`aim_columns`)
    and, with ``measured`` > 0, the camera's (:func:`measured_columns`)."""
    extra = {} if aims is None else aim_columns(layout, aims)
    if measured > 0:
        extra = measured_columns(c, pose, measured, sigma, seed) | extra
    return extra


def laid(model: RobotModel, layout: Layout, nominal_ref, folder, sheet_pose: SheetPose | None, sim: dict):
    """Where a laser simulation's points truly lie: a sheet at ``sheet_pose`` under the truth in its own
    frame (:func:`sheet_world`; ``sim`` gets its record), a sheet layout at its placement, or the layout's
    base-frame points.

    Returns
    -------
    (truth, the layout the session names, the layout aimed at (base frame), the sheet's true pose or None)
    """
    from lasercal.solver.formats.robots import load_model

    aimed = layout
    if sheet_pose is not None:  # the own frame of the nominal the session records
        model, layout, aimed, sim["sheet"] = sheet_world(
            model, load_model(nominal_ref, base=Path(folder)), layout, sheet_pose
        )
    elif layout.frame == "sheet":
        aimed = layout.in_base()  # the sheet lies where its placement says
    true_pose = (sheet_pose or layout.sheet) if layout.frame == "sheet" else None
    return model, layout, aimed, true_pose


def laser_summary(c, layout: Layout, model: RobotModel, aim_noise: float, hidden) -> str:
    """What ``lasercal simulate`` prints of a laser session after ``wrote FOLDER:``."""
    import numpy as np

    shown = ""
    if hidden is not None:
        shown = f", hidden {hidden.effect} {hidden.names} = {np.round(hidden.params, 9).tolist()}"
    return (
        f"{len(c.q)} captures at {', '.join(layout.calibration)} (truth {model.name}, aiming noise "
        f"{aim_noise} mm{shown})"
    )


def _simulate_positions(
    path: Path, folder, robot, configs: int, k: int, noise: float, seed: int, hiding, base_link, tip_link
) -> Simulation:
    """A position session: random in-limit poses, every target each pose (:func:`simulate`); ``hiding``:
    the effect to hide, :func:`hidden_effect`'s (effect, size, joints, point)."""
    import numpy as np

    from lasercal.solver.analysis.simulate import random_configs, simulate_positions
    from lasercal.solver.formats.data import truth_references
    from lasercal.solver.formats.positions import position_meta, write_position_session
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.kinematics.gravity import model_torques

    chain = {k: v for k, v in (("base_link", base_link), ("tip_link", tip_link)) if v}
    truth = load_model(path, **chain)
    effect, size, joints, point = hiding
    hidden = hidden_effect(effect, size, joints, point, None, truth.n, np.random.default_rng(seed + 1))
    truth_ref, nominal = truth_references(path, folder, robot)  # relative to the session
    if not truth.targets:
        truth = truth.replace(targets=default_targets(truth, k))
    if truth.sensor_pose is None:
        truth = truth.replace(sensor_pose=default_sensor())
    rng = np.random.default_rng(seed)
    names = np.array(list(truth.targets), dtype=object)
    q = np.repeat(random_configs(truth, configs, rng), len(names), axis=0)
    tg = np.tile(names, configs)
    tau, src = model_torques(truth, q)
    y = simulate_positions(truth, q, tg, noise, rng, hidden, tau)
    sim = {"truth": truth_ref, "noise_mm": noise, "seed": seed, "torques": src}
    if hidden is not None:
        sim["effect"] = {"name": hidden.effect, **hidden.to_dict()}
    meta = position_meta(nominal, names, **chain, noise_mm=noise, simulated=sim)
    write_position_session(folder, meta, q, y, tg)
    summary = (
        f"{configs} poses x {len(names)} targets (truth {truth.name}, sensor "
        f"{np.linalg.norm(truth.sensor_pose[:3, 3]):.0f} mm from the base, noise {noise} mm)"
    )
    return Simulation(Path(folder), truth, len(q), hidden, summary)
