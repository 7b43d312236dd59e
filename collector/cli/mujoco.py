"""``lasercal mujoco-scene``: a default MuJoCo world for a printed sheet (:mod:`worlds.mujoco_scene`)."""

from __future__ import annotations

import argparse

from lasercal.collector.cli.options import LAYOUT, SEED, count, number, output_argument

JOINT = count(1, 7)


def _passive(kind: str, rng):
    """An argparse ``type`` for ``J:VALUE`` (joint 1-7 and a value in ``rng``), e.g. ``2:1e-4``."""

    def parse(text: str):
        joint, _, value = str(text).partition(":")
        if not value:
            raise argparse.ArgumentTypeError(f"{text!r}: expected JOINT:{kind} (e.g. 2:{rng.range.hi:g})")
        return JOINT(joint.strip()), rng(value.strip())

    parse.__name__ = f"JOINT:{kind}"
    return parse


COMPLIANCE = number(0, 0.01, "rad/Nm", lo_open=True)
FRICTION = number(0, 50, "Nm", lo_open=True)
BACKLASH = number(0, 0.05, "rad", lo_open=True)


def args_mujoco_scene(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal mujoco-scene``."""
    p.add_argument(
        "--layout",
        type=LAYOUT,
        required=True,
        help="the layout.yaml lasercal sheet wrote with --place (its sheet.pdf beside it is the texture)",
    )
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        required=True,
        metavar="DIR",
        help="folder for scene.xml and its files",
    )
    p.add_argument("--force", action="store_true", help="replace an existing, non-empty DIR")
    p.add_argument(
        "--seed",
        type=SEED,
        default=0,
        help="seed of the perturbation of the arm, laser and sheet (default 0)",
    )
    p.add_argument(
        "--exact", action="store_true", help="no perturbation: the arm, laser and sheet exactly as described"
    )
    p.add_argument(
        "--spring",
        type=_passive("RAD_PER_NM", COMPLIANCE),
        action="append",
        metavar="J:C",
        help="a passive spring of compliance C (rad/Nm) after joint J, about its axis: the link bends under "
        "gravity, the encoder does not see it (e.g. 2:1e-4); repeatable",
    )
    p.add_argument(
        "--bend",
        type=_passive("RAD_PER_NM", COMPLIANCE),
        action="append",
        metavar="J:C",
        help="as --spring, about link J's x axis (across its joint axis: the link bends sideways)",
    )
    p.add_argument(
        "--friction",
        type=_passive("NM", FRICTION),
        action="append",
        metavar="J:NM",
        help="dry friction (Nm) on the passive joint after joint J (with a --spring, --bend or --backlash "
        "there)",
    )
    p.add_argument(
        "--backlash",
        type=_passive("RAD", BACKLASH),
        action="append",
        metavar="J:RAD",
        help="a passive joint after joint J, free over RAD (rad) about its axis: gravity takes it to one end",
    )
    p.add_argument(
        "--light",
        type=number(0, 20, lo_open=True),
        default=1.0,
        metavar="GAIN",
        help="the lamp above the table, relative to the default (the paper at about two thirds of full "
        "scale); 3: a bright lamp",
    )
    p.add_argument("--shadows", action="store_true", help="the lamp casts the arm's shadow")
    p.add_argument(
        "--curl",
        type=number(0, 20),
        default=0.0,
        metavar="MM",
        help="the paper curls up toward the page's top and bottom edges, MM there (a parabola; 0: flat)",
    )
    p.add_argument(
        "--camera-at",
        type=number(-3000, 3000),
        nargs=3,
        metavar=("DX", "DY", "DZ"),
        help="where the camera stands from the sheet's centre, mm, along the sheet's x and y and up (default "
        "350 0 600: beyond the sheet, away from the robot); it looks at the centre",
    )


def passives(args):
    """The passive joints the options ask for, one per joint: dicts of :class:`worlds.mujoco_scene.Passive`'s
    fields (``joint``, ``axis``, ``compliance``, ``backlash``, ``friction``).

    Raises
    ------
    LasercalError
        Two passive joints after one joint, or friction without a passive joint to act on.
    """
    from lasercal.solver.errors import LasercalError

    out = {}
    kinds = (
        ("spring", "joint", "compliance"),
        ("bend", "x", "compliance"),
        ("backlash", "joint", "backlash"),
    )
    for flag, axis, key in kinds:
        for j, v in getattr(args, flag) or ():
            old = out.get(j, {"joint": j, "axis": axis})
            if old["axis"] != axis or old.get(key):
                raise LasercalError(
                    f"argument --{flag}: joint {j} has a passive joint of another kind already"
                )
            out[j] = {**old, key: v}
    for j, nm in args.friction or ():
        if j not in out:
            raise LasercalError(
                f"argument --friction: {j}:{nm:g} acts on the passive joint after joint {j}: add --spring, "
                f"--bend or --backlash {j}:..."
            )
        out[j] = {**out[j], "friction": nm}
    return tuple(out[j] for j in sorted(out))


def cmd_mujoco_scene(args) -> int:
    from pathlib import Path

    from lasercal.collector.hardware import write_mujoco_scene
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.whole import dump_yaml

    passive = passives(args)  # the options' own mistakes first
    if args.camera_at is not None and args.camera_at[2] < 100:
        from lasercal.solver.errors import LasercalError

        raise LasercalError(
            f"argument --camera-at: DZ {args.camera_at[2]:g} mm: the camera looks down at the sheet from "
            "at least 100 mm above it"
        )
    layout = load_layout(args.layout)
    if layout.frame != "sheet":
        raise FormatError(
            layout.path,
            "this layout is not a printed sheet (its points are in the robot's base frame): mujoco-scene "
            "draws a sheet lasercal sheet printed (expected the layout.yaml beside its sheet.pdf)",
        )
    pdf = Path(layout.path).parent / "sheet.pdf"
    if not pdf.is_file():
        raise FormatError(layout.path, f"no sheet.pdf beside it (expected {pdf}: lasercal sheet writes both)")
    with atomic_output(args.output, folder=True) as tmp:
        seed = None if args.exact else args.seed
        info = write_mujoco_scene(
            tmp, layout, pdf, seed, passive, args.light, args.shadows, args.curl, args.camera_at
        )
        head = (
            "# What lasercal mujoco-scene drew: lengths mm, angles rad (yaw deg), compliance rad/Nm, "
            "friction Nm.\n"
            "# The world's truth, for scoring a calibration; lasercal reads none of it for an estimate.\n"
        )
        (tmp / "scene.yaml").write_text(
            dump_yaml(
                {"format": "lasercal-mujoco-scene/1", **info},
                head,
                sort_keys=False,
                width=110,
                default_flow_style=None,
            )
        )
    s = info["sheet"]
    print(
        f"wrote {args.output}/scene.xml: {info['arm'].split(' from ')[0]} "
        f"({'exact' if args.exact else f'perturbed, seed {args.seed}'}), the sheet at x {s['x_mm']:.2f} mm, "
        f"y {s['y_mm']:.2f} mm, yaw {s['yaw_deg']:.3f} deg"
        + (f", the paper curled {args.curl:g} mm at its top and bottom edges" if args.curl else "")
        + "".join(f"; passive_joint{p['joint']}: {_passive_text(p)}" for p in passive)
    )
    print(
        f"next: lasercal capture --backend mujoco --world {args.output}/scene.xml --robot fr3 --layout "
        f"{args.layout} --camera mujoco --guide move --auto --per-point 9 -o session"
    )
    return 0


def _passive_text(p) -> str:
    parts = []
    if p.get("compliance"):
        where = "its joint" if p["axis"] == "joint" else p["axis"]
        parts.append(f"spring {p['compliance']:g} rad/Nm about {where}")
    if p.get("backlash"):
        parts.append(f"backlash {p['backlash']:g} rad")
    if p.get("friction"):
        parts.append(f"friction {p['friction']:g} Nm")
    return ", ".join(parts)
