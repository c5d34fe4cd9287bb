"""Fabrics of the synthetic world: physical, surface and appearance parameters, and their labels.

A `Fabric` holds the world's truth. Four physical parameters (paper section 3: thickness,
areal density, stiffness, stretchiness) are drawn like the 100 labelled fabrics of GelFabric;
the surface (weave, yarn period, relief, pile) follows from them; the appearance (colour,
print, sheen) is drawn independently of them, so a network must look past it. Human-style
labels add the paper's measurement and rating noise, and k-means on them gives the clusters.
"""

from __future__ import annotations

import colorsys
import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LABEL_COLUMNS",
    "PRINT_KINDS",
    "WEAVES",
    "Fabric",
    "LabelFile",
    "fabrics_from_labels",
    "human_labels",
    "kmeans",
    "make_fabric",
    "read_label_file",
    "sample_fabrics",
]

LABEL_COLUMNS = ("thickness_mm", "density", "stiffness", "stretchiness")
WEAVES = ("plain", "twill", "satin", "knit", "pile")
PRINT_KINDS = ("solid", "stripes", "checks", "dots", "blobs", "camo")

# Marginal deciles (0, 10, ..., 100 %) of the 100 labelled GelFabric fabrics, and the
# correlation of their normal scores (thickness, density, stiffness, stretchiness): a Gaussian
# copula with these marginals draws fabrics "like the real labels".
_T_DECILES = (0.5, 1.39, 1.58, 2.0, 2.16, 2.4, 2.88, 3.0, 4.62, 5.55, 12.0)
_D_DECILES = (0.2, 0.79, 1.09, 1.29, 1.42, 1.54, 1.74, 1.98, 2.3, 2.81, 4.95)
_S_DECILES = (0.9, 1.29, 2.0, 2.47, 2.8, 2.9, 3.3, 3.5, 4.0, 4.51, 5.5)
_STRETCH_P = (0.47, 0.15, 0.38)  # non-stretchable, stretchable, extremely stretchable
_CORR = np.array(
    [
        [1.00, 0.73, 0.12, 0.42],
        [0.73, 1.00, 0.37, 0.11],
        [0.12, 0.37, 1.00, -0.36],
        [0.42, 0.11, -0.36, 1.00],
    ]
)
_CHOL = np.linalg.cholesky(_CORR)

# Units. The density label's unit is not documented; read as 100 g/m^2 it spans 20-500 g/m^2,
# the range of real apparel, bedding and upholstery fabrics. Flexural rigidity follows the
# stiffness rating log-linearly (ratings are perceptual): 15 uN m at rating 3, x2.5 per point.
_G = 9.81
_DENSITY_UNIT_KG_M2 = 0.1
_B_AT_3 = 15e-6
_B_PER_POINT = 0.9


