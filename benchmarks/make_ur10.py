"""Write the built-in robot ``ur10`` (data/robots/ur10.yaml) from Universal Robots' published DH table.

    python benchmarks/make_ur10.py data/robots/ur10.yaml

How: :func:`lasercal.solver.formats.ipa.ur10_model` (eq. U1 there): standard DH frames -> screws, the flange
as ``ee.M``, UR's link masses and centres of mass carried to the base frame; the prior below.
"""

from __future__ import annotations

import sys

import yaml

from lasercal.solver.formats.ipa import ur10_model

HEADER = """# Universal Robots UR10 (CB3): made by benchmarks/make_ur10.py from UR's published standard DH
# table (d1 127.3, a2 -612, a3 -572.3, d4 163.941, d5 115.7, d6 92.2 mm; alpha pi/2, 0, 0, pi/2, -pi/2, 0)
# and link masses (7.1, 12.7, 4.27, 2.0, 2.0, 0.365 kg) with centres of mass in each link's DH frame (UR's
# "Parameters for calculations of kinematics and dynamics"), carried to the base frame at q = 0 (mm).
# Base frame: UR's controller base (z up along joint 1); ee.M: the flange (tool0) at q = 0. Limits: +-2 pi
# (every UR10 joint turns +-360 deg). Laser: a stand-in, never used (docs/real-data.md: tracker poses).
"""
# The prior (docs/formats.md "Priors"). UR publishes no tolerances; every UR arm leaves the factory with its
# own DH corrections (the controller's calibration.conf), which reach a few mrad and a few mm and which
# the published nominal ignores. So: 0.01 rad in axis direction and 5 mm in axis position, as wide as the
# Panda's measured spread (data/robots/panda.yaml), not narrower; the tool (a probe) is fitted per session.
PRIOR = {"axis_rad": 0.01, "offset_mm": 5.0, "tool_mm": 5.0}


def main(out: str) -> None:
    d = ur10_model().to_dict()
    d["prior"] = PRIOR
    with open(out, "w") as f:
        f.write(HEADER)
        yaml.safe_dump(d, f, sort_keys=False, width=120, default_flow_style=None)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1])
