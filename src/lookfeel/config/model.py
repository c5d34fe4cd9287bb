"""Model configuration: backbone, freezing, per-modality branches and auxiliary heads."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from lookfeel.config._core import ConfigError, check_choices
from lookfeel.modality import Modality

__all__ = [
    "BACKBONE_DEFAULT_FREEZE",
    "BACKBONE_FREEZE_POINTS",
    "BackboneName",
    "ModelConfig",
    "Precision",
]

BackboneName = Literal["alexnet", "compact", "resnet18"]
"""The built-in backbones (`lookfeel.models.list_backbones`; a test keeps the three in step)."""

Precision = Literal["auto", "fp32"]
"""How a network computes on CUDA (`ModelConfig.precision`)."""

BACKBONE_FREEZE_POINTS: dict[str, tuple[str, ...]] = {
    "alexnet": ("none", "to_conv5", "to_fc6", "all"),
    "compact": ("none", "to_block4", "all"),
    "resnet18": ("none", "to_layer2", "to_layer3", "all"),
}
"""The built-in backbones and where each can be cut into a frozen trunk and a trainable head:
``none`` trains everything, ``to_X`` freezes up to and including layer ``X``, ``all`` freezes the
whole backbone (only a projection and the heads train). `lookfeel.models.list_backbones` lists the
same names; a test keeps the two in step."""

BACKBONE_DEFAULT_FREEZE: dict[str, str] = {
    "alexnet": "to_fc6",
    "compact": "none",
    "resnet18": "none",
}
"""Freeze point used when ``model.freeze`` is unset. AlexNet: the paper's (section 4.2: "parameters
of AlexNet before fc7 will be fixed")."""

_PRETRAINABLE = ("alexnet", "resnet18")


