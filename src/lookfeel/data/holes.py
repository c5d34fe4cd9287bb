"""Depth holes: pixels with no sensor reading (0), filled from the nearest reading.

Its own module so that decoding (`lookfeel.data.images`) and scene registration
(`lookfeel.data.register`) share it without importing each other.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["fill_holes"]


def fill_holes(depth: np.ndarray) -> np.ndarray:
    """Fill pixels equal to 0 with the value of the nearest non-zero pixel.

    Args:
        depth: (H, W) array; 0 marks a hole.

    Returns:
        A filled copy (same dtype); an image with no valid pixel is returned unchanged.
    """
    holes = depth == 0
    if not holes.any() or holes.all():
        return depth.copy()
    idx = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
    return depth[tuple(idx)]
