"""The loss the trainer calls: the pairwise objective plus the auxiliary terms, as one dict.

The trainer knows nothing of which objective or how many modalities: it logs every term and
back-propagates ``"loss"`` (open_clip's task layer). The objectives between slots are looked up
by ``loss.kind`` in `PAIR_LOSSES`; `register_loss` adds one of a user's own, `list_losses`
names them.
"""

from __future__ import annotations

import inspect
import re
import warnings
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import get_args, overload

import torch
from torch import Tensor, nn

from lookfeel.config._core import ConfigError
from lookfeel.config.loss import Distance, LossConfig, register_loss_kind
from lookfeel.errors import LookfeelError, caller_stacklevel
from lookfeel.losses._naming import embeddings_of, head_output, term_name
from lookfeel.losses.cluster import masked_cross_entropy
from lookfeel.losses.contrastive import ContrastiveD3Loss
from lookfeel.losses.distance import (
    euclidean_distance,
    mean_squared_distance,
    pairwise_euclidean,
    pairwise_mean_squared,
)
from lookfeel.losses.infonce import MultiPositiveInfoNCE
from lookfeel.losses.property import masked_mse
from lookfeel.losses.triplet import BatchHardTripletLoss
from lookfeel.plugins import check_registry_name

__all__ = [
    "HEAD_TERMS",
    "PAIR_LOSSES",
    "TARGETS",
    "CombinedLoss",
    "LossError",
    "create_loss",
    "list_losses",
    "register_loss",
]

HEAD_TERMS = ("cluster_loss", "property_loss", "class_loss")
"""The terms `CombinedLoss` adds from the model's heads. These and the total ``"loss"`` are
names an objective's own terms cannot take."""

TARGETS = ("cluster", "properties", "classes")
"""The batch's targets an objective between slots is given, besides ``y`` and ``fabric``,
where its ``forward`` names them (or takes ``**kwargs``): each slot -> a tensor, as
`CombinedLoss.forward` describes them."""

_TERM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*_loss\Z")
"""An objective's term name: a word ending in ``_loss`` (``depth_touch_loss``), so that it
stands apart from the other keys of a log line (``step``, ``lr``, ``val/...``)."""


class LossError(LookfeelError):
    """A loss gave something the trainer cannot use (a term that is not a scalar tensor, a term
    that does not depend on the embeddings, a term named as lookfeel's own, or no dict of named
    terms); the message names the loss and the term."""


def _check_terms(terms: object, source: str) -> Mapping[str, Tensor]:
    """``terms`` if it is a dict of 0-dim tensors (a shape check: nothing is read from the
    device), else `LossError` naming ``source`` and the first term that is not."""
    if not isinstance(terms, Mapping):
        raise LossError(
            f"{source} returned a {type(terms).__name__}; a loss returns a dict of named terms, "
            'e.g. {"depth_touch_loss": value}'
        )
    for name, value in terms.items():
        if not isinstance(value, Tensor):
            raise LossError(f"{source}: term {name!r} is a {type(value).__name__}, not a tensor")
        if value.dim() != 0:
            raise LossError(
                f"{source}: term {name!r} has shape {tuple(value.shape)}; every term must be a "
                "scalar (a 0-dim tensor): reduce it, e.g. with .mean()"
            )
    return terms


def _check_names(terms: Mapping[str, Tensor], source: str) -> None:
    """Refuse, in one line naming ``source`` and the term, a term of the objective between
    slots that is named as one of lookfeel's own (`HEAD_TERMS`, the total ``"loss"``), which
    would be overwritten or added twice, or not as a word ending in ``_loss``."""
    for name in terms:
        if name == "loss" or name in HEAD_TERMS:
            raise LossError(
                f"{source}: term {name!r} is named as one of lookfeel's own terms (loss, "
                f"{', '.join(HEAD_TERMS)}), which would replace it or be replaced: name it "
                "otherwise, e.g. depth_touch_loss for the depth-touch pair's term"
            )
        if not (isinstance(name, str) and _TERM_NAME.match(name)):
            raise LossError(
                f"{source}: term {name!r} is not named as a loss term: letters, digits and _, "
                "ending in _loss (e.g. depth_touch_loss, which loss.pair_weights weighs as "
                "depth_touch)"
            )


def _takes(forward: Callable[..., object], names: Sequence[str]) -> tuple[str, ...]:
    """Those of ``names`` that ``forward`` takes as keyword arguments (all of them where it has
    ``**kwargs``; none where its signature cannot be read)."""
    try:
        params = inspect.signature(forward).parameters.values()
    except (TypeError, ValueError):
        return ()
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return tuple(names)
    keyword = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return tuple(n for n in names if n in keyword)


