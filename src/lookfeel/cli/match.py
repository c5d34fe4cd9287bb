"""``lookfeel match``: which library fabric query images show, how it looks and feels, and its
properties.

Rank the library's fabrics for query images of one modality: calibrated probabilities, each
fabric's nearest items in every modality, predicted physical properties, and 'no known fabric'
below the calibrated threshold. Several touch images are the presses of one query (pooled);
depth and colour images are matched one by one. A file that is missing, that cannot be read
or that the model cannot take (a still frame for a model trained on press videos) is answered
with an error naming it, and the other queries are matched, as `lookfeel predict` answers each
query (one such touch press fails the pooled query); the exit status is 1 only when nothing
could be matched. A fabric is shown by its name where the data names its objects
(videos/sponge_0.mov: sponge), else by its id; a property whose values are classes (a word such
as material, a rank such as hardness 0/1/2) is answered with its most likely class and that
class's share of the likeliest fabrics' probability, as `lookfeel predict` answers, other
properties with the probability-weighted mean and spread, both over the 5 likeliest fabrics
(`--property-fabrics`), whatever `--top` lists. With --json, each query's entry names its files
as `predict`'s do (`path`, `paths`), gives its properties as `predict` does (label -> value,
probability, ...; the spread `std` and the count of fabrics beside), and carries an `error`,
null when it was matched. A query identical to an item of the library is
reported as that item's fabric; otherwise, below the calibrated threshold, the answer is 'no
known fabric', shown beside the chance level 1/F (F: the library's fabrics). Across two senses
the library matches through its cross-modal map where calibration found that better (`lookfeel
index info` says which pairs).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from lookfeel.cli._args import Subparsers, add_command, add_device, add_json, add_library, number
from lookfeel.config.model import EMBED_BATCH
from lookfeel.modality import Modality


def add_parser(subparsers: Subparsers) -> None:
    """Register ``match``."""
    mt = add_command(subparsers, "match", __doc__, run)
    mt.add_argument("images", type=Path, nargs="+", metavar="IMAGE", help="query image file(s)")
    add_library(mt)
    mt.add_argument(
        "--modality",
        choices=[m.value for m in Modality],
        default=None,
        help="what they show (default: a video is touch; an image in a depth/, color/ or "
        "touch/ folder, that folder's; a 16-bit PNG, depth; else the library's only modality; "
        "else this is needed). A modality so guessed that the library lacks is refused: give "
        "this to read the file as another. Images are PNG or JPEG",
    )
    mt.add_argument("--top", type=number(int, 1), default=5, help="fabrics to list (default 5)")
    mt.add_argument(
        "--property-fabrics",
        type=number(int, 1),
        default=5,
        metavar="K",
        help="predict the properties from the K likeliest fabrics, each weighted by its "
        "probability, whatever --top lists (default 5)",
    )
    mt.add_argument(
        "--gallery",
        type=Modality,
        default=None,
        metavar="MODALITY",
        help="modality to match against (default: the best in calibration)",
    )
    add_device(mt)
    add_json(mt, "print a JSON list: per query its path(s), fabrics and properties, or its error")
    mt.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (on stderr, while more depth or colour images than one batch "
        f"of {EMBED_BATCH} are embedded)",
    )


def _entry(result: object) -> dict[str, Any]:
    """A query's ``--json`` entry: a `MatchResult`'s fields and ``error`` null; a
    `MatchFailure`'s files and ``error``, the result's other keys null or empty."""
    from lookfeel.index import MatchFailure, MatchResult

    if isinstance(result, MatchResult):
        return {**dataclasses.asdict(result), "error": None}
    assert isinstance(result, MatchFailure)
    return result.entry()


def run(args: argparse.Namespace) -> int:
    """Match the images and print each result (or all of them as JSON)."""
    from lookfeel.data.files import ImageError
    from lookfeel.devices import resolve_device
    from lookfeel.errors import LookfeelError
    from lookfeel.index import Library, Matcher, MatchFailure, MatchResult, format_match
    from lookfeel.predict import guess_modality

    device = resolve_device(args.device)  # a device this machine lacks: one line, first
    matcher = Matcher(Library.open(args.index, checkpoint=args.checkpoint), device=device)
    files = [str(p) for p in args.images]
    refused: dict[int, str] = {}  # a file's own error, found asking what it shows
    modality: Modality | None = None
    if args.modality is not None:
        modality = Modality(args.modality)
    else:  # as `predict` guesses it, among the senses the library holds
        have = [m for m in matcher.model.modalities if m in matcher.library.tables]
        guessed = set()
        for i, p in enumerate(args.images):
            try:
                guessed.add(guess_modality(p, have, "the library"))
            except ImageError as e:  # missing, a folder, no image: this query's error
                refused[i] = str(e)
        if len(guessed) > 1:
            raise LookfeelError(
                "the query files show "
                + " and ".join(sorted(m.value for m in guessed))
                + ": a query is of one modality; say which with --modality"
            )
        modality = next(iter(guessed), None)
    results: list[MatchResult | MatchFailure] = []
    if modality is None:  # no file said what it shows: every one is its own error
        results = [MatchFailure(f, [f], None, refused[i]) for i, f in enumerate(files)]
    elif modality is Modality.TOUCH and refused:  # one pooled query, which a press fails
        results = [MatchFailure(files[0], files, modality, refused[min(refused)])]
    else:
        answers = iter(  # a modality guessed: some file was not refused
            matcher.match_each(
                [p for i, p in enumerate(args.images) if i not in refused],
                modality,
                top=args.top,
                gallery=args.gallery,
                k_properties=args.property_fabrics,
                progress=not args.quiet,
            )
        )
        for i, f in enumerate(files):
            if i in refused:
                results.append(MatchFailure(f, [f], modality, refused[i]))
            elif modality is not Modality.TOUCH or i == 0:
                results.append(next(answers))
    failed = [r.error for r in results if isinstance(r, MatchFailure)]
    matched = len(failed) < len(results)
    for error in failed:  # a warning; where nothing was matched, the command's error
        said = f"warning: {error}; nothing matched for it" if matched else error
        print(f"lookfeel: {said}", file=sys.stderr)
    if args.json:
        print(json.dumps([_entry(r) for r in results], indent=2))
    elif matched:
        print(
            "\n\n".join(
                format_match(r) if isinstance(r, MatchResult) else f"{r.error} (nothing matched)"
                for r in results
            )
        )
    return 0 if matched else 1
