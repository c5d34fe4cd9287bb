"""``lookfeel demo``: the whole system on a generated synthetic world, in minutes.

Summarise the real GelFabric data when present, generate a synthetic world of 150 fabrics (or
reuse a complete one), reproduce the paper's experiments on it at the tiny budget, train the
cross-modal recipe (configs/synth_cross.yaml, shortened) on 100 fabrics as the paper does and
evaluate it on the other 50 (the paper held out 18; 50 narrow the intervals), and print the
headline numbers, each pair of senses with its interval, and where the reports are.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import Choices, Subparsers, add_choice, add_command, add_set, out_folder


def add_parser(subparsers: Subparsers) -> None:
    """Register ``demo``."""
    demo = add_command(subparsers, "demo", __doc__, run)
    demo.add_argument(
        "--data",
        type=Path,
        default=Path("../shared/data/gelfabric"),
        help="real data to summarise first when present (default ../shared/data/gelfabric)",
    )
    demo.add_argument(
        "--out",
        type=out_folder,
        default=Path("demo-output"),
        help="demo folder (default demo-output)",
    )
    demo.add_argument(
        "--fabrics",
        type=int,
        default=150,
        help="fabrics in the synthetic world (default 150: 100 to train on, 50 held out)",
    )
    demo.add_argument(
        "--test-fabrics",
        type=int,
        default=None,
        metavar="N",
        help="fabrics held out for the evaluations (default: a third of --fabrics)",
    )
    add_choice(
        demo,
        "--budget",
        Choices("lookfeel.demo", "DEMO_BUDGETS"),
        "tiny",
        "reproduction budget: %(choices)s (default tiny)",
    )
    add_set(demo, "override every run's config")


def run(args: argparse.Namespace) -> int:
    """Run the demo and print its headline numbers and where everything is."""
    from lookfeel.demo import print_demo_result, run_demo

    result = run_demo(
        args.out,
        real_data=args.data,
        fabrics=args.fabrics,
        test_fabrics=args.test_fabrics,
        budget=args.budget,
        overrides=args.set,
    )
    print_demo_result(result)
    return 0
