"""A default MuJoCo world for a printed sheet (``lasercal mujoco-scene``): an outside arm description with a
seeded perturbation, a table, the sheet as ``lasercal sheet`` printed it, a laser on the flange, a camera.

The arm is not lasercal's: it is the Franka Research 3 that franky-sim ships (``franky_sim/assets/fr3.xml``,
MuJoCo Menagerie's model with franka_description's collision meshes; Apache-2.0, NOTICE copied beside the
scene), installed by ``pip install 'lasercal[sim]'``. Its kinematics are Franka's published ones (the Panda's
DH table): lasercal's nominal for it is ``--robot fr3``. The scene keeps its links, masses and joint limits,
uses its collision meshes (136 kB) as what the camera sees (its visual meshes are 57 MB), drops the gripper's
fingers (the laser holder is the hand), and drives the arm by position actuators; every other element of
the world-file contract (docs/formats.md, "MuJoCo world") is added here.

What is drawn from the seed (``scene.yaml`` records every value; lasercal never reads it for an estimate):

* each link's frame (``fr3_link1`` .. ``fr3_link7``, ``hand``) shifted by N(0, 1.5 mm) per axis and turned by
  N(0, 3 mrad) about each axis: axes tilted and moved, joint zeros off -- a robot as built, not as drawn;
* the laser's aperture N(0, 2 mm) per axis off the flange's axis at 101 mm, its beam tilted N(0, 5 mrad);
* the sheet N(0, 3 mm) off its placement in x and y, N(0, 1 deg) in yaw, tilted N(0, 2 mrad) per axis (a
  table not level with the robot's base), printed at a scale U(-0.2, +0.2) % per axis.

Physics the model does not write down (scene options, :class:`Passive`): a passive hinge in a link's body
after its actuated joint -- a spring (the gearbox's compliance, the link bends under gravity and the encoder
does not see it), with friction (it sticks anywhere within a band), or backlash (free within a range).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lasercal.solver.errors import LasercalError

ARM = "fr3"
LINKS = tuple(f"fr3_link{i}" for i in range(1, 8)) + ("hand",)
JOINTS = tuple(f"fr3_joint{i}" for i in range(1, 8))
APERTURE_M = 0.101  # the laser's aperture along the flange's z, m: lasercal's nominal M z = 926 - 101 mm
CAMERA_PX = (1280, 960)
CAMERA_OFFSET_MM = (350.0, 0.0, 600.0)  # beyond the sheet's centre (away from the robot) and above it
CAMERA_MM_PER_PX = 0.33  # at the sheet's centre
TEXTURE_MM_PER_PX = 0.1  # the sheet's texture: 254 dpi
HOME = (0.0, -0.7854, 0.0, -2.3562, 0.0, 1.5708, 0.7854)  # rad: Franka's ready pose
FRICTION_SOLREF = (0.004, 1.0)  # s, damping ratio: the stiffest MuJoCo allows at its 2 ms step
FRICTION_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)  # an impedance near 1: the friction hardly yields
PASSIVE_DAMPING = 2.0  # Nms/rad on a passive hinge: the link's oscillation settles within a second
# the light: the paper at about two thirds of full scale (a photo exposed for the spot, which is brighter)
LAMP = 0.3
ROOM = (0.2, 0.15)  # the headlight's ambient and diffuse


@dataclass(frozen=True)
class Passive:
    """A passive hinge after arm joint ``joint`` (1-based), in that link's body.

    Attributes
    ----------
    joint : int, the actuated joint it follows (its link's body holds it)
    compliance : float, rad/Nm, 1 / stiffness of its spring (0: no spring)
    friction : float, Nm, its dry friction (MuJoCo's frictionloss)
    backlash : float, rad, the width of its free range (0: no limit)
    axis : str, 'joint' (the actuated joint's own axis: a compliance) or 'x', 'y' (the link bends sideways)
    """

    joint: int
    compliance: float = 0.0
    friction: float = 0.0
    backlash: float = 0.0
    axis: str = "joint"

    @property
    def name(self) -> str:
        return f"passive_joint{self.joint}"


@dataclass(frozen=True)
class Perturbation:
    """The sizes of the seeded draws (one standard deviation, or the half-width of a uniform one)."""

    link_mm: float = 1.5
    link_rad: float = 3e-3
    laser_mm: float = 2.0
    laser_rad: float = 5e-3
    sheet_mm: float = 3.0
    sheet_deg: float = 1.0
    table_rad: float = 2e-3
    print_scale: float = 0.002


@dataclass(frozen=True)
class SceneOptions:
    """What a default scene holds beyond the layout.

    Attributes
    ----------
    seed : int or None, the perturbation's seed (None: the arm, laser and sheet exactly as described)
    perturbation : Perturbation
    passive : tuple of Passive
    light : float, the gain of the lamp above the table (1: an office; 3: a bright lamp)
    shadows : bool, the lamp casts the arm's shadow on the table
    curl : float, mm: the paper curls up toward the page's top and bottom edges (:func:`curled_sheet`);
        0: flat
    camera_at : (3,) tuple, mm: where the camera stands from the sheet's centre, in the sheet's frame turned
        to the base's z (x along the sheet's x, z up); it looks at the centre, at 0.33 mm per pixel there
    """

    seed: int | None = 0
    perturbation: Perturbation = field(default_factory=Perturbation)
    passive: tuple = ()
    light: float = 1.0
    shadows: bool = False
    curl: float = 0.0
    camera_at: tuple = CAMERA_OFFSET_MM


def arm_description() -> Path:
    """franky-sim's FR3 MJCF (MuJoCo Menagerie's, Apache-2.0), or a one-line error naming the extra."""
    from lasercal.collector.hardware.base import import_extra

    sim = import_extra("franky_sim", "the default MuJoCo scene's arm", "franky-sim", "sim")
    path = Path(sim.__file__).parent / "assets" / "fr3.xml"
    if not path.is_file():
        raise LasercalError(f"franky-sim is installed but ships no {path.name} (expected {path})")
    return path


def _rotation(rvec) -> np.ndarray:
    """Rodrigues: the rotation matrix of a rotation vector (rad)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(rvec, dtype=float)).as_matrix()


