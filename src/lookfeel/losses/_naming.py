"""How the losses name their terms and find their inputs in a model's output dict."""

from __future__ import annotations

from collections.abc import Mapping
from itertools import combinations

from torch import Tensor

__all__ = ["embeddings_of", "head_output", "require_fabric", "slot_pairs", "term_name"]


def term_name(*slots: str) -> str:
    """``term_name("depth", "touch") == "depth_touch_loss"``; ``"depth.1"`` becomes ``depth1``."""
    return "_".join(s.replace(".", "") for s in slots) + "_loss"


def slot_pairs(slots: list[str]) -> list[tuple[str, str]]:
    """Every unordered pair of slots, in slot order."""
    return list(combinations(slots, 2))


def embeddings_of(outputs: Mapping[str, Tensor]) -> dict[str, Tensor]:
    """The embeddings of a model's output dict: the slot keys (head outputs hold a ``/``)."""
    return {k: v for k, v in outputs.items() if "/" not in k}


def head_output(outputs: Mapping[str, Tensor], slot: str, head: str) -> Tensor:
    """The output of ``head`` for ``slot`` (key ``"<slot>/<head>"``, `lookfeel.models.head_key`).

    Raises:
        ValueError: the model output lacks it (the model has no such head, or was called
            without ``heads=True``).
    """
    key = f"{slot}/{head}"
    if key not in outputs:
        raise ValueError(
            f"{head} targets given for slot {slot!r} but the model output has no {key!r}; "
            f"build the model with the {head} head and call it with heads=True"
        )
    return outputs[key]


def require_fabric(
    fabric: Mapping[str, Tensor] | None, slots: list[str], loss: str
) -> Mapping[str, Tensor]:
    """Check that per-slot fabric ids are given for every slot.

    Raises:
        ValueError: naming the loss and the first slot without fabric ids.
    """
    if fabric is None:
        raise ValueError(f"{loss} needs per-slot fabric ids (fabric={{slot: (B,) ids}})")
    for s in slots:
        if s not in fabric:
            raise ValueError(f"{loss}: no fabric ids for slot {s!r}")
    return fabric
