"""Training configuration, and `RunConfig`: everything a run needs, saved with every run."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from lookfeel.config._core import ConfigError, check_choices, parse_pairs
from lookfeel.config.data import DataConfig
from lookfeel.config.loss import LossConfig
from lookfeel.config.model import ModelConfig
from lookfeel.modality import Modality, Pair

__all__ = ["RunConfig", "SplitKind", "TrainConfig"]

SplitKind = Literal["stratified", "paper", "seen", "fold", "none"]
"""How a run chooses its validation items (`TrainConfig.split`)."""


def _default_views() -> tuple[Modality, ...]:
    return (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)


@dataclass(frozen=True)
class TrainConfig:
    """The optimisation schedule, the validation split and what is logged and saved.

    Defaults are the paper's (section 4.2): Adam, learning rate 1e-3, batch 128, 25,000
    iterations. The authors' released code used a learning rate of 1e-4.
    """

    views: tuple[Modality, ...] = field(default_factory=_default_views)
    """The slots of a training tuple: ``[depth, color, touch]`` for the paper's three-branch
    nets, ``[depth, touch]`` for Table 4's cross-modal net, ``[depth, depth]`` for its SNN."""
    steps: int = 25_000
    """Optimisation steps (iterations)."""
    batch_size: int = 128
    """Tuples per step (the global batch, over all processes)."""
    lr: float = 1e-3
    """Adam learning rate (paper: 1e-3, constant)."""
    weight_decay: float = 0.0
    """Decoupled weight decay (AdamW when > 0)."""
    lr_schedule: Literal["constant", "cosine"] = "constant"
    """``constant`` (the paper) or ``cosine`` (decay to 0 over ``steps`` after warm-up)."""
    warmup_steps: int = 0
    """Linear warm-up steps for the learning rate."""
    seed: int = 0
    """Seeds the model's initialisation, tuple draws, augmentation and dropout (>= 0)."""
    split: SplitKind = "stratified"
    """Validation fabrics: ``stratified`` holds out ``val_fabrics`` training fabrics evenly
    over clusters; ``paper`` validates on the paper's 18 test fabrics (when the data has them);
    ``seen`` holds out 20% of every fabric's items (Table 4's seen fabrics); ``fold`` holds out
    fold ``fold`` of ``folds`` cluster-stratified folds; ``none`` trains on all, no validation."""
    val_fabrics: int = 18
    """Fabrics held out by the ``stratified`` split (the paper's test set has 18)."""
    folds: int = 5
    """Number of folds for the ``fold`` split."""
    fold_size: int | None = None
    """Fabrics each fold of the ``fold`` split holds out; ``None`` deals every fabric into the
    folds (sizes differ by at most one). With a size, ``folds * fold_size`` fabrics chosen
    evenly over the clusters are dealt and the rest always train (5 folds of 18: five test sets
    like the paper's)."""
    fold: int = 0
    """Which fold the ``fold`` split holds out (0-based)."""
    split_seed: int = 0
    """Seed of the split (kept apart from ``seed`` so seeds vary over one split; >= 0)."""
    val_every: int = 1000
    """Validate every this many steps (and at the end); 0 only at the end."""
    val_pairs: tuple[Pair, ...] = ()
    """Pairs to validate, as ``query_to_gallery`` (e.g. ``touch_to_depth``); empty: every pair
    of the run's modalities. The first is the one `best.pt` is chosen by."""
    checkpoint_every: int = 1000
    """Write ``checkpoints/last.pt`` every this many steps (and at the end)."""
    log_every: int = 50
    """Write a line to ``metrics.jsonl`` every this many steps."""
    cache_trunk: bool = True
    """Run the frozen trunk once per image and train the heads from the cache (much faster).
    Ignored when nothing is frozen."""
    augment_copies: int = 4
    """With the trunk cached, augmented modalities are cached as this many augmented copies
    per image, one picked at random per draw; 0 bypasses the cache for them instead."""
    feature_batch: int = 64
    """Images per forward pass when filling the trunk cache or embedding for validation."""
    workers: int = 0
    """Ignored: batches are built on the training device from images decoded once
    (`lookfeel.data.ImageStore`), with no loader processes. Kept so older configs and run
    directories still load; decoding threads are ``data.workers``."""
    threads: int = 0
    """torch CPU threads (0: leave torch's default)."""
    device: Literal["auto", "cpu", "cuda"] = "auto"
    """``auto`` (CUDA when available, else CPU), ``cpu``, or ``cuda``."""
    progress: bool = True
    """Show a progress bar with the loss and rate."""
    cuda_graph: bool = False
    """On CUDA, in one process with a constant learning rate: run the first steps eagerly,
    then capture one step (forward, loss, backward, optimiser) in a CUDA graph and replay it,
    copying each step's batch in. A cached step is bound by launching ~210 small kernels, not by
    the GPU; replaying them as one graph removes that. Ignored on CPU; on CUDA a warning says
    why when it cannot apply. Opt-in: measured on one H100 so far."""
    channels_last: bool = True
    """Train with the images and the convolutions' weights in channels-last (NHWC) memory
    layout, which cuDNN's and oneDNN's fastest convolutions and pools read, on every device.
    On 2 cores of an Intel Xeon it trains the compact recipes 1.25-1.38 times as fast
    (`python -m benchmarks --only train_layout`); ``false`` keeps the NCHW layout (a CPU where
    that is faster). The two layouts round differently, and over a full run that moves its
    scores as another seed would (docs/synth.md, "Speed"); each layout is reproducible."""

    def __post_init__(self) -> None:
        check_choices(self, "train")
        object.__setattr__(self, "val_pairs", parse_pairs(self.val_pairs, "train.val_pairs"))
        if len(self.views) < 2:
            raise ConfigError(
                "train.views: a training tuple needs at least two slots (e.g. [depth, touch], "
                "or [depth, depth] for the Siamese net)"
            )
        for key in ("steps", "batch_size", "feature_batch"):
            if getattr(self, key) < 1:
                raise ConfigError(f"train.{key}: must be >= 1, got {getattr(self, key)}")
        for key in (
            "val_every",
            "checkpoint_every",
            "log_every",
            "augment_copies",
            "workers",
            "seed",  # numpy's generators take no negative seed
            "split_seed",
        ):
            if getattr(self, key) < 0:
                raise ConfigError(f"train.{key}: must be >= 0, got {getattr(self, key)}")
        if self.lr <= 0:
            raise ConfigError(f"train.lr: must be > 0, got {self.lr}")
        if not 0 <= self.fold < self.folds:
            raise ConfigError(f"train.fold: must be in 0..{self.folds - 1}, got {self.fold}")
        if self.fold_size is not None and self.fold_size < 1:
            raise ConfigError(f"train.fold_size: must be >= 1 or null, got {self.fold_size}")

    @property
    def modalities(self) -> tuple[Modality, ...]:
        """The distinct modalities of the views, in order."""
        return tuple(dict.fromkeys(self.views))