def _quat(R: np.ndarray) -> np.ndarray:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _matrix(quat) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    w, x, y, z = np.asarray(quat, dtype=float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def draw(options: SceneOptions) -> dict:
    """The seeded perturbation: link offsets (m) and turns (rad), the laser's, the sheet's pose and print.

    Every draw is keyed on its own (seed, element), so adding a scene option changes no other draw.
    """
    p, seed = options.perturbation, options.seed
    zero = seed is None

    def normal(key, sigma, n=3):
        return np.zeros(n) if zero else np.random.default_rng([seed, 0x5CE7E, key]).normal(0.0, sigma, n)

    links = {
        name: (normal(2 * i, p.link_mm * 1e-3), normal(2 * i + 1, p.link_rad)) for i, name in enumerate(LINKS)
    }
    scale = (
        np.ones(2)
        if zero
        else 1 + np.random.default_rng([seed, 0x5CE7E, 99]).uniform(-1, 1, 2) * p.print_scale
    )
    return {
        "links": links,
        "laser": (normal(100, p.laser_mm * 1e-3), normal(101, p.laser_rad)),
        "sheet_xy_mm": normal(102, p.sheet_mm, 2),
        "sheet_yaw_deg": float(normal(103, p.sheet_deg, 1)[0]),
        "table_tilt_rad": normal(104, p.table_rad, 2),
        "print_scale": scale,
    }


def rasterise_sheet(pdf: Path, png: Path, mm_per_px: float = TEXTURE_MM_PER_PX) -> tuple[float, float]:
    """The sheet's PDF as a PNG at ``mm_per_px`` (PDFium, through pypdfium2): the texture the scene prints.

    Returns
    -------
    (width, height) of the page, mm
    """
    from lasercal.collector.hardware.base import import_extra

    pdfium = import_extra("pypdfium2", "the MuJoCo scene's sheet texture", "pypdfium2", "mujoco")
    try:
        doc = pdfium.PdfDocument(str(pdf))
        page = doc[0]
        w_pt, h_pt = page.get_size()
        scale = 25.4 / 72 / mm_per_px  # PDF points (1/72 in) to pixels
        page.render(scale=scale).to_pil().convert("RGB").save(png)
    except pdfium.PdfiumError as e:
        raise LasercalError(f"{pdf}: cannot read the sheet's PDF ({e})") from None
    return w_pt * 25.4 / 72, h_pt * 25.4 / 72


def write_scene(out: Path, layout, pdf: Path, options: SceneOptions) -> dict:
    """Write ``scene.xml`` (the world), ``sheet.png`` (its texture), ``meshes/`` and ``NOTICE`` into ``out``.

    Parameters
    ----------
    out : Path, an existing empty folder
    layout : Layout, a sheet's (``frame: sheet``, with a placement): where the sheet is laid
    pdf : Path, the sheet's PDF as ``lasercal sheet`` wrote it (printed at its size)
    options : SceneOptions

    Returns
    -------
    dict, what was drawn and built (``scene.yaml``'s content: units m, rad, mm where named)
    """
    from lasercal.collector.worlds.mujoco import import_mujoco
    from lasercal.solver.formats.robots import load_yaml

    mujoco = import_mujoco("lasercal mujoco-scene")

    source = arm_description()
    width, height = rasterise_sheet(pdf, out / "sheet.png")
    paper = (load_yaml(layout.path) or {}).get("paper") or {}
    if paper and (
        abs(paper.get("width_mm", width) - width) > 0.5 or abs(paper.get("height_mm", height) - height) > 0.5
    ):
        raise LasercalError(
            f"{pdf}: its page is {width:.1f} x {height:.1f} mm but {layout.path} was printed on "
            f"{paper.get('width_mm')} x {paper.get('height_mm')} mm (expected the PDF written with it)"
        )
    spec = mujoco.MjSpec.from_file(str(source))
    drawn = draw(options)
    _arm(spec, drawn, options.passive)
    (out / "meshes").mkdir()
    for mesh in spec.meshes:
        shutil.copyfile(source.parent / "meshes" / mesh.file, out / "meshes" / mesh.file)
    shutil.copyfile(source.parent / "NOTICE", out / "NOTICE")
    spec.meshdir = "meshes"
    sheet = _world(spec, layout, drawn, width, height, options)
    spec.modelfiledir = str(out)
    m = spec.compile()  # refused here (a bad option) rather than when the world is loaded
    home = np.zeros(m.nq)  # the arm starts at Franka's home pose, its passive joints at rest
    home[[m.joint(j).qposadr[0] for j in JOINTS]] = HOME
    spec.add_key(name="home", qpos=home, ctrl=HOME)
    spec.compile()
    (out / "scene.xml").write_text(spec.to_xml())
    return {
        "arm": f"{ARM} from {source} (franky-sim: MuJoCo Menagerie's FR3, Apache-2.0, NOTICE)",
        "seed": options.seed,
        "links_offset_mm": {k: [round(float(v) * 1e3, 4) for v in d] for k, (d, _) in drawn["links"].items()},
        "links_turn_rad": {k: [round(float(v), 6) for v in r] for k, (_, r) in drawn["links"].items()},
        "laser_offset_mm": [round(float(v) * 1e3, 4) for v in drawn["laser"][0]],
        "laser_turn_rad": [round(float(v), 6) for v in drawn["laser"][1]],
        "sheet": sheet,
        "passive": [p.__dict__ | {"name": p.name} for p in options.passive],
        "light": options.light,
        "shadows": options.shadows,
        "curl_mm": options.curl,
        "camera_at_mm": [float(v) for v in options.camera_at],
    }


def _arm(spec, drawn: dict, passive: tuple) -> None:
    """The arm as the scene holds it: collision meshes shown, no fingers, perturbed links, passive hinges,
    position actuators on the seven joints, and the laser on the hand."""
    import mujoco  # imported by write_scene (MUJOCO_GL set first)

    for name in ("left_finger", "right_finger"):
        spec.delete(spec.body(name))
    for t in list(spec.tendons):
        spec.delete(t)
    for e in list(spec.equalities):
        spec.delete(e)
    for a in list(spec.actuators):
        if a.name not in JOINTS:
            spec.delete(a)
    for k in list(spec.keys):
        spec.delete(k)
    for g in list(spec.geoms):
        if g.type == mujoco.mjtGeom.mjGEOM_MESH and g.classname.name == "visual":
            spec.delete(g)
        else:  # the collision hull is what the camera sees, and nothing collides (the arm never touches)
            g.group, g.contype, g.conaffinity = 0, 0, 0
            g.rgba = [0.92, 0.92, 0.92, 1]
            if g.meshname == "link0_coll":
                g.rgba = [0.3, 0.3, 0.3, 1]
    used = {g.meshname for g in spec.geoms if g.meshname}
    for m in list(spec.meshes):
        if m.name not in used:
            spec.delete(m)
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    for j in spec.joints:
        if j.name in JOINTS:  # the controller holds a commanded pose; joint friction would leave it short
            j.frictionloss = 0.0
    for name, (d, r) in drawn["links"].items():
        body = spec.body(name)
        body.pos = np.asarray(body.pos) + d
        body.quat = _quat(_matrix(body.quat) @ _rotation(r))
    for p in passive:
        body = spec.body(f"fr3_link{p.joint}")
        axis = {"joint": [0, 0, 1], "x": [1, 0, 0], "y": [0, 1, 0]}[p.axis]
        j = body.add_joint(name=p.name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis)
        j.stiffness = [1.0 / p.compliance if p.compliance else 0.0, 0.0, 0.0]
        j.damping = [PASSIVE_DAMPING, 0.0, 0.0]
        j.armature = 0.01
        j.frictionloss = p.friction
        if p.friction:  # MuJoCo's default friction is soft: under a steady load it creeps to the spring's
            # rest (a 3 Nm band on a 1e-4 rad/Nm hinge left no trace: the settled poses of a spring alone).
            # Near-rigid, it sticks where the motion stopped, within +-friction / stiffness, and creeps
            # ~2e-6 rad in 5 s (a 17 Nm pendulum; default: at rest to 1e-9 rad in 1 s)
            j.solref_friction = FRICTION_SOLREF
            j.solimp_friction = FRICTION_SOLIMP
        if p.backlash:  # MuJoCo's soft limit: its ends give ~1e-4 rad/Nm (stiffer ends chattered: the arm
            # never came to rest); a backlash here is free play, then a spring
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.range = [-p.backlash / 2, p.backlash / 2]
    d, r = drawn["laser"]
    hand = spec.body("hand")
    # the beam along the site's z: the flange's z (the hand turns about it), tilted by the mount
    hand.add_site(
        name="lasercal_laser", pos=np.r_[0, 0, APERTURE_M] + d, quat=_quat(_rotation(r)), size=[0.003, 0, 0]
    )
    spec.add_text(name="lasercal_joints", data=" ".join(JOINTS))


def _world(spec, layout, drawn: dict, width: float, height: float, options: SceneOptions) -> dict:
    """The table, the sheet (its texture at its printed size, laid where the draw put it), the lamp and the
    camera; returns the sheet's true pose (mm, deg, rad) and print scale."""
    import mujoco  # imported by write_scene (MUJOCO_GL set first)

    if layout.frame != "sheet" or layout.sheet is None:
        raise LasercalError(
            f"{layout.path}: the scene lays a printed sheet where its placement says (expected a layout from "
            "lasercal sheet --place X Y YAW)"
        )
    z = layout.plane_z * 1e-3
    place = layout.sheet
    xy = (np.array([place.x_mm, place.y_mm]) + drawn["sheet_xy_mm"]) * 1e-3
    yaw = np.radians(place.yaw_deg + drawn["sheet_yaw_deg"])
    tilt = drawn["table_tilt_rad"]
    R = _rotation([0, 0, yaw]) @ _rotation([tilt[1], -tilt[0], 0])  # z rises tilt[0] along x, tilt[1] along y
    world = spec.worldbody
    tex = spec.add_texture(name="lasercal_sheet", type=mujoco.mjtTexture.mjTEXTURE_2D, file="sheet.png")
    tex.colorspace = mujoco.mjtColorSpace.mjCOLORSPACE_SRGB
    mat = spec.add_material(
        name="lasercal_sheet", texrepeat=[1, 1], texuniform=False, specular=0.0, shininess=0.0
    )
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "lasercal_sheet"
    spec.add_material(name="table", rgba=[0.55, 0.45, 0.35, 1], specular=0.0)
    # the table slopes as the sheet lies on it: its top 0.2 mm under the paper everywhere
    table = world.add_body(name="table", pos=[xy[0], xy[1], z], quat=_quat(R))
    table.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.45, 0.6, 0.02], pos=[0, 0, -0.0202], material="table"
    )
    world.add_geom(  # the robot's mounting plate, from the table to its base
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.11, -z / 2, 0],
        pos=[0, 0, z / 2],
        rgba=[0.2, 0.2, 0.2, 1],
    )
    scale = drawn["print_scale"]
    sheet = world.add_body(name="lasercal_sheet", pos=[xy[0], xy[1], z], quat=_quat(R))
    # the sheet frame: x up the printed page, y to its left; the texture's u runs right, v up the page
    half = np.array([width * scale[1], height * scale[0]]) / 2e3  # m, along the page's u (right) and v (up)
    if options.curl:
        curled_sheet(spec, sheet, half, options.curl * 1e-3)
    else:
        sheet.add_geom(
            name="lasercal_sheet",
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[*half, 0.01],
            quat=_quat(_rotation([0, 0, -np.pi / 2])),
            material="lasercal_sheet",
        )
    centre = np.r_[xy, z]
    off = np.asarray(options.camera_at, dtype=float) * 1e-3
    eye = centre + _rotation([0, 0, yaw]) @ np.r_[off[:2], 0] + np.r_[0, 0, off[2]]
    fwd = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    w, h = CAMERA_PX
    focal = np.linalg.norm(centre - eye) * 1e3 / CAMERA_MM_PER_PX
    world.add_camera(
        name="lasercal_camera",
        pos=eye,
        quat=_quat(np.column_stack([right, up, -fwd])),
        fovy=float(np.degrees(2 * np.arctan(h / 2 / focal))),
        resolution=[w, h],
    )
    world.add_light(  # a lamp above the table; the room's light is the headlight's
        name="lamp",
        pos=np.r_[xy, 1.5],
        dir=[0, 0, -1],
        diffuse=[LAMP * options.light] * 3,
        specular=[0, 0, 0],
        castshadow=options.shadows,
    )
    spec.visual.headlight.ambient = [ROOM[0]] * 3
    spec.visual.headlight.diffuse = [ROOM[1]] * 3
    spec.visual.global_.offwidth, spec.visual.global_.offheight = w, h
    return {
        "x_mm": round(float(xy[0] * 1e3), 4),
        "y_mm": round(float(xy[1] * 1e3), 4),
        "z_mm": float(layout.plane_z),
        "yaw_deg": round(float(np.degrees(yaw)), 5),
        "tilt_rad": [round(float(t), 6) for t in tilt],
        "print_scale": [round(float(s), 6) for s in scale],
    }


