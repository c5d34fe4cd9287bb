"""Loss configuration: the pairwise objective between modalities and the auxiliary terms."""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Literal

from lookfeel.config._core import ConfigError, check_choices
from lookfeel.modality import Modality
from lookfeel.plugins import check_registry_name

__all__ = [
    "Distance",
    "LossConfig",
    "loss_kinds",
    "register_loss_kind",
    "unregistered_loss_kinds_allowed",
]

_BUILT_IN = ("contrastive", "infonce", "triplet")
"""lookfeel's own objectives: each reads its settings from its own keys, none from ``options``."""

_LOSS_KINDS: dict[str, None] = dict.fromkeys(_BUILT_IN)
"""The values ``loss.kind`` accepts: the built-in objectives, then those
`lookfeel.losses.register_loss` adds (`lookfeel.losses.PAIR_LOSSES` holds their builders; a
test keeps the two in step). Declared here, without torch, so that a config loads before
`lookfeel.losses` is imported."""

Distance = Literal["euclidean", "mean_squared"]
"""Distances between two embeddings for the contrastive and triplet objectives."""

_LENIENT: ContextVar[bool] = ContextVar("lookfeel_unregistered_loss_kinds", default=False)


def register_loss_kind(name: str) -> None:
    """Let `LossConfig` accept ``kind=name`` (called by `lookfeel.losses.register_loss`;
    register a loss through that, which also records how to build it).

    Raises:
        PluginError: ``name`` cannot be given as ``loss.kind`` in a config
            (`lookfeel.plugins.check_registry_name`, the rule ``register_loss`` applies).
    """
    check_registry_name(name, "loss", "loss.kind")
    _LOSS_KINDS[name] = None


def loss_kinds() -> tuple[str, ...]:
    """The names ``loss.kind`` accepts, sorted."""
    return tuple(sorted(_LOSS_KINDS))


@contextmanager
def unregistered_loss_kinds_allowed() -> Iterator[None]:
    """Within this block a `LossConfig` takes a ``kind`` this process has not registered, with
    a warning instead of a `ConfigError`.

    For reading a trained run's record (a checkpoint's config): evaluating, embedding or
    indexing it never builds the loss, so a checkpoint trained with a loss of a user's own
    module loads without that module. Training and resuming read their config outside it and
    refuse the name.
    """
    token = _LENIENT.set(True)
    try:
        yield
    finally:
        _LENIENT.reset(token)