@dataclass(frozen=True)
class Fabric:
    """One fabric of the world: the truth from which every image is rendered.

    Attributes:
        fabric_id: the id written into file names (``F0001``).
        thickness_mm, density, stiffness, stretchiness: the physical parameters on the scales
            of the paper's labels (density in label units, read as 100 g/m^2; stiffness on the
            0-5+ rating scale; stretchiness 0, 0.5 or 1).
        weave: surface structure, one of `WEAVES`.
        yarn_period_mm: period of the weave (or knit loop, or pile tuft) on the surface.
        relief_mm: peak-to-mean height of that surface structure.
        base_rgb: base colour, linear RGB in [0, 1].
        print_kind: one of `PRINT_KINDS`; ``solid`` for single-colour fabrics.
        print_rgb: further colours of the print (linear RGB).
        print_scale_mm: size of the print's motif on the fabric.
        print_angle: orientation of the print in radians.
        sheen: 0 matte ... 1 satin-like specular and velvet-like rim.
        side_mm: side of the (square) sample, about 1 m.
        appearance_seed: seed of the print's random pattern.
    """

    fabric_id: int
    thickness_mm: float
    density: float
    stiffness: float
    stretchiness: float
    weave: str
    yarn_period_mm: float
    relief_mm: float
    base_rgb: tuple[float, float, float]
    print_kind: str
    print_rgb: tuple[tuple[float, float, float], ...]
    print_scale_mm: float
    print_angle: float
    sheen: float
    side_mm: float
    appearance_seed: int

    @property
    def weight_n_m2(self) -> float:
        """Weight per area, N/m^2."""
        return self.density * _DENSITY_UNIT_KG_M2 * _G

    @property
    def bending_rigidity_nm(self) -> float:
        """Flexural rigidity per unit width, N m."""
        return _B_AT_3 * math.exp(_B_PER_POINT * (self.stiffness - 3.0))

    @property
    def bending_length_mm(self) -> float:
        """Bending length ``(B / w) ** (1/3)`` in mm: the length scale of every drape feature."""
        return 1000.0 * (self.bending_rigidity_nm / self.weight_n_m2) ** (1.0 / 3.0)

    @property
    def bulk_density(self) -> float:
        """Mass per volume in g/m^2 per mm: low for fleece and terry, high for denim."""
        return self.density * 100.0 / self.thickness_mm

    @property
    def compliance(self) -> float:
        """Share of a press taken up by the gel rather than by the fabric, in (0, 1).

        Springs in series: a dense fabric is stiff in compression and the gel takes the press
        (its texture shows); a fluffy one squashes and the gel hardly moves.
        """
        k = (self.bulk_density / 80.0) ** 1.5
        return float(np.clip(k / (1.0 + k), 0.12, 0.9))

    def truth(self) -> dict[str, float | str]:
        """The world's parameters of this fabric as plain values (for ``synth.json``)."""
        return {
            "fabric_id": self.fabric_id,
            "thickness_mm": round(self.thickness_mm, 4),
            "density": round(self.density, 4),
            "stiffness": round(self.stiffness, 4),
            "stretchiness": self.stretchiness,
            "bending_length_mm": round(self.bending_length_mm, 3),
            "bending_rigidity_uNm": round(self.bending_rigidity_nm * 1e6, 4),
            "weave": self.weave,
            "yarn_period_mm": round(self.yarn_period_mm, 4),
            "relief_mm": round(self.relief_mm, 4),
            "compliance": round(self.compliance, 4),
            "print_kind": self.print_kind,
            "sheen": round(self.sheen, 3),
        }


# ---------------------------------------------------------------------------------------------
# Drawing fabrics.


def _quantile(u: float, deciles: tuple[float, ...], log: bool) -> float:
    knots = np.linspace(0.0, 1.0, len(deciles))
    vals = np.log(deciles) if log else np.asarray(deciles)
    x = float(np.interp(u, knots, vals))
    return math.exp(x) if log else x


