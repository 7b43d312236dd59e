"""Writes the URDF test fixtures of this folder from published DH tables (run: python make_urdf.py).

* ur5.urdf: UR5, standard DH (Universal Robots' published table), T_i = Rz(q) Tz(d) Tx(a) Rx(alpha),
  with the UR5 link masses and a flange link; one visual mesh that does not exist (a missing mesh).
* arm7.urdf: Franka Panda, modified DH (Craig) T_i = Rx(alpha) Tx(a) Rz(q) Tz(d), Panda limits, a
  fixed flange and a fixed hand (fixed joints to fold).
* rail_ur5.urdf: UR5 on a linear rail (prismatic joint 1, limits in m): 7 joints, one prismatic.
"""

import math
from pathlib import Path

HERE = Path(__file__).parent
UR5 = {  # d, a, alpha (m, rad); masses kg
    "d": [0.089159, 0, 0, 0.10915, 0.09465, 0.0823],
    "a": [0, -0.425, -0.39225, 0, 0, 0],
    "alpha": [math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0],
    "mass": [3.7, 8.393, 2.275, 1.219, 1.219, 0.1879],
}
PANDA = {
    "a": [0, 0, 0, 0.0825, -0.0825, 0, 0.088, 0],
    "d": [0.333, 0, 0.316, 0, 0.384, 0, 0, 0.107],
    "alpha": [0, -math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, math.pi / 2, math.pi / 2, 0],
    "lo": [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973],
    "hi": [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973],
}


def link(name, mass=None, com=(0, 0, 0), mesh=None):
    s = f'  <link name="{name}">\n'
    if mass:
        s += (
            f'    <inertial><origin xyz="{com[0]} {com[1]} {com[2]}" rpy="0 0 0"/><mass value="{mass}"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>\n'
        )
    if mesh:
        s += f'    <visual><geometry><mesh filename="{mesh}"/></geometry></visual>\n'
    return s + "  </link>\n"


def joint(name, kind, parent, child, xyz, rpy, lo=None, hi=None, axis="0 0 1"):
    s = f'  <joint name="{name}" type="{kind}">\n    <parent link="{parent}"/><child link="{child}"/>\n'
    s += f'    <origin xyz="{xyz[0]!r} {xyz[1]!r} {xyz[2]!r}" rpy="{rpy[0]!r} {rpy[1]!r} {rpy[2]!r}"/>\n'
    if kind != "fixed":
        s += f'    <axis xyz="{axis}"/>\n'
    if lo is not None:
        s += f'    <limit lower="{lo}" upper="{hi}" effort="150" velocity="3.15"/>\n'
    return s + "  </joint>\n"


def ur5_body(prefix_parent="base_link", first=1):
    s, parent, prev = "", prefix_parent, None
    for i in range(6):
        xyz, rpy = (0, 0, 0), (0, 0, 0)
        if prev is not None:
            d, a, al = prev
            xyz, rpy = (a, 0, d), (al, 0, 0)
        child = f"link{first + i}"
        s += link(child, UR5["mass"][i], (0, 0, 0.01), "meshes/missing_forearm.stl" if i == 2 else None)
        kind = "continuous" if i == 5 else "revolute"
        lim = (None, None) if kind == "continuous" else (-2 * math.pi, 2 * math.pi)
        s += joint(f"joint{first + i}", kind, parent, child, xyz, rpy, *lim)
        parent, prev = child, (UR5["d"][i], UR5["a"][i], UR5["alpha"][i])
    d, a, al = prev
    s += link("flange") + joint("flange_joint", "fixed", parent, "flange", (a, 0, d), (al, 0, 0))
    return s


def ur5():
    return '<?xml version="1.0"?>\n<robot name="ur5">\n' + link("base_link", 4.0) + ur5_body() + "</robot>\n"


def rail_ur5():
    s = '<?xml version="1.0"?>\n<robot name="rail_ur5">\n' + link("world") + link("carriage", 5.0)
    s += joint("rail", "prismatic", "world", "carriage", (0, 0, 0.1), (0, 0, 0), -0.5, 1.5, axis="1 0 0")
    s += link("base_link", 4.0) + joint("mount", "fixed", "carriage", "base_link", (0, 0, 0.05), (0, 0, 0.3))
    return s + ur5_body("base_link", 2) + "</robot>\n"


def arm7():
    s = '<?xml version="1.0"?>\n<robot name="arm7">\n' + link("link0", 2.0)
    parent = "link0"
    for i in range(7):
        a, d, al = PANDA["a"][i], PANDA["d"][i], PANDA["alpha"][i]
        xyz = (a, -math.sin(al) * d, math.cos(al) * d)
        s += link(f"link{i + 1}", 2.0, (0, 0.01, 0)) + joint(
            f"joint{i + 1}",
            "revolute",
            parent,
            f"link{i + 1}",
            xyz,
            (al, 0, 0),
            PANDA["lo"][i],
            PANDA["hi"][i],
        )
        parent = f"link{i + 1}"
    s += link("flange") + joint("flange_joint", "fixed", parent, "flange", (0, 0, PANDA["d"][7]), (0, 0, 0))
    s += link("hand", 0.7) + joint("hand_joint", "fixed", "flange", "hand", (0, 0, 0), (0, 0, -math.pi / 4))
    return s + "</robot>\n"


if __name__ == "__main__":
    for name, f in (("ur5", ur5), ("arm7", arm7), ("rail_ur5", rail_ur5)):
        (HERE / f"{name}.urdf").write_text(f())
