"""Model configuration: backbone, freezing, per-modality branches and auxiliary heads."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from lookfeel.config._core import ConfigError, check_choices
from lookfeel.modality import Modality
from lookfeel.plugins import check_registry_name

__all__ = [
    "EMBED_BATCH",
    "BackboneSpec",
    "ModelConfig",
    "Precision",
    "backbone_names",
    "backbone_spec",
    "register_backbone_spec",
]

Precision = Literal["auto", "fp32"]
"""How a network computes on CUDA (`ModelConfig.precision`)."""

EMBED_BATCH = 64
"""Images per forward pass when a trained model embeds images: the default of ``--batch-size``
(``lookfeel embed``, ``evaluate``, ``index build``) and of the functions it feeds, and the
batch in which ``lookfeel match`` decodes and embeds its queries (so that its memory grows with
this, not with the number of files matched at once). Declared here, without torch, so that
the command line reads it without importing the model."""


@dataclass(frozen=True)
class BackboneSpec:
    """What the config needs to know of a backbone to check a `ModelConfig` (no torch needed).

    `lookfeel.models.register_backbone` records one for every backbone class it registers,
    from the class's attributes, so a backbone is declared once: its class. The built-in ones
    are also declared below, so that a config loads before `lookfeel.models` (and torch) is
    imported; registering their classes checks that the two agree.
    """

    name: str
    """The value of ``model.backbone`` that selects it."""
    freeze_points: tuple[str, ...]
    """Where it can be cut into a frozen trunk and a trainable head (``model.freeze``):
    ``none`` trains everything, ``to_X`` freezes up to and including layer ``X``, ``all``
    freezes the whole backbone (only a projection and the heads train)."""
    default_freeze: str = "none"
    """The freeze point used when ``model.freeze`` is unset."""
    loads_pretrained: bool = False
    """Whether it loads a local weights file in torchvision's layout (``model.pretrained``)."""
    takes_width: bool = True
    """Whether ``model.width`` means something to it."""
    pretrained_width: int | None = None
    """The ``model.width`` its pretrained weights need (``None``: any)."""

    def __post_init__(self) -> None:
        if not self.freeze_points:
            raise ValueError(f"backbone {self.name!r}: it needs at least one freeze point")
        if self.default_freeze not in self.freeze_points:
            raise ValueError(
                f"backbone {self.name!r}: default freeze {self.default_freeze!r} is not one of "
                f"its freeze points {', '.join(self.freeze_points)}"
            )


_BACKBONE_SPECS: dict[str, BackboneSpec] = {
    spec.name: spec
    for spec in (
        # AlexNet's default: the paper's (section 4.2: "parameters of AlexNet before fc7 will
        # be fixed").
        BackboneSpec(
            "alexnet",
            ("none", "to_conv5", "to_fc6", "all"),
            default_freeze="to_fc6",
            loads_pretrained=True,
            takes_width=False,
        ),
        BackboneSpec("compact", ("none", "to_block4", "all")),
        BackboneSpec(
            "resnet18",
            ("none", "to_layer2", "to_layer3", "all"),
            loads_pretrained=True,
            pretrained_width=64,
        ),
    )
}
"""Name -> spec of every backbone a `ModelConfig` accepts: the built-in ones, then those
`lookfeel.models.register_backbone` adds (`lookfeel.models.BACKBONES` holds their classes; a
test keeps the two in step)."""


def register_backbone_spec(spec: BackboneSpec) -> None:
    """Let `ModelConfig` accept ``spec.name`` (called by `lookfeel.models.register_backbone`;
    register a backbone through that, which also records its class).

    Raises:
        PluginError: ``spec.name`` cannot be given as ``model.backbone`` in a config
            (`lookfeel.plugins.check_registry_name`, the rule ``register_backbone`` applies).
        ValueError: another spec is registered under that name.
    """
    check_registry_name(spec.name, "backbone", "model.backbone")
    known = _BACKBONE_SPECS.get(spec.name)
    if known is not None and known != spec:
        raise ValueError(
            f"backbone {spec.name!r} is already registered as {known}; its class says {spec}"
        )
    _BACKBONE_SPECS[spec.name] = spec


