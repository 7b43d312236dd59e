"""``lasercal sheet``: a printable reference sheet (PDF and SVG at 1:1) and the layout describing it.

Units: mm, and degrees for the placement's yaw. Set-up from printing to the first capture: docs/sessions.md.
"""

from __future__ import annotations

import argparse

from lasercal.collector.cli.options import chain_arguments, number, output_argument, sheet_pose, unused


def _paper(text: str) -> str:
    """An argparse ``type``: a paper name or WxH mm (checked here, laid out by ``design_sheet``)."""
    from lasercal.vision.sheet import paper_size

    try:
        paper_size(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


def args_sheet(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal sheet``."""
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        required=True,
        metavar="DIR",
        help="folder for sheet.pdf, sheet.svg and layout.yaml",
    )
    p.add_argument("--force", action="store_true", help="replace an existing, non-empty DIR")
    p.add_argument(
        "--paper",
        type=_paper,  # no default string: argparse would run the check (and load vision) for --help too
        metavar="A4|A3|letter|WxH",
        help="paper, landscape (default A4); WxH in mm: W across the robot's front, H away from it",
    )
    p.add_argument(
        "--margin",
        type=number(0, 50, "mm"),
        default=10.0,
        metavar="MM",
        help="white border the printer cannot print on, mm (default 10)",
    )
    p.add_argument(
        "--marker",
        type=number(10, 200, "mm"),
        default=30.0,
        metavar="MM",
        help="ArUco marker side (default 30)",
    )
    p.add_argument(
        "--plane-z",
        type=number(-5000, 5000, "mm"),
        metavar="MM",
        help="the sheet's height in the robot base frame, mm (default: the --robot model's plane z, "
        "else -8, the thesis's Panda table)",
    )
    chain_arguments(
        p,
        "check that this robot (built-in name, model YAML or URDF) can aim at every point where --place "
        "lays the sheet",
    )
    p.add_argument(
        "--place",
        nargs=3,
        type=number(-5000, 5000),
        metavar=("X_MM", "Y_MM", "YAW_DEG"),
        help="rough placement written to layout.yaml: the sheet's origin (its centre cross) in the base "
        "frame and the yaw of its x arrow from the base x axis (e.g. 450 0 0: centred 450 mm in front)",
    )


def cmd_sheet(args) -> int:
    """``lasercal sheet``: check the reach (with --robot), write the files, say how to use them."""
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.collector.sheet import DEFAULT_PLANE_Z, REACH_CONFIGS, make_sheet
    from lasercal.solver.formats.robots import load_model
    from lasercal.vision.sheet import design_sheet

    if not args.robot:
        unused(args, "they pick the chain of a URDF --robot", "base_link", "tip_link")
    pose = sheet_pose(args.place, "--place") if args.place else None
    design = design_sheet(args.paper or "A4", args.margin, args.marker)
    model = load_model(args.robot, base_link=args.base_link, tip_link=args.tip_link) if args.robot else None
    plane_z = args.plane_z
    if plane_z is None:
        plane_z = model.plane_z if model is not None and model.plane_z is not None else DEFAULT_PLANE_Z
    with atomic_output(args.output, folder=True) as tmp:
        _, reach = make_sheet(tmp, design, plane_z, model, pose)
    ids = sorted(design.markers)
    print(
        f"sheet {design.paper} ({design.width:g} x {design.height:g} mm, landscape): {len(design.points)} "
        f"crosses, {len(ids)} ArUco markers ({design.dictionary} ids {ids[0]}-{ids[-1]}, "
        f"{design.marker:g} mm), "
        f"plane z {plane_z:g} mm"
    )
    base = {r.name: r.base for r in reach}
    if pose is not None and not base:
        base = dict(zip(design.points, pose.to_base(list(design.points.values()), plane_z)))
    head = f"{'point':<6} {'role':<11} {'x_mm':>7} {'y_mm':>7}  (sheet frame)"
    print(head + ("   base frame x_mm, y_mm" if base else "") + ("   reach" if reach else ""))
    ok = {r.name: r.reachable for r in reach}
    for name, xy in design.points.items():
        role = "validation" if name in design.validation else "calibration"
        line = f"{name:<6} {role:<11} {xy[0]:>7.1f} {xy[1]:>7.1f}"
        if name in base:
            line += f"                {base[name][0]:>7.1f} {base[name][1]:>7.1f}"
        if name in ok:
            line += "   ok" if ok[name] else "   no"
        print(line)
    if reach:
        print(f"{model.name} can aim its beam at every point ({REACH_CONFIGS} in-limit configurations each).")
    print(f"-> {args.output}/sheet.pdf, sheet.svg, layout.yaml")
    print(
        "Print at 100 % (actual size), check the 200 mm and 100 mm bars with a ruler, lay the sheet flat "
        "with its x arrow pointing away from the robot and tape it; then "
        f"lasercal capture --layout {args.output}/layout.yaml ... (docs/sessions.md)"
    )
    return 0
