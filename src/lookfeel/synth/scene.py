"""The capture rig: the cylindrical post in a corner of a room, seen by a Kinect-like camera.

World frame: millimetres, origin at the foot of the post on the floor, ``z`` up, ``y`` away from
the camera (towards the back wall), ``x`` to the camera's right.

The room and the camera were calibrated once against the real GelFabric depth images (224x224,
``shared/data/gelfabric/depth``): in each real image the floor, the back wall and the panel on
the right are planes, and a plane is linear in inverse depth over the image, so three planes
were fitted to the pixels where no fabric lies (residual 1-5 mm). The fitted planes are mutually
perpendicular (dot products below 0.03) for a focal length of 373 px, which fixes the camera:
557 mm above the floor, pitched down 27 degrees, the wall 1.29 m away. The post (paper section
3: 30.7 cm high, 6.3 cm across) stands where the top of the drape appears in the real images.
Only these few numbers are kept here; no real image is read at run time.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from lookfeel.rig import GELFABRIC_CENTRE, GELFABRIC_FOCAL, GELFABRIC_SIZE

__all__ = [
    "POST_HEIGHT_MM",
    "POST_RADIUS_MM",
    "Camera",
    "background_depth",
    "background_plane_index",
    "close_pinholes",
    "color_camera",
    "depth_camera",
    "splat",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

POST_HEIGHT_MM = 307.0
POST_RADIUS_MM = 31.5

# Calibration at the real images' size (224 px): focal length and principal point.
_REF_SIZE = GELFABRIC_SIZE
_REF_F = GELFABRIC_FOCAL
_REF_C = GELFABRIC_CENTRE
# Unit normals (camera coordinates, x right, y down, z forward) and distances of the room's
# planes, from the inverse-depth fit described above.
_FLOOR_N = np.array([-0.0605, 0.8865, 0.4587])
_FLOOR_D = 557.2
_WALL_N = np.array([-0.1529, -0.4647, 0.8721])
_WALL_D = 1293.1
_PANEL_N = np.array([0.9828, -0.0257, 0.1831])
_PANEL_D = 558.9
# Where the post stands: the centre of its top appears at pixel (113, 20) in the real images.
_POST_TOP_PX = (113.0, 20.0)


def _world_axes() -> tuple[F64, F64]:
    """Rotation camera->world (rows are the world axes in camera coordinates), post foot."""
    ez = -_FLOOR_N / np.linalg.norm(_FLOOR_N)
    ey = _WALL_N - (_WALL_N @ ez) * ez
    ey /= np.linalg.norm(ey)
    ex = np.cross(ey, ez)
    rot = np.stack([ex, ey, ez])
    u, v = _POST_TOP_PX
    ray = np.array([(u - _REF_C) / _REF_F, (v - _REF_C) / _REF_F, 1.0])
    # The point on that ray at the height of the post's top, then straight down to the floor.
    top = ray * (_FLOOR_D - POST_HEIGHT_MM) / (_FLOOR_N @ ray)
    foot = top - POST_HEIGHT_MM * ez
    return rot, foot


_ROT, _FOOT = _world_axes()


@dataclass(frozen=True)
class Camera:
    """A pinhole camera in the rig; images are ``height`` x ``width`` pixels.

    Attributes:
        f: focal length in pixels.
        cx, cy: principal point in pixels (pixel centres at integers).
        width, height: image size.
        rot: (3, 3) world -> camera rotation.
        origin: (3,) the world origin (post foot) in camera coordinates.
    """

    f: float
    cx: float
    cy: float
    width: int
    height: int
    rot: F64
    origin: F64

    def to_camera(self, xyz: F32) -> F32:
        """World points (..., 3) -> camera coordinates (..., 3)."""
        # Written out rather than a matmul: no BLAS threads inside worker processes.
        x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
        r = self.rot.astype(np.float32)
        o = self.origin.astype(np.float32)
        out = np.empty(xyz.shape, np.float32)
        for j in range(3):
            out[..., j] = x * r[0, j] + y * r[1, j] + z * r[2, j] + o[j]
        return out

    def rays(self) -> F64:
        """Per-pixel ray directions in camera coordinates with z = 1, shape (H, W, 3)."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        return np.stack([(u - self.cx) / self.f, (v - self.cy) / self.f, np.ones_like(u)], -1)


def depth_camera(size: int) -> Camera:
    """The Kinect-like depth camera at ``size`` x ``size`` pixels (calibrated at 224)."""
    s = size / _REF_SIZE
    c = (_REF_C + 0.5) * s - 0.5
    # rot maps world -> camera: camera = world @ rot + origin with rot = _ROT (rows = axes).
    return Camera(_REF_F * s, c, c, size, size, _ROT, _FOOT)