class CombinedLoss(nn.Module):
    """Weighted sum of a pairwise objective, the cluster cross-entropy and property regression.

    Every returned term already carries its weight; ``"loss"`` is their sum.
    """

    def __init__(
        self,
        pair_loss: nn.Module,
        pair_weight: float = 1.0,
        cluster_weight: float = 1.0,
        property_weight: float = 1.0,
        class_weight: float = 1.0,
        class_sizes: tuple[int, ...] = (),
        pair_weights: Mapping[str, float] | None = None,
        kind: str | None = None,
    ) -> None:
        """Assemble the loss.

        Args:
            pair_loss: maps ``(embeddings, y=, fabric=)`` to named terms (`ContrastiveD3Loss`,
                `MultiPositiveInfoNCE`, `BatchHardTripletLoss`), each a word ending in
                ``_loss``; it is also given those of `TARGETS` its ``forward`` names.
            pair_weight: weight of its terms (0 leaves them out).
            pair_weights: ``"<a>_<b>"`` -> a further weight of the term named
                ``<a>_<b>_loss`` (either order; 0 leaves it out). A pair whose slots the
                outputs lack is ignored; one whose slots they hold but whose term the
                objective does not give (it names its terms otherwise, or gives one term for
                all slots) is warned of once, as changing nothing; leaving out every term is
                an error.
            cluster_weight: weight of the cluster cross-entropy, summed over slots.
            property_weight: weight of the property regression, summed over slots.
            class_weight: weight of the class heads' cross-entropy, summed over heads and slots.
            class_sizes: classes of each class head (how the ``classes`` logits split).
            kind: the ``loss.kind`` that built ``pair_loss``, for messages.
        """
        super().__init__()
        self.pair_loss = pair_loss
        name = type(pair_loss).__name__
        self.source = f"the loss {kind!r} ({name})" if kind else f"the loss {name}"
        """How messages name the objective: ``the loss 'infonce' (MultiPositiveInfoNCE)``."""
        self.pair_targets = _takes(pair_loss.forward, TARGETS)
        """The `TARGETS` the objective's ``forward`` takes."""
        self._said_unweighted = False
        self.pair_weight = pair_weight
        self.cluster_weight = cluster_weight
        self.property_weight = property_weight
        self.class_weight = class_weight
        self.class_sizes = tuple(class_sizes)
        self.pair_weights = dict(pair_weights or {})

    def _pair_factor(self, names: Sequence[str], slots: Collection[str]) -> dict[str, float]:
        """Each term's factor from `pair_weights` (1 where none is named); the first time a
        weight names a pair of ``slots`` the objective gives no term of, a warning."""
        factor = dict.fromkeys(names, 1.0)
        trained = {s.replace(".", "") for s in slots}  # as `term_name` writes them
        unmatched = []
        for key, w in self.pair_weights.items():
            a, _, b = key.partition("_")
            found = [n for n in (term_name(a, b), term_name(b, a)) if n in factor]
            for n in found:
                factor[n] = w
            if not found and a in trained and b in trained:
                unmatched.append(key)
        if unmatched and not self._said_unweighted:
            self._said_unweighted = True
            warnings.warn(
                f"loss.pair_weights ({', '.join(unmatched)}): {self.source} gives no term "
                f"named {term_name(*unmatched[0].split('_'))} (its terms: {', '.join(names)}), "
                "so the weight changes nothing; a pair weight applies to a term named "
                "<a>_<b>_loss, as lookfeel.losses.FabricPairLoss names them",
                stacklevel=caller_stacklevel(),
            )
        if names and not any(factor.values()):
            pairs = ", ".join(n.removesuffix("_loss") for n in names)
            raise ConfigError(
                f"loss.pair_weights leaves out every pair this run trains ({pairs}); nothing "
                'would tie its senses together: give one a weight, or --set "loss.pair_weights={}"'
            )
        return factor

    def forward(
        self,
        outputs: Mapping[str, Tensor],
        y: Tensor | None = None,
        fabric: Mapping[str, Tensor] | None = None,
        cluster: Mapping[str, Tensor] | None = None,
        properties: Mapping[str, Tensor] | None = None,
        classes: Mapping[str, Tensor] | None = None,
        targets: Mapping[str, Mapping[str, Tensor] | None] | None = None,
    ) -> dict[str, Tensor]:
        """Compute every term and the total.

        Args:
            outputs: the `Embedder`'s output: slot -> (B, D) embeddings, plus
                ``"<slot>/cluster"`` (B, K), ``"<slot>/property"`` (B, Q) and
                ``"<slot>/classes"`` head outputs (``model(inputs, heads=True)``).
            y: (B,) 0 when a tuple's slots show one fabric, 1 when not (contrastive; derived
                from ``fabric`` when omitted).
            fabric: slot -> (B,) fabric ids (needed by InfoNCE and triplet).
            cluster: slot -> (B,) cluster targets, -1 where unknown; gives ``cluster_loss``.
            properties: slot -> (B, Q) property targets, NaN where unknown; gives
                ``property_loss``.
            classes: slot -> (B, H) class indices per class head, -1 where unknown; gives
                ``class_loss``.
            targets: the targets the objective between slots is given (those of `TARGETS`
                its ``forward`` names, by those names), with or without the heads; default:
                ``cluster``, ``properties`` and ``classes`` above. The trainer gives every
                target of the batch here, and above only those of the model's heads.

        Returns:
            ``{"<a>_<b>_loss": ..., "cluster_loss": ..., "property_loss": ...,
            "class_loss": ..., "loss": total}``, with only the terms that apply; every value
            is a scalar.

        Raises:
            ValueError: targets given for a head the outputs lack, or nothing to optimise.
            LossError: the pairwise objective gave a term that is not a scalar tensor, or is
                named as lookfeel's own terms, or not ``..._loss``; or, while gradients are
                recorded, a term (or a total) that does not depend on the embeddings.
        """
        terms: dict[str, Tensor] = {}
        embeddings = embeddings_of(outputs)
        if self.pair_weight > 0:
            if targets is None:
                targets = {"cluster": cluster, "properties": properties, "classes": classes}
            given = {n: targets.get(n) for n in self.pair_targets}
            pair_terms = _check_terms(
                self.pair_loss(embeddings, y=y, fabric=fabric, **given), self.source
            )
            _check_names(pair_terms, self.source)
            if torch.is_grad_enabled() and any(v.requires_grad for v in embeddings.values()):
                for name, value in pair_terms.items():
                    if not value.requires_grad:
                        raise LossError(
                            f"{self.source}: term {name!r} does not depend on the embeddings "
                            "(a constant, or a tensor detached from them by .detach(), .item() "
                            "or torch.no_grad()): it trains nothing; compute it from the "
                            "embeddings, or leave it out"
                        )
            factor = self._pair_factor(list(pair_terms), embeddings)
            for name, value in pair_terms.items():
                if factor[name] > 0:
                    terms[name] = self.pair_weight * factor[name] * value
        if cluster is not None and self.cluster_weight > 0:
            parts = [
                masked_cross_entropy(head_output(outputs, slot, "cluster"), target)
                for slot, target in cluster.items()
            ]
            terms["cluster_loss"] = self.cluster_weight * sum(parts[1:], parts[0])
        if properties is not None and self.property_weight > 0:
            parts = [
                masked_mse(head_output(outputs, slot, "property"), target)
                for slot, target in properties.items()
            ]
            terms["property_loss"] = self.property_weight * sum(parts[1:], parts[0])
        if classes is not None and self.class_weight > 0 and self.class_sizes:
            parts = []
            for slot, target in classes.items():
                logits = head_output(outputs, slot, "classes").split(self.class_sizes, dim=-1)
                parts += [masked_cross_entropy(z, target[:, h]) for h, z in enumerate(logits)]
            terms["class_loss"] = self.class_weight * sum(parts[1:], parts[0])
        if not terms:
            raise ValueError("no loss term applies: every weight is 0 or its targets are missing")
        _check_terms(terms, "the combined loss")
        values = list(terms.values())
        terms["loss"] = sum(values[1:], values[0])
        if (
            torch.is_grad_enabled()
            and not terms["loss"].requires_grad
            and any(v.requires_grad for v in embeddings.values())
        ):
            raise LossError(
                f"{self.source}: its terms {', '.join(n for n in terms if n != 'loss')} do not "
                "depend on the embeddings (a constant, or a tensor detached from them): there "
                "is no gradient to train with"
            )
        return terms


