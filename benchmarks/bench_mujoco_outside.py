"""Issue 46: an outside check's own hidden MuJoCo world, written from docs/formats.md's contract alone, and
lasercal driven through it by its public commands.

    python benchmarks/bench_mujoco_outside.py [DIR] [--seed S] [--spring C]

This script imports nothing of lasercal: the world is franka_description's Panda (``fer``, the URDF xacrodoc
makes from ../shared/data/franka_description, meshes dropped) compiled by MuJoCo, each link's frame moved
by a hidden seeded perturbation (1.5 mm, 3 mrad), a laser 2.2 mm off the flange's axis and 7.4 mrad tilted,
the sheet's PDF as a texture at its printed size with a printer's scale and a table slope, a camera of its
own pose and resolution, position servos; with ``--spring`` a passive spring after joint 2. Then
``capture --backend mujoco --camera mujoco --guide move --auto --per-point 9``, ``solve --extend auto``,
``validate -n 30 --point P6`` of the nominal and the calibrated model; the errors are scored by MuJoCo's
own ray on the hidden truth at the joint angles validate photographed (the arm settled there).
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
import mujoco  # noqa: E402
import yaml  # noqa: E402

FRANKA = Path(__file__).resolve().parents[2] / "shared" / "data" / "franka_description"
JOINTS = [f"fer_joint{i}" for i in range(1, 8)]


def rot(rv):
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q, rv / (np.linalg.norm(rv) or 1.0), np.linalg.norm(rv))
    return q


def qmul(a, b):
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def build(out: Path, sheet_dir: Path, seed: int, spring: float) -> dict:
    """The hidden world: out/hidden.xml and its texture; returns the truth (sheet pose, print scale)."""
    import pypdfium2
    import xacrodoc
    from xacrodoc import XacroDoc

    xacrodoc.packages.update_package_cache({"franka_description": str(FRANKA)})
    urdf = XacroDoc.from_file(
        str(FRANKA / "robots/fer/fer.urdf.xacro"), subargs={"hand": "false"}
    ).to_urdf_string()
    urdf = re.sub(r"<(visual|collision)\b.*?</\1>", "", urdf, flags=re.S)
    spec = mujoco.MjSpec.from_string(urdf)
    spec.compiler.balanceinertia = True  # franka_description's link 4 inertia breaks the triangle inequality
    spec.compiler.fusestatic = False  # (a URDF fuses bodies without joints: the sheet must stay a body)
    spec.compiler.discardvisual = False  # (and drops what only the eye sees: the sheet's texture)
    rng = np.random.default_rng([seed, 46])
    for j in range(1, 8):  # the hidden robot as built
        b = spec.body(f"fer_link{j}")
        b.pos = np.asarray(b.pos) + rng.normal(0, 1.5e-3, 3)
        b.quat = qmul(b.quat, rot(rng.normal(0, 3e-3, 3)))
    for j in spec.joints:
        j.armature, j.damping, j.frictionloss = 0.1, [1.0, 0, 0], 0.0
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # stiff servos on light links: implicit
    for name in JOINTS:
        spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT).set_to_position(
            kp=3000, kv=100
        )
    if spring:
        h = spec.body("fer_link2").add_joint(
            name="hidden_spring", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1]
        )
        h.stiffness, h.damping, h.armature = [1 / spring, 0, 0], [3.0, 0, 0], 0.01
    link7 = spec.body("fer_link7")  # the flange (fer_joint8, fixed) lies 107 mm along link 7's z
    off = rng.normal(0, 1, 2)
    off = np.r_[off / np.linalg.norm(off) * 2.2e-3, 0]
    tilt = rng.normal(0, 1, 2)
    tilt = np.r_[tilt / np.linalg.norm(tilt) * 7.4e-3, 0]
    link7.add_site(name="lasercal_laser", pos=np.r_[0, 0, 0.107 + 0.101] + off, quat=rot(tilt))
    # the sheet: where its placement says, off by a few mm and a degree, on a table sloping 3 mrad
    lay = yaml.safe_load((sheet_dir / "layout.yaml").read_text())
    paper = lay["paper"]
    W, H = paper["width_mm"], paper["height_mm"]
    doc = pypdfium2.PdfDocument(str(sheet_dir / "sheet.pdf"))
    doc[0].render(scale=254 / 72).to_pil().convert("RGB").save(out / "paper.png")
    z = lay["plane"]["z"] * 1e-3
    yaw = np.radians(lay["sheet"]["yaw_deg"] + 1.2)
    centre = np.r_[(lay["sheet"]["x_mm"] + 4.0) * 1e-3, (lay["sheet"]["y_mm"] - 3.0) * 1e-3, z]
    q_sheet = qmul(rot(np.r_[0, 0, yaw]), rot(np.r_[0.0, -3e-3, 0]))
    scale = np.array([1.001, 0.9985])  # the printer, along the sheet's x (page height) and y (page width)
    tex = spec.add_texture(name="paper", type=mujoco.mjtTexture.mjTEXTURE_2D, file=str(out / "paper.png"))
    tex.colorspace = mujoco.mjtColorSpace.mjCOLORSPACE_SRGB
    mat = spec.add_material(name="paper", texrepeat=[1, 1], texuniform=False)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "paper"
    world = spec.worldbody
    sheet = world.add_body(name="lasercal_sheet", pos=centre, quat=q_sheet)
    sheet.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[W * scale[1] / 2e3, H * scale[0] / 2e3, 0.01],
        quat=rot(np.r_[0, 0, -np.pi / 2]),  # the page's right is the sheet frame's -y, its top +x
        material="paper",
    )
    sheet.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.4, 0.5, 0.01], pos=[0, 0, -0.0102], rgba=[0.4, 0.3, 0.2, 1]
    )
    eye = centre + np.r_[0.30 * np.cos(yaw) - 0.02, 0.30 * np.sin(yaw) + 0.03, 0.65]
    fwd = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(fwd, [0, 0, 1])
    right /= np.linalg.norm(right)
    world.add_camera(
        name="lasercal_camera",
        pos=eye,
        xyaxes=np.r_[right, np.cross(right, fwd)],
        fovy=24.0,
        resolution=[1600, 1200],
    )
    world.add_light(
        pos=np.r_[centre[:2], 1.2],
        dir=[0, 0, -1],
        diffuse=[0.4] * 3,
        castshadow=False,
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
    )
    spec.visual.headlight.ambient, spec.visual.headlight.diffuse = [0.25] * 3, [0.1] * 3
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 1600, 1200
    spec.add_text(name="lasercal_joints", data=" ".join(JOINTS))
    m = spec.compile()
    home = np.zeros(m.nq)
    home[[m.joint(j).qposadr[0] for j in JOINTS]] = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]
    spec.add_key(qpos=home, ctrl=home[[m.joint(j).qposadr[0] for j in JOINTS]])
    spec.compile()
    (out / "hidden.xml").write_text(spec.to_xml())
    return {"scale": scale}


def true_spot(world_file: Path, q: np.ndarray, scale) -> np.ndarray:
    """Where the hidden world's beam meets its sheet at joint angles q (the arm settled there under its own
    servo and gravity compensation), printed sheet mm."""
    m = mujoco.MjModel.from_xml_path(str(world_file))
    d = mujoco.MjData(m)
    adr = [m.joint(j).qposadr[0] for j in JOINTS]
    dof = [m.joint(j).dofadr[0] for j in JOINTS]
    d.qpos[adr] = q
    d.ctrl[:] = q
    for _ in range(1500):
        mujoco.mj_step1(m, d)
        d.qfrc_applied[dof] = d.qfrc_bias[dof]
        mujoco.mj_step2(m, d)
    d.qpos[adr] = q  # the encoders' reading: joint angles exactly, the spring as it settled
    mujoco.mj_kinematics(m, d)
    s = m.site("lasercal_laser").id
    a, u = d.site_xpos[s], d.site_xmat[s].reshape(3, 3)[:, 2]
    x = mujoco.mj_ray(m, d, a, u, None, 1, m.site_bodyid[s], np.zeros(1, np.int32))
    b = m.body("lasercal_sheet").id
    p = d.xmat[b].reshape(3, 3).T @ (a + x * u - d.xpos[b]) * 1e3
    return p[:2] / scale


def lasercal(*args) -> str:
    t = time.time()
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", *map(str, args)], capture_output=True, text=True
    )
    if p.returncode not in (0, 1):
        raise SystemExit(f"lasercal {args[0]} failed:\n{p.stderr}")
    print(f"  ({time.time() - t:.0f} s) lasercal {args[0]}", flush=True)
    return p.stdout


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", nargs="?", default="bench_mujoco_outside")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--spring", type=float, default=0.0, help="rad/Nm, a hidden spring after joint 2")
    a = ap.parse_args()
    d = Path(a.dir).resolve()
    d.mkdir(exist_ok=True)
    if not (d / "sheet").exists():
        lasercal("sheet", "-o", d / "sheet", "--robot", "panda", "--place", 450, 0, 0)
    truth = build(d, d / "sheet", a.seed, a.spring)
    layout, world = d / "sheet" / "layout.yaml", d / "hidden.xml"
    common = ["--backend", "mujoco", "--world", world, "--robot", "panda"]
    lasercal(
        "capture", *common, "--layout", layout, "--camera", "mujoco", "--guide", "move", "--auto",
        "--per-point", 9, "-o", d / "session",
    )  # fmt: skip
    solve = lasercal("solve", d / "session", "-o", d / "model.yaml", "--extend", "auto")
    print("  solve:", next(x for x in solve.splitlines() if x.startswith("finding")))
    p6 = np.array(yaml.safe_load(layout.read_text())["points"]["P6"][:2])
    for name, model, extra in (
        ("nominal", "panda", ["--sheet-from", d / "model.yaml"]),
        ("calibrated", d / "model.yaml", []),
    ):
        out = lasercal(
            "validate",
            model,
            "--layout",
            layout,
            "--point",
            "P6",
            "-n",
            30,
            *common,
            *extra,
            "-o",
            d / f"val_{name}",
        )
        said = float(out.split("error mean ")[1].split(" mm")[0]) if "error mean " in out else float("nan")
        rows = list(
            csv.DictReader(
                line for line in open(d / f"val_{name}" / "validation.csv") if not line.startswith("#")
            )
        )
        err = [
            np.linalg.norm(
                true_spot(world, np.array([float(r[f"q{j}"]) for j in range(1, 8)]), truth["scale"]) - p6
            )
            for r in rows
        ]
        print(
            f"{name}: validate says error mean {said:.3f} mm; MuJoCo's ray on the hidden truth "
            f"{np.mean(err):.3f} mm"
        )


if __name__ == "__main__":
    main()
