"""Depth holes: pixels with no sensor reading (0), filled from the nearest reading.

Its own module so that decoding (`lookfeel.data.images`) and scene registration
(`lookfeel.data.register`) share it without importing each other.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

__all__ = ["UNSEEN_REGION", "fill_holes", "unseen_regions"]


def fill_holes(depth: np.ndarray) -> np.ndarray:
    """Fill pixels equal to 0 with the value of the nearest non-zero pixel.

    Args:
        depth: (H, W) array; 0 marks a hole.

    Returns:
        A filled copy (same dtype); an image with no valid pixel is returned unchanged (all
        0: `lookfeel.data.images.ImageLoader` warns that it reads such an image as blank,
        `lookfeel.data.images.BlankDepthWarning`).
    """
    holes = depth == 0
    if not holes.any() or holes.all():
        return depth.copy()
    idx = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
    return depth[tuple(idx)]


UNSEEN_REGION = 0.01
"""`unseen_regions`: a connected region without a reading that covers this share of the image
or more is left out of registration (GelFabric's largest covers 0.46%)."""


def unseen_regions(d: NDArray[np.generic]) -> NDArray[np.bool_] | None:
    """The pixels of large regions without a reading (0) in a depth image ``d``, or None when
    there are none.

    Filling a hole from its nearest neighbours (`fill_holes`) is a fair guess for the small
    holes a depth camera leaves at edges and dark spots, and registration uses the filled
    image. A large region with no reading (a band along the image's edge, the blind corner of
    another camera) would be filled with a flat copy of its rim, which is neither room nor
    cloth: it would pull the room's planes and stand as cloth in front of them. Such regions
    (`UNSEEN_REGION` of the image or more) are left out of `lookfeel.data.register` instead.
    GelFabric's Kinect images and the synthetic world's have none, so their registration is
    unchanged by this."""
    holes = np.asarray(d) <= 0
    size = UNSEEN_REGION * holes.size
    if holes.sum() < size:
        return None
    lab, _ = ndimage.label(holes)
    big = np.bincount(lab.ravel())[1:] >= size
    if not big.any():
        return None
    return np.concatenate([[False], big])[lab]