_DISTANCES: dict[str, tuple[Callable[[Tensor, Tensor], Tensor], Callable[[Tensor, Tensor], Tensor]]]
_DISTANCES = {
    "euclidean": (euclidean_distance, pairwise_euclidean),
    "mean_squared": (mean_squared_distance, pairwise_mean_squared),
}
"""`LossConfig.distance` -> (row-by-row distance, pairwise distance)."""


def _contrastive(config: LossConfig) -> nn.Module:
    dist = _DISTANCES[config.distance][0]
    return ContrastiveD3Loss(config.margin, dist, per_pair=config.contrastive_pairs)


def _infonce(config: LossConfig) -> nn.Module:
    return MultiPositiveInfoNCE(
        config.temperature, config.learn_temperature, config.max_logit_scale
    )


def _triplet(config: LossConfig) -> nn.Module:
    return BatchHardTripletLoss(config.triplet_margin, _DISTANCES[config.distance][1])


PAIR_LOSSES: dict[str, Callable[[LossConfig], nn.Module]] = {}
"""`LossConfig.kind` -> a function of the `LossConfig` that builds the objective between slots
it names (`register_loss` adds to it; a test keeps it and `lookfeel.config.loss.loss_kinds` in
step)."""

_LossBuilder = Callable[[LossConfig], nn.Module]


