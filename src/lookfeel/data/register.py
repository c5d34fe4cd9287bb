"""Scene registration for depth: fit the room in each image, keep only the cloth, relative to it.

A depth image of a drape shows the cloth in front of a room (floor, back wall, a side panel).
Between capture sessions the camera and the room sit a few millimetres differently, and that is
enough to tell sessions, hence fabrics, apart (`lookfeel.data.leakage`). `register_depth`
removes it, per image, with no calibration of the rig:

1. **Room planes.** A plane seen by a pinhole camera is linear in *inverse* depth over the
   image, ``1/z = a u + b v + c``, whatever the camera's pose and focal length, so the planes
   are fitted in image space. A sequential RANSAC finds up to ``max_planes`` planes: each
   hypothesis (three pixels) is scored by its inliers (within ``inlier_mm`` of the plane, in
   depth) minus a heavy penalty for pixels *behind* it, since no pixel can lie behind the
   room's walls; a plane through the cloth has the wall behind it and loses. The winner is
   refined by least squares on its inliers (weighted so residuals are in millimetres), and
   rejected (its pixels set aside, the search goes on) when more than 1% of the image lies
   behind it or, with ``box_deg``, when it is not square to the planes already found.
2. **Cloth.** The room's depth at a pixel is the nearest of its planes along the ray (the room
   is a convex box around the camera). Cloth is every pixel more than ``margin_mm`` in front of
   it; strips thinner than a few pixels (the room's corners, flying pixels) and specks smaller
   than ``min_blob`` pixels are dropped.
3. **Registered geometry.** With the camera's intrinsics (default: GelFabric's crop, scaled
   to the image) each plane becomes a normal and a distance in the camera frame; the plane
   whose normal points down the image is the floor, the one facing the camera the wall. The
   registered image is the cloth's height above the fitted floor (its distance in front of the
   nearest room plane when no floor was found), in millimetres, and 0 where there is no cloth.
   The post is the cloth's top (the drape hangs from it): `Registration.post_uv`.

A room moved by a few millimetres changes the raw depth of every background pixel but neither
the cloth mask nor the registered image (tests move it and check).

`registered_input` is the training input (``data.depth_input: registered``): the registered
image with, by default (``data.depth_cloth: drape``), only the drape kept: the cloth region
holding the post (`drape_mask`). Objects that stand in the room apart from the cloth (on
GelFabric, a strip along the left edge some 20 mm above the floor, cloth in 88% of the images
by the margin rule) are scene: their few-mm shifts between sessions would leak the session.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from lookfeel.config import DataConfig
from lookfeel.data.holes import fill_holes, unseen_regions
from lookfeel.errors import LookfeelError
from lookfeel.rig import GELFABRIC_CENTRE, GELFABRIC_FOCAL, GELFABRIC_SIZE

__all__ = [
    "Intrinsics",
    "Plane",
    "Registration",
    "RegistrationError",
    "camera_points",
    "drape_mask",
    "drape_post",
    "drape_top",
    "drop_near_walls",
    "heights_from_top",
    "kept_heights",
    "move_drape",
    "placed_heights",
    "plane_gaps",
    "register_configured",
    "register_depth",
    "register_in_room",
    "registered_heights",
    "registered_input",
    "registered_intrinsics",
    "wall_gap_input",
    "wall_gaps",
    "without_cap",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
TopRule = Literal["first_rows", "highest_row", "cloth_top"]


class RegistrationError(LookfeelError):
    """A depth image in which no room could be found (the message says what is missing)."""


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera: focal length and principal point in pixels (pixel centres at integers)."""

    f: float
    cx: float
    cy: float

    @classmethod
    def gelfabric(cls, width: int = GELFABRIC_SIZE, height: int = GELFABRIC_SIZE) -> Intrinsics:
        """GelFabric's Kinect crop (calibrated at 224 px), scaled to ``width`` x ``height``."""
        s = width / GELFABRIC_SIZE
        return cls(
            GELFABRIC_FOCAL * s,
            (GELFABRIC_CENTRE + 0.5) * s - 0.5,
            (GELFABRIC_CENTRE + 0.5) * height / GELFABRIC_SIZE - 0.5,
        )


@dataclass(frozen=True)
class Plane:
    """One fitted room plane.

    Attributes:
        coef: (a, b, c) with ``1/z = a u + b v + c`` (z in mm, u column, v row).
        normal: unit normal in the camera frame (x right, y down, z forward), pointing away
            from the camera: points X on the plane satisfy ``normal . X = distance``.
        distance: the camera's distance to the plane (mm).
        label: ``"floor"``, ``"wall"`` or ``"side"``.
        inlier_fraction: share of the image's pixels within ``inlier_mm`` of it.
    """

    coef: tuple[float, float, float]
    normal: tuple[float, float, float]
    distance: float
    label: str
    inlier_fraction: float

    def depth(self, u: F64, v: F64) -> F64:
        """Depth (mm) of the plane along each pixel's ray; inf where the ray misses it."""
        a, b, c = self.coef
        p = a * u + b * v + c
        with np.errstate(divide="ignore"):
            return np.where(p > 1e-12, 1.0 / np.maximum(p, 1e-12), np.inf)


