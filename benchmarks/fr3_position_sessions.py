"""Position sessions from the real FR3 camera poses (issue 15, item 5), for ``lasercal solve``.

Run from the repository: ``python benchmarks/fr3_position_sessions.py OUT [--axes 100]``. Reads
``../shared/data/fr3-camera/poses.csv`` (or ``LASERCAL_FR3_DATA``; used in place, never copied into
the repository) and writes two session folders (robot: the built-in ``fr3``):

* ``OUT/fr3-positions``: positions only, one target ``O``, the camera origin in the board frame;
* ``OUT/fr3-fullposes``: the full poses as positions of four targets: ``O`` and the points ``X``,
  ``Y``, ``Z`` at ``--axes`` mm along the camera's axes (p + L R e_k). Three non-collinear points
  fix a pose, so the position model sees the orientation too; their errors are correlated through
  the pose's (the position fit treats rows as independent).

Then ``lasercal solve OUT/fr3-fullposes --extend auto --folds 5 -o fr3.yaml`` (docs/position.md).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from lasercal.solver.formats.fullpose_io import read_pose_csv
from lasercal.solver.formats.positions import position_meta, write_position_session

ROOT = Path(__file__).resolve().parents[1]
FR3 = Path(os.environ.get("LASERCAL_FR3_DATA", ROOT.parent / "shared" / "data" / "fr3-camera"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="folder to write the two sessions into")
    ap.add_argument("--axes", type=float, default=100.0, help="distance of X, Y, Z from the origin, mm")
    a = ap.parse_args()
    d = read_pose_csv(FR3 / "poses.csv", 7)
    note = {"sensor": f"board frame of {FR3 / 'poses.csv'} (camera poses, PROVENANCE.md)"}
    out = Path(a.out)
    m = len(d.q)
    write_position_session(
        out / "fr3-positions",
        position_meta("fr3", ["O"], **note),
        d.q,
        d.T[:, :3, 3],
        np.full(m, "O", dtype=object),
    )
    pts = [d.T[:, :3, 3]] + [d.T[:, :3, 3] + a.axes * d.T[:, :3, k] for k in range(3)]
    names = ["O", "X", "Y", "Z"]
    write_position_session(
        out / "fr3-fullposes",
        position_meta("fr3", names, **note, axes_mm=a.axes),
        np.repeat(d.q, 4, axis=0),
        np.stack(pts, axis=1).reshape(-1, 3),
        np.tile(np.array(names, dtype=object), m),
    )
    print(f"wrote {out / 'fr3-positions'} ({m} captures) and {out / 'fr3-fullposes'} ({4 * m} captures)")


if __name__ == "__main__":
    main()
