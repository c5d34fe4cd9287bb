"""Modalities, touch press kinds and (query, gallery) pairs: the keys every model, loss and
metric is indexed by.

All three are ``str`` types, so ``Modality.DEPTH == "depth"``,
``Pair(Modality.TOUCH, Modality.DEPTH) == "touch_to_depth"`` and they round-trip through YAML and
JSON unchanged (ImageBind's ``ModalityType``, made an enum).
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import Enum
from pathlib import Path
from typing import Any

from lookfeel.errors import LookfeelError

__all__ = [
    "REPRINTS",
    "Modality",
    "ModalityError",
    "Pair",
    "PressKind",
    "parse_modalities",
    "reprint_path",
    "slot_modality",
    "slot_names",
]

REPRINTS = "reprints"
"""The folder of a dataset (beside ``color/``) that holds re-printed renders of its colour
photos: the same drape, light and camera under other prints and colours, written by ``lookfeel
synth`` (``--reprints``) and read in place of the photos in training (``data.color_reprints``)."""


def reprint_path(photo: Path, k: int) -> Path:
    """Re-printed render ``k`` (1, 2, ...) of the colour photo ``photo``:
    ``ROOT/color/F0001_1.jpg`` -> ``ROOT/reprints/F0001_1_r1.jpg``."""
    return photo.parent.parent / REPRINTS / f"{photo.stem}_r{k}{photo.suffix}"


class ModalityError(LookfeelError):
    """A modality named by a value that is none of `Modality`'s names."""


class Modality(str, Enum):
    """One way of sensing a fabric (paper section 3).

    A modality is a ``str`` (``Modality.COLOR == "color"``), but code compares members by
    identity (``m is Modality.COLOR``), so a plain ``"color"`` must become the member first:
    every public function that takes a modality accepts either and converts it with `of`.
    """

    DEPTH = "depth"
    """Kinect depth image of the fabric draped over the post (16-bit PNG, millimetres)."""
    COLOR = "color"
    """Colour photo of the draped fabric (8-bit RGB)."""
    TOUCH = "touch"
    """GelSight press: an ordered sequence of 8-bit RGB tactile frames."""

    def __str__(self) -> str:
        return self.value

    @property
    def pooled(self) -> bool:
        """This modality's inputs have a press axis: one input is several items of one fabric
        whose embeddings are pooled into one (the paper's Multi-input Net, section 4.1).

        True for touch only, whose input is ``DataConfig.presses`` presses: (B, P, C, H, W)
        into its branch (`Branch.pressed`), P items per training slot, queries pooling
        ``EvalConfig.presses`` presses. The model (`Branch`, `Embedder`'s input check, the
        press-axis helpers), the training tuples and batches, `evaluate`'s pooled queries and
        candidates, ``lookfeel cv``'s pooled queries and class-head scores of held-out objects,
        `lookfeel match`'s query batch (`lookfeel.index.query.query_batch`) and the ONNX
        export's ``presses`` input read it here. Still by touch's name: `evaluate`'s press
        curve (``touch_to_*_presses{P}`` keys), and what is touch's own rather than the press
        axis's (press videos, with the ONNX export's ``views`` input; the GelSight's
        untouched-sensor control).

        Example:
            >>> Modality.TOUCH.pooled, Modality.DEPTH.pooled
            (True, False)
        """
        return self is Modality.TOUCH

    @classmethod
    def of(cls, value: Modality | str) -> Modality:
        """``value`` as a member: a `Modality` as it is, a name (``"color"``) as its member.

        Example:
            >>> Modality.of("color") is Modality.COLOR
            True

        Raises:
            ModalityError: ``value`` names no modality (``"colour"``), naming it and the
                valid names.
        """
        if isinstance(value, cls):
            return value
        try:
            return cls(value)
        except ValueError:
            valid = ", ".join(m.value for m in cls)
            raise ModalityError(f"unknown modality {value!r}; expected one of: {valid}") from None


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


class Pair(str):
    """An ordered (query, gallery) pair of modalities, written ``"{query}_to_{gallery}"``.

    Retrieval is directional (the paper's Table 3 lists both ``Gel2Color`` and ``Color2Gel``):
    ``touch_to_depth`` matches a GelSight press against depth images. A `Pair` is the ``str``
    of that name, so metric keys (``f"{pair}_top1"``), JSON and YAML keep the plain text and a
    pair equals its name; but only a valid pair can be built, and its two modalities are typed
    attributes, so no code splits or joins the text itself.

    Example:
        >>> p = Pair.parse("touch_to_depth")
        >>> p.query, p.gallery, p == Pair(Modality.TOUCH, Modality.DEPTH) == "touch_to_depth"
        (<Modality.TOUCH: 'touch'>, <Modality.DEPTH: 'depth'>, True)
    """

    SEPARATOR = "_to_"

    query: Modality
    gallery: Modality

    def __new__(cls, query: Modality | str, gallery: Modality | str) -> Pair:
        q, g = Modality.of(query), Modality.of(gallery)
        self = super().__new__(cls, f"{q.value}{cls.SEPARATOR}{g.value}")
        object.__setattr__(self, "query", q)
        object.__setattr__(self, "gallery", g)
        return self

    @classmethod
    def parse(cls, text: str) -> Pair:
        """``"touch_to_depth"`` (or a `Pair`) -> ``Pair(Modality.TOUCH, Modality.DEPTH)``.

        Raises:
            ValueError: naming the text and the form a pair takes.
        """
        if isinstance(text, Pair):
            return text
        if not isinstance(text, str):
            raise ValueError(f"{text!r} is not a modality pair; expected query_to_gallery")
        q, sep, g = text.partition(cls.SEPARATOR)
        try:
            if not sep:
                raise ValueError
            return cls(q, g)
        except ValueError:
            valid = ", ".join(m.value for m in Modality)
            raise ValueError(
                f"{text!r} is not a modality pair query_to_gallery (e.g. touch_to_depth) of "
                f"the modalities {valid}"
            ) from None

    @classmethod
    def every(cls, modalities: Iterable[Modality]) -> list[Pair]:
        """Every ordered pair of ``modalities``, same-modality pairs included, query-major."""
        mods = list(modalities)
        return [cls(q, g) for q in mods for g in mods]

    @property
    def same(self) -> bool:
        """Query and gallery are one modality (``depth_to_depth``)."""
        return self.query is self.gallery

    def reverse(self) -> Pair:
        """The pair the other way round: ``touch_to_depth`` -> ``depth_to_touch``."""
        return Pair(self.gallery, self.query)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"Pair is immutable; cannot set {name!r}")

    def __reduce__(self) -> tuple[type[Pair], tuple[str, str]]:
        return (Pair, (self.query.value, self.gallery.value))


def parse_modalities(text: str | list[str] | tuple[str, ...]) -> tuple[Modality, ...]:
    """Parse ``"depth,touch"`` (or a list of names) into modalities, keeping order.

    Raises:
        ModalityError: naming the unknown value and the valid ones (a ``ValueError``).
        ValueError: no modality given.
    """
    names = [t.strip() for t in text.split(",")] if isinstance(text, str) else list(text)
    out: list[Modality] = []
    for name in names:
        if not name:
            continue
        m = Modality.of(name)
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
