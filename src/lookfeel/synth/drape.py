"""How a fabric hangs over the post: a procedural drape model driven by the bending length.

Why procedural and not a cloth simulator: the paper-size world needs 1,180 drapes in a small
share of three minutes on two cores. A cloth simulation (MuJoCo's cloth runs ~8 ms a step for a
25x25 grid and needs thousands of steps to settle, and a 25x25 grid cannot show a fold 3 cm
wide on a 1 m square) would cost minutes per drape. Instead the drape is built from the
relations that govern real drapes (the Cusick drape test literature): every length in it scales
with the bending length ``c = (B / w) ** (1/3)`` (flexural rigidity over weight per area).

- Over the post's top the fabric lies flat; past the edge it bends down over a length ~``c``
  (a stiff fabric keeps its direction longer, so it flares out), then hangs as a cone whose
  half-angle grows with ``c``; it cannot kink where it meets the floor, so it lands along an
  arc of radius ~``c``, then spreads on the floor and piles in lumps.
- Hanging, the fabric has more material than circumference (a ring of cloth of radius ``s``
  hangs at radius ``r < s``); the excess buckles into folds ("nodes") whose wavelength scales
  with ``c``: heavy, flexible fabrics hang close with many narrow, sharp folds; stiff, light
  ones stand out with few broad, round nodes. A fold is as deep as the excess allows (so the
  cloth is never stretched), at most half its wavelength (self-contact limits it).
- Every drape differs: fold count (+-15%), positions and depths, where the cloth's centre
  lands on the post, its rotation, a lean of the cone, and how the hem lands and crumples on
  the floor, all drawn per drape.

The model returns the surface as a grid over the fabric's own (material) coordinates, so the
colour renderer can put the print where it belongs on the cloth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lookfeel.synth.fabric import Fabric
from lookfeel.synth.scene import POST_HEIGHT_MM, POST_RADIUS_MM

__all__ = ["DrapeParams", "Surface", "drape_surface", "sample_drape"]

F32 = NDArray[np.float32]

_TABLE = 1024  # samples of the per-angle tables
_DS = 2.0  # mm, step of the meridian profile


@dataclass(frozen=True)
class DrapeParams:
    """One drape's random draw, in physical units (mm, radians)."""

    bend_mm: float
    """Length over which the cloth turns down past the post's edge."""
    cone_tan: float
    """Tangent of the hanging cone's half-angle."""
    folds: int
    """Number of folds around the post."""
    fold_angles: tuple[float, ...]
    fold_depth: tuple[float, ...]
    """Relative depth of each fold (log-normal, the deepest 1)."""
    fold_sharpness: float
    """0 round sinusoidal nodes ... 1 sharp zig-zag pleats."""
    fold_amp_mm: float
    offset_mm: tuple[float, float]
    """Where the cloth's centre lies relative to the post's axis."""
    rotation: float
    lean: float
    lean_angle: float
    spread: float
    """Share of the material beyond the landing ring that extends outwards on the floor."""
    landing: tuple[float, ...]
    """Amplitudes and phases (a2, p2, a3, p3) of the hem's uneven landing."""
    floor_ridge_mm: float
    floor_phase: float
    landing_mm: float
    """Radius of the arc along which the cloth lands on the floor (~ bending length)."""
    crumple_seed: int
    """Seed of the random lumps the cloth forms where it piles on the floor."""


