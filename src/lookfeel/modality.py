"""Modalities and touch press kinds: the keys every model, loss and metric is indexed by.

Both are ``str`` enums, so ``Modality.DEPTH == "depth"`` and they round-trip through YAML and
JSON unchanged (ImageBind's ``ModalityType``, made an enum).
"""

from __future__ import annotations

from enum import Enum

__all__ = ["Modality", "PressKind", "parse_modalities", "slot_modality", "slot_names"]


class Modality(str, Enum):
    """One way of sensing a fabric (paper section 3)."""

    DEPTH = "depth"
    """Kinect depth image of the fabric draped over the post (16-bit PNG, millimetres)."""
    COLOR = "color"
    """Colour photo of the draped fabric (8-bit RGB)."""
    TOUCH = "touch"
    """GelSight press: an ordered sequence of 8-bit RGB tactile frames."""

    def __str__(self) -> str:
        return self.value


class PressKind(str, Enum):
    """How a GelSight press met the fabric."""

    FOLD = "fold"
    """Pressed on a fold of the fabric lying on a table (the paper's main touch data)."""
    FLAT = "flat"
    """Pressed on a single flat layer (the paper's 'Flat' model)."""
    RAND = "rand"
    """Pressed at random, neither a deliberate fold nor flat."""

    def __str__(self) -> str:
        return self.value


def parse_modalities(text: str | list[str] | tuple[str, ...]) -> tuple[Modality, ...]:
    """Parse ``"depth,touch"`` (or a list of names) into modalities, keeping order.

    Raises:
        ValueError: naming the unknown value and the valid ones.
    """
    names = [t.strip() for t in text.split(",")] if isinstance(text, str) else list(text)
    out: list[Modality] = []
    for name in names:
        if not name:
            continue
        try:
            m = Modality(name)
        except ValueError:
            valid = ", ".join(x.value for x in Modality)
            raise ValueError(f"unknown modality {name!r}; expected one of: {valid}") from None
        if m not in out:
            out.append(m)
    if not out:
        raise ValueError("no modality given")
    return tuple(out)


def slot_names(views: tuple[Modality, ...] | list[Modality]) -> list[str]:
    """Names for the slots of a training tuple: the modality, then ``depth.1``, ``depth.2`` ...

    A tuple may hold one modality more than once (the Siamese net compares two depth images),
    so slots are named rather than keyed by modality alone; `slot_modality` inverts this.
    """
    seen: dict[Modality, int] = {}
    names = []
    for m in views:
        k = seen.get(m, 0)
        names.append(m.value if k == 0 else f"{m.value}.{k}")
        seen[m] = k + 1
    return names


def slot_modality(name: str) -> Modality:
    """The modality of a slot name from `slot_names` (``"depth.1"`` -> ``Modality.DEPTH``)."""
    return Modality(name.split(".", 1)[0])
