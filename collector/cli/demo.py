"""``lasercal demo`` subcommand: the whole workflow on the simulated Panda, with a progress bar."""

from __future__ import annotations

import argparse
from pathlib import Path

from lasercal.collector.cli.options import SEED, output_argument


def args_demo(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal demo``."""
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        instead="remove it or choose another folder with -o",
        default="lasercal-demo",
        help="folder for the session, models, validations and report (default: ./lasercal-demo)",
    )
    p.add_argument(
        "--seed",
        type=SEED,
        default=0,
        metavar="S",
        help="seed of the simulated world (the robot's hidden errors, the operator's aim, the camera's "
        "noise); the README's figures are seed 0's (a whole number, default 0)",
    )


def cmd_demo(args) -> int:
    from tqdm import tqdm

    from lasercal.collector.demo import DemoOptions, format_summary, run_demo

    opts = DemoOptions(seed=args.seed)
    with tqdm(
        total=opts.units(), desc="demo", unit="step", leave=False, delay=0.5, disable=None
    ) as bar:  # delay: no bar for an instant error; disable=None: none when stderr is not a terminal

        def progress(stage: str) -> None:
            bar.set_description(stage, refresh=False)
            bar.update()

        s = run_demo(Path(args.output), opts, progress)
    print(format_summary(s))
    return 0
