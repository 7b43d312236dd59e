"""The labelled real photos scored as the outside check scores them (issue 47 item 1).

Run from the repository root::

    nice python benchmarks/bench_vision_outside.py              # ~5 min on 2 busy cores
    nice python benchmarks/bench_vision_outside.py laser4 image # photos whose name holds a word

Each photo of ``../shared/data/real-photos`` (``labels.json``; see its ``PROVENANCE.md``; never copied
into the repository) goes through ``lasercal spots --json --expect any PHOTO``, one photo a call, with
the default options, in a process of its own (the outside check's contract,
/work/shared/notes/how-work-is-checked.md): a labelled spot is found when a reported spot lies within
max(4 px, 2 x its ``uncertainty_px``); a reported spot farther than 3 x ``radius_px`` + 6 px from every
labelled and uncertain spot is false; a photo whose error says "could not be measured" is unmeasurable.
Prints each photo's distance to its label, then the totals and the median distance of the found spots.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"
COMMAND = [sys.executable, "-c", "from lasercal.collector.cli.main import main; main()"]


def reported(photo: Path) -> tuple[list[dict], str]:
    """The spots ``lasercal spots --json --expect any PHOTO`` reports, and what it says on stderr."""
    r = subprocess.run(
        [*COMMAND, "spots", "--json", "--expect", "any", str(photo)], capture_output=True, text=True
    )
    spots = [s for p in (json.loads(r.stdout) if r.stdout.strip() else []) for s in p.get("spots", [])]
    return spots, r.stderr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("only", nargs="*", help="score only photos whose name holds one of these words")
    ap.add_argument("--photos", type=Path, default=PHOTOS, help="folder with labels.json")
    a = ap.parse_args()
    found, labelled, false, lost, near = 0, 0, 0, 0, []
    for e in json.loads((a.photos / "labels.json").read_text()):
        if a.only and not any(w in e["file"] for w in a.only):
            continue
        spots, said = reported(a.photos / e["file"])
        lost += "could not be measured" in said
        said_here = []
        for lab in e["spots"]:
            labelled += 1
            d = min((np.hypot(s["u"] - lab["x"], s["v"] - lab["y"]) for s in spots), default=np.inf)
            hit = d <= max(4.0, 2.0 * lab["uncertainty_px"])
            found += hit
            near += [d] if hit else []
            said_here.append(f"{d:.2f} px from its label, {'found' if hit else 'MISSED'}")
        marks = e["spots"] + (e.get("uncertain_spots") or [])
        for s in spots:
            if all(np.hypot(s["u"] - m["x"], s["v"] - m["y"]) > 3 * m.get("radius_px", 0) + 6 for m in marks):
                false += 1
                said_here.append(f"FALSE at ({s['u']:.0f}, {s['v']:.0f})")
        print(f"{e['file']:<52} {len(spots)} reported; {'; '.join(said_here)}", flush=True)
    median = f"{np.median(near):.2f}" if near else "-"
    print(f"found {found}/{labelled}, false {false}, unmeasurable {lost}, median {median} px")


if __name__ == "__main__":
    main()
