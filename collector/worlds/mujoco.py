"""The ``mujoco`` backend and camera: a world file (MJCF) simulated by MuJoCo, driven as hardware is.

lasercal reads from the world only what a robot and a camera give -- the arm's joint angles, speeds and
torques, and the camera's frames -- never its geometry for an estimate: the nominal is ``--robot`` as
always. What the world file must hold (docs/formats.md, "MuJoCo world"):

* ``<custom><text name="lasercal_joints" data="J1 J2 ..."/></custom>``: the arm's hinge joints in lasercal's
  order (q1 .. qn), each driven by a position actuator (MJCF ``<position>``: ctrl is its angle, rad);
* a site ``lasercal_laser``: the laser's aperture, its beam along the site's +z axis;
* a camera ``lasercal_camera`` (``--camera mujoco``): its ``resolution`` the photo's size (default
  1280 x 960);
* a body ``lasercal_sheet`` whose frame is the printed sheet's (origin at its centre cross, x up the printed
  page, z out of the paper): the simulated operator aims at the layout's points there.

The controller is a position servo with gravity compensation, as Franka's joint controller holds a pose:
each step the actuated joints get the gravity (and Coriolis) torque MuJoCo computes (``qfrc_bias``) on top of
their servo's; passive joints get none, so a spring after a joint bends under the links' weight and no
encoder sees it. Time is MuJoCo's: waiting steps the physics (:class:`MujocoClock`), so a capture waits for
standstill as on hardware. The laser's spot is where ``mj_ray`` from the site meets what the camera sees
(the geom groups MuJoCo's renderer draws, 0-2); a small emissive disc (group 5, which the ray skips) is
placed there before each photo, and MuJoCo's renderer draws it with everything else.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.collector.errors import SessionError
from lasercal.collector.hardware.base import Clock, JointState, RobotAdapter, import_extra
from lasercal.solver.errors import FormatError, LasercalError

JOINTS_TEXT = "lasercal_joints"
LASER_SITE = "lasercal_laser"
CAMERA = "lasercal_camera"
SHEET_BODY = "lasercal_sheet"
SPOT_GROUP = 5  # lasercal's group: the spot's disc, which the laser's own ray must not hit
SPOT_SIGMA_M = 1.0e-3  # the beam's footprint at normal incidence: a Gaussian of this sigma, m
SPOT_LAYERS, SPOT_ALPHA = 10, 0.17  # stacked discs, each this opaque: 85 % of their light at the centre
# disc k's radius: where the Gaussian falls to the middle of the k-th and (k+1)-th layers' cover
SPOT_RINGS_M = tuple(
    SPOT_SIGMA_M
    * np.sqrt(2 * np.log((1 - (1 - SPOT_ALPHA) ** SPOT_LAYERS) / (1 - (1 - SPOT_ALPHA) ** (k + 0.5))))
    for k in range(SPOT_LAYERS)
)
# the laser's light: red with the Bayer filters' crosstalk (vision.render's LASER_RESPONSE), its peak adding
# 0.43 of full scale to the photo at exposure 1, whatever the room's light (on paper at two thirds of full
# scale its core just clips; a session's exposure settles below that, sessions.exposure)
SPOT_RGBA = (1.0, 0.1, 0.04, SPOT_ALPHA)
SPOT_LIFT_M = 4e-5  # each disc above the one below it (and the surface): clear of it in the depth buffer
SPOT_EMISSION = 0.5
DEFAULT_PX = (1280, 960)
SPEED = 0.6  # rad/s, a commanded move's peak joint speed (as the fake arm's)
HOP_S = 0.5  # s, the shortest commanded move


def import_mujoco(what: str = "the mujoco backend"):
    """MuJoCo, rendering headless through EGL unless ``MUJOCO_GL`` says otherwise; a one-line error when
    it is not installed."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    return import_extra("mujoco", what, "mujoco", "mujoco")


