"""The ``fake`` backend: a simulated Panda and a simulated operator, on a simulated clock.

* The robot's true geometry differs from nominal: a robot file (by default the thesis's
  identified Panda, Table 4.3) or a seeded random perturbation of the nominal model.
* The operator hand-guides the arm to each reference point: for the k-th capture at a
  point they take the k-th of a set of diverse aiming poses of the *true* robot and
  aim with Gaussian noise per in-plane axis (mm), realised exactly with ``polish``.
  Every random draw is keyed by (seed, point, k, attempt), so a session that is
  interrupted and resumed captures exactly what an uninterrupted one would.
* Motion: a minimum-jerk transit to the pose, then a release jiggle whose joint speed
  decays exponentially, plus velocity-sensor noise -- the standstill detector has to
  wait for it. Torques: the true robot's gravity torques at the pose its links stand in, plus sensor noise.
* The true robot's ``extensions`` (compliance, eccentricity, drift, a joint map, a point offset): the
  encoders report q while the links stand where the effects put them
  (:mod:`collector.worlds.fakeeffects`).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from lasercal.collector.errors import RobotConnectionError
from lasercal.collector.hardware.base import FakeClock, JointState, RobotAdapter
from lasercal.collector.worlds.fakeeffects import ArmEffects, arm_effects
from lasercal.collector.worlds.truearm import beam as true_beam_of
from lasercal.collector.worlds.truearm import plane_spot
from lasercal.solver.errors import AimingError, FormatError
from lasercal.solver.formats.robots import load_model, resolve_robot_path
from lasercal.solver.kinematics.aim import aim, polish, spot_error
from lasercal.solver.kinematics.laser import LaserParams
from lasercal.solver.kinematics.model import RobotModel


@dataclass(frozen=True)
class Motion:
    """How the fake arm moves (rad, s).

    Attributes
    ----------
    speed : float, peak joint speed of a commanded move, rad/s (the largest joint move sets its duration)
    guide_time : (min, max), duration of a hand-guided transit, s (uniform)
    settle_speed : float, std of each joint's speed just after arrival (the release jiggle), rad/s
    settle_tau : float, time constant of its exponential decay, s
    dq_noise : float, std of the velocity sensor noise, rad/s
    tau_noise : float, std of the torque sensor noise, Nm
    """

    speed: float = 0.6
    guide_time: tuple = (2.0, 5.0)
    settle_speed: float = 0.05
    settle_tau: float = 0.3
    dq_noise: float = 1e-3
    tau_noise: float = 0.05


def perturbed_model(
    nominal: RobotModel, seed: int, rotation: float = 3e-3, offset: float = 1.5
) -> RobotModel:
    """A seeded random 'true' robot near ``nominal``.

    Every joint axis is tilted by N(0, rotation) rad about two axes and shifted by
    N(0, offset) mm in two directions (minimal POE), the laser direction tilted by
    N(0, rotation) and the aperture moved by N(0, offset) mm per axis.
    """
    P = LaserParams(nominal)
    rng = np.random.default_rng([seed, 0xFA4E])
    scale = np.r_[
        np.tile([rotation, rotation, offset, offset], nominal.n), rotation, rotation, offset, offset, offset
    ]
    return P.to_model(P.x0() + rng.normal(0.0, scale), name=f"{nominal.name}_perturbed_{seed}")


class FakeOperator:
    """Aims the true robot's beam at reference points with Gaussian aiming noise.

    Parameters
    ----------
    truth : RobotModel
    points : dict name -> (3,) array, mm
    per_point : int, size of each point's set of diverse poses
    aim_noise : float, std of the aiming error per in-plane axis, mm
    seed : int
    aim_kw : dict, keyword arguments of :func:`solver.aim.aim` (the layout's hints)
    wrong : dict (point, index) -> other point: first attempts aimed at the wrong point (tests)
    """

    def __init__(
        self,
        truth: RobotModel,
        points: dict,
        per_point: int,
        aim_noise: float,
        seed: int,
        aim_kw: dict | None = None,
        wrong: dict | None = None,
    ):
        self.truth, self.points, self.per_point = truth, points, per_point
        self.aim_noise, self.seed, self.aim_kw, self.wrong = aim_noise, seed, aim_kw or {}, wrong or {}
        self._poses: dict = {}

    def key(self, name: str) -> int:
        """The point's number, part of every random key."""
        return list(self.points).index(name)

    def poses(self, name: str) -> np.ndarray:
        """The diverse aiming poses (per_point, n) of the true robot at a point, rad."""
        if name not in self._poses:
            rng = np.random.default_rng([self.seed, self.key(name)])
            self._poses[name] = aim(self.truth, self.points[name], self.per_point, rng, **self.aim_kw)
        return self._poses[name]

    def configuration(
        self,
        name: str,
        index: int,
        attempt: int,
        start: np.ndarray | None = None,
        at: np.ndarray | None = None,
    ) -> np.ndarray:
        """Where the operator brings the arm for capture ``index`` at ``name`` (try ``attempt``), (n,) rad.

        With ``start`` (the coach's suggested pose, rad) the operator hand-guides from it until the
        true beam hits the point up to the aiming noise; otherwise from their own set of diverse poses.
        With ``at`` (3,) mm in the true robot's frame, they aim there instead of at the point.
        """
        rng = np.random.default_rng([self.seed, self.key(name), index, attempt])
        aimed = self.wrong.get((name, index), name) if attempt == 0 else name
        hit = (self.points[aimed] if at is None else at) + np.r_[rng.normal(0.0, self.aim_noise, 2), 0.0]
        if start is not None and aimed == name:
            q = polish(self.truth, np.asarray(start, dtype=float)[None], hit)
            if spot_error(self.truth, q, hit)[0] < 1e-6 and self.truth.within_limits(q)[0]:
                return q[0]
        poses = self.poses(aimed)
        for k in range(
            self.per_point
        ):  # a pose whose polish does not land on the hit is passed over for the next
            q = polish(self.truth, poses[(index + k) % self.per_point][None], hit)
            if spot_error(self.truth, q, hit)[0] < 1e-6 and self.truth.within_limits(q)[0]:
                return q[0]
        raise AimingError(f"the simulated operator cannot aim at {aimed} with these poses")


class FakeRobot(RobotAdapter):
    """A simulated arm whose true geometry is ``truth``, on a :class:`FakeClock`.

    Parameters
    ----------
    truth : RobotModel, the true geometry (with link masses for the torques)
    clock : FakeClock
    operator : FakeOperator or None (None: nobody guides the arm)
    motion : Motion
    seed : int, seed of the motion and sensor noise
    disconnect_at : float or None, simulated time after which every read fails, s (tests)
    repeat_sigma : float, the arm's repeatability (:mod:`collector.worlds.fakeworld`): the pose it
        reaches differs from what its encoders report by Gaussian joint noise of this std, rad (0: exact),
        a new draw keyed like the motion for every pose reached
    place : callable (k, 2) -> (k, 3) or None, where spots of the layout's frame truly are on the table
        (:func:`collector.worlds.fakeworld.on_table`): the simulated operator aims at a planned spot there
    effects : ArmEffects or None, the truth's extensions (:mod:`collector.worlds.fakeeffects`; None:
        those of ``truth``, refused with its name when the fake arm cannot simulate them)
    """

    name = "fake"
    can_move = True
    guidance = "simulated robot: the simulated operator hand-guides the arm to each point"
    extra_columns = ("robot_mode",)

    def __init__(
        self,
        truth: RobotModel,
        clock: FakeClock,
        operator: FakeOperator | None = None,
        motion: Motion = Motion(),
        seed: int = 0,
        disconnect_at: float | None = None,
        repeat_sigma: float = 0.0,
        place=None,
        effects: ArmEffects | None = None,
    ):
        self.truth, self.clock, self.operator, self.motion = truth, clock, operator, motion
        self.seed, self.disconnect_at, self.repeat_sigma = seed, disconnect_at, repeat_sigma
        self.place = place
        self.effects = arm_effects(truth) if effects is None else effects
        self._attempts: dict = {}
        self._connected = False
        home = np.array(truth.home if truth.home is not None else truth.limits.mean(axis=1), dtype=float)
        self._q0 = self._q1 = home  # at rest at home until told otherwise
        self._t0, self._T, self._v0, self._mode = clock.now(), 0.0, np.zeros_like(home), "Idle"
        self._noise = np.random.default_rng([seed])
        self._grid = None
        self._suggested = None
        self._delta = np.zeros_like(home)  # the reached pose minus the reported one, rad

    # ------------------------------------------------------------ motion model

    def _start(
        self, q: np.ndarray, mode: str, key: tuple, duration: float | None = None, aimed: bool = False
    ) -> None:
        """Begin a transit from where the arm is now to q, ending in a release jiggle.

        Every draw of the motion and of its sensor noise is keyed by ``key``; a hand-guided
        transit's duration is drawn too (not taken from the distance), so that the same
        capture comes out the same after a resume, whatever pose the arm started from.
        q is what the encoders will read, or with ``aimed`` where the operator brings the links: the
        encoders then read the effects' inverse at arrival, off by the repeatability's delta.
        """
        q = np.asarray(q, dtype=float)
        q_now, _ = self._kinematics(self.clock.now())
        rng = np.random.default_rng([self.seed, *key])
        self._v0 = rng.normal(0.0, self.motion.settle_speed, q.shape)
        self._T = rng.uniform(*self.motion.guide_time) if duration is None else duration
        self._noise = rng
        self._delta = self._repeat(key, q.shape)
        if aimed:
            q = self.effects.encoders(q[None], self.clock.now() + self._T)[0] - self._delta
        self._q0, self._q1, self._t0, self._mode = q_now, q, self.clock.now(), mode
        self._grid = None

    def _repeat(self, key: tuple, shape) -> np.ndarray:
        """The reached minus the reported pose of the transit ``key``, rad (its own stream: switching
        repeatability on leaves every other draw as it was)."""
        return np.random.default_rng([self.seed, *key, 0x4E9]).normal(0.0, self.repeat_sigma, shape)

    def _kinematics(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free q (rad) and dq (rad/s) at time t."""
        tau = self.motion.settle_tau
        arrive = self._q1 - self._v0 * tau  # the jiggle ends exactly at q1
        u = (t - self._t0) / self._T if self._T > 0 else 1.0
        if u < 1.0:
            s = u**3 * (10 - 15 * u + 6 * u**2)
            ds = 30 * u**2 * (1 - u) ** 2 / self._T
            return self._q0 + (arrive - self._q0) * s, (arrive - self._q0) * ds
        decay = np.exp(-(t - self._t0 - self._T) / tau)
        return self._q1 - self._v0 * tau * decay, self._v0 * decay

    # ------------------------------------------------------------ adapter
    def connect(self) -> None:
        self._connected = True

    def read(self) -> JointState:
        t = self.clock.now()
        if not self._connected or (self.disconnect_at is not None and t >= self.disconnect_at):
            raise RobotConnectionError("fake robot: connection lost (simulated)")
        q, dq = self._kinematics(t)
        dq = dq + self._noise.normal(0.0, self.motion.dq_noise, dq.shape)
        # Gravity on a 1/8 s grid keeps the simulation cheap: a settling arm moves far less than the
        # torque noise shows in that time (exact binary steps, so a resumed session repeats itself).
        k = np.floor((t - self._t0) * 8.0)
        if k != self._grid:
            self._grid, self._gravity = k, self.effects.torques(self._links_at(self._t0 + k / 8.0))[0]
        tau = self._gravity + self._noise.normal(0.0, self.motion.tau_noise, q.shape)
        return JointState(q, dq, tau, t, {"robot_mode": self._mode})

    def close(self) -> None:
        self._connected = False

    def move_to(self, q: np.ndarray) -> None:
        """Move to q like a position-controlled arm; returns on arrival (the jiggle follows; with
        ``repeat_sigma`` none: the arm holds the pose it reached, the repeatability's draw off q)."""
        # a capture session's moves (the operator's arm) are keyed by the pose they go to and how often it
        # was gone to, not by a count of moves a killed process forgets: its resumed session draws what the
        # unbroken one drew; a validation's keep their count (its figures are measured with it)
        pose = () if self.operator is None else (zlib.crc32(np.asarray(q, dtype=float).tobytes()),)
        key = ("move", *pose)
        self._attempts[key] = self._attempts.get(key, 0) + 1
        q_now, _ = self._kinematics(self.clock.now())
        duration = max(
            1.875 * np.abs(np.asarray(q) - q_now).max() / self.motion.speed, 0.5
        )  # 1.875: min-jerk peak/mean speed
        self._start(q, "Move", (0x30FE, *pose, self._attempts[key]), duration)
        if self.repeat_sigma:  # an honest arm: position control holds the pose, off by its repeatability only
            self._v0 = np.zeros_like(self._v0)
        self.clock.sleep(self._T)

    def prompt_point(self, name: str, xyz: np.ndarray, index: int, spot: np.ndarray | None = None) -> None:
        if self.operator is None:
            return
        attempt = self._attempts.get((name, index), 0)
        self._attempts[(name, index)] = attempt + 1
        at = None if spot is None else self.place(np.asarray(spot, dtype=float)[None])[0]
        q = self.operator.configuration(name, index, attempt, self._suggested, at)
        self._suggested = None
        # the operator aims the true beam: the encoders report that pose through the effects, off by the
        # repeatability's delta
        self._start(q, "Guiding", (self.operator.key(name), index, attempt), aimed=True)

    def suggest_pose(self, q: np.ndarray) -> None:
        """The simulated operator starts the next hand-guiding from q (rad)."""
        self._suggested = np.asarray(q, dtype=float)

    def resume_at(self, q: np.ndarray, t: float) -> None:
        """A resumed session's arm: at rest at q (rad, the last capture's reported pose) with the clock at
        the session's time t (s) -- as the killed session's arm and clock were when it logged that capture,
        so the transits that follow (their durations from the start pose) are the unbroken session's."""
        self.clock.t = float(t)
        self._q0 = self._q1 = np.array(q, dtype=float)
        self._t0, self._T, self._v0, self._grid = self.clock.t, 0.0, np.zeros_like(self._q1), None
        self._delta = np.zeros_like(self._q1)

    def prompt_configuration(self, q: np.ndarray) -> None:
        self._attempts["guide"] = self._attempts.get("guide", 0) + 1
        self._start(q, "Guiding", (0x6D1E, self._attempts["guide"]))

    # ------------------------------------------------------------ truth, for the fake camera and rangefinder
    def _links_at(self, t: float) -> np.ndarray:
        """Where the links stand at clock time t, (1, n) rad: the encoders' pose plus the repeatability's
        delta, through the truth's effects."""
        return self.effects.links((self._kinematics(t)[0] + self._delta)[None], t)

    def true_q(self) -> np.ndarray:
        """The configuration the arm truly is in now (the reported one plus the repeatability's, through the
        truth's effects), rad."""
        return self._links_at(self.clock.now())[0]

    def true_beam(self) -> tuple[np.ndarray, np.ndarray]:
        """The true laser beam now, by the world's own kinematics (:mod:`collector.worlds.truearm`):
        aperture (3,) mm and unit direction (3,)."""
        return true_beam_of(self.truth, self.true_q())

    def true_spot(self, z: float) -> tuple[np.ndarray, float]:
        """Where the true beam meets the plane z now: spot (3,) mm and laser length, mm."""
        return plane_spot(*self.true_beam(), z)


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
        (:func:`collector.worlds.fakeeffects.arm_effects`).
    """
    if cfg.get("perturb_seed") is not None:
        return perturbed_model(nominal, cfg["perturb_seed"])
    truth = load_model(cfg["truth"], base=base)
    arm_effects(truth, truth_file(cfg["truth"], base))  # refused now, naming the file
    return truth


def truth_file(ref, base=None) -> str:
    """How errors name the truth ``ref``: its file (a built-in name resolved), else ``ref`` as given."""
    if str(ref).lower().endswith(".urdf"):
        return str(ref)
    try:
        return str(resolve_robot_path(ref, base))
    except FormatError:
        return str(ref)
