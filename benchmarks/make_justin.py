"""Write the built-in robot ``justin`` (data/robots/justin.yaml) from DLR's published facts.

    python benchmarks/make_justin.py ../shared/data/justin/robot-facts.yaml data/robots/justin.yaml

How: :func:`lasercal.solver.formats.justin.justin_model` (eq. J1 there): Craig DH frames -> screws, the
torso coupling, the CAD point masses, two lateral axes per joint; the marker guesses as targets.
"""

from __future__ import annotations

import sys

import yaml

from lasercal.solver.formats.justin import justin_model

HEADER = """# DLR Agile Justin, upper body: made by benchmarks/make_justin.py from robot-facts.yaml (Craig DH
# table, torso coupling, static frames, CAD point masses; sources in the data's PROVENANCE.md). mm, rad, kg.
# 18 joints on a tree (torso 4, right arm 7, left arm 7) + 2 lateral axes per joint (value 0 unless the link
# bends); the captures' q1..q19 are the commanded joints (torso_4 = -(q2 + q3); head_1, head_2 move nothing
# described). Targets right/left: the hand markers' starting guesses (dataset page), identified by solve.
"""


def main(facts_path: str, out: str) -> None:
    facts = yaml.safe_load(open(facts_path))
    model = justin_model(facts)
    with open(out, "w") as f:
        f.write(HEADER)
        yaml.safe_dump(model.to_dict(), f, sort_keys=False, width=120, default_flow_style=None)
    print(f"wrote {out}: {model.n} joints ({int(model.real.sum())} real), {model.n_commanded} commanded")


if __name__ == "__main__":
    main(*sys.argv[1:3])
