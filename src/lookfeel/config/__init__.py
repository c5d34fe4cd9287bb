"""Configuration: one frozen dataclass per concern; defaults, then YAML, then ``--set`` overrides.

Every config class is strict: unknown keys and wrong types raise `ConfigError` naming the key.
"""

from lookfeel.config._core import (
    ConfigError,
    apply_overrides,
    from_dict,
    load_config,
    save_config,
    to_dict,
)
from lookfeel.config.data import AugmentConfig, DataConfig
from lookfeel.config.eval import EvalConfig
from lookfeel.config.loss import LossConfig
from lookfeel.config.model import ModelConfig
from lookfeel.config.train import RunConfig, TrainConfig

__all__ = [
    "AugmentConfig",
    "ConfigError",
    "DataConfig",
    "EvalConfig",
    "LossConfig",
    "ModelConfig",
    "RunConfig",
    "TrainConfig",
    "apply_overrides",
    "from_dict",
    "load_config",
    "save_config",
    "to_dict",
]
