"""``lasercal mujoco-scene``: a default MuJoCo world for a printed sheet (:mod:`hardware.mujoco_scene`)."""

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


def passives(args):
    """The passive joints the options ask for (:class:`hardware.mujoco_scene.Passive`), one per joint.

    Raises
    ------
    LasercalError
        Two passive joints after one joint, or friction without a passive joint to act on.
    """
    from dataclasses import replace

    from lasercal.collector.hardware.mujoco_scene import Passive
    from lasercal.solver.errors import LasercalError

    out = {}
    kinds = (
        ("spring", "joint", "compliance"),
        ("bend", "x", "compliance"),
        ("backlash", "joint", "backlash"),
    )
    for flag, axis, key in kinds:
        for j, v in getattr(args, flag) or ():
            old = out.get(j, Passive(j, axis=axis))
            if old.axis != axis or getattr(old, key):
                raise LasercalError(
                    f"argument --{flag}: joint {j} has a passive joint of another kind already"
                )
            out[j] = replace(old, **{key: v})
    for j, nm in args.friction or ():
        if j not in out:
            raise LasercalError(
                f"argument --friction: {j}:{nm:g} acts on the passive joint after joint {j}: add --spring, "
                f"--bend or --backlash {j}:..."
            )
        out[j] = replace(out[j], friction=nm)
    return tuple(out[j] for j in sorted(out))


def cmd_mujoco_scene(args) -> int:
    from pathlib import Path

    from lasercal.collector.hardware.mujoco_scene import SceneOptions, write_scene
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.whole import dump_yaml

    passive = passives(args)  # the options' own mistakes first
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
    options = SceneOptions(
        None if args.exact else args.seed, passive=passive, light=args.light, shadows=args.shadows
    )
    with atomic_output(args.output, folder=True) as tmp:
        info = write_scene(tmp, layout, pdf, options)
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
        + "".join(f"; {p.name}: {_passive_text(p)}" for p in options.passive)
    )
    print(
        f"next: lasercal capture --backend mujoco --world {args.output}/scene.xml --robot fr3 --layout "
        f"{args.layout} --camera mujoco --guide move --auto --per-point 9 -o session"
    )
    return 0


def _passive_text(p) -> str:
    parts = []
    if p.compliance:
        parts.append(f"spring {p.compliance:g} rad/Nm about {'its joint' if p.axis == 'joint' else p.axis}")
    if p.backlash:
        parts.append(f"backlash {p.backlash:g} rad")
    if p.friction:
        parts.append(f"friction {p.friction:g} Nm")
    return ", ".join(parts)
