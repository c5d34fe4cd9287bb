"""``lookfeel predict``: what an input feels like, each property with its probability.

Read a trained model's property heads on query files: touch videos (.mov, .mp4, .m4v, .avi, .mkv,
.webm), touch frames, depth maps or photos. Each file is one query; --together pools the files as
presses of one object (the Multi-input Net's max over presses). An input that is missing, that the
model cannot take (a still touch image to a model of press videos) or cannot read (an
empty or damaged file, an image renamed .mp4), or a video that holds no press (too short, no
contact), is answered with an "error" naming the file and no properties, and a warning; the others
are still predicted (the exit status is 1 only when nothing could be; one input is answered alike).
With --together, a press without contact is left out; a file that cannot be taken is the error. A
model trained on press videos cannot take a still touch image: it read each press as its change
from the frames before contact, which a still image lacks (a model trained on still frames takes a
video with a warning). A video with no colour (grey) is answered with a warning: the model reads a
press's colours, and one trained on colour presses reads a grey one unlike them (one trained on
grey presses is warned of a colour one instead). A class head
(model.class_heads, e.g. hardness 0/1/2 or material) answers with its most likely class in the label
column's own terms and that class's probability; a property-regression head answers in the column's
units, and a column of ranks without a class head with the rank nearest its number, the number
beside (softness_rank 1 (0.93)). Images are PNG or JPEG (.png, .jpg, .jpeg), as `serve` takes them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from lookfeel.cli._args import Subparsers, add_command, add_device, add_json
from lookfeel.modality import Modality


def add_parser(subparsers: Subparsers) -> None:
    """Register ``predict``."""
    pr = add_command(subparsers, "predict", __doc__, run)
    pr.add_argument("inputs", type=Path, nargs="+", metavar="INPUT", help="video or image file(s)")
    pr.add_argument("--checkpoint", type=Path, required=True, help="a run's checkpoint (.pt)")
    pr.add_argument(
        "--modality",
        choices=[m.value for m in Modality],
        default=None,
        help="what the files show (default: a video is touch; an image in a depth/, color/ or "
        "touch/ folder, that folder's; a 16-bit PNG, depth; else the model's only modality). "
        "A modality so guessed that the model lacks is refused: give this to read the file as "
        "another",
    )
    pr.add_argument(
        "--together", action="store_true", help="the files are presses of one object: pool them"
    )
    add_device(pr)
    add_json(pr, "print a JSON list: per query its path(s) and properties, or its error")


def _line(p: object) -> str:
    from lookfeel.predict import Prediction

    assert isinstance(p, Prediction)
    if p.error is not None:
        return f"{p.error} (nothing predicted)"
    parts = []
    for col, v in p.properties.items():
        prob = f" ({v.probability:.0%})" if v.probability is not None else ""
        if v.number is not None:
            prob = f" ({v.number:g})"  # a rank read from the property head's number
        parts.append(f"{col} {v.value}{prob}")
    name = p.path if len(p.paths) == 1 else f"{p.path} (+{len(p.paths) - 1} presses)"
    return f"{name}: " + ", ".join(parts)


def run(args: argparse.Namespace) -> int:
    """Predict and print one line per query (or a JSON list)."""
    from lookfeel.checkpoint import load_model
    from lookfeel.predict import predict_files

    loaded = load_model(args.checkpoint, args.device)
    modality = Modality(args.modality) if args.modality else None
    results = predict_files(
        loaded, args.inputs, modality, together=args.together, device=args.device
    )
    for r in results:
        if r.error is not None:
            print(f"lookfeel: warning: {r.error}; nothing predicted for it", file=sys.stderr)
    if args.json:
        print(json.dumps([dataclasses.asdict(r) for r in results], indent=2))
    else:
        print("\n".join(_line(r) for r in results))
    return 0 if any(r.error is None for r in results) else 1
