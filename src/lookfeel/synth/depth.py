"""Kinect-like depth images of a drape: 16-bit millimetres, 0 where there is no reading.

The room comes from `lookfeel.synth.scene`; the cloth is z-buffered from its dense surface grid
(small gaps between samples closed from their neighbours). Then the sensor: a time-of-flight
camera's noise grows with distance (about 1 mm at 0.8 m, 3 mm at 1.4 m), readings are whole
millimetres, and "flying pixels" at depth edges are dropped (the real files have 0.2-2% holes,
mostly along silhouettes), with a few isolated dropouts elsewhere.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from lookfeel.synth.drape import Surface
from lookfeel.synth.scene import Camera, background_depth, close_pinholes, splat

__all__ = ["cloth_depth", "render_depth"]

F32 = NDArray[np.float32]


def cloth_depth(
    surface: Surface, camera: Camera
) -> tuple[F32, NDArray[np.int64], NDArray[np.int64]]:
    """Z-buffer of the cloth alone (inf where no cloth), with the splat's pixel/point indices.

    Pixels that no sample of the front layer reached (empty, or showing a layer behind it)
    are filled from their neighbours, so the cloth has no pinholes where it is seen obliquely.
    """
    pts = camera.to_camera(surface.xyz.reshape(-1, 3))
    zbuf, pix, keep = splat(camera, pts)
    zbuf, _ = close_pinholes(zbuf)
    return zbuf, pix, keep


def render_depth(surface: Surface, camera: Camera, rng: np.random.Generator) -> NDArray[np.uint16]:
    """One depth image of the draped cloth in the room, as the Kinect would record it.

    Returns:
        (H, W) uint16 depth in millimetres; 0 = no reading.
    """
    cloth, _, _ = cloth_depth(surface, camera)
    room = background_depth(camera)
    z = np.minimum(room, cloth).astype(np.float32)
    h, w = z.shape
    sigma = 0.5 + 1.5 * (z / 1000.0) ** 2
    z = z + sigma * rng.standard_normal((h, w), dtype=np.float32)
    # Flying pixels: where depth jumps, the pixel on the far side mixes two returns; the
    # sensor drops most of them.
    lo = ndimage.minimum_filter(z, 3)
    hi = ndimage.maximum_filter(z, 3)
    edge = (hi - lo) > 35.0
    far = z - lo > 0.5 * (hi - lo)
    drop = edge & (far | (rng.random((h, w)) < 0.2)) & (rng.random((h, w)) < 0.25)
    drop |= rng.random((h, w)) < 0.0008
    out = np.clip(np.rint(z), 1, 65535).astype(np.uint16)
    out[drop] = 0
    return out