@dataclass(frozen=True)
class Registration:
    """`register_depth`'s result for one image (arrays are (H, W)).

    Attributes:
        planes: the fitted room planes, largest first.
        room: the fitted empty room's depth (mm).
        cloth: True where the cloth is (more than the margin in front of the room).
        height: the cloth's height above the fitted floor (mm; without a floor, its distance
            in front of the nearest room plane), 0 off the cloth: the registered image.
        clearance: the cloth's distance in front of the nearest room plane (mm), 0 off it.
        post_uv: (u, v) pixel of the cloth's top, where the post holds it; None without cloth.
        residual_mm: median absolute depth residual of the room's inlier pixels.
        wall_clearance: each pixel's distance in front of the nearest fitted plane other than
            the floor (mm; inf where only a floor was fitted), or None (a registration made
            by hand): what ``data.depth_wall_band_mm`` reads (`kept_heights`).
    """

    planes: tuple[Plane, ...]
    room: F32
    cloth: NDArray[np.bool_]
    height: F32
    clearance: F32
    post_uv: tuple[float, float] | None
    residual_mm: float
    wall_clearance: F32 | None = None

    def plane(self, label: str) -> Plane | None:
        """The plane labelled ``label`` (``"floor"``, ``"wall"``), if one was found."""
        return next((p for p in self.planes if p.label == label), None)


def _fit_inverse(u: F64, v: F64, z: F64) -> F64:
    """Least-squares (a, b, c) of 1/z = a u + b v + c, weighted so residuals are in mm."""
    w = z**2  # d(1/z) = -dz / z^2: scaling by z^2 makes the residual a depth residual
    a = np.stack([u, v, np.ones_like(u)], axis=1) * w[:, None]
    coef, *_ = np.linalg.lstsq(a, w / z, rcond=None)
    return np.asarray(coef, dtype=np.float64)


def _residual(coef: F64, u: F64, v: F64, z: F64) -> F64:
    """(..., N) z minus the plane's depth; -inf where the ray misses the plane (never behind).

    ``coef`` is (3,) or (K, 3) for K hypotheses at once.
    """
    c = np.atleast_2d(coef)
    p = c[:, 0:1] * u[None] + c[:, 1:2] * v[None] + c[:, 2:3]
    with np.errstate(divide="ignore"):
        zp = np.where(p > 1e-12, 1.0 / np.maximum(p, 1e-12), np.inf)
    r = z[None] - zp
    return r[0] if np.ndim(coef) == 1 else r