def sample_drape(fabric: Fabric, rng: np.random.Generator) -> DrapeParams:
    """Draw one drape of ``fabric``; all lengths scale with its bending length."""
    c = fabric.bending_length_mm
    bend = 0.35 * c + 4.0
    cone_tan = (0.15 + 0.8 * c / 100.0) * math.exp(0.08 * rng.standard_normal())
    # Radius half-way down the cone, where the folds are counted.
    r_mid = POST_RADIUS_MM + bend + 0.5 * POST_HEIGHT_MM * cone_tan
    wavelength = 2.3 * c + 6.0
    n_mean = 2.0 * math.pi * r_mid / wavelength
    folds = int(np.clip(round(n_mean * math.exp(0.13 * rng.standard_normal())), 3, 26))
    phase0 = rng.uniform(0.0, 2.0 * math.pi)
    jitter = 0.17 * rng.standard_normal(folds)
    angles = phase0 + 2.0 * math.pi * (np.arange(folds) + jitter) / folds
    depth = np.exp(0.2 * rng.standard_normal(folds))
    depth /= depth.max()  # the deepest fold reaches the depth the excess cloth allows
    amp = 0.5 * (2.0 * math.pi * r_mid / folds) * math.exp(0.1 * rng.standard_normal())
    off = np.clip(22.0 * rng.standard_normal(2), -55.0, 55.0)
    return DrapeParams(
        bend_mm=bend,
        cone_tan=cone_tan,
        folds=folds,
        fold_angles=tuple(float(a) for a in np.sort(angles)),
        fold_depth=tuple(float(d) for d in depth),
        fold_sharpness=float(np.clip(1.2 - c / 30.0, 0.0, 1.0)),
        fold_amp_mm=float(amp),
        offset_mm=(float(off[0]), float(off[1])),
        rotation=float(rng.uniform(0.0, 2.0 * math.pi)),
        lean=float(rng.uniform(0.0, 0.22)),
        lean_angle=float(rng.uniform(0.0, 2.0 * math.pi)),
        spread=float(rng.uniform(0.45, 0.8)),
        landing=(
            float(0.1 * rng.standard_normal()),
            float(rng.uniform(0, 2 * math.pi)),
            float(0.07 * rng.standard_normal()),
            float(rng.uniform(0, 2 * math.pi)),
        ),
        floor_ridge_mm=float((1.2 * c + 15.0) * math.exp(0.2 * rng.standard_normal())),
        landing_mm=float((2.5 * c + 20.0) * math.exp(0.1 * rng.standard_normal())),
        crumple_seed=int(rng.integers(0, 2**31 - 1)),
        floor_phase=float(rng.uniform(0, 2 * math.pi)),
    )


@dataclass(frozen=True)
class Surface:
    """The draped cloth as a grid over its material coordinates.

    Attributes:
        xyz: (N, N, 3) world positions in mm.
        uv: (N, N, 2) material coordinates in mm from the cloth's centre.
    """

    xyz: F32
    uv: F32

    def normals(self) -> F32:
        """(N, N, 3) unit normals of the grid (one side of the cloth; renderers face them)."""
        du = np.gradient(self.xyz, axis=1)
        dv = np.gradient(self.xyz, axis=0)
        nrm = np.cross(du, dv)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-9)
        return nrm.astype(np.float32)

    def densify(self, k: int) -> Surface:
        """The same surface interpolated (bilinearly) ``k`` times finer: (N-1) k + 1 samples."""
        if k <= 1:
            return self
        n = (self.uv.shape[0] - 1) * k + 1
        g = np.linspace(self.uv[0, 0, 0], self.uv[0, -1, 0], n, dtype=np.float32)
        uv = np.stack(np.meshgrid(g, g, indexing="xy"), -1)
        return Surface(_refine(self.xyz, k), uv)


def _refine(a: F32, k: int) -> F32:
    """Linear interpolation of an (N, M, C) grid to ((N-1) k + 1, (M-1) k + 1, C)."""
    n, m, c = a.shape
    w = np.arange(k, dtype=np.float32) / k
    rows = np.empty(((n - 1) * k + 1, m, c), np.float32)
    step = a[1:] - a[:-1]
    rows[:-1].reshape(n - 1, k, m, c)[:] = a[:-1, None] + step[:, None] * w[None, :, None, None]
    rows[-1] = a[-1]
    out = np.empty((rows.shape[0], (m - 1) * k + 1, c), np.float32)
    step = rows[:, 1:] - rows[:, :-1]
    out[:, :-1].reshape(rows.shape[0], m - 1, k, c)[:] = (
        rows[:, :-1, None] + step[:, :, None] * w[None, None, :, None]
    )
    out[:, -1] = rows[:, -1]
    return out


