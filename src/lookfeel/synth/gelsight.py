"""GelSight frames of a press on the fabric, lying flat or on a fold.

The sensor (paper section 3): a fingertip GelSight with an 18.4 x 13.8 mm field, a slightly
domed gel, black markers printed on its membrane and three coloured lights from the sides.
Its look (the colour gradient of the lights over the field, marker grid, size and darkness)
was fitted to a published no-contact frame of such a sensor (a co-author's calibration data,
``shared/reference/gelsight``); only those fitted numbers are kept here.

A press, step by step:

1. The fabric's surface height under the sensor, in mm above the table: the weave (or knit, or
   pile) relief of one layer, its yarns swollen and raised at their thick places (streaks a few
   mm long whose strength is the fibre's `Fabric.yarn_irregularity`), its valleys filled by
   hairs in proportion to the hairiness, roughened by the fibres' hairiness, with the cloth's
   gentle waviness. For a fold (the paper's "flat fold"), the cloth folded back over itself: two
   layers on one side of the edge, parting near it where the loop at the edge holds them
   open by ``gap``; the edge a half circle of radius ``t + gap / 2``; the table beyond. Left
   alone, the loop stands open to about the bending length ``c = (B / w)^(1/3)``, the
   elasto-gravity length of a heavy elastica (Wang, "Folding of elastica - similarity
   solutions", J. Appl. Mech. 1981; Vella, Boudaoud & Adda-Bedia, "Statics and inertial
   dynamics of a ruck in a rug", PRL 2009). Pressed with a line load ``q``, bending resists
   as ``q ~ 4 B / gap^2`` (a ring pressed flat), so the gap is ``(1 / c^2 + q / 4B)^(-1/2)``:
   open at first touch, closing as the force rises, wider for a stiffer cloth at every force.
2. The domed gel comes down until the force (gel stiffness times indentation, integrated)
   reaches the frame's target. Gel and fabric are springs in series: a fluffy fabric takes most
   of the press itself and the gel hardly moves (`Fabric.compliance`).
3. The gel smooths what it touches (elastic spreading, two length scales).
4. Each coloured light shades the membrane by its slope (Lambertian, low elevation), over the
   sensor's no-contact image.
5. Markers move outwards from the indentation and with the hand's shear, then darken the image.
6. Camera noise.

Frames of one press share position, orientation and texture phase; the force rises frame by
frame, geometrically from first contact (0.4-0.8 N) to the press's peak (3-10 N), so the frames
show the fold flattening. Position, orientation and forces are random per press.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from lookfeel.modality import PressKind
from lookfeel.synth.fabric import Fabric

__all__ = [
    "FIELD_MM",
    "Sensor",
    "fold_gap_mm",
    "no_contact_frame",
    "press_forces",
    "render_press",
    "sensor",
]

F32 = NDArray[np.float32]

FIELD_MM = (18.4, 13.8)
_DOME_RADIUS_MM = 60.0  # sag 0.7 mm at the long edges' centres
_GEL_STIFFNESS = 0.25  # N per mm of indentation per mm^2
_MARKER_PITCH_MM = 0.87  # ~21 x 16 markers
_MARKER_RADII_MM = (0.22, 0.14)
_MARKER_PUSH_MM = 0.5  # lateral marker motion per unit slope of the indentation
_BARREL = -0.12  # lens distortion of the marker grid (the reference grid bows outwards)

# Illumination fitted to the reference no-contact frame: per channel (R, G, B) a base level, a
# lobe (amplitude, centre x, centre y, width; coordinates in field heights from the centre),
# and a vignette ``1 - v r^(2 p)`` with r^2 in units of 0.4 field heights^2.
_LIGHT_FIT = (
    (134.8, 197.5, 0.206, 0.453, 0.288),
    (156.0, 150.6, -0.519, 0.109, 0.251),
    (207.1, 154.8, 0.209, -0.558, 0.235),
)
_VIGNETTE = (0.496, 0.809)
# Where each light sits (unit vector in the image plane, x right, y down) and its elevation:
# red from the lower right, green from the left, blue from the top (as in the reference frames).
_LIGHT_DIRS = ((0.45, 0.89), (-0.97, 0.24), (0.1, -0.99))
_LIGHT_ELEVATION = math.radians(28.0)
_AMBIENT = 0.25


@dataclass(frozen=True)
class Sensor:
    """A GelSight at ``width`` x ``height`` pixels: its no-contact image and marker pattern."""

    width: int
    height: int
    pitch_mm: float
    background: F32
    """(H, W, 3) no-contact image, 0-255 float."""
    markers: F32
    """(H, W) marker coverage at rest, 0-1."""
    marker_centres: F32
    """(N, 2) marker centres at rest, pixel coordinates (x, y), with the lens' distortion."""


