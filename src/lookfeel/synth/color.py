"""Colour photos of a drape: the fabric's colour and print on the draped shape, lit per capture.

The print lives on the cloth (material coordinates), so it bends into the folds with it. Shading
is Lambertian with a soft key light whose direction, strength and colour temperature change from
capture to capture, plus ambient light darkened in the folds' hollows (a cavity term from the
depth buffer). The material shows as a camera resolves it at a drape's scale (a weave does not:
one pixel is ~3 mm): a specular lobe as strong and sharp as the fibre and weave make it (silk
satin's sheen), hairiness as asperity scattering, a bright rim at grazing angles and shading
that wraps softly round the folds (fleece's matte fuzz: Koenderink & Pont, "The secret of
velvety skin", Machine Vision and Applications 2003), and light let through a thin, light
cloth, which flattens its shading (`Fabric.translucency`). Exposure and white balance vary per
capture as they would between photos; sensor noise is added last. Colour and print are
independent of everything else.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from lookfeel.synth.drape import Surface
from lookfeel.synth.fabric import Fabric
from lookfeel.synth.scene import (
    Camera,
    background_depth,
    background_plane_index,
    close_pinholes,
    splat,
)

__all__ = ["print_texture", "render_color", "render_colors"]

F32 = NDArray[np.float32]
_TEX = 384  # texels across the cloth (~2.7 mm each)

# Room surfaces (floor, back wall, side panel): linear albedo.
_ROOM_ALBEDO = np.array([[0.42, 0.38, 0.33], [0.70, 0.70, 0.68], [0.55, 0.54, 0.52]], np.float32)


def print_texture(fabric: Fabric) -> F32:
    """The fabric's albedo over the cloth, (T, T, 3) linear RGB; texel (0, 0) is a corner."""
    return _print_texture_cached(fabric)


