"""``lookfeel synth``: generate a synthetic visuo-tactile fabric world in the dataset layout.

Generate depth and colour images of fabrics draped over the post and GelSight press sequences
(flat and on a fold) from physical fabric parameters, in the layout that `lookfeel data check`
reads. With --labels, render exactly the fabrics of a labels.csv (ids kept) from their labels:
by default colour and touch, to stand beside real depth images. The same seed gives
byte-identical files. See docs/synth.md in the lookfeel source repository.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_command,
    add_modalities,
    number,
)


def add_parser(subparsers: Subparsers) -> None:
    """Register ``synth``."""
    syn = add_command(subparsers, "synth", __doc__, run)
    syn.add_argument(
        "out", type=Path, help="output folder (new, empty, or an earlier synth output)"
    )
    syn.add_argument(
        "--fabrics", type=number(int, 1), default=118, help="fabrics to sample (default 118)"
    )
    syn.add_argument(
        "--test-fabrics",
        type=number(int, 0),
        default=None,
        metavar="N",
        help="fabrics held out as paper_split test in labels.csv (default: the paper's share, "
        "18 of every 118)",
    )
    syn.add_argument(
        "--drapes", type=number(int, 0), default=10, help="drapes per fabric (default 10)"
    )
    syn.add_argument(
        "--presses-flat", type=number(int, 0), default=10, help="flat presses (default 10)"
    )
    syn.add_argument(
        "--presses-fold", type=number(int, 0), default=15, help="fold presses (default 15)"
    )
    syn.add_argument(
        "--frames", type=number(int, 1), default=3, help="frames per press (default 3)"
    )
    syn.add_argument(
        "--reprints",
        type=number(int, 0),
        default=4,
        help="re-printed renders of each colour photo, in reprints/ (default 4; 0: none): the "
        "same drape under another print and colours, which training reads in place of the "
        "photo so that a net cannot name a fabric by its print (data.color_reprints)",
    )
    add_choice(
        syn,
        "--size",
        Choices("lookfeel.synth.config", "SIZE_PRESETS"),
        "net",
        "image sizes (default net): net (depth 224, colour 256, touch 320x240), tiny, or "
        "full (touch 960x720 like the authors' sensor)",
    )
    syn.add_argument(
        "--seed",
        type=number(int, 0),
        default=0,
        help="world seed, an integer >= 0: the same seed gives byte-identical files (default 0)",
    )
    syn.add_argument(
        "--workers",
        type=number(int, 0),
        default=0,
        help="processes rendering at once (default 0: one per core; 1: one after the other "
        "in this process)",
    )
    syn.add_argument(
        "--labels", type=Path, default=None, help="label-conditioned mode: a labels.csv"
    )
    add_modalities(syn, "--modalities", "what to render", "all; with --labels: color,touch")
    add_choice(
        syn,
        "--format",
        Choices("lookfeel.synth.config", "IMAGE_FORMATS"),
        "jpg",
        "file format of colour and touch images: %(choices)s (default jpg)",
    )
    syn.add_argument("--no-contact-sheet", action="store_true", help="skip contact_sheet.png")
    syn.add_argument(
        "--beside",
        type=Path,
        default=None,
        metavar="ROOT",
        help="a dataset folder (e.g. the real GelFabric data, with --labels ROOT/labels.csv) "
        "whose depth images of the same fabrics open each row of the contact sheet",
    )
    syn.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Generate the world and say what was written."""
    from lookfeel.locks import BusyError
    from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate

    try:
        config = SynthConfig(
            **SIZE_PRESETS[args.size],
            fabrics=args.fabrics,
            drapes=args.drapes,
            presses_flat=args.presses_flat,
            presses_fold=args.presses_fold,
            frames=args.frames,
            seed=args.seed,
            workers=args.workers,
            image_format=args.format,
            modalities=args.modalities,
            contact_sheet=not args.no_contact_sheet,
            reprints=args.reprints,
            test_fabrics=args.test_fabrics,
        )
        summary = generate(
            config, args.out, labels=args.labels, progress=not args.quiet, beside=args.beside
        )
    except BusyError:
        raise  # another synth is writing the folder: not a usage error (`lookfeel: `, exit 1)
    except (ValueError, FileExistsError) as e:
        # Not only LookfeelError: the labels file, --beside and the output folder raise plain
        # ValueError and FileExistsError, and a bad value here is a usage error (exit 2).
        print(f"lookfeel synth: {e}", file=sys.stderr)
        return 2
    print(
        f"Wrote {summary.fabrics} fabrics to {summary.out} in {summary.seconds:.1f} s: "
        f"{summary.depth_images} depth, {summary.color_images} colour images"
        + (f" ({summary.reprints} re-printed renders of them)" if summary.reprints else "")
        + f", {summary.touch_presses} touch presses ({summary.touch_frames} frames)."
    )
    if summary.contact_sheet is not None:
        print(f"Contact sheet: {summary.contact_sheet}")
    return 0