@lru_cache(maxsize=4)
def sensor(width: int, height: int) -> Sensor:
    """The sensor at a given image size (the field is always 18.4 x 13.8 mm)."""
    pitch = FIELD_MM[0] / width
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    # Field coordinates in units of the field's height, as in the fit.
    xn = (xx + 0.5 - width / 2) / width * (FIELD_MM[0] / FIELD_MM[1])
    yn = (yy + 0.5 - height / 2) / height
    v, vp = _VIGNETTE
    vig = np.clip(1 - v * ((xn**2 + yn**2) / 0.4) ** vp, 0.0, 1.0)
    bg = np.stack(
        [
            (b + a * np.exp(-((xn - px) ** 2 + (yn - py) ** 2) / (2 * s * s))) * vig
            for b, a, px, py, s in _LIGHT_FIT
        ],
        -1,
    )
    # Markers: a regular grid of soft dark ellipses, wider than tall (as printed), seen
    # through a lens with a little barrel distortion.
    cx, cy = width / 2 - 0.5, height / 2 - 0.5
    gx, gy = np.meshgrid(
        (np.arange(-1, FIELD_MM[0] / _MARKER_PITCH_MM + 1) + 0.5) * _MARKER_PITCH_MM / pitch,
        (np.arange(-1, FIELD_MM[1] / _MARKER_PITCH_MM + 1) + 0.2) * _MARKER_PITCH_MM / pitch,
    )
    q0 = np.stack([gx.ravel() - 0.5 - cx, gy.ravel() - 0.5 - cy], -1) / (width / 2)
    # Invert  membrane = q (1 + k |q|^2)  for the radius, by bisection on the monotonic part.
    rho = np.linalg.norm(q0, axis=-1)
    r_max = math.sqrt(1.0 / (3.0 * abs(_BARREL))) if _BARREL < 0 else 10.0
    lo, hi = np.zeros_like(rho), np.full_like(rho, r_max)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        below = mid * (1.0 + _BARREL * mid**2) < rho
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    reachable = rho <= r_max * (1.0 + _BARREL * r_max**2)
    scale = np.where(rho > 0, lo / np.maximum(rho, 1e-12), 1.0)
    centres = (q0 * scale[:, None] * (width / 2) + np.array([cx, cy])).astype(np.float32)
    inside = (
        reachable
        & (centres[:, 0] > -10)
        & (centres[:, 0] < width + 10)
        & (centres[:, 1] > -10)
        & (centres[:, 1] < height + 10)
    )
    centres = centres[inside]
    marks = _draw_markers(centres, height, width, pitch)
    bg32 = bg.astype(np.float32)
    for a in (bg32, marks, centres):
        a.setflags(write=False)
    return Sensor(width, height, pitch, bg32, marks, centres)


