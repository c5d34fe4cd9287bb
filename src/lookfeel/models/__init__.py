"""Networks: backbones, per-modality branches with press pooling and heads, the joint model.

Example:
    >>> from lookfeel.config import ModelConfig
    >>> from lookfeel.modality import Modality
    >>> model = create_model(ModelConfig(backbone="compact"), [Modality.DEPTH, Modality.TOUCH])
    >>> out = model({"depth": depth, "touch": presses})  # (B, 1, H, W), (B, P, 3, H, W)
    >>> out["touch"].shape  # (B, D)
"""

from lookfeel.models.alexnet import AlexNet
from lookfeel.models.backbone import Backbone, BackboneError, ModelInputError
from lookfeel.models.branch import CLASSES, CLUSTER, PROPERTY, Branch, BranchEnsemble
from lookfeel.models.compact import CompactCNN
from lookfeel.models.embedder import Embedder, create_model, head_key
from lookfeel.models.modes import (
    add_press_axis,
    autocast,
    drop_press_axis,
    eval_mode,
    to_channels_last,
)
from lookfeel.models.pretrained import (
    PretrainedError,
    apply_state_dict,
    load_pretrained,
    read_state_dict,
)
from lookfeel.models.registry import (
    BACKBONES,
    create_backbone,
    list_backbones,
    register_backbone,
)
from lookfeel.models.resnet import ResNet18

__all__ = [
    "BACKBONES",
    "CLASSES",
    "CLUSTER",
    "PROPERTY",
    "AlexNet",
    "Backbone",
    "BackboneError",
    "Branch",
    "BranchEnsemble",
    "CompactCNN",
    "Embedder",
    "ModelInputError",
    "PretrainedError",
    "ResNet18",
    "add_press_axis",
    "apply_state_dict",
    "autocast",
    "create_backbone",
    "create_model",
    "drop_press_axis",
    "eval_mode",
    "head_key",
    "list_backbones",
    "load_pretrained",
    "read_state_dict",
    "register_backbone",
    "to_channels_last",
]
