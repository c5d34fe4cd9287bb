"""What an evaluation returns: flat metrics, and the structured results the figures need."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lookfeel.config import DataConfig, EvalConfig
from lookfeel.embedding import EmbeddedItems
from lookfeel.metrics import Confusion, QuerySet, ReliabilityCurve
from lookfeel.metrics.cross_map import CrossMap
from lookfeel.modality import Modality, Pair

__all__ = [
    "CalibrationResult",
    "EvalResult",
    "GlanceExample",
    "GlanceGallery",
    "PickExample",
    "PressCurve",
]


@dataclass(frozen=True)
class CalibrationResult:
    """How calibrated the match probabilities ``P ∝ exp(-c D^2)`` of one pair are (paper
    section 5.2), measured on the test items.

    Not to be confused with `lookfeel.index.PairCalibration`, what a fabric library fits to
    match new images (c, an unknown class and its threshold).

    Attributes:
        pair: the pair.
        c: the coefficient used.
        c_source: ``"fixed"`` (EvalConfig.c), ``"fitted"`` (maximum likelihood on the reference
            fabrics) or ``"paper"`` (0.085).
        reliability: accuracy against confidence of each query's most probable gallery fabric.
        accuracy: fraction of queries whose most probable gallery fabric is their own.
        confidence: mean probability of the most probable fabric.
        nll: mean ``-log P(own fabric)``.
        n_fabrics: gallery fabrics the probabilities spread over.
        confusion: fabric-level confusion, fabrics ordered by cluster (Figure 8), for the figure
            pairs only.
        cluster_confusion: cluster-level confusion (Figure 8b), when clusters are known.
        fit_fabrics: the reference fabrics c was fitted on (those whose queries had an item of
            their own to find); 0 when c was not fitted.
        nll_se: the standard error of ``nll`` over the query fabrics (the spread of their own
            mean NLLs over the square root of their number; queries of one fabric are not
            independent); NaN with fewer than two fabrics.
        accuracy_ci: the 95% bootstrap interval of ``accuracy`` over the query fabrics, as the
            pick scores' (NaN without resamples, ``n_boot`` 0, or without scored queries).
    """

    pair: Pair
    c: float
    c_source: str
    reliability: ReliabilityCurve
    accuracy: float
    confidence: float
    nll: float
    n_fabrics: int
    confusion: Confusion | None = None
    cluster_confusion: Confusion | None = None
    fit_fabrics: int = 0
    nll_se: float = math.nan
    accuracy_ci: tuple[float, float] = (math.nan, math.nan)

    @property
    def nll_chance(self) -> float:
        """The NLL of a uniform guess over the gallery fabrics, ``log n_fabrics``."""
        return math.log(max(self.n_fabrics, 1))

    @property
    def overconfident(self) -> bool:
        """Whether the NLL is clearly above chance's: by more than twice its standard error
        over the query fabrics (`nll_se`; by any amount where that is not known), or to more
        than twice chance's (a few fabrics given next to no probability spread the error
        wide, yet say the same). A uniform guess over the gallery fabrics would then score
        better, so c is larger than these distances support (a smaller c, down to the
        uniform guess at c = 0, does better)."""
        if not math.isfinite(self.nll):
            return False
        margin = 2 * self.nll_se if math.isfinite(self.nll_se) else 0.0
        return self.nll > min(self.nll_chance + margin, 2 * self.nll_chance)


@dataclass(frozen=True)
class PickExample:
    """One drawn pick-1-of-n trial, for a figure like the paper's Figure 6.

    Attributes:
        pair: the pair.
        query_rows: the query's rows in the query modality's `EmbeddedItems` (several for a
            pooled multi-press touch query).
        candidates: gallery rows of the candidates, nearest first.
        distances: distance D from the query to each candidate, in that order.
        true_position: index into ``candidates`` of the true (same-fabric) candidate.
    """

    pair: Pair
    query_rows: tuple[int, ...]
    candidates: tuple[int, ...]
    distances: tuple[float, ...]
    true_position: int


@dataclass(frozen=True)
class GlanceGallery:
    """The gallery fabrics nearest to one glance query, in one modality.

    Attributes:
        modality: the gallery's modality (depth or colour).
        rows: per fabric shown, nearest first, the row of its item nearest to the query in the
            modality's `EmbeddedItems`.
        fabrics: the fabric of each row.
        true_rank: where the query's own fabric ranks among all ``n_fabrics`` (1 = nearest;
            0 when it has no item in this modality).
        n_fabrics: the gallery's fabrics, all ranked.
        mapped: ranked through the cross-modal map (`EvalResult.cross_maps`), not by the
            embedding's own distances.
    """

    modality: Modality
    rows: tuple[int, ...]
    fabrics: tuple[int, ...]
    true_rank: int
    n_fabrics: int
    mapped: bool = False


@dataclass(frozen=True)
class GlanceExample:
    """One touch query at a glance: the drapes and photos nearest to it, and what it
    predicts the fabric feels like beside what it is.

    Attributes:
        query_rows: the query's rows in the touch `EmbeddedItems` (its pooled presses).
        fabric: the query's fabric.
        galleries: the nearest fabrics in each look modality (depth, colour) there is.
        label_names: the label columns.
        predicted: per label, the mean label of the training (reference) fabrics whose touch
            is nearest to the query (NaN where none is known).
        truth: per label, the query fabric's own label (NaN where unknown).
        neighbours: the training fabrics ``predicted`` averages, nearest first.
        n_reference: the training fabrics with labels they were chosen among (the query's own
            fabric left out); ``neighbours`` is at most half of them
            (`lookfeel.metrics.properties.knn_neighbours`).
    """

    query_rows: tuple[int, ...]
    fabric: int
    galleries: tuple[GlanceGallery, ...]
    label_names: tuple[str, ...] = ()
    predicted: tuple[float, ...] = ()
    truth: tuple[float, ...] = ()
    neighbours: tuple[int, ...] = ()
    n_reference: int = 0


@dataclass(frozen=True)
class PressCurve:
    """Touch-query accuracy against the number of pooled presses, for one gallery modality."""

    gallery: Modality
    presses: NDArray[np.int64]
    """(P,) press counts scored."""
    value: NDArray[np.float64]
    """(P,) exact top-k."""
    low: NDArray[np.float64]
    high: NDArray[np.float64]
    chance: NDArray[np.float64]


@dataclass(frozen=True)
class EvalResult:
    """Everything `evaluate_embeddings` measured.

    Attributes:
        metrics: flat JSON-able floats keyed ``{query}_to_{gallery}_{metric}`` (see
            `lookfeel.evaluate`), plus ``property_*`` and calibration keys.
        config: the evaluation settings (``presses`` resolved).
        pairs: the scored pairs, in order.
        calibration: per pair, c and the calibration of ``P ∝ exp(-c D^2)``.
        examples: per figure pair, drawn pick trials.
        properties: modality -> probe -> label -> {r2, spearman, mae, mae_chance, n_train,
            n_test}, and for ``knn`` k (the neighbours averaged: at most half of ``n_train``).
        embedded: the scored embeddings (the test items).
        clusters: fabric id -> cluster (None where unknown).
        notes: what was skipped or approximated, and why.
        info: provenance (split, checkpoint, step, data root, ...).
        data_config: how images were preprocessed, to show example images (None: unknown).
        glance: touch queries at a glance (`GlanceExample`), when touch and a look modality
            were scored.
        cross_maps: the cross-modal map of every pair scored through one (``*_mapped`` keys),
            fitted on the reference fabrics (`EvalConfig.cross_map`).
        not_scored: pairs none of whose queries could be scored (none has an item of its own
            fabric to find, e.g. touch to touch when every test fabric's presses all went into
            its query), each with the reason (`lookfeel.evaluate.core.no_query_scored`); their
            ``top{k}`` and calibration keys are NaN.
        names: fabric id -> the object's name, for data that names its objects
            (``videos/<name>_<n>.mov``, `lookfeel.data.Fabric.name`); empty for numbered
            fabrics (GelFabric) or when the dataset is unknown. The report shows these names
            in place of the ids (`fabric_label`).
        pooled_queries: the pooled queries of a modality (touch queries of ``config.presses``
            presses, in the space the pairs were scored in), as every pair scored them: as
            queries, and as the candidates of another modality's queries. The controls
            (`lookfeel.evaluate.controls`) score the same groups of presses. Empty when no
            query pools presses.
    """

    metrics: dict[str, float]
    config: EvalConfig
    pairs: tuple[Pair, ...]
    calibration: dict[Pair, CalibrationResult]
    examples: dict[Pair, tuple[PickExample, ...]]
    properties: dict[Modality, dict[str, dict[str, dict[str, float]]]]
    embedded: Mapping[Modality, EmbeddedItems]
    clusters: dict[int, int | None] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    info: dict[str, Any] = field(default_factory=dict)
    data_config: DataConfig | None = None
    glance: tuple[GlanceExample, ...] = ()
    cross_maps: dict[Pair, CrossMap] = field(default_factory=dict)
    not_scored: dict[Pair, str] = field(default_factory=dict)
    names: dict[int, str] = field(default_factory=dict)
    pooled_queries: dict[Modality, QuerySet] = field(default_factory=dict)

    @property
    def unit(self) -> str:
        """What the report calls one of the things told apart: ``"object"`` for data that
        names its objects (`names`), ``"fabric"`` otherwise."""
        return "object" if self.names else "fabric"

    def fabric_label(self, fabric_id: int) -> str:
        """How the report names a fabric: ``sponge`` for a named object, ``F12`` otherwise."""
        return self.names.get(int(fabric_id), f"F{int(fabric_id)}")

    @property
    def figure_pairs(self) -> tuple[Pair, ...]:
        """The pairs with confusion matrices (and figures), in order."""
        return tuple(p for p, c in self.calibration.items() if c.confusion is not None)

    def press_curves(self, k: int = 1) -> list[PressCurve]:
        """Exact top-k of touch queries against pooled presses, one curve per gallery modality.

        Read from the ``touch_to_{gallery}_presses{P}_top{k}`` metrics.
        """
        out = []
        for g in Modality:
            prefix = f"{Pair(Modality.TOUCH, g)}_presses"
            ps = sorted(
                int(key[len(prefix) :].split("_", 1)[0])
                for key in self.metrics
                if key.startswith(prefix) and key.endswith(f"_top{k}")
            )
            if not ps:
                continue

            def get(p: int, suffix: str, prefix: str = prefix) -> float:
                return self.metrics.get(f"{prefix}{p}_top{k}{suffix}", float("nan"))

            out.append(
                PressCurve(
                    gallery=g,
                    presses=np.array(ps, dtype=np.int64),
                    value=np.array([get(p, "") for p in ps]),
                    low=np.array([get(p, "_ci_low") for p in ps]),
                    high=np.array([get(p, "_ci_high") for p in ps]),
                    chance=np.array([get(p, "_chance") for p in ps]),
                )
            )
        return out