@dataclass(frozen=True)
class Contract:
    """The contract's elements found in a compiled world (indices into MuJoCo's arrays).

    Attributes
    ----------
    joints : tuple of str, the arm's joints, lasercal's order
    qadr, dadr : (n,) int arrays, their addresses in qpos and qvel
    actuators : (n,) int array, each joint's position actuator
    kp : (n,) array, the servos' gains, Nm/rad
    laser : int, the laser site; laser_body : int, its body
    camera : int or None; sheet : int or None (bodies), base : int, the body holding the first joint's body
    spot_geom, spot_body : int, the spot's disc (added by lasercal), its mocap index
    """

    joints: tuple
    qadr: np.ndarray
    dadr: np.ndarray
    actuators: np.ndarray
    kp: np.ndarray
    laser: int
    laser_body: int
    camera: int | None
    sheet: int | None
    base: int
    spot_geom: int
    spot_mocap: int


def _contract(mj, m, path) -> Contract:
    """Find the contract's elements in the compiled model ``m`` of the world file ``path``."""
    tid = mj.mj_name2id(m, mj.mjtObj.mjOBJ_TEXT, JOINTS_TEXT)
    if tid < 0:
        raise FormatError(
            path,
            f'no <custom><text name="{JOINTS_TEXT}" data="joint1 joint2 ..."/>: name the arm\'s joints in '
            "order (docs/formats.md, MuJoCo world)",
            field=JOINTS_TEXT,
        )
    adr, size = m.text_adr[tid], m.text_size[tid]
    names = tuple(bytes(m.text_data[adr : adr + size - 1]).decode().split())
    if not names:
        raise FormatError(path, "names no joint", field=JOINTS_TEXT)
    ids, acts, kp = [], [], []
    for name in names:
        j = mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, name)
        if j < 0:
            raise FormatError(path, f"no joint {name!r} in the world", field=JOINTS_TEXT)
        if m.jnt_type[j] != mj.mjtJoint.mjJNT_HINGE:
            raise FormatError(
                path, f"joint {name!r} is not a hinge (expected revolute arm joints)", field=name
            )
        drive = [
            a
            for a in range(m.nu)
            if m.actuator_trntype[a] == mj.mjtTrn.mjTRN_JOINT and m.actuator_trnid[a, 0] == j
        ]
        servo = [
            a
            for a in drive
            if m.actuator_biastype[a] == mj.mjtBias.mjBIAS_AFFINE
            and m.actuator_gainprm[a, 0] > 0
            and abs(m.actuator_biasprm[a, 1] + m.actuator_gainprm[a, 0]) < 1e-9 * m.actuator_gainprm[a, 0]
        ]
        if len(servo) != 1:
            raise FormatError(
                path,
                f"joint {name!r} has {len(servo)} position actuators (expected one <position joint="
                f'"{name}" kp="..."/>: ctrl is its angle, rad)',
                field="actuator",
            )
        ids.append(j)
        acts.append(servo[0])
        kp.append(m.actuator_gainprm[servo[0], 0])
    site = mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, LASER_SITE)
    if site < 0:
        raise FormatError(
            path, f"no site {LASER_SITE!r} (the laser's aperture, its beam along +z)", field="site"
        )
    cam = mj.mj_name2id(m, mj.mjtObj.mjOBJ_CAMERA, CAMERA)
    sheet = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, SHEET_BODY)
    spot = mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, "lasercal_spot_0")
    ids = np.array(ids)
    return Contract(
        names,
        m.jnt_qposadr[ids].copy(),
        m.jnt_dofadr[ids].copy(),
        np.array(acts),
        np.array(kp),
        site,
        int(m.site_bodyid[site]),
        cam if cam >= 0 else None,
        sheet if sheet >= 0 else None,
        int(m.body_parentid[m.jnt_bodyid[ids[0]]]),
        spot,
        int(m.body_mocapid[m.geom_bodyid[spot]]),
    )


