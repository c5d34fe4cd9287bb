"""The ``lookfeel`` command. Flags become config objects here; library code never sees argv."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from lookfeel import __version__


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lookfeel",
        description="Connect how fabrics look (colour, depth) with how they feel (GelSight).",
    )
    parser.add_argument("--version", action="version", version=f"lookfeel {__version__}")
    parser.add_subparsers(dest="command", metavar="COMMAND")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
