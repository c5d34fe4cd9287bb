"""The background control: each image's background replaced by another fabric's, cloth kept.

A model that recognises the material, not the capture session, scores the same on such images;
one that reads the wall or the floor drops (issue #12: 0.890 -> 0.802 top-1 when only the wall
is swapped). `swap_backgrounds` builds the swapped batch from cloth masks (from
`lookfeel.data.register.register_depth` or any other segmentation):

- every image ``i`` is paired with an image ``j`` of *another* fabric, drawn uniformly and
  reproducibly from ``seed``;
- the output is image ``i`` where ``i`` shows cloth, and image ``j``'s background elsewhere;
- where ``j`` shows cloth but ``i`` does not, ``j``'s background is unknown: it is taken from
  ``rooms[j]`` (the fitted empty room) when given, else from ``j``'s nearest background pixel.

So no pixel of the output comes from ``i``'s background or from any cloth but ``i``'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from lookfeel.errors import LookfeelError

__all__ = ["SwappedBatch", "pair_other_fabric", "swap_backgrounds"]


@dataclass(frozen=True)
class SwappedBatch:
    """`swap_backgrounds`' result.

    Attributes:
        images: (N, H, W) the swapped images, dtype of the input.
        partner: (N,) index of the image whose background each image received.
    """

    images: NDArray[np.generic]
    partner: NDArray[np.int64]


def pair_other_fabric(fabric_ids: ArrayLike, seed: int = 0) -> NDArray[np.int64]:
    """(N,) for each item, a uniformly drawn index of an item of another fabric.

    Deterministic for a given ``seed`` and ``fabric_ids``.

    Raises:
        LookfeelError: fewer than two fabrics (no other fabric to draw from).
    """
    fab = np.asarray(fabric_ids).reshape(-1)
    n = len(fab)
    if len(np.unique(fab)) < 2:
        raise LookfeelError(
            f"background swap needs images of two or more fabrics; got {len(np.unique(fab))}"
        )
    rng = np.random.default_rng(seed)
    order = np.argsort(fab, kind="stable")
    sorted_fab = fab[order]
    starts = np.searchsorted(sorted_fab, fab, side="left")
    ends = np.searchsorted(sorted_fab, fab, side="right")
    own = ends - starts
    # A uniform draw among the n - own items of other fabrics: draw a rank among them and
    # skip over the own fabric's block in the fabric-sorted order.
    r = np.floor(rng.random(n) * (n - own)).astype(np.int64)
    pos = np.where(r < starts, r, r + own)
    return order[pos].astype(np.int64)


def swap_backgrounds(
    images: ArrayLike,
    cloth: ArrayLike,
    fabric_ids: ArrayLike,
    *,
    seed: int = 0,
    rooms: ArrayLike | None = None,
) -> SwappedBatch:
    """Replace each image's background with another fabric's image's background (module doc).

    Args:
        images: (N, H, W) depth images (any dtype; e.g. millimetres or [0, 1]).
        cloth: (N, H, W) bool, True where the image shows cloth.
        fabric_ids: (N,) each image's fabric.
        seed: seeds the pairing.
        rooms: optional (N, H, W) each image's empty room (same units as ``images``), used
            where the partner's own cloth hides its background.

    Returns:
        A `SwappedBatch`.

    Raises:
        LookfeelError: shapes disagree, or fewer than two fabrics.
    """
    x = np.asarray(images)
    m = np.asarray(cloth, dtype=bool)
    fab = np.asarray(fabric_ids).reshape(-1)
    if x.ndim != 3 or m.shape != x.shape or len(fab) != len(x):
        raise LookfeelError(
            f"background swap: images {x.shape}, cloth masks {m.shape} and {len(fab)} fabric "
            "ids must agree as (N, H, W), (N, H, W), (N,)"
        )
    room = None if rooms is None else np.asarray(rooms)
    if room is not None and room.shape != x.shape:
        raise LookfeelError(f"background swap: rooms {room.shape} must match images {x.shape}")
    partner = pair_other_fabric(fab, seed)
    out = x.copy()
    for i, j in enumerate(partner):
        back = _background_of(x[j], m[j], None if room is None else room[j])
        out[i] = np.where(m[i], x[i], back)
    return SwappedBatch(out, partner)


def _background_of(
    image: NDArray[np.generic], cloth: NDArray[np.bool_], room: NDArray[np.generic] | None
) -> NDArray[np.generic]:
    """The image with its cloth replaced by the room (or the nearest background pixel)."""
    if not cloth.any():
        return image
    if room is not None:
        return np.where(cloth, room, image).astype(image.dtype)
    if cloth.all():  # no background at all: nothing better than the image itself
        return image
    idx = ndimage.distance_transform_edt(cloth, return_distances=False, return_indices=True)
    return image[tuple(idx)]