@lru_cache(maxsize=4)
def _print_texture_cached(fabric: Fabric) -> F32:
    rng = np.random.default_rng([fabric.appearance_seed, 21])
    t = _TEX
    mm = fabric.side_mm / t
    yy, xx = np.mgrid[0:t, 0:t].astype(np.float32) * mm
    a = fabric.print_angle
    u = xx * math.cos(a) + yy * math.sin(a)
    v = -xx * math.sin(a) + yy * math.cos(a)
    base = np.asarray(fabric.base_rgb, np.float32)
    cols = [np.asarray(c, np.float32) for c in fabric.print_rgb] or [base * 0.5]
    scale = fabric.print_scale_mm
    out = np.broadcast_to(base, (t, t, 3)).copy()

    def paint(mask: F32, col: NDArray[np.float32]) -> None:
        nonlocal out
        m = np.clip(mask, 0.0, 1.0)[..., None]
        out = out * (1 - m) + col * m

    kind = fabric.print_kind
    if kind == "stripes":
        paint(_band(u / scale, rng.uniform(0.2, 0.6), mm / scale), cols[0])
        if len(cols) > 1:
            paint(_band(u / scale + 0.5, 0.12, mm / scale), cols[1])
    elif kind == "checks":
        duty = rng.uniform(0.25, 0.5)
        su, sv = _band(u / scale, duty, mm / scale), _band(v / scale, duty, mm / scale)
        paint(0.55 * su + 0.55 * sv, cols[0])
        if len(cols) > 1:
            paint(su * sv, cols[1])
    elif kind == "dots":
        fu = u / scale - np.floor(u / scale) - 0.5
        fv = v / scale - np.floor(v / scale) - 0.5
        r = rng.uniform(0.18, 0.35)
        paint((r - np.hypot(fu, fv)) * scale / mm + 0.5, cols[0])
    elif kind in ("blobs", "camo"):
        # Smooth noise made at a quarter of the resolution and enlarged: same look, 16x cheaper.
        sigma = scale / mm / (2.0 if kind == "blobs" else 1.2) / 4.0
        for i, col in enumerate(cols * (2 if kind == "camo" else 1)):
            small = ndimage.gaussian_filter(
                rng.standard_normal((t // 4, t // 4)).astype(np.float32), sigma, mode="wrap"
            )
            noise = ndimage.zoom(small, 4, order=1, mode="grid-wrap", grid_mode=True)
            noise /= noise.std() + 1e-9
            level = 0.6 if kind == "blobs" else 0.2 + 0.2 * i
            paint((noise - level) * 3.0, col)
    # Dye is never perfectly even.
    mottle = ndimage.gaussian_filter(rng.standard_normal((t, t)).astype(np.float32), 6.0)
    out *= 1.0 + 0.5 * mottle[..., None]
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def _band(x: F32, duty: float, blur: float) -> F32:
    """Antialiased stripes: 1 inside the first ``duty`` of each period of ``x``."""
    f = x - np.floor(x)
    d = np.minimum(f, duty - f)  # > 0 inside
    d = np.where(f > duty, np.minimum(f - duty, 1.0 - f) * -1.0, d)
    return np.clip(d / max(blur, 1e-3) + 0.5, 0.0, 1.0).astype(np.float32)


def _screen_normals(z: F32, camera: Camera) -> F32:
    """Camera-space unit normals (facing the camera) from a depth buffer, (H, W, 3)."""
    h, w = z.shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    x = (u - camera.cx) * (1.0 / camera.f) * z
    y = (v - camera.cy) * (1.0 / camera.f) * z
    # Tangents along image columns (a) and rows (b); the normal is b x a (towards the camera).
    ax, ay, az = (np.gradient(c, axis=1) for c in (x, y, z))
    bx, by, bz = (np.gradient(c, axis=0) for c in (x, y, z))
    n = np.empty((h, w, 3), np.float32)
    n[..., 0] = by * az - bz * ay
    n[..., 1] = bz * ax - bx * az
    n[..., 2] = bx * ay - by * ax
    n *= (np.sign(-n[..., 2:3]) + (n[..., 2:3] == 0)) / np.maximum(
        np.sqrt((n * n).sum(-1, keepdims=True)), 1e-6
    )
    return n


def render_color(
    fabric: Fabric, surface: Surface, camera: Camera, rng: np.random.Generator
) -> NDArray[np.uint8]:
    """One colour photo of ``fabric`` draped as ``surface``, (H, W, 3) uint8 sRGB."""
    return render_colors([fabric], surface, camera, rng)[0]


def render_colors(
    fabrics: list[Fabric], surface: Surface, camera: Camera, rng: np.random.Generator
) -> list[NDArray[np.uint8]]:
    """Photos of one cloth in several prints (`fabric.reprinted`: the same optics, other colours
    and prints) on one drape: each image is what `render_color` gives for its fabric from a
    generator in ``rng``'s state, but the drape's geometry and light are computed once."""
    fabric = fabrics[0]
    h, w = camera.height, camera.width
    pts = camera.to_camera(surface.xyz.reshape(-1, 3))
    zbuf, pix, keep = splat(camera, pts)
    # Which sample won each pixel (ties resolved by the later sample, deterministically).
    won = pts[keep, 2] <= zbuf.ravel()[pix]
    owner = np.full(h * w, -1, np.int64)
    owner[pix[won]] = keep[won]
    # Close pinholes (pixels where a farther layer shows through the front one); a filled
    # pixel takes its print from the nearest pixel that kept its own sample.
    zfill, hole = close_pinholes(zbuf)
    bad = hole | (owner < 0).reshape(h, w)
    near = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    owner = owner[(near[0] * w + near[1]).ravel()]
    room = background_depth(camera)
    is_cloth = np.isfinite(zfill) & (zfill < room - 1.0) & (owner >= 0).reshape(h, w)
    z = np.where(is_cloth, zfill, room).astype(np.float32)
    # Normals of the cloth from its own depth only (the room around it filled with the
    # nearest cloth depth so smoothing does not bend the cloth's edge towards the wall).
    cloth_z = np.where(is_cloth, zfill, np.float32(np.inf))
    near_z = ndimage.minimum_filter(cloth_z, 5)  # a few pixels past the edge is all it takes
    zc = np.where(is_cloth, zfill, np.where(np.isfinite(near_z), near_z, room)).astype(np.float32)
    cloth_n = _screen_normals(ndimage.gaussian_filter(zc, 1.2), camera)
    plane = background_plane_index(camera)
    room_n = np.stack([camera.rot[2], -camera.rot[1], -camera.rot[0]]).astype(np.float32)
    normal = np.where(is_cloth[..., None], cloth_n, room_n[plane])

    # Albedo: cloth from its print, room from its planes.
    uv = surface.uv.reshape(-1, 2)[np.maximum(owner, 0)]
    scale = (_TEX - 1) / fabric.side_mm
    tu = np.clip(np.rint((uv[:, 0] + fabric.side_mm / 2) * scale), 0, _TEX - 1).astype(np.int64)
    tv = np.clip(np.rint((uv[:, 1] + fabric.side_mm / 2) * scale), 0, _TEX - 1).astype(np.int64)
    room_albedo = _ROOM_ALBEDO[plane]

    # Light for this capture: a key light from the front, above, left or right of the camera.
    az = rng.uniform(-1.0, 1.0)
    el = rng.uniform(0.35, 0.9)
    key = np.array([math.sin(az) * math.cos(el), -math.sin(el), -math.cos(az) * math.cos(el)])
    key /= np.linalg.norm(key)
    ambient = rng.uniform(0.25, 0.45)
    # Hairy cloth scatters light round its folds: a wrapped diffuse term (softer shading).
    wrap = 0.6 * fabric.fuzz
    lambert = np.clip((normal @ key.astype(np.float32) + wrap) / (1.0 + wrap), 0.0, 1.0)
    # Hollows between folds see less of the room's light.
    cavity = np.clip(ndimage.gaussian_filter(z, 3.0) - z, -40.0, 0.0)
    occl = np.exp(cavity / 25.0)
    shade = ambient * occl + (1.0 - ambient) * lambert
    # A thin, light cloth lets light through from the room behind and round it: its shading
    # flattens towards an even glow.
    tau = fabric.translucency
    shade = np.where(is_cloth, (1.0 - tau) * shade + tau * (0.35 + 0.4 * ambient), shade)
    # Specular lobe (Blinn-Phong) as strong and sharp as the material makes it, white.
    view = np.array([0.0, 0.0, -1.0], np.float32)
    half = key + view
    half /= np.linalg.norm(half)
    n_dot_h = np.clip(normal @ half.astype(np.float32), 0.0, 1.0)
    gloss = fabric.gloss
    spec = n_dot_h**gloss * ((gloss + 8.0) / 32.0)  # energy-normalised: 1 at peak for gloss 24
    # Asperity scattering: fibre ends light up at grazing angles, in the fibres' own colour.
    rim = (1.0 - np.abs(normal[..., 2])) ** 2
    on = is_cloth[..., None]
    camera_state = rng.bit_generator.state  # every print sees the same exposure and noise
    photos = []
    for f in fabrics:
        tex = print_texture(f)
        alb = tex[tv, tu].reshape(h, w, 3)
        albedo = np.where(is_cloth[..., None], alb, room_albedo).astype(np.float32)
        img = albedo * shade[..., None]
        img = img + on * (fabric.sheen * 0.5 * spec * lambert)[..., None]
        img = img + on * (fabric.fuzz * 0.35 * rim * (ambient + lambert))[..., None] * (
            0.4 * albedo + 0.12
        )
        # Camera: exposure and white balance per capture, then sRGB and noise.
        rng.bit_generator.state = camera_state
        temp = rng.uniform(-0.12, 0.12)
        wb = np.array([1.0 + temp, 1.0, 1.0 - temp], np.float32) * rng.uniform(0.75, 1.3) * 1.6
        img = np.clip(img * wb, 0.0, 1.0)
        srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055)
        srgb = srgb * 255.0 + rng.standard_normal(srgb.shape, dtype=np.float32) * 1.5
        photos.append(np.clip(np.rint(srgb), 0, 255).astype(np.uint8))
    return photos