def _normal_cdf(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def _physics(rng: np.random.Generator) -> tuple[float, float, float, float]:
    z = _CHOL @ rng.standard_normal(4)
    u = [_normal_cdf(float(v)) for v in z]
    thickness = _quantile(u[0], _T_DECILES, log=True)
    density = _quantile(u[1], _D_DECILES, log=True)
    stiffness = _quantile(u[2], _S_DECILES, log=False)
    stretch = 0.0 if u[3] < _STRETCH_P[0] else (0.5 if u[3] < 1.0 - _STRETCH_P[2] else 1.0)
    return thickness, density, stiffness, stretch


def _surface(
    thickness: float, density: float, stretch: float, rng: np.random.Generator
) -> tuple[str, float, float]:
    """Weave, yarn period and relief that follow from the physical parameters."""
    bulk = density * 100.0 / thickness
    r = rng.random()
    if thickness > 3.0 and bulk < 45.0 and r < 0.85:
        weave = "pile"  # thick and fluffy: terry, fleece, faux fur
    elif stretch >= 0.5 and r < 0.35 + 0.5 * stretch:
        weave = "knit"
    else:
        weave = str(rng.choice(["plain", "twill", "satin"], p=[0.5, 0.32, 0.18]))
    jitter = math.exp(0.2 * rng.standard_normal())
    # Yarn diameter grows with thickness (a plain weave is about two yarns thick).
    period = float(np.clip(0.24 * thickness**0.55 * jitter, 0.12, 1.6))
    # Relief: how far the yarn crossings (loops, tufts) stand above the mean surface.
    if weave == "knit":
        period = min(2.4, period * 2.2)
        relief = 0.2 * period
    elif weave == "pile":
        period = min(2.0, 0.35 * thickness**0.6 * jitter)
        relief = min(0.5, 0.05 * thickness)
    elif weave == "satin":
        relief = 0.08 * period
    else:
        relief = 0.18 * period
    return weave, period, float(relief)


def _srgb_to_linear(c: float) -> float:
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _random_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    h = rng.random()
    s = 0.9 * rng.beta(1.4, 1.4)
    v = rng.uniform(0.15, 0.93)
    r, g, b = colorsys.hsv_to_rgb(h, s, v)
    return (_srgb_to_linear(r), _srgb_to_linear(g), _srgb_to_linear(b))


def _appearance(
    rng: np.random.Generator,
) -> tuple[
    tuple[float, float, float], str, tuple[tuple[float, float, float], ...], float, float, float
]:
    base = _random_colour(rng)
    # Paper section 3: about 60% of the fabrics are of a single colour, the rest printed.
    kind = "solid" if rng.random() < 0.6 else str(rng.choice(PRINT_KINDS[1:]))
    n_extra = 0 if kind == "solid" else int(rng.integers(1, 3))
    extra = tuple(_random_colour(rng) for _ in range(n_extra))
    scale = float(math.exp(rng.uniform(math.log(12.0), math.log(140.0))))
    angle = float(rng.choice([0.0, math.pi / 2, math.pi / 4, rng.uniform(0, math.pi)]))
    sheen = float(rng.beta(1.1, 3.5))
    return base, kind, extra, scale, angle, sheen


def make_fabric(
    fabric_id: int,
    thickness: float,
    density: float,
    stiffness: float,
    stretch: float,
    seed: int,
) -> Fabric:
    """A fabric with the given physics; surface and appearance drawn from ``(seed, id)``."""
    srng = np.random.default_rng([seed, 11, fabric_id])
    arng = np.random.default_rng([seed, 12, fabric_id])
    weave, period, relief = _surface(thickness, density, stretch, srng)
    base, kind, extra, scale, angle, sheen = _appearance(arng)
    return Fabric(
        fabric_id=fabric_id,
        thickness_mm=thickness,
        density=density,
        stiffness=stiffness,
        stretchiness=stretch,
        weave=weave,
        yarn_period_mm=period,
        relief_mm=relief,
        base_rgb=base,
        print_kind=kind,
        print_rgb=extra,
        print_scale_mm=scale,
        print_angle=angle,
        sheen=sheen,
        side_mm=float(srng.uniform(900.0, 1100.0)),
        appearance_seed=int(arng.integers(0, 2**31 - 1)),
    )


def sample_fabrics(n: int, seed: int) -> list[Fabric]:
    """Fabrics 1..n, each drawn from its own stream ``(seed, id)``.

    Fabric ``k`` is the same fabric whatever ``n`` is, so a small world is a prefix of a big one.
    """
    out = []
    for fid in range(1, n + 1):
        t, d, s, st = _physics(np.random.default_rng([seed, 10, fid]))
        out.append(make_fabric(fid, t, d, s, st, seed))
    return out


# ---------------------------------------------------------------------------------------------
# Labels as people would write them down.


def human_labels(fabric: Fabric, seed: int) -> dict[str, float]:
    """Labels with the paper's noise: ruler, scale, 5 raters' mean, a 3-level stretch guess.

    Ruler readings are rounded to 0.1 mm with about 8% error; the scale is accurate to ~3%;
    each of 5 raters scores stiffness to the nearest half point with their own bias; the
    stretchiness class is off by one level 10% of the time.
    """
    rng = np.random.default_rng([seed, 13, fabric.fabric_id])
    thickness = max(0.1, round(fabric.thickness_mm * math.exp(0.08 * rng.standard_normal()), 1))
    density = round(fabric.density * math.exp(0.03 * rng.standard_normal()), 6)
    scores = fabric.stiffness + 0.3 * rng.standard_normal(5) + 0.5 * rng.standard_normal(5)
    stiffness = round(float(np.mean(np.clip(np.round(scores * 2) / 2, 0.0, 6.0))), 1)
    stretch = fabric.stretchiness
    if rng.random() < 0.1:
        stretch = float(np.clip(stretch + rng.choice([-0.5, 0.5]), 0.0, 1.0))
    return {
        "thickness_mm": thickness,
        "density": density,
        "stiffness": stiffness,
        "stretchiness": stretch,
    }


def kmeans(x: NDArray[np.float64], k: int, seed: int, n_init: int = 10) -> NDArray[np.int64]:
    """Cluster rows of ``x`` (standardised first) into ``k`` clusters, as the paper does.

    Plain k-means++ and Lloyd iterations in NumPy, so the result is bit-reproducible.
    Clusters are numbered by increasing mean of the first column (as `lookfeel.data` does),
    so the numbering does not depend on the initialisation.

    Args:
        x: (N, C) label matrix without missing values.
        k: number of clusters (at most N).
        seed: seed of the initialisations.
    """
    n = x.shape[0]
    k = min(k, n)
    std = x.std(axis=0)
    z = (x - x.mean(axis=0)) / np.where(std > 0, std, 1.0)
    rng = np.random.default_rng([seed, 14])
    best: tuple[float, NDArray[np.int64], NDArray[np.float64]] | None = None
    for _ in range(n_init):
        centres = [z[rng.integers(n)]]
        for _ in range(1, k):
            d2 = np.min([((z - c) ** 2).sum(1) for c in centres], axis=0)
            p = d2 / d2.sum() if d2.sum() > 0 else np.full(n, 1.0 / n)
            centres.append(z[rng.choice(n, p=p)])
        c = np.array(centres)
        assign = np.zeros(n, np.int64)
        for _ in range(100):
            assign = np.argmin(((z[:, None, :] - c[None]) ** 2).sum(-1), axis=1)
            new = np.array(
                [z[assign == j].mean(0) if np.any(assign == j) else c[j] for j in range(k)]
            )
            if np.allclose(new, c):
                break
            c = new
        inertia = float(((z - c[assign]) ** 2).sum())
        if best is None or inertia < best[0] - 1e-12:
            best = (inertia, assign, c)
    assert best is not None
    _, assign, c = best
    order = np.argsort(c[:, 0], kind="stable")
    rename = np.empty(k, np.int64)
    rename[order] = np.arange(k)
    return rename[assign]


# ---------------------------------------------------------------------------------------------
# Label-conditioned mode: fabrics from a labels.csv.


@dataclass(frozen=True)
class LabelFile:
    """A labels.csv as read: its header and its rows (cells as written), in file order."""

    path: Path
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    ids: tuple[int, ...]


def _parse_id(text: str) -> int | None:
    t = text.strip()
    if t[:1] in ("F", "f"):
        t = t[1:]
    return int(t) if t.isdigit() else None


def read_label_file(path: Path) -> LabelFile:
    """Read a labels.csv for label-conditioned rendering.

    Raises:
        ValueError: the file is missing, has no ``fabric_id`` column, a row has a bad or
            repeated id or the wrong number of cells, or a physical label is not a number;
            the message names the file and line.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise ValueError(f"cannot read labels file {path}: {e.strerror}") from None
    reader = csv.reader(text.splitlines())
    header = tuple(h.strip() for h in next(reader, []))
    if "fabric_id" not in header:
        raise ValueError(f"{path}: no 'fabric_id' column in the header (line 1)")
    col = header.index("fabric_id")
    rows, ids = [], []
    for line, cells in enumerate(reader, start=2):
        if not cells or all(not c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            raise ValueError(
                f"{path}, line {line}: {len(cells)} cells but the header has {len(header)}"
            )
        fid = _parse_id(cells[col])
        if fid is None or fid < 0:
            raise ValueError(f"{path}, line {line}: fabric_id {cells[col]!r} is not an integer")
        if fid in ids:
            raise ValueError(f"{path}, line {line}: fabric {fid} appears twice")
        for name in LABEL_COLUMNS:
            if name in header:
                raw = cells[header.index(name)].strip()
                if raw and raw.lower() not in ("na", "n/a", "nan", "none", "null"):
                    try:
                        v = float(raw)
                    except ValueError:
                        raise ValueError(
                            f"{path}, line {line}: column {name!r}: {raw!r} is not a number"
                        ) from None
                    if not math.isfinite(v) or v < 0:
                        raise ValueError(
                            f"{path}, line {line}: column {name!r}: {raw!r} must be >= 0"
                        )
        rows.append(tuple(cells))
        ids.append(fid)
    if not rows:
        raise ValueError(f"{path}: no fabric rows")
    return LabelFile(path, header, tuple(rows), tuple(ids))


def _cell(lf: LabelFile, row: tuple[str, ...], name: str) -> float | None:
    if name not in lf.header:
        return None
    raw = row[lf.header.index(name)].strip()
    try:
        return float(raw)
    except ValueError:
        return None


def fabrics_from_labels(lf: LabelFile, seed: int) -> list[Fabric]:
    """One fabric per row, its physics read from the labels, ids kept.

    Missing labels (GelFabric's fabrics 101-119 have a cluster only) are filled from the
    fabrics of the same cluster in the file (median, with a small per-fabric spread), else
    from the whole file, else from the prior; stiffness is clipped at 0.3, thickness and
    density at small positive values. Surface and appearance are drawn from ``(seed, id)``.
    """
    cluster_col = next((h for h in lf.header if h.lower().startswith("cluster")), None)
    if "cluster8" in lf.header:
        cluster_col = "cluster8"
    values = {name: [_cell(lf, r, name) for r in lf.rows] for name in LABEL_COLUMNS}
    clusters = [_cell(lf, r, cluster_col) if cluster_col is not None else None for r in lf.rows]
    prior = dict(zip(LABEL_COLUMNS, (2.4, 1.54, 2.9, 0.5), strict=True))
    out = []
    for i, fid in enumerate(lf.ids):
        rng = np.random.default_rng([seed, 15, fid])
        got: dict[str, float] = {}
        for name in LABEL_COLUMNS:
            v = values[name][i]
            if v is not None:
                got[name] = v
                continue
            same = [
                w
                for w, c in zip(values[name], clusters, strict=True)
                if w is not None and clusters[i] is not None and c == clusters[i]
            ]
            pool = same or [w for w in values[name] if w is not None]
            centre = float(np.median(pool)) if pool else prior[name]
            spread = float(np.std(pool)) if len(pool) > 1 else 0.2 * centre
            if name == "stretchiness":
                got[name] = float(np.clip(np.round(2 * centre) / 2, 0.0, 1.0))
            else:
                got[name] = centre + 0.5 * spread * float(rng.standard_normal())
        out.append(
            make_fabric(
                fid,
                max(0.1, got["thickness_mm"]),
                max(0.05, got["density"]),
                max(0.3, got["stiffness"]),
                float(np.clip(got["stretchiness"], 0.0, 1.0)),
                seed,
            )
        )
    return out
