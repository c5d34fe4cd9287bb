"""Fabrics of the synthetic world: physical, surface and appearance parameters, and their labels.

A `Fabric` holds the world's truth. Four physical parameters (paper section 3: thickness,
areal density, stiffness, stretchiness) are drawn like the 100 labelled fabrics of GelFabric.
The material (fibre: cotton, linen, wool, silk, synthetic, fleece) is drawn given them, as
real fabrics come (thick, fluffy ones are mostly fleece or wool; thin, light ones silk or
synthetic), and with the physics it sets what both senses perceive: the weave, yarn period,
relief, yarn evenness and hairiness a fingertip sensor feels, and the sheen, gloss, hairiness and
translucency a camera sees. Colour and print are drawn independently of everything else, so a
network must look past them. Human-style labels add the paper's measurement and rating noise,
and k-means on them gives the clusters.
"""

from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LABEL_COLUMNS",
    "MATERIALS",
    "PRINT_KINDS",
    "WEAVES",
    "Fabric",
    "LabelFile",
    "fabrics_from_labels",
    "human_labels",
    "kmeans",
    "make_fabric",
    "read_label_file",
    "reprinted",
    "sample_fabrics",
]

LABEL_COLUMNS = ("thickness_mm", "density", "stiffness", "stretchiness")
WEAVES = ("plain", "twill", "satin", "knit", "pile")
MATERIALS = ("cotton", "linen", "wool", "silk", "synthetic", "fleece")
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
        material: the fibre family, one of `MATERIALS`; with the weave it sets the optical and
            surface properties below.
        weave: surface structure, one of `WEAVES`.
        yarn_period_mm: period of the weave (or knit loop, or pile tuft) on the surface.
        relief_mm: peak-to-mean height of that surface structure.
        base_rgb: base colour, linear RGB in [0, 1].
        print_kind: one of `PRINT_KINDS`; ``solid`` for single-colour fabrics.
        print_rgb: further colours of the print (linear RGB).
        print_scale_mm: size of the print's motif on the fabric.
        print_angle: orientation of the print in radians.
        sheen: strength of the specular highlight, 0 matte ... 1 (silk satin).
        gloss: sharpness of that highlight (Blinn-Phong exponent): high for filament silk and
            polyester, low for spun cotton.
        fuzz: hairiness 0 ... 1: fibre ends standing off the surface. Felt as fine roughness;
            seen as a soft, bright rim at grazing angles and softer shading.
        side_mm: side of the (square) sample, about 1 m.
        appearance_seed: seed of the print's random pattern.
    """

    fabric_id: int
    thickness_mm: float
    density: float
    stiffness: float
    stretchiness: float
    material: str
    weave: str
    yarn_period_mm: float
    relief_mm: float
    base_rgb: tuple[float, float, float]
    print_kind: str
    print_rgb: tuple[tuple[float, float, float], ...]
    print_scale_mm: float
    print_angle: float
    sheen: float
    gloss: float
    fuzz: float
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

    @property
    def yarn_irregularity(self) -> float:
        """How much a yarn's thickness varies along its length (thick and thin places), as the
        standard deviation of the log of its diameter: filament yarns (silk, polyester) are
        nearly even, spun staple yarns are not, wool more than cotton, and flax's slubs most
        (the ranking of yarn evenness, CV% of mass, in the Uster Statistics: filament ~1-3%,
        combed cotton ~10-14%, wool ~15-20%, flax ~20-30%; the diameter's spread is about half
        the mass's, here raised so that a 64 px view of the 18 mm field still resolves it)."""
        return _IRREGULARITY[self.material]

    @property
    def translucency(self) -> float:
        """Share of light a single layer lets through, in [0, 1): thin, light cloth (voile,
        chiffon) glows; a heavy one does not. Beer-Lambert in the areal density, with filament
        fibres (silk, polyester) more transparent than spun or hairy ones, which scatter."""
        fibre = {
            "silk": 1.0,
            "synthetic": 0.9,
            "linen": 0.8,
            "cotton": 0.7,
            "wool": 0.45,
            "fleece": 0.3,
        }
        kg_m2 = self.density * _DENSITY_UNIT_KG_M2
        return float(fibre[self.material] * math.exp(-kg_m2 / 0.05))

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
            "material": self.material,
            "weave": self.weave,
            "yarn_period_mm": round(self.yarn_period_mm, 4),
            "relief_mm": round(self.relief_mm, 4),
            "compliance": round(self.compliance, 4),
            "yarn_irregularity": round(self.yarn_irregularity, 3),
            "print_kind": self.print_kind,
            "sheen": round(self.sheen, 3),
            "gloss": round(self.gloss, 2),
            "fuzz": round(self.fuzz, 3),
            "translucency": round(self.translucency, 4),
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


def _pick(rng: np.random.Generator, options: dict[str, float]) -> str:
    names = list(options)
    p = np.asarray([options[n] for n in names], np.float64)
    return str(names[int(rng.choice(len(names), p=p / p.sum()))])


def _material(thickness: float, density: float, stretch: float, rng: np.random.Generator) -> str:
    """The fibre family, drawn given the physics as real fabrics come."""
    bulk = density * 100.0 / thickness
    if thickness > 3.0 and bulk < 45.0:  # thick and fluffy: fleece, blankets, terry
        return _pick(rng, {"fleece": 0.6, "wool": 0.25, "cotton": 0.15})
    if stretch >= 0.5:  # jersey and other knits
        return _pick(rng, {"synthetic": 0.4, "cotton": 0.4, "wool": 0.2})
    if thickness < 1.2 and density < 1.2:  # thin and light: lining, chiffon, voile, shirting
        return _pick(rng, {"silk": 0.35, "synthetic": 0.4, "cotton": 0.15, "linen": 0.1})
    return _pick(rng, {"cotton": 0.4, "linen": 0.15, "wool": 0.2, "synthetic": 0.2, "silk": 0.05})


# Per material: the chance of a knit when the fabric stretches, the woven structures it comes
# in, and its optics and hairiness (specular strength, Blinn-Phong exponent, fuzz).
_WOVEN = {
    "cotton": {"plain": 0.55, "twill": 0.45},
    "linen": {"plain": 0.85, "twill": 0.15},
    "wool": {"twill": 0.6, "plain": 0.4},
    "silk": {"satin": 0.6, "plain": 0.4},
    "synthetic": {"satin": 0.4, "plain": 0.4, "twill": 0.2},
}
_KNIT_P = {"cotton": 0.6, "linen": 0.0, "wool": 0.7, "silk": 0.5, "synthetic": 0.75}
_IRREGULARITY = {  # Fabric.yarn_irregularity
    "cotton": 0.12,
    "linen": 0.3,
    "wool": 0.18,
    "silk": 0.03,
    "synthetic": 0.03,
    "fleece": 0.15,
}
_OPTICS = {  # sheen, gloss, fuzz
    "cotton": (0.05, 8.0, 0.3),
    "linen": (0.06, 10.0, 0.2),
    "wool": (0.02, 5.0, 0.6),
    "silk": (0.55, 40.0, 0.05),
    "synthetic": (0.3, 25.0, 0.12),
    "fleece": (0.0, 5.0, 0.9),
}


def _surface(
    material: str,
    thickness: float,
    density: float,
    stretch: float,
    rng: np.random.Generator,
    weave: str | None = None,
) -> tuple[str, float, float]:
    """Weave (unless given), yarn period and relief that follow from the material and the
    physics."""
    bulk = density * 100.0 / thickness
    r = rng.random()
    if weave is None:
        if material == "fleece" or (
            material == "cotton" and thickness > 3.0 and bulk < 45.0 and r < 0.5
        ):
            weave = "pile"  # fleece, faux fur, terry
        elif stretch >= 0.5 and r < _KNIT_P.get(material, 0.5):
            weave = "knit"
        else:
            weave = _pick(rng, _WOVEN.get(material, {"plain": 1.0}))
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


def _optics(material: str, weave: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """Sheen, gloss and fuzz of the material, each varying a little from fabric to fabric.

    A satin weave's long floats shine more than a plain weave of the same fibre; a knit's
    loops and a pile's tufts are hairier.
    """
    sheen, gloss, fuzz = _OPTICS[material]
    sheen *= {"satin": 1.5, "plain": 1.0, "twill": 1.1}.get(weave, 0.7)
    fuzz += {"knit": 0.1, "pile": 0.1}.get(weave, 0.0)
    sheen = float(np.clip(sheen * math.exp(0.25 * rng.standard_normal()), 0.0, 1.0))
    gloss = float(gloss * math.exp(0.2 * rng.standard_normal()))
    fuzz = float(np.clip(fuzz + 0.06 * rng.standard_normal(), 0.0, 1.0))
    return sheen, gloss, fuzz


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
) -> tuple[tuple[float, float, float], str, tuple[tuple[float, float, float], ...], float, float]:
    base = _random_colour(rng)
    # Paper section 3: about 60% of the fabrics are of a single colour, the rest printed.
    kind = "solid" if rng.random() < 0.6 else str(rng.choice(PRINT_KINDS[1:]))
    n_extra = 0 if kind == "solid" else int(rng.integers(1, 3))
    extra = tuple(_random_colour(rng) for _ in range(n_extra))
    scale = float(math.exp(rng.uniform(math.log(12.0), math.log(140.0))))
    angle = float(rng.choice([0.0, math.pi / 2, math.pi / 4, rng.uniform(0, math.pi)]))
    return base, kind, extra, scale, angle


def make_fabric(
    fabric_id: int,
    thickness: float,
    density: float,
    stiffness: float,
    stretch: float,
    seed: int,
    material: str | None = None,
    weave: str | None = None,
) -> Fabric:
    """A fabric with the given physics; material, surface and appearance drawn from
    ``(seed, id)`` (the material and surface given the physics, colour and print apart).

    ``material`` (one of `MATERIALS`) and ``weave`` (one of `WEAVES`), when given, are taken
    instead of drawn; what follows from them (relief, sheen, gloss, fuzz) is derived as usual.

    Raises:
        ValueError: an unknown material or weave.
    """
    if material is not None and material not in MATERIALS:
        raise ValueError(f"material {material!r} is not one of {', '.join(MATERIALS)}")
    if weave is not None and weave not in WEAVES:
        raise ValueError(f"weave {weave!r} is not one of {', '.join(WEAVES)}")
    srng = np.random.default_rng([seed, 11, fabric_id])
    arng = np.random.default_rng([seed, 12, fabric_id])
    if material is None:
        material = _material(thickness, density, stretch, srng)
    weave, period, relief = _surface(material, thickness, density, stretch, srng, weave)
    sheen, gloss, fuzz = _optics(material, weave, srng)
    base, kind, extra, scale, angle = _appearance(arng)
    return Fabric(
        fabric_id=fabric_id,
        thickness_mm=thickness,
        density=density,
        stiffness=stiffness,
        stretchiness=stretch,
        material=material,
        weave=weave,
        yarn_period_mm=period,
        relief_mm=relief,
        base_rgb=base,
        print_kind=kind,
        print_rgb=extra,
        print_scale_mm=scale,
        print_angle=angle,
        sheen=sheen,
        gloss=gloss,
        fuzz=fuzz,
        side_mm=float(srng.uniform(900.0, 1100.0)),
        appearance_seed=int(arng.integers(0, 2**31 - 1)),
    )


def reprinted(fabric: Fabric, rng: np.random.Generator) -> Fabric:
    """``fabric`` with its colour and print drawn afresh from ``rng`` (as `make_fabric` draws
    them), everything else kept: the same cloth dyed and printed otherwise."""
    base, kind, extra, scale, angle = _appearance(rng)
    return replace(
        fabric,
        base_rgb=base,
        print_kind=kind,
        print_rgb=extra,
        print_scale_mm=scale,
        print_angle=angle,
        appearance_seed=int(rng.integers(0, 2**31 - 1)),
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
    """A labels.csv keyed by ``fabric_id``, as the dataset reader parsed it (rows in file
    order), and its text: the world's labels.csv is a copy."""

    path: Path
    text: str
    ids: tuple[int, ...]
    values: tuple[dict[str, float], ...]
    """Per row, its known physical labels (`LABEL_COLUMNS`)."""
    clusters: tuple[int | None, ...]
    """Per row, its cluster (``cluster8``, or another ``cluster*`` column), None if unknown."""


def read_label_file(path: Path) -> LabelFile:
    """Read a labels.csv for label-conditioned rendering.

    The dataset reader (`lookfeel.data.labels.read_labels`) parses it, the one that `lookfeel
    data check` and `lookfeel train` read the world's copy with: synth refuses what they would
    refuse, in their words. Rendering needs more: numbered fabrics (a ``fabric_id`` column, not
    ``object``), at least one row, and physical labels that are numbers >= 0.

    Raises:
        ValueError: the first problem as the reader words it (``FILE:LINE: what``), and how
            many more there are: the file cannot be read or is not UTF-8, it has no
            ``fabric_id`` column, a row has a bad or repeated id or the wrong number of cells,
            a label is not a number or not finite (or, for a physical label, negative), a
            ``paper_split`` is not train, test or excluded, a cluster is not an integer >= 0,
            or there is no fabric row.
    """
    # Imported here, not at the top: `lookfeel.data` imports torch, which the spawned render
    # workers (they import this module) never need.
    from lookfeel.data.labels import read_labels
    from lookfeel.data.problems import Problem

    path = Path(path)
    table, problems = read_labels(path)
    problems = [p for p in problems if p.severity == "error"]  # not a warning of the reader's
    if not problems and table.key != "fabric_id":
        problems = [
            Problem(
                path, "no 'fabric_id' column in the header: synth renders fabrics by id", line=1
            )
        ]
    for row in table.rows.values():
        for name in LABEL_COLUMNS:
            raw = row.text.get(name)
            if raw is None:  # unknown
                continue
            if name in table.text_columns and not _is_number(raw):  # mostly words: text
                problems.append(
                    Problem(path, f"column {name!r}: {raw!r} is not a number", line=row.line)
                )
            elif row.values.get(name, 0.0) < 0:
                problems.append(
                    Problem(path, f"column {name!r}: {raw!r} must be >= 0", line=row.line)
                )
    if not problems and not table.rows:
        problems = [Problem(path, "no fabric rows")]
    errors = sorted(problems, key=lambda p: p.line or 0)
    if errors:
        more = f" (and {len(errors) - 1} more problem(s) in this file)" if len(errors) > 1 else ""
        raise ValueError(f"{errors[0]}{more}")
    rows = list(table.rows.values())
    return LabelFile(
        path,
        # The world copies the file as it is; the reader read it a moment ago.
        path.read_text(encoding="utf-8-sig"),
        tuple(table.rows),
        tuple({n: r.values[n] for n in LABEL_COLUMNS if n in r.values} for r in rows),
        tuple(r.cluster for r in rows),
    )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def fabrics_from_labels(lf: LabelFile, seed: int) -> list[Fabric]:
    """One fabric per row, its physics read from the labels, ids kept.

    Missing labels (GelFabric's fabrics 101-119 have a cluster only) are filled from the
    fabrics of the same cluster in the file (median, with a small per-fabric spread), else
    from the whole file, else from the prior; stiffness is clipped at 0.3, thickness and
    density at small positive values. Surface and appearance are drawn from ``(seed, id)``.
    """
    values = {name: [row.get(name) for row in lf.values] for name in LABEL_COLUMNS}
    clusters = lf.clusters
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