def _draw_markers(centres: F32, h: int, w: int, pitch: float) -> F32:
    """Marker coverage (0-1), (H, W): a soft ellipse around each centre (pixel x, y)."""
    rx, ry = (r / pitch for r in _MARKER_RADII_MM)
    edge = max(0.35, 1.2 * pitch / _MARKER_RADII_MM[1])  # about a pixel of soft edge
    reach = math.ceil(rx * (1 + 0.5 * edge)) + 1
    off = np.arange(-reach, reach + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")
    base = np.floor(centres).astype(np.int64)
    px = base[:, 0, None, None] + ox[None]
    py = base[:, 1, None, None] + oy[None]
    dx = (px - centres[:, 0, None, None]) / rx
    dy = (py - centres[:, 1, None, None]) / ry
    val = np.clip((1.0 - np.sqrt(dx * dx + dy * dy)) / edge + 0.5, 0.0, 1.0)
    ok = (px >= 0) & (px < w) & (py >= 0) & (py < h) & (val > 0)
    out = np.zeros(h * w, np.float32)
    np.maximum.at(out, (py[ok] * w + px[ok]), val[ok].astype(np.float32))
    return out.reshape(h, w)


def no_contact_frame(s: Sensor) -> NDArray[np.uint8]:
    """The sensor's frame with nothing touching it (markers at rest), without noise."""
    img = s.background * (1.0 - 0.55 * s.markers[..., None])
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


# ---------------------------------------------------------------------------------------------
# The fabric's surface.


def _weave(fabric: Fabric, x: F32, y: F32, rng: np.random.Generator, pitch: float) -> F32:
    """Relief of one layer's surface (mm, zero mean) at field points ``x, y`` (mm)."""
    p = fabric.yarn_period_mm
    a = fabric.relief_mm
    k = 2.0 * math.pi / p
    w = fabric.weave
    if w == "plain":
        h = 0.6 * np.sin(k * x) * np.sin(k * y) + 0.2 * (np.cos(2 * k * x) + np.cos(2 * k * y))
    elif w == "twill":
        h = 0.8 * np.cos(k * (x + 0.5 * y)) + 0.2 * np.cos(k * y)
    elif w == "satin":
        h = 0.5 * np.cos(0.5 * k * y) + 0.2 * np.cos(k * (x + 0.2 * y))
    elif w == "knit":
        saw = np.abs((x / p) % 1.0 - 0.5)  # V-shaped loops along each wale
        h = np.cos(k * 1.25 * (y + 0.6 * p * saw)) * (0.6 + 0.4 * np.cos(k * x))
    else:  # pile: tufts and loops at random
        sigma = max(0.6, 0.5 * p / pitch)
        n = ndimage.gaussian_filter(rng.standard_normal(x.shape).astype(np.float32), sigma)
        h = n / (n.std() + 1e-9)
    h = np.asarray(h, np.float32)
    # Spun yarns have thick and thin places along their length (flax's slubs most, filament
    # hardly): a thick place swells its yarn's relief and raises it by about half the extra
    # diameter (the relief is about a third of a yarn's diameter), streaked along the warp and
    # the weft in the cloth's own coordinates.
    swell = fabric.yarn_irregularity * _slub_field(x, y, rng)
    h = h * np.exp(swell) + 1.4 * swell
    # Hairs lying across the valleys between yarns fill them under the gel: a hairy fabric's
    # weave shows less contrast (wool, fleece) than a smooth filament's (silk).
    h = h * (1.0 - 0.7 * fabric.fuzz)
    # Yarns are not perfectly regular; fibres stick out.
    rows, cols = x.shape
    oy, ox = int(rng.integers(0, rows)), int(rng.integers(0, cols))
    fuzz = _fuzz_bank(rows, cols)[oy : oy + rows, ox : ox + cols]
    # Hairy fibres (wool, fleece) roughen the surface more than smooth filaments (silk).
    return (a * (h + (0.1 + 0.6 * fabric.fuzz) * fuzz)).astype(np.float32)


_SLUB_STEP_MM = 0.1
_SLUB_SIZE = 1024


def _slub_field(xr_mm: F32, yr_mm: F32, rng: np.random.Generator) -> F32:
    """Unit noise in the cloth's coordinates (mm), streaked along both yarn directions:
    thick places a few mm long and a yarn or two wide, cut at a random place of one periodic
    bank."""
    bank = _slub_bank()
    oy, ox = (float(v) for v in rng.uniform(0, _SLUB_SIZE, 2))
    coords = np.stack([yr_mm / _SLUB_STEP_MM + oy, xr_mm / _SLUB_STEP_MM + ox])
    return ndimage.map_coordinates(bank, coords, order=1, mode="grid-wrap").astype(np.float32)


@lru_cache(maxsize=1)
def _slub_bank() -> F32:
    """The periodic bank `_slub_field` cuts from: warp streaks plus weft streaks, unit spread."""
    n = _SLUB_SIZE
    noise = np.random.default_rng(8765).standard_normal((2, n, n)).astype(np.float32)
    along, across = 2.5 / _SLUB_STEP_MM, 0.4 / _SLUB_STEP_MM  # mm -> bank cells
    warp = ndimage.gaussian_filter(noise[0], (along, across), mode="wrap")
    weft = ndimage.gaussian_filter(noise[1], (across, along), mode="wrap")
    bank = warp / (warp.std() + 1e-9) + weft / (weft.std() + 1e-9)
    bank /= bank.std() + 1e-9
    bank.setflags(write=False)
    return bank


@lru_cache(maxsize=4)
def _fuzz_bank(h: int, w: int) -> F32:
    """Smooth unit noise (fibres sticking out, finer than a yarn) for presses to cut windows
    from."""
    n = ndimage.gaussian_filter(
        np.random.default_rng(4321).standard_normal((2 * h, 2 * w)).astype(np.float32), 1.0
    )
    n /= n.std() + 1e-9
    n.setflags(write=False)
    return n


def _waviness(shape: tuple[int, int], rng: np.random.Generator, amp: float) -> F32:
    """Smooth bumps a few mm across: a cloth lying on a table is never perfectly flat."""
    h, w = shape
    return amp * _upsample(rng.standard_normal((5, 6)), h, w, smooth=True)


@dataclass(frozen=True)
class _Pose:
    angle: float
    shift: tuple[float, float]
    fold_angle: float
    fold_offset: float
    peak_force: float
    first_force: float
    tilt: tuple[float, float]
    shear: tuple[float, float]
    exposure: float


def fold_gap_mm(fabric: Fabric, force: float) -> float:
    """The gap (mm) inside a fold's loop under the sensor pressing with ``force`` (N).

    At no load the loop stands open to about the bending length; a line load ``q`` (the force
    over the field's width) closes it to where bending holds it, ``q = 4 B / gap^2``.
    """
    q = max(force, 0.0) / FIELD_MM[0]  # N/mm
    b = fabric.bending_rigidity_nm * 1000.0  # N mm
    free = fabric.bending_length_mm
    return float(1.0 / math.sqrt(1.0 / free**2 + q / (4.0 * b)))


def _fold_surface(base: F32, table: F32, u: F32, fabric: Fabric, force: float) -> F32:
    """Height (mm) of a flat fold under the sensor: the cloth folded back over itself.

    ``u`` is the distance from the fold's edge (mm; negative over the folded cloth). Over the
    fold two layers lie one on the other, and near the edge they part where the loop holds
    them open: the top layer stands ``gap * exp(u / L)`` above the plateau, ``L = 1.3 gap`` (a
    loop about as long as it is open). The edge itself is the loop's end, a half circle of
    radius ``t + gap / 2``; beyond it lies the table. A limp fold is a crisp step; a stiff one
    rises in a ridge along its edge, and both flatten as the force rises (`fold_gap_mm`).
    """
    t = fabric.thickness_mm
    gap = fold_gap_mm(fabric, force)
    radius = t + 0.5 * gap
    opening = 1.3 * gap
    flap = t + gap * np.exp(np.minimum(u, 0.0) / opening)
    cap = radius + np.sqrt(np.maximum(radius**2 - np.minimum(u, radius) ** 2, 0.0)) - t
    delta = np.where(u <= 0.0, flap, cap)
    return np.where(u > radius, table, base + delta).astype(np.float32)


def press_forces(peak: float, first: float, frames: int) -> list[float]:
    """Forces (N) of a press's frames: geometric from first contact to the peak."""
    if frames == 1:
        return [peak]
    return [first * (peak / first) ** (k / (frames - 1)) for k in range(frames)]


def render_press(
    fabric: Fabric,
    kind: PressKind,
    s: Sensor,
    rng: np.random.Generator,
    frames: int,
) -> list[NDArray[np.uint8]]:
    """The frames of one press of the sensor on ``fabric``, force rising frame by frame.

    Args:
        fabric: the fabric.
        kind: ``PressKind.FLAT`` (one flat layer) or ``PressKind.FOLD`` (on a fold).
        s: the sensor (see `sensor`).
        rng: the press's random stream.
        frames: number of frames.

    Returns:
        ``frames`` images, (H, W, 3) uint8 RGB.
    """
    h, w = s.height, s.width
    pose = _Pose(
        angle=float(rng.uniform(0, math.pi)),
        shift=(float(rng.uniform(0, 50)), float(rng.uniform(0, 50))),
        fold_angle=float(rng.uniform(0, 2 * math.pi)),
        fold_offset=float(rng.uniform(-0.22, 0.22) * FIELD_MM[1]),
        peak_force=float(math.exp(rng.uniform(math.log(3.0), math.log(10.0)))),
        first_force=float(rng.uniform(0.4, 0.8)),
        tilt=(float(rng.normal(0, 0.012)), float(rng.normal(0, 0.012))),
        shear=(float(rng.normal(0, 0.06)), float(rng.normal(0, 0.06))),
        exposure=float(rng.normal(1.0, 0.02)),
    )
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    x = (xx + 0.5 - w / 2) * s.pitch_mm
    y = (yy + 0.5 - h / 2) * s.pitch_mm
    ca, sa = math.cos(pose.angle), math.sin(pose.angle)
    xr = ca * x + sa * y + pose.shift[0]
    yr = -sa * x + ca * y + pose.shift[1]
    t = fabric.thickness_mm
    texture = _weave(fabric, xr, yr, rng, s.pitch_mm)
    wavy = _waviness((h, w), rng, 0.04 + 0.03 * math.sqrt(t))
    base = (t + texture + wavy).astype(np.float32)
    table = (0.3 * wavy).astype(np.float32)  # beyond a fold's edge: the table
    if kind is PressKind.FOLD:
        u = math.cos(pose.fold_angle) * x + math.sin(pose.fold_angle) * y - pose.fold_offset
        u = u.astype(np.float32)
    # The gel's surface above the table when the sensor's centre is at height 0.
    dome = ((x**2 + y**2) / (2 * _DOME_RADIUS_MM) + pose.tilt[0] * x + pose.tilt[1] * y).astype(
        np.float32
    )
    eps = fabric.compliance
    area = s.pitch_mm**2
    sub = (slice(None, None, 4), slice(None, None, 4))
    ce, se = math.cos(_LIGHT_ELEVATION), math.sin(_LIGHT_ELEVATION)
    noise = _noise_bank(h, w)

    out = []
    forces = press_forces(pose.peak_force, pose.first_force, frames)
    for k, force in enumerate(forces, start=1):
        surf = _fold_surface(base, table, u, fabric, force) if kind is PressKind.FOLD else base
        # Bisection on the sensor's height: force = stiffness * sum of gel indentation.
        gap = surf[sub] - dome[sub]
        top = float(gap.max())
        lo, hi = top - 4.0, top
        for _ in range(22):
            mid = 0.5 * (lo + hi)
            f = _GEL_STIFFNESS * eps * float(np.maximum(gap - mid, 0.0).sum()) * area * 16
            lo, hi = (mid, hi) if f > force else (lo, mid)
        pen = np.maximum(surf - dome - hi, 0.0) * eps
        # Elastic gel: fine detail blurred over ~0.1 mm, the bulk spread over ~0.8 mm.
        fine = ndimage.gaussian_filter(pen, 0.1 / s.pitch_mm, truncate=3.0)
        broad = _blur_coarse(pen, 0.8 / s.pitch_mm)
        height = np.maximum(fine, 0.7 * broad)
        gy, gx = np.gradient(height, s.pitch_mm)
        norm = (1.0 - _AMBIENT) / (se * np.sqrt(1.0 + gx * gx + gy * gy))
        img = np.empty((h, w, 3), np.float32)
        for ch, (dx, dy) in enumerate(_LIGHT_DIRS):
            lam = np.maximum((se - ce * (gx * dx + gy * dy)) * norm, 0.0) + _AMBIENT
            img[..., ch] = s.background[..., ch] * lam
        # Markers: pushed outwards from the indentation and dragged by the hand's shear.
        drag: F32 = (k / frames) / s.pitch_mm * np.clip(broad / (broad.max() + 1e-6), 0.0, 1.0)
        bgy, bgx = (np.asarray(g, np.float32) for g in np.gradient(broad))
        c = s.marker_centres
        ix = np.clip(np.rint(c[:, 0]).astype(np.int64), 0, w - 1)
        iy = np.clip(np.rint(c[:, 1]).astype(np.int64), 0, h - 1)
        # Outward push (mm) ~ 0.5 mm times the indentation's slope; both terms in pixels.
        push = _MARKER_PUSH_MM / s.pitch_mm**2
        ux = -push * bgx[iy, ix] + pose.shear[0] * drag[iy, ix]
        uy = -push * bgy[iy, ix] + pose.shear[1] * drag[iy, ix]
        marks = _draw_markers(c + np.stack([ux, uy], -1), h, w, s.pitch_mm)
        img *= ((1.0 - 0.55 * marks) * pose.exposure)[..., None]
        oy, ox = int(rng.integers(0, h)), int(rng.integers(0, w))
        img += noise[oy : oy + h, ox : ox + w]
        out.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return out


def _blur_coarse(a: F32, sigma_px: float) -> F32:
    """A wide Gaussian blur done at a quarter of the resolution (the result is smooth)."""
    h, w = a.shape
    ap = np.pad(a, ((0, -h % 4), (0, -w % 4)), mode="edge")
    small = ap.reshape(ap.shape[0] // 4, 4, ap.shape[1] // 4, 4).mean(axis=(1, 3))
    small = ndimage.gaussian_filter(small, sigma_px / 4.0, mode="nearest")
    return _upsample(small, ap.shape[0], ap.shape[1])[:h, :w]


def _upsample(a: NDArray[np.floating], h: int, w: int, smooth: bool = False) -> F32:
    """Interpolate a coarse grid (cell-centred) up to (h, w); linear, or smoothstep."""

    def axis(n_in: int, n_out: int) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
        pos = (np.arange(n_out, dtype=np.float32) + 0.5) * (n_in / n_out) - 0.5
        pos = np.clip(pos, 0.0, n_in - 1.0)
        i = np.minimum(pos.astype(np.int64), max(n_in - 2, 0))
        t = (pos - i).astype(np.float32)
        if smooth:
            t = t * t * (3 - 2 * t)
        return i, t

    a = np.asarray(a, np.float32)
    iy, ty = axis(a.shape[0], h)
    ix, tx = axis(a.shape[1], w)
    iy1 = np.minimum(iy + 1, a.shape[0] - 1)
    ix1 = np.minimum(ix + 1, a.shape[1] - 1)
    rows = a[iy] * (1 - ty)[:, None] + a[iy1] * ty[:, None]
    return (rows[:, ix] * (1 - tx)[None, :] + rows[:, ix1] * tx[None, :]).astype(np.float32)


@lru_cache(maxsize=4)
def _noise_bank(h: int, w: int) -> F32:
    """Camera noise (1.2 grey levels) for frames to cut windows from: one fixed bank per size."""
    bank = 1.2 * np.random.default_rng(1234).standard_normal((2 * h, 2 * w, 3), dtype=np.float32)
    bank.setflags(write=False)
    return bank