class MujocoWorld:
    """A world file loaded into MuJoCo: its model and state, the contract's elements, the arm's servo.

    Parameters
    ----------
    path : str or Path, the MJCF world file

    Raises
    ------
    FormatError
        The file is no MJCF MuJoCo compiles, or it lacks an element of the contract (naming it).
    """

    def __init__(self, path):
        mj = self.mj = import_mujoco()
        self.path = Path(path)
        try:
            spec = mj.MjSpec.from_file(str(self.path))
            # the laser's light: emissive translucent discs stacked into a Gaussian footprint (drawn in a
            # photo's second pass, in the dark: their light adds to the room's, as a laser's does)
            spot = spec.worldbody.add_body(
                name="lasercal_spot", mocap=True
            )  # at the origin: the extent stays
            spec.add_material(name="lasercal_spot", rgba=SPOT_RGBA, emission=SPOT_EMISSION, specular=0.0)
            for k, r in enumerate(SPOT_RINGS_M):
                spot.add_geom(
                    name=f"lasercal_spot_{k}",
                    type=mj.mjtGeom.mjGEOM_ELLIPSOID,
                    size=[r, r, 1e-5],
                    pos=[0, 0, SPOT_LIFT_M * (k + 1)],
                    material="lasercal_spot",
                    group=SPOT_GROUP,
                    contype=0,
                    conaffinity=0,
                    mass=0.0,
                )
            self.m = spec.compile()
        except (ValueError, mj.FatalError) as e:
            raise FormatError(self.path, f"MuJoCo cannot load it: {str(e).strip().splitlines()[0]}") from None
        self.d = mj.MjData(self.m)
        self.c = _contract(mj, self.m, self.path)
        # the beam meets what the camera sees: the geom groups MuJoCo's renderer draws by default (0-2), never
        # lasercal's spot (5); a collision-only geom (group 3 by MuJoCo's convention) neither shows nor
        # stops it
        drawn = np.asarray(mj.MjvOption().geomgroup, dtype=np.uint8).copy()
        drawn[SPOT_GROUP] = 0
        self.ray_groups = drawn
        if self.m.nkey:  # the world's first keyframe is where the arm starts
            self.d.qpos[:] = self.m.key_qpos[0]
        mj.mj_forward(self.m, self.d)
        self.target = self.d.qpos[self.c.qadr].copy()  # the servos hold where the arm is
        self.d.ctrl[self.c.actuators] = self.target
        self._path = None  # a commanded move: (t0, T, q0, q1)

    @property
    def n(self) -> int:
        return len(self.c.joints)

    # ------------------------------------------------------------ physics and control
    def step(self, seconds: float) -> None:
        """Advance the simulation by ``seconds``: the servos follow the commanded move (minimum jerk), the
        actuated joints' gravity is compensated, passive joints bend."""
        mj, m, d, c = self.mj, self.m, self.d, self.c
        for _ in range(max(int(round(seconds / m.opt.timestep)), 0)):
            if self._path is not None:
                t0, T, q0, q1 = self._path
                u = min((d.time - t0) / T, 1.0)
                d.ctrl[c.actuators] = q0 + (q1 - q0) * u**3 * (10 - 15 * u + 6 * u**2)
                if u >= 1.0:
                    self._path = None
            mj.mj_step1(m, d)
            d.qfrc_applied[c.dadr] = d.qfrc_bias[c.dadr]  # gravity compensation of the actuated joints
            mj.mj_step2(m, d)

    def command(self, q: np.ndarray, speed: float = SPEED) -> float:
        """Start a move of the servos' target to q (rad) at a bounded peak speed; returns its duration, s."""
        q = np.asarray(q, dtype=float)
        T = max(1.875 * float(np.abs(q - self.target).max()) / speed, HOP_S)  # 1.875: min-jerk peak/mean
        self._path = (self.d.time, T, self.target.copy(), q)
        self.target = q
        return T

    def state(self) -> JointState:
        """The arm's joint angles (rad), speeds (rad/s) and drive torques (Nm: servo plus compensation)."""
        c, d = self.c, self.d
        tau = d.actuator_force[c.actuators] + d.qfrc_applied[c.dadr]
        return JointState(d.qpos[c.qadr].copy(), d.qvel[c.dadr].copy(), tau, float(d.time))

    # ------------------------------------------------------------ the laser
    def beam(self) -> tuple[np.ndarray, np.ndarray]:
        """The laser's aperture (3,) and beam direction (3,) in the world, m."""
        mj, m, d = self.mj, self.m, self.d
        mj.mj_kinematics(m, d)
        return d.site_xpos[self.c.laser].copy(), d.site_xmat[self.c.laser].reshape(3, 3)[:, 2].copy()

    def ray(self) -> tuple[np.ndarray | None, int, np.ndarray]:
        """Where the beam meets the world (3,) m (None: nowhere), the geom hit and its normal there."""
        a, u = self.beam()
        gid, normal = np.array([-1], np.int32), np.zeros(3)
        x = self.mj.mj_ray(self.m, self.d, a, u, self.ray_groups, 1, self.c.laser_body, gid, normal)
        return (None if x < 0 else a + x * u), int(gid[0]), normal

    def show_spot(self, eye: np.ndarray) -> np.ndarray | None:
        """Place the spot's discs where the beam meets the world (the footprint stretched by 1/cos of the
        beam's tilt from the surface's normal, along its azimuth), or hide them; returns the hit, m.

        Each disc floats its lift above the surface (they are stacked) on the line of sight from the camera
        at ``eye`` (m) through the hit: seen from there each is centred on the hit, which a lift along the
        normal alone would shift by lift x tan(the view's tilt) (0.06 mm, the camera 30 deg off vertical).
        """
        hit, _, normal = self.ray()
        c = self.c
        self.m.mat_rgba[self.m.geom_matid[c.spot_geom], 3] = (
            0.0 if hit is None else SPOT_ALPHA
        )  # no hit: none
        if hit is None:
            return None
        _, u = self.beam()
        cos = max(abs(float(u @ normal)), 0.1)
        along = u - (u @ normal) * normal
        if np.linalg.norm(along) < 1e-9:
            along = np.cross(normal, [1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.cross(normal, [0, 1.0, 0])
        x = along / np.linalg.norm(along)
        R = np.column_stack([x, np.cross(normal, x), normal])
        quat = np.zeros(4)
        self.mj.mju_mat2Quat(quat, R.ravel())
        self.d.mocap_pos[c.spot_mocap] = hit
        self.d.mocap_quat[c.spot_mocap] = quat
        sight = (eye - hit) / np.linalg.norm(eye - hit)
        rise = R.T @ sight / max(float(sight @ normal), 0.05)  # body frame: 1 up the normal per unit along it
        for k, r in enumerate(SPOT_RINGS_M):
            self.m.geom_size[c.spot_geom + k] = [r / cos, r, 1e-5]
            self.m.geom_pos[c.spot_geom + k] = SPOT_LIFT_M * (k + 1) * rise
        self.mj.mj_kinematics(self.m, self.d)
        return hit

    def on_sheet(self, hit: np.ndarray) -> np.ndarray:
        """A world point (m) in the sheet body's frame, mm (the truth a photo's spot is scored against)."""
        if self.c.sheet is None:
            raise FormatError(self.path, f"no body {SHEET_BODY!r} (the printed sheet's frame)", field="body")
        R = self.d.xmat[self.c.sheet].reshape(3, 3)
        return R.T @ (hit - self.d.xpos[self.c.sheet]) * 1e3

    def ray_jacobian(self, h: float = 1e-6) -> np.ndarray:
        """d(hit)/dq (3, n), m/rad: finite differences of the ray at the arm's state (passive joints held)."""
        d, qadr = self.d, self.c.qadr
        hit0 = self.ray()[0]
        J = np.zeros((3, self.n))
        for j, a in enumerate(qadr):
            d.qpos[a] += h
            hit = self.ray()[0]
            d.qpos[a] -= h
            if hit is not None and hit0 is not None:
                J[:, j] = (hit - hit0) / h
        self.mj.mj_kinematics(self.m, d)
        return J


class MujocoClock(Clock):
    """MuJoCo's simulated time: waiting steps the physics."""

    def __init__(self, world: MujocoWorld):
        self.world = world

    def now(self) -> float:
        return float(self.world.d.time)

    def sleep(self, seconds: float) -> None:
        self.world.step(seconds)


class MujocoOperator:
    """The simulated operator in a MuJoCo world: starts from a pose of the nominal robot aimed at the point
    (the coach's suggestion, or one of :class:`~collector.worlds.fake.FakeOperator`'s diverse poses), then,
    watching the spot, nudges the arm until MuJoCo's beam lands on the point as printed on the sheet body,
    up to their aiming noise.

    Parameters
    ----------
    poses : FakeOperator of the nominal robot (no noise): the pose the operator starts from
    aim_noise : float, std of the aiming error per in-plane axis of the sheet, mm
    seed : int
    """

    def __init__(self, poses, aim_noise: float, seed: int):
        self.poses, self.aim_noise, self.seed = poses, aim_noise, seed

    def target(self, world: MujocoWorld, xy: np.ndarray, key: tuple) -> tuple[np.ndarray, np.ndarray]:
        """Where the operator aims: the sheet frame's xy (mm) on the sheet body plus the aiming noise, world
        m, and the sheet's normal."""
        rng = np.random.default_rng([self.seed, *key, 0xA1])
        s = np.r_[np.asarray(xy, dtype=float) + rng.normal(0.0, self.aim_noise, 2), 0.0] * 1e-3
        R = world.d.xmat[world.c.sheet].reshape(3, 3)
        return world.d.xpos[world.c.sheet] + R @ s, R[:, 2]


class MujocoRobot(RobotAdapter):
    """A MuJoCo world's arm, read and moved as hardware is.

    Parameters
    ----------
    world : MujocoWorld
    operator : MujocoOperator or None (None: nobody guides the arm)
    placement : SheetPose or None, the layout's placement of its sheet (base frame): the operator finds a
        base-frame point on the sheet through it
    """

    name = "mujoco"
    can_move = True
    guidance = "simulated robot (MuJoCo): the simulated operator hand-guides the arm to each point"

    def __init__(self, world: MujocoWorld, operator: MujocoOperator | None = None, placement=None):
        self.world, self.operator, self.placement = world, operator, placement
        self.clock = MujocoClock(world)
        self._attempts: dict = {}
        self._suggested = None
        self._connected = False

    def connect(self) -> None:
        self._connected = True

    def read(self) -> JointState:
        if not self._connected:
            from lasercal.collector.errors import RobotConnectionError

            raise RobotConnectionError("mujoco: not connected")
        return self.world.state()

    def close(self) -> None:
        self._connected = False

    def move_to(self, q: np.ndarray) -> None:
        """Command q (rad) to the servos; returns when the move's trajectory ends (the arm then settles)."""
        self.clock.sleep(self.world.command(q))

    def stop(self) -> None:
        """Hold where the arm is now."""
        self.world._path = None
        self.world.target = self.world.d.qpos[self.world.c.qadr].copy()
        self.world.d.ctrl[self.world.c.actuators] = self.world.target

    def suggest_pose(self, q: np.ndarray) -> None:
        self._suggested = np.asarray(q, dtype=float)

    def prompt_configuration(self, q: np.ndarray) -> None:
        self.move_to(q)

    def prompt_point(self, name: str, xyz: np.ndarray, index: int, spot: np.ndarray | None = None) -> None:
        """The simulated operator aims at ``name`` (base frame ``xyz`` at the layout's placement), or at
        ``spot`` (the layout's frame), on the world's sheet."""
        if self.operator is None:
            return
        attempt = self._attempts.get((name, index), 0)
        self._attempts[(name, index)] = attempt + 1
        op = self.operator
        xy = spot if spot is not None else self._sheet_xy(xyz)
        start = op.poses.configuration(name, index, attempt, self._suggested, None if spot is None else xyz)
        self._suggested = None
        target, normal = op.target(self.world, xy, (op.poses.key(name), index, attempt))
        self.aim(start, target, normal)

    def _sheet_xy(self, xyz) -> np.ndarray:
        if self.placement is None:
            raise LasercalError(
                "the mujoco backend's operator aims on a printed sheet (frame: sheet layouts)"
            )
        return self.placement.from_base(np.asarray(xyz, dtype=float)[None])[0]

    def aim(self, q: np.ndarray, target: np.ndarray, normal: np.ndarray, tol_m: float = 1e-6) -> None:
        """Guide the arm from q until the beam meets ``target`` (world, m) within ``tol_m`` in the plane
        normal to ``normal``: move, let it settle, look at the spot, nudge (Gauss-Newton on MuJoCo's ray)."""
        w = self.world
        for _ in range(12):
            self.move_to(q)
            self.clock.sleep(0.5)
            hit = w.ray()[0]
            if hit is None:
                return
            e = hit - target
            e -= (e @ normal) * normal
            if np.linalg.norm(e) < tol_m:
                return
            J = w.ray_jacobian()
            J -= np.outer(normal, normal @ J)
            q = q - np.linalg.lstsq(J, e, rcond=None)[0]

    def camera(self):
        """The world's camera (``--camera mujoco``), sharing this arm's simulation."""
        return MujocoCamera(self.world)


class MujocoCamera:
    """Photos of the world through its camera ``lasercal_camera``, rendered by MuJoCo (the spot's disc placed
    where the beam meets the world first).

    A photo is two MuJoCo renders added: the world as its lights show it without the spot, and the spot's
    emissive discs alone with every light off (the world black behind them, hiding them where it is in
    front): the laser's light adds to the room's, brighter on lit paper, clipping where both are bright.
    Its exposure is a gain on all the light it renders -- the world's lights, the headlight and the spot's
    emission, scaled together before each photo -- set through OpenCV's properties as a real camera's is
    (``CAP_PROP_AUTO_EXPOSURE`` manual, ``CAP_PROP_EXPOSURE`` the gain; :mod:`sessions.exposure` lowers it
    while the spot clips or cannot be found, as under a bright lamp that clips the paper).
    """

    name = "mujoco"
    exposure_control = True

    def __init__(self, world: MujocoWorld):
        if world.c.camera is None:
            raise FormatError(world.path, f"no camera {CAMERA!r} (--camera mujoco photographs through it)")
        self.world = world
        res = world.m.cam_resolution[world.c.camera]
        self.size = (int(res[0]), int(res[1])) if res[0] > 1 and res[1] > 1 else DEFAULT_PX
        g = world.m.vis.global_
        g.offwidth, g.offheight = max(g.offwidth, self.size[0]), max(g.offheight, self.size[1])
        self._renderer = None
        self.last_hit = None  # the world point the spot was drawn at, m (truth: for scoring, never estimates)
        m = world.m
        self.exposure = 1.0
        self._light = (m.light_diffuse.copy(), m.light_ambient.copy(), m.light_specular.copy())
        self._head = (np.array(m.vis.headlight.ambient), np.array(m.vis.headlight.diffuse))
        self._emission = m.mat_emission.copy()

    def get(self, prop) -> float:
        """OpenCV's exposure properties: manual (1), and the gain."""
        import cv2

        return {cv2.CAP_PROP_AUTO_EXPOSURE: 1.0, cv2.CAP_PROP_EXPOSURE: self.exposure}.get(prop, 0.0)

    def set(self, prop, value) -> bool:
        import cv2

        if prop == cv2.CAP_PROP_EXPOSURE and np.isfinite(value) and value > 0:
            self.exposure = float(value)
            return True
        return prop == cv2.CAP_PROP_AUTO_EXPOSURE

    def _expose(self, room: float, laser: float) -> None:
        """Scale the world's lights by ``room`` and the spot's emission by ``laser`` (the exposure, or 0)."""
        m = self.world.m
        m.light_diffuse[:], m.light_ambient[:], m.light_specular[:] = (x * room for x in self._light)
        m.vis.headlight.ambient, m.vis.headlight.diffuse = self._head[0] * room, self._head[1] * room
        spot = m.geom_matid[self.world.c.spot_geom]
        m.mat_emission[:] = self._emission * room
        m.mat_emission[spot] = self._emission[spot] * laser

    def _render(self, spot: bool) -> np.ndarray:
        opt = self.world.mj.MjvOption()
        opt.geomgroup[SPOT_GROUP] = int(spot)
        self._renderer.update_scene(self.world.d, CAMERA, scene_option=opt)
        return self._renderer.render()

    def photo(self) -> np.ndarray:
        """One frame, (h, w, 3) BGR uint8."""
        mj = self.world.mj
        if self._renderer is None:
            try:
                self._renderer = mj.Renderer(self.world.m, self.size[1], self.size[0])
            except Exception as e:  # no EGL (or OSMesa) context: one line saying what to install
                raise SessionError(
                    "--camera mujoco: MuJoCo cannot render here with "
                    f"MUJOCO_GL={os.environ.get('MUJOCO_GL')} "
                    f"({str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__}): install "
                    "Mesa's EGL (Debian: apt-get install libegl-mesa0 libgl1-mesa-dri)"
                ) from None
        self.last_hit = self.world.show_spot(self.world.d.cam_xpos[self.world.c.camera])
        self._expose(self.exposure, 0.0)
        room = self._render(spot=False)
        self._expose(0.0, self.exposure)
        laser = self._render(spot=True)
        img = np.minimum(room.astype(np.uint16) + laser, 255).astype(np.uint8)
        return np.ascontiguousarray(img[:, :, ::-1])

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def mujoco_camera(robot):
    """``--camera mujoco``: the camera of the MuJoCo world ``robot`` moves in."""
    if not isinstance(robot, MujocoRobot):
        raise SessionError(
            f"--camera mujoco photographs the MuJoCo world: it needs --backend mujoco (not {robot.name})"
        )
    return robot.camera()


def make_mujoco_robot(cfg: dict, nominal, layout, per_point: int, placement=None) -> MujocoRobot:
    """The mujoco backend of the settings ``cfg`` (``world``, ``aim_noise``, ``seed``): its world, and with
    ``per_point`` a simulated operator aiming at ``layout``'s calibration points (base frame)."""
    from lasercal.collector.worlds.fake import FakeOperator

    if not cfg.get("world"):
        raise LasercalError("--backend mujoco needs --world scene.xml (lasercal mujoco-scene writes one)")
    world = MujocoWorld(cfg["world"])
    if world.n != nominal.n:
        raise FormatError(
            world.path,
            f"names {world.n} arm joints but the robot {nominal.name} has {nominal.n}",
            field=JOINTS_TEXT,
        )
    operator = None
    if per_point:
        if world.c.sheet is None:
            raise FormatError(world.path, f"no body {SHEET_BODY!r}: the simulated operator aims on the sheet")
        pts = {k: layout.points[k] for k in layout.calibration}
        poses = FakeOperator(nominal, pts, per_point, 0.0, cfg["seed"], layout.aim_kwargs())
        operator = MujocoOperator(poses, cfg["aim_noise"], cfg["seed"])
    return MujocoRobot(world, operator, placement)