@overload
def register_loss(name: str) -> Callable[[_LossBuilder], _LossBuilder]: ...
@overload
def register_loss(name: str, build: _LossBuilder) -> _LossBuilder: ...
def register_loss(
    name: str, build: _LossBuilder | None = None
) -> _LossBuilder | Callable[[_LossBuilder], _LossBuilder]:
    """Register an objective between slots under ``name``, for ``loss.kind`` and `create_loss`.

    Registering the same function again (a module imported twice) changes nothing.

    Args:
        name: the value of ``loss.kind`` that selects it.
        build: ``build(config: LossConfig) -> nn.Module``; it reads the loss's settings from
            ``config`` (its own under ``config.options``, ``loss.options`` in a config). The
            module is called as ``module(embeddings, y=..., fabric=...)`` with slot -> (B, D)
            embeddings, and also given the batch's ``cluster=``, ``properties=`` and
            ``classes=`` targets where its ``forward`` names them (`TARGETS`; see
            `CombinedLoss.forward`). It returns a dict of scalar terms, each depending on the
            embeddings and named ``<word>_loss``, other than lookfeel's own `HEAD_TERMS`;
            ``loss.pair_weights`` weighs those named ``<a>_<b>_loss`` for slots a and b
            (`lookfeel.losses.FabricPairLoss` gives one such term per slot pair). Without it,
            a decorator: ``@register_loss("mine")``.

    Returns:
        ``build`` (or the decorator).

    Raises:
        PluginError: ``name`` cannot be given as ``loss.kind`` in a config (it must be
            letters, digits, ``_``, ``-`` and ``.``, beginning with a letter:
            `lookfeel.plugins.check_registry_name`); refused by the decorator form too.
        TypeError: ``build`` is not callable.
        ValueError: another function is registered under ``name``.
    """
    check_registry_name(name, "loss", "loss.kind")
    if build is None:
        return lambda b: register_loss(name, b)
    if not callable(build):
        raise TypeError(f"loss {name!r}: expected a function of the LossConfig, got {build!r}")
    known = PAIR_LOSSES.get(name)
    if known is not None and _where(known) != _where(build):
        raise ValueError(f"loss {name!r} is already registered ({_where(known)})")
    register_loss_kind(name)
    PAIR_LOSSES[name] = build
    return build


def _where(fn: object) -> str:
    return f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', repr(fn))}"


register_loss("contrastive", _contrastive)
register_loss("infonce", _infonce)
register_loss("triplet", _triplet)


def list_losses() -> list[str]:
    """Names `create_loss` accepts as ``loss.kind`` (the built-in three and those registered
    with `register_loss`), sorted."""
    return sorted(PAIR_LOSSES)


def create_loss(config: LossConfig, class_sizes: tuple[int, ...] = ()) -> CombinedLoss:
    """Build the loss a `LossConfig` describes.

    Args:
        config: the loss configuration.
        class_sizes: classes of each of the model's class heads (`ModelConfig.class_sizes`).

    Returns:
        A `CombinedLoss`; call it as ``loss_fn(model(inputs, heads=True), y=..., fabric=...,
        cluster=..., properties=..., classes=...)``. With ``infonce`` and a learnt temperature
        it has a parameter: optimise ``loss_fn.parameters()`` too.

    Raises:
        ValueError: a ``kind`` or ``distance`` with nothing built for it (a `LossConfig` checks
            its choices, so only one forced past that check, or read from a checkpoint whose
            loss this process has not registered, gets here).
    """
    for what, value, known, allowed in (
        ("kind", config.kind, PAIR_LOSSES, tuple(sorted(PAIR_LOSSES))),
        ("distance", config.distance, _DISTANCES, get_args(Distance)),
    ):
        if value not in known:
            raise ValueError(f"loss.{what}: {value!r} is not one of {', '.join(allowed)}")
    build = PAIR_LOSSES[config.kind]
    pair_loss = build(config)
    if not isinstance(pair_loss, nn.Module):
        raise LossError(
            f"loss {config.kind!r}: its build function {_where(build)} returned "
            f"{type(pair_loss).__name__}, not a torch.nn.Module (register_loss takes a function "
            "of the LossConfig that returns the loss module)"
        )
    return CombinedLoss(
        pair_loss,
        pair_weight=config.pair_weight,
        cluster_weight=config.cluster_weight,
        property_weight=config.property_weight,
        class_weight=config.class_weight,
        class_sizes=class_sizes,
        pair_weights=config.pair_weights,
        kind=config.kind,
    )