@dataclass(frozen=True)
class LossConfig:
    """Which objective ties the modalities' embeddings together, and the weight of each term.

    Every term the loss returns is already multiplied by its weight; the total ``"loss"`` is
    their sum.
    """

    kind: str = "contrastive"
    """The objective between slots: ``contrastive`` (the paper's equation 2 on the tuple
    distance D3), ``infonce`` (multi-positive InfoNCE over every slot pair), ``triplet``
    (batch-hard triplet over every slot pair), or one registered with
    `lookfeel.losses.register_loss` (`loss_kinds`; a name nobody has registered loads the
    user's plugins first, `lookfeel.plugins.load_plugins`)."""
    margin: float = 2.0
    """Contrastive margin m: pairs of different fabrics are pushed until their distance reaches
    it (paper: 2; the authors' code also used 1 with ``mean_squared``)."""
    distance: Distance = "euclidean"
    """Distance between two embeddings, for ``contrastive`` and ``triplet``: ``euclidean`` (the
    paper's ``||E1 - E2||``) or ``mean_squared`` (the authors' released code: the mean over
    dimensions of the squared difference)."""
    contrastive_pairs: bool = False
    """``False``: one contrastive term on D3, the sum of the distances of all slot pairs of a
    tuple (paper equation 1-2). ``True``: one contrastive term per slot pair, each pair's label
    taken from its two fabric ids when given."""
    temperature: float = 0.07
    """InfoNCE temperature (its starting value when learnt); logits are cosine / temperature."""
    learn_temperature: bool = True
    """Learn the InfoNCE temperature (CLIP); its parameter lives in the loss module."""
    max_logit_scale: float = 100.0
    """Upper clamp of the learnt inverse temperature (CLIP: 100)."""
    triplet_margin: float = 0.2
    """Margin of the batch-hard triplet loss, in units of ``distance``."""
    pair_weight: float = 1.0
    """Weight of the objective's terms between slots."""
    pair_weights: dict[str, float] = field(default_factory=dict)
    """A weight for one pair of slots' term, on top of ``pair_weight``, keyed ``<a>_<b>`` by
    the two modalities (``color_touch``, either order; a second slot of one modality is
    ``depth1``); 0 leaves the term out. Pairs not named weigh 1, and a pair whose slots a run
    does not train is ignored. For objectives with a term per slot pair (``infonce``,
    ``triplet``, ``contrastive`` with ``contrastive_pairs``, or one's own whose terms are named
    ``<a>_<b>_loss``): a weight of a pair the run trains whose term the objective does not
    give changes nothing, and is warned of once."""
    cluster_weight: float = 1.0
    """Weight of the cluster cross-entropy summed over slots (paper's Auxiliary Net: 1, the three
    cross-entropies are added to the contrastive loss). Needs the model's cluster head."""
    class_weight: float = 1.0
    """Weight of the class heads' cross-entropy (one per ``model.class_heads`` column, unknown
    labels masked), summed over columns and slots. Needs the model's class heads."""
    property_weight: float = 1.0
    """Weight of the masked property regression (mean squared error over known labels, summed
    over slots). Needs the model's property head. The targets are standardised over the training
    fabrics, so every label weighs alike."""
    options: dict[str, Any] = field(default_factory=dict)
    """Settings of a loss of one's own (one registered with `lookfeel.losses.register_loss`),
    by name: ``--set loss.options.alpha=0.5``, or ``options: {alpha: 0.5}`` under ``loss:`` in
    a YAML file. lookfeel checks only that the names are text and the values plain YAML data
    (numbers, text, true/false, null, lists and mappings of them), and records them in the
    run's config.yaml and checkpoint; the loss's build function reads them
    (``config.options.get("alpha", 0.5)``) and checks them itself. The built-in kinds take
    none (their settings are the keys above)."""

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str):
            raise ConfigError(f"loss.kind: expected a name, got {self.kind!r}")
        if self.kind not in _LOSS_KINDS:  # first, as the first field
            # A name nobody has registered: the user's plugins may register it.
            from lookfeel.plugins import load_plugins, unknown_name_hint

            load_plugins()
        if self.kind not in _LOSS_KINDS:
            if not _LENIENT.get():
                raise ConfigError(
                    f"loss.kind: {self.kind!r} is not one of {', '.join(loss_kinds())} "
                    f"({unknown_name_hint()})"
                )
            warnings.warn(
                f"loss.kind: {self.kind!r} is not registered in this process "
                "(lookfeel.losses.register_loss); the model loads without it, since only "
                "training uses the loss",
                stacklevel=2,
            )
        check_choices(self, "loss")
        for key, value in (
            ("margin", self.margin),
            ("temperature", self.temperature),
            ("max_logit_scale", self.max_logit_scale),
            ("triplet_margin", self.triplet_margin),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"loss.{key}: must be a finite number > 0, got {value}")
        if 1.0 / self.temperature > self.max_logit_scale:
            raise ConfigError(
                f"loss.temperature: 1 / {self.temperature} exceeds loss.max_logit_scale "
                f"({self.max_logit_scale}); raise the temperature or the clamp"
            )
        for key, weight in (
            *((f"pair_weights.{k}", w) for k, w in self.pair_weights.items()),
            ("pair_weight", self.pair_weight),
            ("cluster_weight", self.cluster_weight),
            ("property_weight", self.property_weight),
            ("class_weight", self.class_weight),
        ):
            if not (math.isfinite(weight) and weight >= 0):
                raise ConfigError(f"loss.{key}: must be a finite number >= 0, got {weight}")
        _check_options(self.options, self.kind)
        senses = {m.value for m in Modality}
        for key in self.pair_weights:
            sides = key.split("_")
            if len(sides) != 2 or not all(s.rstrip("0123456789") in senses for s in sides):
                raise ConfigError(
                    f"loss.pair_weights.{key}: name a pair of modalities as <a>_<b>, each one "
                    f"of {', '.join(sorted(senses))}, e.g. color_touch"
                )


def _check_options(options: object, kind: str) -> None:
    """Refuse ``loss.options`` that are not a mapping of names to plain YAML data (which
    config.yaml could not record), or any for a built-in ``kind``, in one line naming the key."""
    if not isinstance(options, dict):
        raise ConfigError(
            f"loss.options: expected a mapping of names to values, got a {type(options).__name__}"
        )
    if options and kind in _BUILT_IN:
        raise ConfigError(
            f"loss.options.{next(iter(options))}: the built-in loss {kind!r} takes no options "
            "(its settings are loss's own keys, e.g. loss.margin); options are for a loss "
            "registered with lookfeel.losses.register_loss"
        )
    for name, value in options.items():
        if not isinstance(name, str):
            raise ConfigError(f"loss.options: a name must be text, got {name!r}")
        _check_plain(value, f"loss.options.{name}")


def _check_plain(value: object, key: str) -> None:
    """Refuse a value config.yaml cannot hold: anything but numbers, text, true/false, null and
    lists and text-keyed mappings of them."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(
            f"{key}: {value} is not a finite number (a run with it could never be resumed or "
            "compared: NaN equals nothing); give a number"
        )
    if value is None or isinstance(value, (str, int, float, bool)):
        return
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _check_plain(v, f"{key}[{i}]")
        return
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, str):
                raise ConfigError(f"{key}: a name must be text, got {k!r}")
            _check_plain(v, f"{key}.{k}")
        return
    raise ConfigError(
        f"{key}: a value of type {type(value).__name__} cannot be written in config.yaml; give "
        "numbers, text, true/false, null, or lists and mappings of them"
    )