def color_camera(size: int) -> Camera:
    """The colour (SLR) camera: beside the Kinect, framing the draped fabric at ``size``^2."""
    s = size / _REF_SIZE
    # A slightly longer lens, centred lower so the photo is "cropped to the fabric".
    f = _REF_F * s * 1.12
    c = (_REF_C + 0.5) * s - 0.5
    # The SLR sits 60 mm right of the Kinect (same orientation): the world moves left.
    origin = _FOOT - 60.0 * _ROT[0]
    return Camera(f, c, c + 8.0 * s, size, size, _ROT, origin)


def _plane_depths(camera: Camera) -> F64:
    """Depth of floor, wall and panel along each pixel's ray, shape (3, H, W)."""
    rays = camera.rays()
    moved = _FOOT - camera.origin  # camera position relative to the Kinect, camera axes
    zs = []
    for n, d in ((_FLOOR_N, _FLOOR_D), (_WALL_N, _WALL_D), (_PANEL_N, _PANEL_D)):
        d_eff = d - n @ moved
        denom = rays @ n
        zs.append(np.where(denom > 1e-6, d_eff / np.maximum(denom, 1e-6), np.inf))
    return np.stack(zs)


@lru_cache(maxsize=8)
def _room_cached(key: tuple[float, ...]) -> tuple[F32, NDArray[np.int8]]:
    f, cx, cy, w, h, ox, oy, oz = key
    cam = Camera(f, cx, cy, int(w), int(h), _ROT, np.array([ox, oy, oz]))
    zs = _plane_depths(cam)
    depth = zs.min(axis=0).astype(np.float32)
    index = np.argmin(zs, axis=0).astype(np.int8)
    depth.setflags(write=False)
    index.setflags(write=False)
    return depth, index


def _room(camera: Camera) -> tuple[F32, NDArray[np.int8]]:
    key = (camera.f, camera.cx, camera.cy, camera.width, camera.height, *camera.origin.tolist())
    return _room_cached(tuple(float(k) for k in key))


def background_depth(camera: Camera) -> F32:
    """Depth (mm along the optical axis) of the empty room, (H, W); cached per camera."""
    return _room(camera)[0]


def background_plane_index(camera: Camera) -> NDArray[np.int8]:
    """Which room plane each pixel sees: 0 floor, 1 wall, 2 panel; (H, W), cached."""
    return _room(camera)[1]


def splat(camera: Camera, xyz_cam: F32) -> tuple[F32, NDArray[np.int64], NDArray[np.int64]]:
    """Z-buffer points into the image.

    Args:
        camera: the camera.
        xyz_cam: (N, 3) points in camera coordinates.

    Returns:
        ``zbuf`` (H, W) nearest depth per pixel (inf where no point fell), ``pix`` the flat
        pixel index of each kept point, ``keep`` the indices of the points inside the image.
    """
    z = xyz_cam[:, 2]
    inv = camera.f / np.maximum(z, 1.0)
    u = np.rint(xyz_cam[:, 0] * inv + camera.cx).astype(np.int64)
    v = np.rint(xyz_cam[:, 1] * inv + camera.cy).astype(np.int64)
    ok = (z > 1.0) & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    keep = np.flatnonzero(ok)
    pix = v[keep] * camera.width + u[keep]
    zbuf = np.full(camera.width * camera.height, np.inf, np.float32)
    np.minimum.at(zbuf, pix, z[keep])
    return zbuf.reshape(camera.height, camera.width), pix, keep


def close_pinholes(zbuf: F32, step_mm: float = 20.0) -> tuple[F32, NDArray[np.bool_]]:
    """Fill pixels where the front layer of cloth was missed between samples.

    Such a pixel is empty, or shows a layer behind: most (5 of 8) of its neighbours are nearer
    by more than ``step_mm``. On a slope seen edge-on only about half are, so slopes survive.

    Returns:
        The filled buffer (inf where still empty) and the mask of filled pixels.
    """
    big = np.where(np.isfinite(zbuf), zbuf, np.float32(1e5)).astype(np.float32)
    pad = np.pad(big, 1, mode="edge")
    h, w = big.shape
    cnt = np.zeros((h, w), np.float32)
    tot = np.zeros((h, w), np.float32)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            if dy == 1 and dx == 1:
                continue
            nb = pad[dy : dy + h, dx : dx + w]
            closer = nb < big - step_mm
            cnt += closer
            tot += np.where(closer, nb, 0.0)
    hole = cnt >= 5
    out = np.where(hole, tot / np.maximum(cnt, 1.0), big)
    out = np.where(out >= 1e5 - 1, np.float32(np.inf), out).astype(np.float32)
    return out, hole