def backbone_names() -> tuple[str, ...]:
    """The names ``model.backbone`` accepts, sorted."""
    return tuple(sorted(_BACKBONE_SPECS))


def backbone_spec(name: str) -> BackboneSpec:
    """The spec of backbone ``name``.

    A name nobody has registered loads the user's plugins first (`lookfeel.plugins`:
    ``LOOKFEEL_PLUGINS`` and the installed entry points), which may register it.

    Raises:
        ConfigError: no backbone of that name is registered, even after loading the plugins
            (naming those that are).
        PluginError: a plugin cannot be imported.
    """
    spec = _BACKBONE_SPECS.get(name)
    if spec is None:
        from lookfeel.plugins import load_plugins, unknown_name_hint

        load_plugins()
        spec = _BACKBONE_SPECS.get(name)
        if spec is None:
            raise ConfigError(
                f"model.backbone: {name!r} is not one of {', '.join(backbone_names())} "
                f"({unknown_name_hint()})"
            )
    return spec


@dataclass(frozen=True)
class ModelConfig:
    """The embedding network: one branch per modality, each a backbone plus optional heads.

    The paper's architectures (section 4.1, Figure 4) are settings of this one config: the
    Cross-modal Net is the default; the Auxiliary Net sets ``cluster_head``; the Multi-input Net
    is the Auxiliary Net fed several presses per touch input (``data.presses``), pooled here by
    ``press_pool``; the SNN is a model of one modality fed two slots of it.
    """

    backbone: str = "alexnet"
    """Backbone of every branch: ``alexnet`` (the paper's; torchvision's layout, 227 px inputs,
    at least 63 px), ``compact`` (a small CNN for 64-112 px inputs on a CPU), ``resnet18``
    (torchvision's layout), or one registered with `lookfeel.models.register_backbone`
    (`backbone_names`; a name nobody has registered loads the user's plugins first,
    `lookfeel.plugins.load_plugins`)."""
    pretrained: str | None = None
    """Path to a local torchvision state dict to start from (``alexnet-owt-7be5be79.pth`` for
    ``alexnet``, ``resnet18-f37072fd.pth`` for ``resnet18``). Weights are never downloaded;
    ``None`` starts from random weights."""
    init_from: str | None = None
    """Path to a lookfeel checkpoint (``RUN/checkpoints/last.pt``) to start from: every weight
    whose name and shape match is copied (e.g. a depth branch pre-trained on the synthetic
    world, then trained on real depth); the rest start fresh. Applied after ``pretrained``."""
    freeze: str | None = None
    """Where the frozen trunk ends (the backbone's `BackboneSpec.freeze_points`: ``none``,
    ``to_X`` up to and including layer ``X``, ``all``); ``None`` takes the backbone's default
    (`BackboneSpec.default_freeze`: ``to_fc6`` for AlexNet as the paper, else ``none``).
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
        if self.freeze is not None:
            return self.freeze
        return backbone_spec(self.backbone).default_freeze

    def __post_init__(self) -> None:
        if not isinstance(self.backbone, str):
            raise ConfigError(f"model.backbone: expected a name, got {self.backbone!r}")
        spec = backbone_spec(self.backbone)  # first, as the first field
        check_choices(self, "model")
        points = spec.freeze_points
        if self.freeze is not None and self.freeze not in points:
            raise ConfigError(
                f"model.freeze: {self.freeze!r} is not a freeze point of backbone "
                f"{self.backbone!r}; one of {', '.join(points)}"
            )
        if self.pretrained is not None:
            if not spec.loads_pretrained:
                able = [n for n in backbone_names() if _BACKBONE_SPECS[n].loads_pretrained]
                raise ConfigError(
                    f"model.pretrained: backbone {self.backbone!r} has no pretrained weights; "
                    f"only {', '.join(able)} load a torchvision file"
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
            if not spec.takes_width:
                raise ConfigError(
                    f"model.width: {self.backbone} has a fixed width; leave width unset"
                )
            if self.width < 1:
                raise ConfigError(f"model.width: must be >= 1, got {self.width}")
            need = spec.pretrained_width
            if self.pretrained is not None and need is not None and self.width != need:
                raise ConfigError(
                    f"model.width: pretrained {self.backbone} weights need width {need}, "
                    f"got {self.width}"
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
