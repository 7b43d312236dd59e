"""The simulated world of a validation on the fake backend: the true robot, and where the sheet truly lies.

On a printed sheet (``frame: sheet``) the model under test aims at the points where a calibration found
the sheet (eq. S1, in the robot's own base frame, eq. S2); the simulated camera sees where the true beam
meets the sheet where it truly lies. That world is, in order:

1. ``--sheet-pose X Y YAW`` (mm, mm, deg): the settings' true robot in its own frame (eq. S2) and the
   sheet at that pose -- the world ``lasercal simulate --sheet-pose`` makes;
2. the world the session was simulated in, the session the sheet's pose was identified from (a model's
   ``identification.session``): ``simulate --sheet-pose`` stores its truth in its own frame
   (``truth.yaml``) and the sheet's pose; ``simulate`` without it and ``capture --backend fake`` lay the
   sheet at its placement under the truth they name;
3. otherwise the settings' true robot, with the sheet at the layout's placement (as ``capture --backend
   fake`` lays it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lasercal.collector.worlds.fake import fake_truth
from lasercal.collector.worlds.fakeworld import World
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.robots import load_model, load_yaml, sheet_pose
from lasercal.solver.kinematics.frames import moved, own_frame
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose


@dataclass(frozen=True)
class SimulatedWorld:
    """The fake backend's world.

    Attributes
    ----------
    truth : RobotModel, the true robot (in the frame the sheet's pose is given in)
    sheet : SheetPose or None, where the sheet truly lies in the truth's base frame (None: no sheet)
    source : str, where both come from (one line, for the operator and validation.yaml)
    effects : World, what a real table, camera and arm add (:mod:`collector.worlds.fakeworld`): the
        session's, so that the arm is as repeatable and the sheet as high in validation as in capture
    """

    truth: RobotModel
    sheet: SheetPose | None
    source: str
    effects: World = field(default_factory=World)

    def as_dict(self) -> dict:
        """``{truth, sheet, from}``: what validation.yaml records of the world (the truth by name)."""
        out = {
            "truth": self.truth.name,
            "sheet": None if self.sheet is None else self.sheet.as_dict(),
            "from": self.source,
        }
        if self.effects.effects:
            out["effects"] = self.effects.as_dict()
        return out


def session_world(folder) -> SimulatedWorld | None:
    """The world a simulated session was captured in, or None for a measured one (or no sheet session).

    Parameters
    ----------
    folder : a session folder (session.yaml)

    Returns
    -------
    SimulatedWorld or None

    Raises
    ------
    FormatError
        A simulated session whose truth or sheet pose cannot be read (naming session.yaml and the field).
    """
    folder = Path(folder)
    path = folder / "session.yaml"
    meta = load_yaml(path)
    sim = meta.get("simulated") if isinstance(meta, dict) else None
    if not sim or meta.get("frame") != "sheet":
        return None
    if not isinstance(sim, dict):
        raise FormatError(
            path, "'simulated' must be a mapping (truth, aim_noise_mm, seed)", field="simulated"
        )
    placed = sheet_pose(meta, "sheet", path, placement=True)
    truth_sheet = sim.get("sheet")
    if truth_sheet is not None:  # simulate --sheet-pose: the truth in its own frame, the sheet's true pose
        if not isinstance(truth_sheet, dict) or not truth_sheet.get("truth_in_own_frame"):
            raise FormatError(path, "expected {pose, truth_in_own_frame}", field="simulated.sheet")
        pose = sheet_pose(truth_sheet, "pose", path)
        truth = load_model(folder / str(truth_sheet["truth_in_own_frame"]))
        return SimulatedWorld(truth, pose, f"session {folder.name!r}: simulated, the sheet at its true pose")
    collector = meta.get("collector")
    if isinstance(collector, dict) and collector.get("backend") == "fake":  # capture --backend fake
        truth = fake_truth(collector, load_model(collector.get("robot", "panda")), folder)
    elif sim.get("truth"):  # simulate on a sheet layout: the sheet lies at its placement
        truth = load_model(str(sim["truth"]), base=folder)
    else:
        return None
    if placed is None:
        return None
    effects = World.from_dict(sim.get("world"))
    return SimulatedWorld(
        truth, placed, f"session {folder.name!r}: simulated, the sheet at its placement", effects
    )


def stored_effects(folder) -> World:
    """The simulated world's effects a session recorded (``simulated.world`` of its session.yaml; none when it
    records none): what a resumed capture goes on in, as drawn when it started."""
    meta = load_yaml(Path(folder) / "session.yaml")
    sim = meta.get("simulated") if isinstance(meta, dict) else None
    return World.from_dict(sim.get("world") if isinstance(sim, dict) else None)


def true_sheet_pose(world: SimulatedWorld, nominal: RobotModel, z: float) -> tuple[SheetPose, np.ndarray]:
    """Where a simulated sheet truly lies in the frame ``solve`` reports its pose in: the true robot's own
    base frame (eq. S2: joint 1 as the nominal's, joint 2 pointing as the nominal's), not the truth file's.

    Read off the world's own paper (:meth:`collector.worlds.fakeworld.World.paper`: the printer's scale
    and skew, the table's slope, the sheet's height) at the layout's origin: the pose, print scale and tilt
    eq. S3 would give it there (the paper's bulge, which eq. S3 cannot hold, left out; the printer's skew,
    neither, split evenly between the axes: the yaw the rotation nearest the print's axes). A
    truth whose base differs from the nominal's (the thesis's Panda: turned 0.44 deg about joint 1) puts a
    sheet laid at its placement (450, 0, 0) elsewhere in its own frame (y -4.0 mm): the number ``solve``
    finds, within its sigma.

    Parameters
    ----------
    world : SimulatedWorld with a sheet, in the truth's base frame
    nominal : RobotModel, the robot the session names
    z : float, the plane's height, mm

    Returns
    -------
    SheetPose, the sheet in the truth's own frame, as printed; (4, 4) array G, the truth's base frame to its
    own, mm
    """
    G = own_frame(world.truth, nominal)
    paper = world.effects.paper(world.sheet, z)
    origin = G[:3, :3] @ paper.surface(np.zeros((1, 2)))[0] + G[:3, 3]
    T = G[:3, :3] @ paper.tangents(np.zeros((1, 2)))[0]  # (3, 2): how a printed mm moves, own frame
    A = T[:2]  # its horizontal part: eq. S3's Rz(yaw) diag(scale), but for the printer's skew
    yaw = np.arctan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1])  # the rotation nearest A (a skew split evenly)
    c, s = np.cos(yaw), np.sin(yaw)
    scale = np.diag(np.array([[c, s], [-s, c]]) @ A)
    tilt = T[2] / scale  # the rise per printed mm, over the scale (eq. S3)
    pose = SheetPose(
        float(origin[0]), float(origin[1]), float(np.degrees(yaw)), *map(float, scale), *map(float, tilt)
    )
    return pose, G


def validation_world(
    cfg: dict,
    nominal: RobotModel,
    sheet_session: Path | None = None,
    pose: SheetPose | None = None,
    placement: SheetPose | None = None,
) -> SimulatedWorld:
    """The fake backend's world for a validation on a sheet (the module's rules 1-3).

    Parameters
    ----------
    cfg : dict, the validation settings (``truth`` or ``perturb_seed``)
    nominal : RobotModel, the robot the settings name
    sheet_session : Path or None, the session the sheet's pose was identified from
    pose : SheetPose or None, the sheet's true pose given (``--sheet-pose``), in the truth's own frame
    placement : SheetPose or None, the layout's placement of the sheet

    Returns
    -------
    SimulatedWorld
    """
    if pose is not None:
        truth = fake_truth(cfg, nominal)
        truth = moved(truth, own_frame(truth, nominal))
        return SimulatedWorld(truth, pose, "--sheet-pose, the truth in its own frame")
    world = session_world(sheet_session) if sheet_session is not None else None
    if world is not None:
        return world
    return SimulatedWorld(fake_truth(cfg, nominal), placement, "the layout's placement")