@dataclass(frozen=True)
class RunConfig:
    """One training run: data, model, loss and training settings.

    Written to ``RUN/config.yaml`` and embedded in every checkpoint, so a checkpoint alone
    rebuilds the model. Configs under ``configs/`` are YAML files of this shape.
    """

    data: DataConfig = field(default_factory=DataConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def check_input_sizes(self, min_size: int) -> None:
        """Refuse network inputs smaller than the backbone accepts, before any work is done.

        Every branch uses ``model.backbone``; each modality the run trains (``train.views``)
        enters it at ``data.size_of(modality)`` pixels a side: ``data.color_size`` for colour
        when set, else ``data.image_size``. Without this check a too small image fails deep
        inside training, after the data are loaded.

        Args:
            min_size: the smallest side the backbone accepts, in pixels: its class's
                ``min_size`` (`lookfeel.models.BACKBONES`), which the caller looks up so that
                the minimums live in one place and configs need not import the models.

        Raises:
            ConfigError: naming the size key, its value, the backbone and its minimum.
        """
        small: dict[str, int] = {}  # size key -> its value, for every key below the minimum
        for modality in self.train.modalities:
            own = modality is Modality.COLOR and self.data.color_size is not None
            key = "color_size" if own else "image_size"
            if self.data.size_of(modality) < min_size:
                small[f"data.{key}"] = self.data.size_of(modality)
        if small:
            sizes = " and ".join(f"{k}={v}" for k, v in small.items())
            verb = "is" if len(small) == 1 else "are"
            raise ConfigError(
                f"{sizes} {verb} below the {min_size} px on each side that "
                f"model.backbone={self.model.backbone} accepts; set {' and '.join(small)} to "
                f"at least {min_size}, or choose another model.backbone"
            )
