"""Evaluation configuration: the paper's protocols (section 5) and what is added around them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from lookfeel.config._core import ConfigError, check_choices, parse_pairs
from lookfeel.modality import Modality, Pair

__all__ = ["EvalConfig", "ProbeKind", "Space"]

ProbeKind = Literal["knn", "ridge"]
"""Physical-property probes: k nearest neighbours or ridge regression."""
Space = Literal["embedding", "labels"]
"""Where queries meet galleries: the model's embedding, or its map onto the labels."""


@dataclass(frozen=True)
class EvalConfig:
    """How embeddings are scored by `lookfeel.evaluate` (paper section 5).

    Defaults are the paper's protocol: pick 1 of 10, top 1 and top 3, 15 queries per fabric
    drawn 10 times for the sampled form; the exact expectation of the same experiment is
    always computed beside it.
    """

    n: int = 10
    """Candidates per pick (the true item and ``n - 1`` distractor fabrics; paper: 10). With
    fewer gallery fabrics, all of them are offered and the report says so."""
    ks: tuple[int, ...] = (1, 3)
    """Top-k of pick k of n (paper: top 1 and top 3)."""
    recall_ks: tuple[int, ...] = (1, 5, 10)
    """The k of recall@k over the whole gallery."""
    sampled: bool = True
    """Also run the paper's sampled protocol (``top{k}_sampled`` with a standard error)."""
    queries_per_fabric: int = 15
    """Sampled protocol: queries drawn per fabric (paper: 15 GelSight inputs per fabric)."""
    repeats: int = 10
    """Sampled protocol: candidate draws per query (paper: 10)."""
    released_variant: bool = False
    """Also run the authors' released code's variant of the sampled protocol, where distractor
    fabrics may include the query's own (another of its items counts as a wrong candidate):
    ``top{k}_released`` keys."""
    n_boot: int = 1000
    """Bootstrap resamples of the test fabrics for the intervals (0: no intervals)."""
    alpha: float = 0.05
    """Intervals cover 1 - alpha (0.05: 95%)."""
    seed: int = 0
    """Seeds every draw: the sampled protocol, bootstrap, press groups and pick examples
    (>= 0)."""
    presses: int | None = None
    """Presses per touch query in the main ``touch_to_*`` keys, max-pooled like the
    Multi-input Net (paper: 3). ``None``: the checkpoint's ``data.presses`` (1 for bare
    embeddings). Above 1, the touch candidates of another modality's queries are pooled the
    same way (the Multi-input Net embeds touch from its presses wherever touch is); touch to
    touch picks among single presses."""
    max_presses: int = 5
    """Touch queries of P = 1 .. max_presses pooled presses are scored for the
    accuracy-against-presses curve (``touch_to_{gallery}_presses{P}_*`` keys)."""
    c: float | None = None
    """Fixed c in ``P ∝ exp(-c D^2)`` (paper section 5.2). ``None``: fitted by maximum likelihood
    on the reference (training) fabrics when they are given and ``fit_c``, else the paper's
    0.085."""
    fit_c: bool = True
    """Fit c on the reference fabrics (per pair) when ``c`` is not fixed."""
    n_bins: int = 10
    """Equal-width confidence bins of the reliability curve and the ECE."""
    probes: tuple[ProbeKind, ...] = ("knn", "ridge")
    """Physical-property probes fitted on the reference fabrics: ``knn`` and/or ``ridge``."""
    probe_k: int = 5
    """Neighbours of the k-NN probe."""
    figure_pairs: tuple[Pair, ...] = (Pair(Modality.TOUCH, Modality.DEPTH),)
    """Pairs (``query_to_gallery``) that get confusion, reliability and pick-example figures
    (paper Figures 6-7 show touch to depth); when none is present, the first cross-modal pair."""
    examples: int = 4
    """Queries shown in the pick-examples figure (half picked right, half wrong, when both
    occur)."""
    space: Space = "embedding"
    """``labels``: score every pair in label space (`lookfeel.metrics.label_space`): each
    modality's embeddings mapped onto the labels' normal scores by a ridge fitted on the
    reference (training) fabrics, a query matched to the gallery items whose predicted labels
    are nearest. Needs labels and reference fabrics (a checkpoint's split has them)."""
    cross_map: bool = True
    """With reference (training) fabrics, also score every pair of two modalities through a
    cross-modal map (`lookfeel.metrics.cross_map`: linear maps between the two embedding
    spaces, fitted on the reference fabrics' mean embeddings, no labels used), keys
    ``{pair}_top{k}_mapped``. Not in label space (``space: labels``)."""
    background_control: bool = True
    """Evaluating a checkpoint whose model has a depth branch: score every pair with depth
    again with each test depth image's background replaced by another fabric's, the cloth
    kept (`lookfeel.data.background_swap.BackgroundControl`), beside raw pixels
    (``{pair}_top{k}_swapped`` keys). A model that reads the cloth, not the room, scores the
    same."""

    def __post_init__(self) -> None:
        check_choices(self, "eval")
        object.__setattr__(
            self, "figure_pairs", parse_pairs(self.figure_pairs, "eval.figure_pairs")
        )
        if self.n < 2:
            raise ConfigError(f"eval.n: must be >= 2, got {self.n}")
        for key, ks in (("ks", self.ks), ("recall_ks", self.recall_ks)):
            if not ks or min(ks) < 1:
                raise ConfigError(f"eval.{key}: must be positive integers, got {list(ks)}")
        for key, value in (
            ("queries_per_fabric", self.queries_per_fabric),
            ("repeats", self.repeats),
            ("max_presses", self.max_presses),
            ("n_bins", self.n_bins),
            ("probe_k", self.probe_k),
        ):
            if value < 1:
                raise ConfigError(f"eval.{key}: must be >= 1, got {value}")
        if self.presses is not None and self.presses < 1:
            raise ConfigError(f"eval.presses: must be >= 1, got {self.presses}")
        if self.n_boot < 0:
            raise ConfigError(f"eval.n_boot: must be >= 0, got {self.n_boot}")
        if self.seed < 0:  # numpy's generators take no negative seed
            raise ConfigError(f"eval.seed: must be >= 0, got {self.seed}")
        if self.examples < 0:
            raise ConfigError(f"eval.examples: must be >= 0, got {self.examples}")
        if not 0.0 < self.alpha < 1.0:
            raise ConfigError(f"eval.alpha: must be in (0, 1), got {self.alpha}")
        if self.c is not None and not self.c > 0:
            raise ConfigError(f"eval.c: must be positive, got {self.c}")
