"""Training: `train` runs a `RunConfig` on a dataset, in one process or many (torchrun)."""

from lookfeel.train.divergence import TrainingDiverged
from lookfeel.train.features import FeatureTable
from lookfeel.train.loop import (
    TrainResult,
    TrainRun,
    config_changes,
    member_config,
    run_started,
    select_split,
    train,
    train_step,
)
from lookfeel.train.validate import default_pairs, validate

__all__ = [
    "FeatureTable",
    "TrainResult",
    "TrainRun",
    "TrainingDiverged",
    "config_changes",
    "default_pairs",
    "member_config",
    "run_started",
    "select_split",
    "train",
    "train_step",
    "validate",
]
