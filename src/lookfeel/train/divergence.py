"""Stopping a run whose loss or weights stop being finite, with one line that says so.

A learning rate far too high makes the weights overflow within a few steps: the loss turns NaN,
every embedding after it is NaN, and a checkpoint written then is useless. The training loop
therefore reads the loss only where it reads it anyway (log steps, validations, checkpoints:
reading it every step would make the CPU wait for the GPU every step), checks the weights
before it writes a checkpoint (`lookfeel.checkpoint.non_finite_tensors`, which loading a
checkpoint uses too), and stops with `TrainingDiverged`. Checkpoints written before
are kept as they are: nothing non-finite is ever written over them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from lookfeel.errors import LookfeelError
from lookfeel.losses import HEAD_TERMS

__all__ = ["TrainingDiverged", "diverged"]


class TrainingDiverged(LookfeelError):
    """A run's loss or weights became NaN or infinite; the message says when, a likely cause,
    and which checkpoint is kept."""


def diverged(
    what: str,
    value: float,
    first: int,
    step: int,
    lr: float,
    kept: Mapping[Path, int],
    checkpoint_every: int,
    terms: Sequence[str] = (),
    own_loss: str | None = None,
) -> TrainingDiverged:
    """The error that stops a diverged run.

    Args:
        what: ``"loss"`` or ``"weights"``.
        value: the non-finite value seen (NaN or infinity; for the weights, NaN).
        first, step: the steps between which it became non-finite (the loss is read only at
            log steps, validations and checkpoints; equal when it was read every step).
        lr: the run's ``train.lr``.
        kept: the checkpoints on disk that hold finite weights, with their steps.
        checkpoint_every: ``train.checkpoint_every``, named when nothing was kept.
        terms: the loss terms that were not finite, when known (``depth_touch_loss``): a
            loss of one's own that gives NaN is told apart from a learning rate too high.
        own_loss: ``loss.kind`` when a plugin registered it (not lookfeel): where its terms
            are among those not finite (or none are known), the hint names it first.

    Returns:
        A `TrainingDiverged` whose message reads, for example, ``train: the loss became NaN
        between steps 6 and 10, in its term depth_touch_loss (train.lr=1e+08 too high?); the
        last finite checkpoint is kept at run/checkpoints/last.pt (step 5)``.
    """
    became = "NaN" if math.isnan(value) else "infinite"
    when = f"at step {step}" if first >= step else f"between steps {first} and {step}"
    if kept:
        path, at = max(kept.items(), key=lambda kv: (kv[1], kv[0].name == "last.pt"))
        tail = f"the last finite checkpoint is kept at {path} (step {at})"
    else:
        tail = f"no checkpoint was written before it (train.checkpoint_every={checkpoint_every})"
    where = ""
    if terms:
        where = f", in its term{'s' if len(terms) > 1 else ''} {', '.join(terms)}"
    hint = f"train.lr={lr:g} too high?"
    if what == "loss" and own_loss is not None and not set(terms) <= set(HEAD_TERMS):
        hint = (
            f"does the loss {own_loss!r} divide by zero, say a mean over pairs a batch may "
            f"lack? or train.lr={lr:g} too high?"
        )
    return TrainingDiverged(f"train: the {what} became {became} {when}{where} ({hint}); {tail}")