def _counts(
    coefs: F64,
    u: F64,
    v: F64,
    z: F64,
    free: NDArray[np.bool_],
    inlier_mm: float,
    behind_mm: float,
    seen: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """For (K, 3) hypotheses: the free pixels within ``inlier_mm`` of each, and the pixels more
    than ``behind_mm`` behind it (of the ``seen`` pixels only, when given: those outside
    `lookfeel.data.holes.unseen_regions`). The numbers `_residual` gives, bit for bit, computed
    in one (K, N) buffer: the registration's hot loop (with a new array at every step,
    registering a GelFabric drape took 41 ms on one thread; so it takes 26 ms:
    `benchmarks/bench_register.py`)."""
    r = coefs[:, 0:1] * u[None]
    r += coefs[:, 1:2] * v[None]
    r += coefs[:, 2:3]
    missed = r <= 1e-12  # the ray misses the plane: depth inf, residual -inf
    np.maximum(r, 1e-12, out=r)
    np.divide(1.0, r, out=r)
    np.copyto(r, np.inf, where=missed)
    np.subtract(z[None], r, out=r)
    behind = np.count_nonzero(
        (r > behind_mm) if seen is None else (r > behind_mm) & seen[None], axis=1
    )
    np.abs(r, out=r)
    inl = np.count_nonzero((r < inlier_mm) & free[None], axis=1)
    return inl, behind


def _ransac_plane(
    u: F64,
    v: F64,
    z: F64,
    free: NDArray[np.bool_],
    grid: tuple[int, int],
    rng: np.random.Generator,
    iterations: int,
    inlier_mm: float,
    behind_mm: float,
    seen: NDArray[np.bool_] | None = None,
) -> tuple[F64, NDArray[np.bool_]] | None:
    """The best plane among ``free`` pixels: most inliers, nearly nothing (``seen``) behind it.

    Half the hypotheses draw three pixels anywhere, half draw two more near a first one (within
    a tenth of the image): a plane that fills 5% of the image is then still drawn often.
    """
    idx = np.flatnonzero(free)
    if len(idx) < 3:
        return None
    hs, ws = grid
    n_glob = iterations // 2
    glob = idx[rng.integers(0, len(idx), (n_glob, 3))]
    first = idx[rng.integers(0, len(idx), iterations - n_glob)]
    r0, c0 = np.divmod(first, ws)
    rad = max(2, max(hs, ws) // 10)
    rr = np.clip(r0[:, None] + rng.integers(-rad, rad + 1, (len(first), 2)), 0, hs - 1)
    cc = np.clip(c0[:, None] + rng.integers(-rad, rad + 1, (len(first), 2)), 0, ws - 1)
    local = np.concatenate([first[:, None], rr * ws + cc], axis=1)
    local = local[free[local].all(axis=1)]
    picks = np.concatenate([glob, local])
    a = np.stack([u[picks], v[picks], np.ones(picks.shape)], axis=2)  # (K, 3, 3)
    ok = np.abs(np.linalg.det(a)) > 1e-6
    if not ok.any():
        return None
    coefs = np.linalg.solve(a[ok], (1.0 / z[picks[ok]])[..., None])[..., 0]  # (K, 3)
    best: tuple[float, F64] | None = None
    for chunk in np.array_split(coefs, max(1, len(coefs) // 64)):
        inl, behind = _counts(chunk, u, v, z, free, inlier_mm, behind_mm, seen)
        score = inl - 20.0 * behind
        j = int(np.argmax(score))
        if best is None or score[j] > best[0]:
            best = (float(score[j]), chunk[j])
    assert best is not None
    coef = best[1]
    for _ in range(3):  # refine on the inliers, then re-select them
        inliers = free & (np.abs(_residual(coef, u, v, z)) < inlier_mm)
        if inliers.sum() < 3:
            return None
        coef = _fit_inverse(u[inliers], v[inliers], z[inliers])
    inliers = free & (np.abs(_residual(coef, u, v, z)) < inlier_mm)
    return coef, inliers


def _metric(coef: F64, k: Intrinsics) -> tuple[F64, float]:
    """Inverse-depth coefficients -> camera-frame unit normal and distance (n . X = d)."""
    a, b, c = coef
    w = np.array([a * k.f, b * k.f, c + a * k.cx + b * k.cy])  # = n / d
    d = 1.0 / float(np.linalg.norm(w))
    return w * d, d


def _labels(normals: list[F64]) -> list[str]:
    labels = ["side"] * len(normals)
    if not normals:
        return labels
    ny = [n[1] for n in normals]
    floor = int(np.argmax(ny))
    if ny[floor] > 0.5:  # the normal points down the image (camera y is down)
        labels[floor] = "floor"
    rest = [i for i in range(len(normals)) if labels[i] == "side"]
    if rest:
        wall = max(rest, key=lambda i: normals[i][2])
        if normals[wall][2] > 0.5:  # faces the camera
            labels[wall] = "wall"
    return labels


def _post(cloth: NDArray[np.bool_]) -> tuple[float, float] | None:
    """The top of the largest cloth region: (u, v) mean over its top two rows."""
    lab, n = ndimage.label(cloth)
    if n == 0:
        return None
    sizes = np.bincount(lab.ravel())[1:]
    main = lab == (1 + int(np.argmax(sizes)))
    rows = np.flatnonzero(main.any(axis=1))
    top = rows[0]
    vv, uu = np.nonzero(main[top : top + 2])
    return float(uu.mean()), float(top + vv.mean())


def register_depth(
    depth_mm: NDArray[np.generic],
    intrinsics: Intrinsics | None = None,
    *,
    margin_mm: float = 15.0,
    inlier_mm: float = 8.0,
    max_planes: int = 4,
    min_plane_fraction: float = 0.03,
    min_blob: int | None = None,
    open_px: int | None = None,
    box_deg: float | None = 20.0,
    iterations: int = 400,
    stride: int | None = None,
    seed: int = 0,
) -> Registration:
    """Fit the room of one depth image and express the cloth relative to it (module doc).

    Args:
        depth_mm: (H, W) depth in millimetres, 0 where the sensor had no reading.
        intrinsics: the camera; default `Intrinsics.gelfabric` scaled to the image. Only the
            metric outputs (normals, heights, labels) use it; planes and cloth do not.
        margin_mm: cloth is more than this in front of the fitted room.
        inlier_mm: a pixel within this of a plane (in depth) belongs to it.
        max_planes: room planes to look for (GelFabric: floor, back wall, side panel, and
            sometimes the panel's edge).
        min_plane_fraction: a plane must hold this share of the pixels.
        min_blob: cloth regions smaller than this many pixels are dropped (default 0.1% of
            the image).
        open_px: radius (px) of the morphological opening that removes strips thinner than
            about twice it (the room's edges and corners, flying pixels at the cloth's rim);
            default: 2 px at 224 px, scaled with the image.
        box_deg: a plane after the first must be square (within this many degrees) to every
            plane found before it, as a room's walls and floor are; None: any plane.
        iterations: RANSAC hypotheses per plane.
        stride: the fit uses every ``stride``-th pixel in each direction (speed); default:
            about 64 pixels along the longer side.
        seed: seeds the RANSAC draws (the result is deterministic).

    Returns:
        A `Registration`.

    Raises:
        RegistrationError: the image has no valid pixel or no plane could be fitted.
    """
    d = np.asarray(depth_mm)
    if d.ndim != 2:
        raise RegistrationError(f"depth image must be 2-D (H, W); got shape {d.shape}")
    if not (d > 0).any():
        raise RegistrationError("depth image has no valid pixel (all 0)")
    h, w = d.shape
    k = intrinsics or Intrinsics.gelfabric(w, h)
    z_full = fill_holes(d).astype(np.float64)
    vg, ug = np.mgrid[0:h, 0:w].astype(np.float64)
    step = max(1, round(max(h, w) / 64)) if stride is None else stride
    sub = (slice(None, None, step), slice(None, None, step))
    u, v, z = ug[sub].ravel(), vg[sub].ravel(), z_full[sub].ravel()
    rng = np.random.default_rng(seed)
    unseen = unseen_regions(d)
    seen = None if unseen is None else ~unseen[sub].ravel()
    if seen is not None and seen.sum() < 3:
        raise RegistrationError("depth image has almost no valid pixel")
    free = np.ones(len(z), dtype=bool) if seen is None else seen.copy()
    n_seen = len(z) if seen is None else int(seen.sum())
    found: list[tuple[F64, float]] = []
    behind_mm = max(margin_mm, 2.0 * inlier_mm)
    for _ in range(2 * max_planes):  # a rejected candidate costs an attempt, not the search
        if len(found) == max_planes:
            break
        fit = _ransac_plane(
            u, v, z, free, z_full[sub].shape, rng, iterations, inlier_mm, behind_mm, seen
        )
        if fit is None:
            break
        coef, inliers = fit
        if inliers.sum() < min_plane_fraction * n_seen:
            break
        r = _residual(coef, u, v, z)
        far = r > behind_mm if seen is None else (r > behind_mm)[seen]
        behind = far.mean() > 0.01  # part of the room lies behind it
        if not behind and box_deg is not None and found:
            n_new = _metric(coef, k)[0]
            cos = [abs(float(n_new @ _metric(c, k)[0])) for c, _ in found]
            behind = max(cos) > np.sin(np.radians(box_deg))  # not square to the room
        if behind:  # cloth (a heap covering the floor, a flat fold): not a room plane
            free &= ~inliers
            continue
        found.append((coef, float(inliers.mean() if seen is None else inliers.sum() / n_seen)))
        # Also retire what lies just above it (cloth lying flat on the floor), so the next
        # plane found is another wall, not the floor again a few millimetres higher.
        free &= ~((r > -behind_mm) & (r < inlier_mm))
    if not found:
        raise RegistrationError("no room plane found: no large flat background in the image")
    metric = [_metric(c, k) for c, _ in found]
    labels = _labels([n for n, _ in metric])
    planes = tuple(
        Plane(
            coef=(float(c[0]), float(c[1]), float(c[2])),
            normal=(float(n[0]), float(n[1]), float(n[2])),
            distance=dist,
            label=lab,
            inlier_fraction=frac,
        )
        for (c, frac), (n, dist), lab in zip(found, metric, labels, strict=True)
    )
    return _in_room(z_full, planes, k, margin_mm, inlier_mm, min_blob, open_px, step, unseen)


def register_in_room(
    depth_mm: NDArray[np.generic],
    planes: tuple[Plane, ...],
    intrinsics: Intrinsics | None = None,
    *,
    margin_mm: float = 15.0,
    inlier_mm: float = 8.0,
    min_blob: int | None = None,
    open_px: int | None = None,
    stride: int | None = None,
) -> Registration:
    """Steps 2 and 3 of the module doc for a room already fitted: the cloth of ``depth_mm``
    and its heights relative to ``planes``, with no fit of its own.

    `register_depth` calls it with the planes it fitted on the same image. Given the planes
    fitted on *another* image of the same camera (`Registration.planes`), it registers this
    image as if it had been taken in that image's room: the room control of ``lookfeel cv``
    (`lookfeel.data.background_swap.BackgroundControl.room_loader`).

    Args:
        depth_mm: (H, W) depth in millimetres, 0 where the sensor had no reading.
        planes: the room (at least one plane), in this image's pixel grid.
        intrinsics, margin_mm, inlier_mm, min_blob, open_px, stride: as `register_depth`.
            ``intrinsics`` only sets the cloth's 3-D points; the planes' normals and distances
            are used as given.

    Raises:
        RegistrationError: the image is not 2-D or ``planes`` is empty.
    """
    d = np.asarray(depth_mm)
    if d.ndim != 2:
        raise RegistrationError(f"depth image must be 2-D (H, W); got shape {d.shape}")
    if not planes:
        raise RegistrationError("no room plane to register against")
    h, w = d.shape
    k = intrinsics or Intrinsics.gelfabric(w, h)
    step = max(1, round(max(h, w) / 64)) if stride is None else stride
    z_full = fill_holes(d).astype(np.float64)
    return _in_room(
        z_full, planes, k, margin_mm, inlier_mm, min_blob, open_px, step, unseen_regions(d)
    )


def _in_room(
    z_full: F64,
    planes: tuple[Plane, ...],
    k: Intrinsics,
    margin_mm: float,
    inlier_mm: float,
    min_blob: int | None,
    open_px: int | None,
    step: int,
    unseen: NDArray[np.bool_] | None = None,
) -> Registration:
    """`register_in_room` of a depth image whose holes are filled (``z_full``, mm); no cloth
    where the camera saw nothing (``unseen``: `lookfeel.data.holes.unseen_regions`)."""
    h, w = z_full.shape
    vg, ug = np.mgrid[0:h, 0:w].astype(np.float64)
    sub = (slice(None, None, step), slice(None, None, step))
    room = np.min([p.depth(ug, vg) for p in planes], axis=0)
    in_front = room - z_full
    cloth = np.isfinite(room) & (in_front > margin_mm)
    if unseen is not None:
        cloth &= ~unseen
    rad = round(min(h, w) / 112) if open_px is None else open_px
    if rad > 0:  # thin strips along the room's corners and edges are not cloth
        disk = np.hypot(*np.mgrid[-rad : rad + 1, -rad : rad + 1]) <= rad + 0.5
        cloth = ndimage.binary_opening(cloth, structure=disk)
    blob = max(1, int(0.001 * h * w)) if min_blob is None else min_blob
    lab, n = ndimage.label(cloth)
    if n:
        sizes = np.bincount(lab.ravel())
        cloth &= sizes[lab] >= blob
    # Metric geometry: each pixel's 3-D point, its distance in front of each plane.
    gaps = plane_gaps(z_full, planes, k)  # (P, H, W)
    clearance = np.where(cloth, gaps.min(axis=0), 0.0)
    floor = [i for i, p in enumerate(planes) if p.label == "floor"]
    height = np.where(cloth, gaps[floor[0]], 0.0) if floor else clearance
    walls = [i for i, p in enumerate(planes) if p.label != "floor"]
    wall_clearance = gaps[walls].min(axis=0) if walls else np.full((h, w), np.inf)
    resid = -in_front[sub].ravel()
    inl = np.abs(resid) < inlier_mm
    if unseen is not None:
        inl &= ~unseen[sub].ravel()
    return Registration(
        planes=planes,
        room=np.where(np.isfinite(room), room, 0.0).astype(np.float32),
        cloth=cloth,
        height=height.astype(np.float32),
        clearance=clearance.astype(np.float32),
        post_uv=_post(cloth),
        residual_mm=float(np.median(np.abs(resid[inl]))) if inl.any() else float("nan"),
        wall_clearance=wall_clearance.astype(np.float32),
    )


def drape_mask(cloth: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The drape: the largest connected cloth region (8-connected), which holds the post.

    A drape hangs from the post in one piece and spreads on the floor from there; regions
    apart from it are objects standing in the room, not the cloth.
    """
    lab, n = ndimage.label(cloth, structure=np.ones((3, 3), bool))
    if n <= 1:
        return cloth.copy()
    sizes = np.bincount(lab.ravel())
    sizes[0] = 0
    return np.asarray(lab == int(np.argmax(sizes)))


def plane_gaps(z_mm: F64, planes: tuple[Plane, ...] | list[Plane], k: Intrinsics) -> F64:
    """(P, H, W) how far each pixel's point lies in front of each plane (mm, along its
    normal), from the pixels' depth ``z_mm`` (H, W; holes filled)."""
    pts = camera_points(z_mm, k)
    return np.stack([p.distance - pts @ np.asarray(p.normal) for p in planes])


def camera_points(z_mm: F64, k: Intrinsics) -> F64:
    """(H, W, 3) each pixel's point in the camera frame (mm; x right, y down, z forward)
    from its depth ``z_mm`` (H, W)."""
    h, w = z_mm.shape
    vg, ug = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([(ug - k.cx) / k.f * z_mm, (vg - k.cy) / k.f * z_mm, z_mm], axis=-1)


def registered_intrinsics(shape: tuple[int, ...], config: DataConfig) -> Intrinsics | None:
    """The camera of ``config.depth_focal_px`` for an image of ``shape`` (principal point at
    its centre); ``None`` (GelFabric's, scaled) when it is not set."""
    if config.depth_focal_px is None or len(shape) != 2:
        return None
    h, w = shape
    return Intrinsics(config.depth_focal_px, (w - 1) / 2.0, (h - 1) / 2.0)


def register_configured(depth_mm: NDArray[np.generic], config: DataConfig) -> Registration:
    """`register_depth` with ``config``'s camera (``depth_focal_px``; `registered_intrinsics`)
    and margin (``depth_margin_mm``), as every registered run registers its depth.

    Raises:
        RegistrationError: no room could be fitted (the message says what is missing).
    """
    d = np.asarray(depth_mm)
    return register_depth(
        d, registered_intrinsics(d.shape, config), margin_mm=config.depth_margin_mm
    )


def registered_heights(
    depth_mm: NDArray[np.generic], config: DataConfig
) -> tuple[F32, tuple[float, float] | None]:
    """The cloth's heights as ``config`` keeps them, where the camera saw them, and the
    drape's top (`Registration.post_uv`): `registered_input` before the drape is moved.

    Registers with ``config``'s ``depth_margin_mm`` and ``depth_focal_px`` (principal point
    at the image centre; ``None``: GelFabric's crop, scaled) and keeps the cloth as
    ``depth_cloth`` says (``drape``: `drape_mask`; ``all``: every cloth pixel), without the
    cloth lower than ``depth_min_height_mm`` above the floor, and with ``depth_top_mm``
    measured from the drape's top (`heights_from_top`); 0 elsewhere.

    Raises:
        RegistrationError: no room could be fitted, or no cloth stands in front of it (the
            message says what is missing).
    """
    reg = register_configured(depth_mm, config)
    if not reg.cloth.any():  # an input of zeros would train and embed as if it were a drape
        found = ", ".join(p.label for p in reg.planes)
        raise RegistrationError(
            f"no cloth found: nothing stands more than data.depth_margin_mm="
            f"{config.depth_margin_mm:g} mm in front of the fitted room ({found})"
        )
    kept = kept_heights(reg, config)
    return kept, drape_post(reg, kept, config)


def kept_heights(reg: Registration, config: DataConfig, *, band: bool = True) -> F32:
    """`registered_heights` of an image already registered (``reg``, registered with
    ``config``'s margin and camera): the cloth kept and measured as ``config`` says.

    With ``band`` (the default) and ``config.depth_wall_band_mm``, the cloth within that of a
    fitted plane other than the floor, past ``depth_margin_mm``, is not kept
    (`Registration.wall_clearance`; a registration without it keeps its cloth). This comes
    first, so the drape's piece, its top and the heights below it are those of the cloth
    left: a room fitted a few millimetres elsewhere moves none of them. ``band=False`` is the
    image a training draw of ``data.depth_wall_drop`` drops from (`wall_gap_input`)."""
    cloth = reg.cloth
    if band and config.depth_wall_band_mm and reg.wall_clearance is not None:
        cloth = cloth & (reg.wall_clearance > config.depth_margin_mm + config.depth_wall_band_mm)
    if config.depth_cloth == "drape":
        cloth = drape_mask(cloth)
    height = np.where(cloth, reg.height, np.float32(0.0))  # reg.height is 0 off its cloth
    if config.depth_min_height_mm:
        height = np.where(height < config.depth_min_height_mm, np.float32(0.0), height)
    if config.depth_top_mm is not None:
        height = heights_from_top(height, config.depth_top_mm, config.depth_top_from)
    return height.astype(np.float32, copy=False)


def drape_post(reg: Registration, kept: F32, config: DataConfig) -> tuple[float, float] | None:
    """Where the drape's top lies in the image (u, v): `Registration.post_uv`, or with
    ``depth_top_from: cloth_top`` the top of the cloth kept (``kept``, `kept_heights`), whose
    cap of the sensor's mixed pixels is gone."""
    if config.depth_top_mm is not None and config.depth_top_from == "cloth_top":
        return _post(kept > 0)
    return reg.post_uv


def placed_heights(reg: Registration, config: DataConfig) -> F32:
    """`registered_input` of an image already registered (``reg``): `kept_heights` moved
    as ``depth_post_at`` says (`move_drape`, from `drape_post`)."""
    kept = kept_heights(reg, config)
    return move_drape(kept, drape_post(reg, kept, config), config.depth_post_at)


CAP_TOLERANCE_MM = 10.0
"""`without_cap`: the drape's first row stands within this of its highest row median."""


def _top_band(height: F32) -> list[tuple[int, float]]:
    """(row, median height of its cloth) over the drape's top 16 rows (at 224 px, scaled)."""
    cloth = height > 0
    rows = np.flatnonzero(cloth.any(axis=1))
    if len(rows) == 0:
        return []
    band = max(4, round(16 * height.shape[0] / GELFABRIC_SIZE))
    last = min(rows[0] + band, height.shape[0])
    return [
        (r, float(np.median(height[r][cloth[r]]))) for r in range(rows[0], last) if cloth[r].any()
    ]


def without_cap(height: F32, tolerance_mm: float = CAP_TOLERANCE_MM) -> F32:
    """``height`` without the cap of mixed pixels above the drape (``depth_top_from:
    cloth_top``): the rows above the first one whose median height lies within
    ``tolerance_mm`` of the highest row median over the drape's top rows (`drape_top`'s
    ``highest_row`` band) are set to 0.

    On GelFabric's Kinect images 3-8 rows (at 224 px) above the drape stand 15-60 mm in
    front of the wall and 30-60 mm below the cloth over the post, then the depth jumps by
    about 250 mm to the cloth: the sensor's mix of wall and cloth, counted as cloth by the
    margin. A drape with no cap (the synthetic world's) is unchanged.
    """
    med = _top_band(height)
    if not med:
        return height
    top = max(m for _, m in med)
    first = next(r for r, m in med if m >= top - tolerance_mm)
    if first == med[0][0]:
        return height
    out = height.copy()
    out[:first] = 0.0
    return out


def drape_top(height: F32, rule: TopRule = "first_rows") -> float | None:
    """The height (mm) of the drape's top, where the post holds it; None without cloth.

    ``first_rows``: the median height of the cloth in its top rows (4 rows at 224 px, scaled
    with the image). ``highest_row``: the largest of the per-row median heights over the
    drape's top 16 rows (scaled), i.e. the cloth lying over the post. On GelFabric's Kinect
    images the first rows are often not the cloth: where the drape's rim meets the wall the
    sensor mixes the two, a few rows of wall pixels stand more than the margin in front of
    the fitted wall and count as cloth, and their heights vary by about 25 mm within one
    fabric (the cloth over the post: 7 mm; docs/results/real-depth.md, "Where the drape's top
    is read"). ``cloth_top`` reads the top as ``highest_row`` does; `heights_from_top` then also
    drops the cap (`without_cap`) and `drape_post` places the drape by the cloth's top.

    Raises:
        ValueError: ``rule`` is none of the three.
    """
    if rule not in ("first_rows", "highest_row", "cloth_top"):
        raise ValueError(f"unknown drape-top rule {rule!r}: first_rows, highest_row or cloth_top")
    if rule != "first_rows":
        medians = _top_band(height)
        return max(m for _, m in medians) if medians else None
    cloth = height > 0
    rows = np.flatnonzero(cloth.any(axis=1))
    if len(rows) == 0:
        return None
    band = max(2, round(4 * height.shape[0] / GELFABRIC_SIZE))
    return float(np.median(height[rows[0] : rows[0] + band][cloth[rows[0] : rows[0] + band]]))


def heights_from_top(height: F32, top_mm: float, rule: TopRule = "first_rows") -> F32:
    """Registered heights re-measured from the drape's top, which is set to ``top_mm``.

    ``top`` is `drape_top` by ``rule`` (``data.depth_top_from``); every cloth pixel becomes
    ``height - top + top_mm``, at least 1 mm so that it stays cloth (0 is no cloth). A shift
    of the fitted floor then changes nothing: only the floor's orientation is used
    (``data.depth_top_mm``). With ``cloth_top`` the cap above the drape is dropped first
    (`without_cap`). Unchanged when there is no cloth.
    """
    if rule == "cloth_top":
        height = without_cap(height)
    cloth = height > 0
    top = drape_top(height, rule)
    if top is None:
        return height
    out = np.where(cloth, np.maximum(height - np.float32(top - top_mm), np.float32(1.0)), 0.0)
    return out.astype(np.float32, copy=False)


def move_drape(
    height: F32, post_uv: tuple[float, float] | None, post_at: tuple[float, float] | None
) -> F32:
    """``height`` translated (bilinear, 0 beyond its edges) so that the drape's top
    ``post_uv`` lies at ``post_at`` (fractions of the width and height,
    ``data.depth_post_at``); unchanged when either is None."""
    if post_at is None or post_uv is None:
        return height
    h, w = height.shape
    dx, dy = post_at[0] * (w - 1) - post_uv[0], post_at[1] * (h - 1) - post_uv[1]
    return ndimage.shift(height, (dy, dx), order=1, mode="constant", cval=0.0).astype(
        np.float32, copy=False
    )


def registered_input(depth_mm: NDArray[np.generic], config: DataConfig) -> F32:
    """The registered training input of one depth image: (H, W) mm, the cloth's height
    above the fitted floor (with ``depth_top_mm``, below the drape's top set to it).

    `registered_heights`, then with ``depth_post_at`` the drape moved so that its top lies
    at that fraction of the image (`move_drape`).

    Raises:
        RegistrationError: no room could be fitted (the message says what is missing).
    """
    height, post = registered_heights(depth_mm, config)
    return move_drape(height, post, config.depth_post_at)


def wall_gaps(depth_mm: NDArray[np.generic], reg: Registration, config: DataConfig) -> F32:
    """(P, H, W) how far each pixel's point lies in front of each fitted plane but the floor,
    less ``config.depth_margin_mm`` (mm; cloth is where every gap is above 0). (0, H, W)
    when only a floor was fitted."""
    d = np.asarray(depth_mm)
    h, w = d.shape
    k = registered_intrinsics(d.shape, config) or Intrinsics.gelfabric(w, h)
    walls = [p for p in reg.planes if p.label != "floor"]
    if not walls:
        return np.zeros((0, h, w), np.float32)
    gaps = plane_gaps(fill_holes(d).astype(np.float64), walls, k) - config.depth_margin_mm
    return gaps.astype(np.float32)


def wall_gap_input(depth_mm: NDArray[np.generic], config: DataConfig) -> tuple[F32, F32, F32]:
    """What ``data.depth_wall_drop`` needs of one depth image, each placed as the training
    input places the drape (`move_drape`): `registered_input` (H, W) mm (without
    ``depth_wall_band_mm``: the draw drops near the walls instead); the share of each
    pixel that is cloth (H, W, in [0, 1]: the moved drape's edge is blended); and (P, H, W)
    the cloth's gap to each fitted plane but the floor (`wall_gaps`, mm) times that share.
    Resized to the input's size, the third divided by the second is each input pixel's gap
    (`lookfeel.data.images.ImageLoader.views`).

    Raises:
        RegistrationError: no room could be fitted (the message says what is missing).
    """
    reg = register_configured(depth_mm, config)
    kept = kept_heights(reg, config, band=False)  # a training draw drops near the walls
    post = drape_post(reg, kept, config)
    cloth = (kept > 0).astype(np.float32)
    gaps = wall_gaps(depth_mm, reg, config)
    return (
        move_drape(kept, post, config.depth_post_at),
        move_drape(cloth, post, config.depth_post_at),
        np.stack(
            [move_drape(np.where(cloth > 0, g, 0).astype(np.float32), post, config.depth_post_at)
             for g in gaps]
        ) if len(gaps) else np.zeros((0, *kept.shape), np.float32),
    )  # fmt: skip


def drop_near_walls(
    cloth: NDArray[np.bool_], gaps: F32, draws: NDArray[np.float64], shift_mm: float, tilt_mm: float
) -> NDArray[np.bool_]:
    """The cloth a room with its walls moved toward it keeps (``data.depth_wall_drop``).

    Args:
        cloth: (B, H, W) where each image is cloth.
        gaps: (B, P, H, W) each pixel's gap to each wall (mm past ``depth_margin_mm``; large
            where there is no such wall).
        draws: (B, P, 3) uniform draws in [0, 1) per image and wall: the shift (times
            ``shift_mm``), the tilt's direction and its size (times ``tilt_mm``, at the
            image's edge midpoints).
        shift_mm, tilt_mm: ``data.depth_wall_shift_mm`` and ``depth_wall_tilt_mm``.

    Returns:
        (B, H, W): the cloth at least the margin in front of every moved wall, then only its
        largest piece (`drape_mask`), as registration in such a room would keep it.
    """
    _, _, h, w = gaps.shape
    f = np.float32
    u = ((np.arange(w, dtype=f) + f(0.5)) * f(2.0 / w) - f(1.0))[None, None, None, :]
    v = ((np.arange(h, dtype=f) + f(0.5)) * f(2.0 / h) - f(1.0))[None, None, :, None]
    angle = 2.0 * np.pi * draws[..., 1]
    tilt = draws[..., 2] * tilt_mm
    shift, tx, ty = (
        a.astype(f)[..., None, None]
        for a in (draws[..., 0] * shift_mm, tilt * np.cos(angle), tilt * np.sin(angle))
    )
    left = cloth & (gaps >= shift + tx * u + ty * v).all(axis=1)
    return np.stack([drape_mask(m) for m in left]) if len(left) else left
