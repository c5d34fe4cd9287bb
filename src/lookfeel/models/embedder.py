"""The joint model: one branch per modality, dict in and dict out by slot (paper Figure 4).

Inputs and outputs are keyed by slot name (`lookfeel.modality.slot_names`): ``"depth"``,
``"touch"``, ``"depth.1"`` ... A slot goes through the branch of its modality, so the Siamese
net (one depth branch, slots ``depth`` and ``depth.1``) and the cross-modal nets (a branch per
modality) are the same code.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence

import torch
from torch import Tensor, nn

from lookfeel.config.model import ModelConfig, Precision, backbone_spec
from lookfeel.modality import Modality, slot_modality
from lookfeel.models.backbone import ModelInputError
from lookfeel.models.branch import Branch, BranchEnsemble
from lookfeel.models.pretrained import apply_state_dict, read_state_dict
from lookfeel.models.registry import create_backbone

__all__ = ["Embedder", "SlotError", "create_model", "head_key"]

_CHANNELS = {Modality.DEPTH: 1, Modality.COLOR: 3, Modality.TOUCH: 3}


class SlotError(ModelInputError, KeyError):
    """An input slot the model cannot embed: its name names no modality (``"colour"``), or
    the model has no branch of its modality; the message names the slot and the branches
    there are. Also a ``KeyError``, as `Embedder.branch` raised before, but ``str(e)`` is the
    plain line (a ``KeyError``'s quotes its message)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def head_key(slot: str, head: str) -> str:
    """Key of an auxiliary head's output in `Embedder.forward`'s dict: ``"touch/cluster"``."""
    return f"{slot}/{head}"


class Embedder(nn.Module):
    """Embeds every slot of a batch with its modality's branch.

    Attributes:
        branches: ``nn.ModuleDict`` keyed by modality value (``"depth"``, ``"touch"``).
        config: the `ModelConfig` it was built from, when built by `create_model`.
        input_sizes: modality value -> the side in pixels of the square images the model was
            trained on (``DataConfig.size_of``), for the modalities whose size is known: a
            model loaded from a checkpoint (`lookfeel.checkpoint.load_model`) knows them all
            and refuses an image of another size, which it would embed far from where the
            same image at its size lies. Empty (nothing checked) for a model built for
            training; clear it to embed other sizes on purpose.
    """

    def __init__(
        self,
        branches: Mapping[Modality, Branch],
        config: ModelConfig | None = None,
        input_sizes: Mapping[Modality | str, int] | None = None,
    ) -> None:
        """Assemble branches.

        Args:
            branches: modality -> its branch; all must share one embedding size.
            config: kept for checkpoints (a checkpoint alone rebuilds the model).
            input_sizes: modality -> the side of the images it was trained on (`input_sizes`).
        """
        super().__init__()
        if not branches:
            raise ValueError("an Embedder needs at least one branch")
        dims = {b.embed_dim for b in branches.values()}
        if len(dims) != 1:
            raise ValueError(f"all branches must share one embedding size, got {sorted(dims)}")
        self.branches = nn.ModuleDict({Modality(m).value: b for m, b in branches.items()})
        self.config = config
        self.input_sizes: dict[str, int] = {
            Modality.of(m).value: int(s) for m, s in (input_sizes or {}).items()
        }

    @property
    def modalities(self) -> tuple[Modality, ...]:
        """The modalities with a branch, in order."""
        return tuple(Modality(k) for k in self.branches)

    @property
    def precision(self) -> Precision:
        """How it computes on CUDA (`ModelConfig.precision`; ``auto`` without a config)."""
        return self.config.precision if self.config is not None else "auto"

    @property
    def embed_dim(self) -> int:
        """Size D of every embedding."""
        return next(iter(self._branches())).embed_dim

    def _branches(self) -> list[Branch]:
        return [b for b in self.branches.values() if isinstance(b, Branch)]

    def branch(self, slot: str) -> Branch:
        """The branch that embeds ``slot`` (``"depth.1"`` -> the depth branch).

        Raises:
            SlotError: naming the slot, when it names no modality or no branch embeds its
                modality (a `ModelInputError`, and a ``KeyError``).
        """
        name = str(slot)
        have = ", ".join(self.branches)
        try:
            m = slot_modality(name)
        except ValueError:
            valid = ", ".join(m.value for m in Modality)
            raise SlotError(
                f"slot {name!r} names no modality: expected {valid} (or a second slot of one, "
                f"'depth.1'); this model has {have}"
            ) from None
        if m.value not in self.branches:
            raise SlotError(f"slot {name!r}: this model has no {m.value} branch (it has: {have})")
        b = self.branches[m.value]
        assert isinstance(b, Branch)
        return b

    def trainable_parameters(self) -> list[nn.Parameter]:
        """Parameters that train (frozen trunks and unused ImageNet classifiers excluded)."""
        return [p for p in self.parameters() if p.requires_grad]

    def _inputs(self, inputs: object) -> Mapping[str, Tensor]:
        """``inputs`` when it is a mapping of slots, else a `ModelInputError` saying so."""
        if isinstance(inputs, Mapping):
            return inputs
        have = ", ".join(self.branches)
        raise ModelInputError(
            f"the model takes a dict of slot -> images ({{{next(iter(self.branches))!r}: x}}; "
            f"its slots: {have}), got a {type(inputs).__name__}"
        )

    def _check(self, slot: str, x: Tensor, views: bool = True) -> None:
        name = str(slot)
        if not isinstance(x, Tensor):
            raise ModelInputError(
                f"slot {name!r}: expected a torch.Tensor, got {type(x).__name__}"
                + (" (torch.from_numpy(a) makes one)" if type(x).__module__ == "numpy" else "")
            )
        b = self.branch(name)
        m, c = b.modality, b.in_channels
        got = tuple(x.shape)
        if m.pooled:
            if x.dim() not in ((5, 6) if views else (5,)) or x.shape[-3] != c:
                hint = ""
                if x.dim() in (3, 4) and x.shape[-3] == c:
                    hint = " (one press? x[:, None] adds the press axis)"
                    if x.dim() == 3:
                        hint = " (one press? x[None, None] adds the batch and press axes)"
                elif x.dim() in (5, 6) and c > 3 and x.shape[-3] == 3:
                    hint = (
                        f" (this model reads {c // 3} frames of each press stacked as channels, "
                        "data.touch_frames: load_query_image reads a frame with the others)"
                    )
                raise ModelInputError(
                    f"slot {name!r}: {m.value} input must be (B, P, {c}, H, W) with a press axis "
                    f"(P = 1 for one press), or (B, P, V, {c}, H, W) with V views of each "
                    f"press, got {got}{hint}"
                )
        elif x.dim() != 4 or x.shape[1] != c:
            hint = " (one image? x[None] adds the batch axis)" if got[:1] == (c,) else ""
            raise ModelInputError(f"slot {name!r}: expected (B, {c}, H, W), got {got}{hint}")
        side = self.input_sizes.get(m.value)
        if side is not None and tuple(x.shape[-2:]) != (side, side):
            h, w = x.shape[-2:]
            raise ModelInputError(
                f"slot {name!r}: this model was trained on {m.value} images of {side}x{side} "
                f"pixels, got {h}x{w}; lookfeel.index.query.load_query_image(path, "
                f"{m.value!r}, loaded.config.data) resizes an image to it for you"
            )

    def _per_branch(
        self, inputs: Mapping[str, Tensor], fn: Callable[[Branch, Tensor], Tensor]
    ) -> dict[str, Tensor]:
        """Apply ``fn(branch, x)`` to every slot; slots sharing a branch run as one batch."""
        groups: dict[str, list[str]] = {}
        for slot in inputs:
            groups.setdefault(self.branch(slot).modality.value, []).append(slot)
        out: dict[str, Tensor] = {}
        for m, slots in groups.items():
            branch = self.branches[m]
            assert isinstance(branch, Branch)
            shapes = {tuple(inputs[s].shape[1:]) for s in slots}
            if len(slots) > 1 and len(shapes) == 1:
                # One larger batch for the shared branch (the Siamese net's two depth slots).
                y = fn(branch, torch.cat([inputs[s] for s in slots]))
                for s, part in zip(slots, y.split([len(inputs[s]) for s in slots]), strict=True):
                    out[s] = part
            else:
                for s in slots:
                    out[s] = fn(branch, inputs[s])
        return {s: out[s] for s in inputs}

    def trunk(self, inputs: Mapping[str, Tensor]) -> dict[str, Tensor]:
        """Frozen trunk features per slot: a fixed function of each image, safe to cache.

        Args:
            inputs: slot -> images as for `forward`.

        Returns:
            slot -> (B, *F), or (B, P, *F) for touch; feed back with ``from_trunk=True``.

        Raises:
            ModelInputError: as `forward`.
        """
        inputs = self._inputs(inputs)
        for slot, x in inputs.items():
            self._check(slot, x, views=False)
        return self._per_branch(inputs, lambda b, x: b.trunk(x))

    def forward(
        self, inputs: Mapping[str, Tensor], from_trunk: bool = False, heads: bool = False
    ) -> dict[str, Tensor]:
        """Embed every slot.

        Args:
            inputs: slot -> images in [0, 1]: depth (B, 1, H, W), colour (B, 3, H, W), touch
                (B, P, C, H, W) with any P >= 1, or (B, P, V, C, H, W) with V views of each
                press (averaged; `Branch.forward`). C is 3, or 3 per frame of a press read
                together (``data.touch_frames``, as the default synthetic recipe reads 3
                frames: C = 9; `lookfeel.config.DataConfig.touch_channels`,
                ``model.branch("touch").in_channels``). H = W = the side the model was trained
                on, where it knows it (`input_sizes`). With ``from_trunk``, slot -> `trunk`
                output.
            from_trunk: inputs are (cached) trunk features; only the trainable part runs.
            heads: also return the auxiliary heads' outputs, under ``head_key(slot, "cluster")``
                ((B, K) logits) and ``head_key(slot, "property")`` ((B, Q)), for the heads the
                model has. Training passes ``True``; evaluation needs only the embeddings.

        Returns:
            slot -> (B, D) embedding, in the order of ``inputs`` (plus head outputs if asked).

        Raises:
            ModelInputError: ``inputs`` is not a dict; an image batch of the wrong type, shape
                or (on the CPU) values; or of another size than the model was trained on
                (`input_sizes`).
            SlotError: a slot names no modality, or one the model has no branch for.
        """
        inputs = self._inputs(inputs)
        if not from_trunk:
            for slot, x in inputs.items():
                self._check(slot, x)
        emb = self._per_branch(inputs, lambda b, x: b(x, from_trunk=from_trunk))
        if not heads:
            return emb
        out = dict(emb)
        for slot, e in emb.items():
            for name, value in self.branch(slot).heads(e).items():
                out[head_key(slot, name)] = value
        return out


def create_model(
    config: ModelConfig,
    modalities: Sequence[Modality | str],
    *,
    load_weights: bool = True,
    touch_channels: int = 3,
    input_sizes: Mapping[Modality | str, int] | None = None,
) -> Embedder:
    """Build the joint model: one branch per modality (paper section 4.1, Figure 4).

    Cross-modal Net: the default config. Auxiliary Net: ``config.cluster_head``. Multi-input
    Net: touch inputs with P > 1 presses. SNN: a single modality fed two slots of it. With
    ``config.members`` > 1 every branch is a `BranchEnsemble` of that many fresh members.

    Args:
        config: the model configuration.
        modalities: modalities that get a branch (duplicates are ignored: slots of one
            modality share its branch).
        load_weights: read ``config.pretrained`` into every branch. Pass ``False`` when a
            checkpoint's state dict will be loaded next (the weights file need not exist then).
        touch_channels: channels of a touch input: 3, or 3 per frame of a press read
            together (`DataConfig.touch_channels`).
        input_sizes: modality -> the side of the images it was trained on
            (`Embedder.input_sizes`: images of another size are refused); none checked when
            not given.

    Returns:
        The `Embedder`.

    Raises:
        ValueError: no modality given.
        PretrainedError: the weights file is absent, unreadable or does not fit.
    """
    mods = list(dict.fromkeys(Modality(m) for m in modalities))
    if not mods:
        raise ValueError("create_model needs at least one modality")
    freeze = config.resolved_freeze
    state = None
    if load_weights and config.pretrained is not None:
        state = read_state_dict(config.pretrained)  # once, shared by every branch
    elif load_weights and freeze != "none":
        warnings.warn(_random_frozen_layers(config, freeze), stacklevel=2)
    branches: dict[Modality, Branch] = {}
    for m in mods:
        channels = touch_channels if m is Modality.TOUCH else _CHANNELS[m]
        members = [_branch(config, m, channels, freeze, state) for _ in range(config.members)]
        branches[m] = members[0] if len(members) == 1 else BranchEnsemble(members)
    return Embedder(branches, config, input_sizes)


def _random_frozen_layers(config: ModelConfig, freeze: str) -> str:
    """The warning for a frozen trunk that no weights file fills: what to set instead."""
    said = f"model.freeze={freeze} freezes randomly initialised {config.backbone} layers"
    if not backbone_spec(config.backbone).loads_pretrained:
        return (
            f"{said}, which stay random ({config.backbone} loads no pretrained weights): set "
            "model.freeze=none to train them"
        )
    return (
        f"{said} because model.pretrained is not set: set model.pretrained (ModelConfig("
        "pretrained=PATH), or `lookfeel train --pretrained PATH`) to a local file of weights "
        f"for {config.backbone} in torchvision's layout ("
        + ("e.g. alexnet-owt-7be5be79.pth; " if config.backbone == "alexnet" else "")
        + "lookfeel never downloads), or set model.freeze=none"
    )


def _branch(
    config: ModelConfig,
    m: Modality,
    channels: int,
    freeze: str,
    state: dict[str, Tensor] | None,
) -> Branch:
    """One freshly initialised branch of modality ``m`` (with ``state``'s pretrained weights)."""
    backbone = create_backbone(
        config.backbone,
        in_channels=channels,
        stem=config.depth_stem,
        freeze=freeze,
        dropout=config.dropout_of(m),
        width=config.width,
    )
    if state is not None:
        apply_state_dict(backbone, state, source=str(config.pretrained))
    return Branch(
        m,
        backbone,
        embed_dim=config.embed_dim,
        normalize=config.normalize,
        press_pool=config.press_pool,
        num_clusters=config.num_clusters if config.cluster_head else 0,
        num_properties=config.property_outputs,
        class_sizes=config.class_sizes,
    )
