"""lookfeel: one embedding space for how fabrics look and how they feel.

An implementation of Yuan, Wang, Dong & Adelson, "Connecting Look and Feel: Associating the
visual and tactile properties of physical materials" (CVPR 2017), and beyond.
"""

from lookfeel.config import AugmentConfig, ConfigError, DataConfig, load_config
from lookfeel.modality import Modality, PressKind

__version__ = "0.1.0"

__all__ = [
    "AugmentConfig",
    "ConfigError",
    "DataConfig",
    "Modality",
    "PressKind",
    "__version__",
    "load_config",
]