CURL_GRID = 41  # vertices along each of the page's axes: the curl's parabola within 1 um between them


def curled_sheet(spec, body, half: np.ndarray, curl: float) -> None:
    """The sheet as a curled surface: a mesh in the sheet body's frame whose height rises as a parabola
    toward the page's top and bottom edges (along its printed x, up the page), ``curl`` m at those edges,

        z(x) = curl (x / half_v)^2,                                          (eq. M1)

    the page's texture laid by the point's x, y (a printed point (x, y) lies at height z(x) above it: the
    paper stretched over the curl rather than rolled, (2/3) curl^2 / half_v apart at the edges, 0.025 mm
    for a 2 mm curl over an A4 page's 210 mm).

    Parameters
    ----------
    spec : mujoco.MjSpec; body : the sheet's body (its frame the sheet frame)
    half : (2,) m, the page's half width (u, right) and half height (v, up)
    curl : float, m
    """
    import mujoco

    u, v = np.meshgrid(np.linspace(-1, 1, CURL_GRID), np.linspace(-1, 1, CURL_GRID))
    # the sheet frame: x up the page (v), y to its left (-u)
    xyz = np.stack([v * half[1], -u * half[0], curl * v**2], axis=-1).reshape(-1, 3)
    tex = np.stack([(1 + u) / 2, (1 - v) / 2], axis=-1).reshape(-1, 2)  # a mesh texture's v runs down
    k = np.arange(CURL_GRID * CURL_GRID).reshape(CURL_GRID, CURL_GRID)
    a, b, c, d = k[:-1, :-1], k[:-1, 1:], k[1:, 1:], k[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    faces = np.concatenate([faces, faces[:, ::-1]])  # both sides face out: the camera and the beam see it
    mesh = spec.add_mesh(name="lasercal_sheet_surface")
    mesh.uservert = xyz.ravel().tolist()
    mesh.usertexcoord = tex.ravel().tolist()
    mesh.userface = faces.ravel().tolist()
    mesh.userfacetexcoord = faces.ravel().tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    body.add_geom(
        name="lasercal_sheet",
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname="lasercal_sheet_surface",
        material="lasercal_sheet",
        contype=0,
        conaffinity=0,
    )