@dataclass(frozen=True)
class ModelConfig:
    """The embedding network: one branch per modality, each a backbone plus optional heads.

    The paper's architectures (section 4.1, Figure 4) are settings of this one config: the
    Cross-modal Net is the default; the Auxiliary Net sets ``cluster_head``; the Multi-input Net
    is the Auxiliary Net fed several presses per touch input (``data.presses``), pooled here by
    ``press_pool``; the SNN is a model of one modality fed two slots of it.
    """

    backbone: BackboneName = "alexnet"
    """Backbone of every branch: ``alexnet`` (the paper's; torchvision's layout, 227 px inputs,
    at least 63 px), ``compact`` (a small CNN for 64-112 px inputs on a CPU) or ``resnet18``
    (torchvision's layout)."""
    pretrained: str | None = None
    """Path to a local torchvision state dict to start from (``alexnet-owt-7be5be79.pth`` for
    ``alexnet``, ``resnet18-f37072fd.pth`` for ``resnet18``). Weights are never downloaded;
    ``None`` starts from random weights."""
    init_from: str | None = None
    """Path to a lookfeel checkpoint (``RUN/checkpoints/last.pt``) to start from: every weight
    whose name and shape match is copied (e.g. a depth branch pre-trained on the synthetic
    world, then trained on real depth); the rest start fresh. Applied after ``pretrained``."""
    freeze: str | None = None
    """Where the frozen trunk ends (see `BACKBONE_FREEZE_POINTS`); ``None`` takes the backbone's
    default (`BACKBONE_DEFAULT_FREEZE`: ``to_fc6`` for AlexNet as the paper, else ``none``).
    A frozen trunk always runs in eval mode (no dropout, fixed BatchNorm statistics), so its
    output per image can be cached."""
    depth_stem: Literal["replicate", "sum"] = "replicate"
    """How one-channel depth enters a backbone: ``replicate`` copies it into three channels;
    ``sum`` uses a one-channel first convolution whose pretrained filters are the sums of the
    RGB filters (a third of conv1's work, near-identical outputs)."""
    dropout: float = 0.5
    """Dropout probability before the fully connected layers (AlexNet fc6/fc7, compact fc);
    ``resnet18`` has none. torchvision's AlexNet: 0.5."""
    branch_dropout: dict[Modality, float] = field(default_factory=dict)
    """Per-modality overrides of ``dropout``, e.g. ``{depth: 0.3, touch: 0.3}``: the named
    branches use their own probability, the others ``dropout``."""
    width: int | None = None
    """Channels of the first stage of ``compact`` (default 32) or ``resnet18`` (default 64;
    pretrained weights need 64); doubled at each later stage. Not used by ``alexnet``."""
    embed_dim: int | None = None
    """Size of a linear projection of each branch's embedding; ``None`` keeps the backbone's
    (AlexNet fc7: 4096, as the paper)."""
    normalize: bool = False
    """L2-normalise each embedding (CLIP style). The paper does not."""
    members: int = 1
    """Networks per branch, trained as separate runs and used as one (a deep ensemble,
    `lookfeel.models.BranchEnsemble`). ``lookfeel train`` trains member ``k`` in
    ``RUN/members/k`` with its own seed (member 0 with ``train.seed``), so its own batches,
    views and initial weights, then writes one checkpoint holding all of them: the embedding
    is the members' embeddings side by side over sqrt(N) (squared distances average the
    members'), the heads average the members'. Training and embedding cost N times one
    network. 1: a single network."""
    press_pool: Literal["max", "mean"] = "max"
    """How the embeddings of a touch input's presses become one: ``max`` (element-wise maximum,
    the paper's Multi-input Net) or ``mean``."""
    cluster_head: bool = False
    """Add a linear cluster classifier on each branch's embedding (the paper's Auxiliary Net)."""
    num_clusters: int = 8
    """Classes of the cluster head (paper: 8 k-means clusters of the physical labels)."""
    num_properties: int | Literal["auto"] = 0
    """Outputs of a linear property-regression head on each branch's embedding, one per numeric
    column of labels.csv (4 for GelFabric: thickness, density, stiffness, stretchiness); 0
    disables it. ``auto``: as many as the dataset's labels.csv has numeric columns (none, so no
    head, for a dataset without labels); `lookfeel train` fills in the number and saves it with
    the run."""
    class_heads: tuple[str, ...] = ()
    """Label columns to classify with a linear head on each branch's embedding: ranks
    (``hardness``: 0, 1, 2) or words (``material``). Trained with cross-entropy
    (``loss.class_weight``); `lookfeel predict` reports them with their probabilities."""
    classes: dict[str, tuple[str, ...]] = field(default_factory=dict)
    """Each class head's class names, in output order. `lookfeel train` fills it in from the
    dataset's labels (and saves it with the run); leave it unset."""
    class_temperature: dict[str, float] = field(default_factory=dict)
    """A temperature per class head that `lookfeel predict` divides its logits by before the
    softmax: above 1 softens a head that is surer than it is right on objects it
    never saw. The predicted class does not change. `lookfeel cv` measures how far each head's
    probabilities can be trusted and fits the temperature on held-out objects (its cv.md);
    unset heads use 1, and a column with no head is ignored (a recipe's temperatures stay valid
    when ``--set model.class_heads=...`` keeps fewer heads)."""
    precision: Precision = "auto"
    """How the network computes on CUDA, in training and whenever its checkpoint embeds:
    ``auto`` runs the forward pass under bf16 autocast (the GPU's fast path); ``fp32`` in full
    fp32, TF32 off, as on a CPU (slower; for comparing a GPU run with CPU runs). On a CPU
    every run is fp32 whatever this says (bf16 there is ~100x slower)."""

    def dropout_of(self, modality: Modality | str) -> float:
        """The dropout probability of ``modality``'s branch (``branch_dropout`` or ``dropout``)."""
        return self.branch_dropout.get(Modality(modality), self.dropout)

    @property
    def resolved_freeze(self) -> str:
        """``freeze``, or the backbone's default freeze point when it is ``None``."""
        return self.freeze if self.freeze is not None else BACKBONE_DEFAULT_FREEZE[self.backbone]

    def __post_init__(self) -> None:
        check_choices(self, "model")
        points = BACKBONE_FREEZE_POINTS[self.backbone]
        if self.freeze is not None and self.freeze not in points:
            raise ConfigError(
                f"model.freeze: {self.freeze!r} is not a freeze point of backbone "
                f"{self.backbone!r}; one of {', '.join(points)}"
            )
        if self.pretrained is not None:
            if self.backbone not in _PRETRAINABLE:
                raise ConfigError(
                    f"model.pretrained: backbone {self.backbone!r} has no pretrained weights; "
                    f"only {', '.join(_PRETRAINABLE)} load a torchvision file"
                )
            if not self.pretrained.strip():
                raise ConfigError("model.pretrained: empty path; use null for random weights")
        if self.init_from is not None and not self.init_from.strip():
            raise ConfigError("model.init_from: empty path; use null to start from scratch")
        if not 0.0 <= self.dropout < 1.0:
            raise ConfigError(f"model.dropout: must be in [0, 1), got {self.dropout}")
        for name, p in self.branch_dropout.items():
            if not 0.0 <= p < 1.0:
                raise ConfigError(f"model.branch_dropout.{name.value}: must be in [0, 1), got {p}")
        if self.width is not None:
            if self.backbone == "alexnet":
                raise ConfigError("model.width: alexnet has a fixed width; leave width unset")
            if self.width < 1:
                raise ConfigError(f"model.width: must be >= 1, got {self.width}")
            if self.pretrained is not None and self.width != 64:
                raise ConfigError(
                    f"model.width: pretrained resnet18 weights need width 64, got {self.width}"
                )
        if self.embed_dim is not None and self.embed_dim < 1:
            raise ConfigError(f"model.embed_dim: must be >= 1 or null, got {self.embed_dim}")
        if self.members < 1:
            raise ConfigError(f"model.members: must be >= 1, got {self.members}")
        if self.num_clusters < 2:
            raise ConfigError(f"model.num_clusters: must be >= 2, got {self.num_clusters}")
        if self.num_properties != "auto" and (
            not isinstance(self.num_properties, int) or self.num_properties < 0
        ):
            raise ConfigError(
                f"model.num_properties: must be >= 0 or auto, got {self.num_properties}"
            )
        if len(set(self.class_heads)) != len(self.class_heads):
            raise ConfigError(f"model.class_heads: a column is named twice: {self.class_heads}")
        for col in self.classes:
            if col not in self.class_heads:
                raise ConfigError(f"model.classes: {col!r} is not one of model.class_heads")
        for col, temp in self.class_temperature.items():
            number = isinstance(temp, int | float) and not isinstance(temp, bool)
            if not (number and math.isfinite(temp) and temp > 0):
                raise ConfigError(
                    f"model.class_temperature.{col}: must be a number > 0, got {temp!r}"
                )
        for col, names in self.classes.items():
            if len(names) < 2 or len(set(names)) != len(names):
                raise ConfigError(
                    f"model.classes.{col}: needs two or more distinct classes, got {list(names)}"
                )

    @property
    def property_outputs(self) -> int:
        """``num_properties`` as a number (the head must be resolved).

        Raises:
            ConfigError: it is still ``auto``.
        """
        if self.num_properties == "auto":
            raise ConfigError(
                "model.num_properties: auto is not resolved yet; `lookfeel train` fills it in "
                "from the dataset's labels.csv"
            )
        return self.num_properties

    @property
    def class_sizes(self) -> tuple[int, ...]:
        """Classes per head, in ``class_heads`` order (the heads must be resolved).

        Raises:
            ConfigError: a head's classes are not known yet (``model.classes`` lacks it).
        """
        missing = [c for c in self.class_heads if c not in self.classes]
        if missing:
            raise ConfigError(
                f"model.classes: no classes for {', '.join(missing)}; `lookfeel train` fills "
                "them in from the dataset's labels"
            )
        return tuple(len(self.classes[c]) for c in self.class_heads)
