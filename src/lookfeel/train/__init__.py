"""Training: `train` runs a `RunConfig` on a dataset, in one process or many (torchrun)."""

from lookfeel.train.divergence import TrainingDiverged
from lookfeel.train.features import FeatureTable
from lookfeel.train.loop import TrainResult, member_config, run_started, select_split, train
from lookfeel.train.validate import default_pairs, validate

__all__ = [
    "FeatureTable",
    "TrainResult",
    "TrainingDiverged",
    "default_pairs",
    "member_config",
    "run_started",
    "select_split",
    "train",
    "validate",
]
