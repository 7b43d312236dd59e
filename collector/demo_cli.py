"""``lasercal demo`` subcommand."""
from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from .demo import format_summary, run_demo


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="the whole calibration on the built-in simulated Panda (no robot needed)")
    p.add_argument("-o", "--output", default="lasercal-demo", help="folder for the session, models and summary (default: ./lasercal-demo)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_demo)


def cmd_demo(args) -> int:
    with tqdm(total=6, desc="demo", unit="step", leave=False) as bar:
        def progress(msg):
            bar.set_postfix_str(msg[:60])
            bar.update(1)
        s = run_demo(Path(args.output), seed=args.seed, progress=progress)
    print(format_summary(s))
    print(f"\nfiles in {args.output}/ (session/, model_lm.yaml, model_thesis.yaml, summary.json)")
    return 0