def _fold_table(p: DrapeParams) -> NDArray[np.float64]:
    """The fold waveform around the post on a regular angle grid, values in about [-1, 1]."""
    theta = np.linspace(0.0, 2.0 * math.pi, _TABLE, endpoint=False)
    a = np.asarray(p.fold_angles)
    # Phase rises by 2 pi from one fold crest to the next: irregular spacing, periodic.
    knots = np.concatenate([a - 2 * math.pi, a, a + 2 * math.pi])
    phase = np.interp(theta, knots, 2 * math.pi * np.arange(len(knots)))
    wave = (1 - p.fold_sharpness) * np.cos(phase) + p.fold_sharpness * (
        2 / math.pi * np.arcsin(np.cos(phase))
    )
    depth = np.concatenate([p.fold_depth] * 3)
    return wave * np.interp(theta, knots, depth)


def _profile(
    p: DrapeParams,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    """Meridian of the hanging part: radius and height against arc length past the edge.

    The direction turns from horizontal at the edge towards the cone's angle over the bend
    length. Near the floor the cloth cannot kink: it lands along an arc whose radius
    (``landing_mm``) scales with the bending length, meeting the floor flat. Returns (arc
    length, radius, height, arc length where it lands, radius there).
    """
    sigma = np.arange(0.0, 1200.0, _DS)
    phi = math.atan(p.cone_tan)
    alpha = phi + (0.5 * math.pi - phi) * np.exp(-sigma / p.bend_mm)
    r = np.empty_like(sigma)
    z = np.empty_like(sigma)
    rr, zz = POST_RADIUS_MM, POST_HEIGHT_MM
    landing = False
    a = float(alpha[0])
    hit = len(sigma) - 1
    for i in range(len(sigma)):
        r[i], z[i] = rr, zz
        if zz <= 0.0:
            hit = i
            break
        if not landing:
            a = float(alpha[i])
            # Start the arc when the height left equals the arc's drop at this angle.
            landing = zz <= p.landing_mm * (1.0 - math.sin(a))
        if landing:
            a = min(0.5 * math.pi, a + _DS / p.landing_mm)
            if a >= 0.5 * math.pi - 1e-9:
                r[i + 1 :], z[i + 1 :] = rr, 0.0
                hit = i + 1
                break
        rr += math.sin(a) * _DS
        zz = max(0.0, zz - math.cos(a) * _DS)
    r[hit:] = r[hit] if hit < len(r) else rr
    z[hit:] = 0.0
    return sigma, r, z, float(sigma[hit]), float(r[hit])


def _lumps(
    seed: int, pu: NDArray[np.float64], pv: NDArray[np.float64], side: float, scale: float
) -> NDArray[np.float64]:
    """Smooth random bumps in [0, 1] over the cloth, about ``scale`` mm across."""
    rng = np.random.default_rng([seed, 1])
    k = max(3, math.ceil(side / scale) + 2)
    knots = rng.random((k, k))
    # Bilinear interpolation of the knot values, squared to make separate lumps.
    fx = (pu / side + 0.5) * (k - 1)
    fy = (pv / side + 0.5) * (k - 1)
    i = np.clip(fx.astype(np.int64), 0, k - 2)
    j = np.clip(fy.astype(np.int64), 0, k - 2)
    tx = fx - i
    ty = fy - j
    tx = tx * tx * (3 - 2 * tx)  # smoothstep: no creases along the knot lines
    ty = ty * ty * (3 - 2 * ty)
    v = (
        knots[j, i] * (1 - tx) * (1 - ty)
        + knots[j, i + 1] * tx * (1 - ty)
        + knots[j + 1, i] * (1 - tx) * ty
        + knots[j + 1, i + 1] * tx * ty
    )
    return np.asarray(v**2)


def drape_surface(fabric: Fabric, p: DrapeParams, n: int = 120) -> Surface:
    """Build the draped surface of ``fabric`` for drape ``p`` on an ``n`` x ``n`` material grid.

    Folds are centimetres wide, so ~8 mm steps suffice for the shape; `Surface.densify`
    interpolates it finer for rendering.
    """
    side = fabric.side_mm
    t = fabric.thickness_mm
    c = fabric.bending_length_mm
    g = np.linspace(-side / 2, side / 2, n)
    pu, pv = np.meshgrid(g, g, indexing="xy")
    cr, sr = math.cos(p.rotation), math.sin(p.rotation)
    mx = cr * pu - sr * pv + p.offset_mm[0]
    my = sr * pu + cr * pv + p.offset_mm[1]
    s = np.hypot(mx, my)
    theta = np.mod(np.arctan2(my, mx), 2 * math.pi)
    ti = theta * (_TABLE / (2 * math.pi))
    grid = np.arange(_TABLE + 1, dtype=np.float64)

    def table(values: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.interp(ti, grid, np.append(values, values[0]))

    tab_theta = np.linspace(0.0, 2 * math.pi, _TABLE, endpoint=False)
    wave = table(_fold_table(p))
    lean = table(1.0 + p.lean * np.cos(tab_theta - p.lean_angle))
    a2, p2, a3, p3 = p.landing
    land = table(1.0 + a2 * np.cos(2 * tab_theta + p2) + a3 * np.cos(3 * tab_theta + p3))

    sigma_tab, r_tab, z_tab, s_land, r_land = _profile(p)
    sig = np.maximum(s - POST_RADIUS_MM, 0.0)
    on_top = s <= POST_RADIUS_MM
    floor = sig > s_land
    beyond = np.maximum(sig - s_land, 0.0)

    # Mean surface: flat on top, the meridian while hanging, spreading out on the floor.
    # The hem's uneven landing (``land``) sets in gradually down the cone.
    down = np.clip(sig / max(s_land, 1.0), 0.0, 1.0)
    r_hang = POST_RADIUS_MM + (np.interp(sig, sigma_tab, r_tab) - POST_RADIUS_MM) * lean * (
        1.0 + (land - 1.0) * down
    )
    r_floor = POST_RADIUS_MM + (r_land - POST_RADIUS_MM) * lean * land + p.spread * beyond
    r0 = np.where(on_top, s, np.where(floor, r_floor, r_hang))
    z0 = np.where(on_top, POST_HEIGHT_MM, np.interp(sig, sigma_tab, z_tab))

    # Excess material: a ring of cloth of radius s hangs at radius r0 < s. Buckled into
    # ``folds`` zig-zag folds of depth A it takes up 2 pi s when A = pi / (2 n) sqrt(s^2 - r^2);
    # folds grow to that depth but no deeper than a share of their wavelength. (The bound
    # 2 (s - r) keeps the growth gentle where folds start, so the cloth is never stretched.)
    gap = np.maximum(s - r0, 0.0)
    excess = np.minimum(np.sqrt(gap * (s + r0)), 2.0 * gap)
    amp = np.minimum(p.fold_amp_mm, math.pi / (2 * p.folds) * excess)
    hang_amp = np.where(floor, amp * np.exp(-beyond / (c + 30.0)), amp)
    r = np.where(on_top, r0, np.maximum(r0 + hang_amp * wave, POST_RADIUS_MM + t))
    # On the floor the excess stands up as ridges along the fold crests and a crumple of
    # wavelength ~ the bending length, both dying away from where the hem landed.
    decay = np.exp(-beyond / (3.0 * c + 120.0))
    crest = np.maximum(wave, 0.0) ** 1.5
    crumple = 0.5 + 0.5 * np.sin(beyond / (0.6 * c + 6.0) + p.floor_phase + 3.0 * wave)
    rise = 1.0 - np.exp(-beyond / (0.5 * c + 15.0))
    lumps = _lumps(p.crumple_seed, pu, pv, side, 3.0 * c + 60.0)
    lift = p.floor_ridge_mm * decay * rise * (0.6 * crest + 0.25 * crumple + 0.6 * lumps)
    lift = np.minimum(lift, 0.6 * amp + 0.4 * excess)
    z = np.where(floor, lift, z0) + 0.5 * t

    xyz = np.stack([r * np.cos(theta), r * np.sin(theta), z], -1).astype(np.float32)
    uv = np.stack([pu, pv], -1).astype(np.float32)
    return Surface(xyz, uv)
