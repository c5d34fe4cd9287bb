"""The backbone registry: name -> class, the one place a backbone is declared.

`register_backbone` records a class in `BACKBONES` and tells the config layer what it needs to
check a `ModelConfig` (`lookfeel.config.model.BackboneSpec`: freeze points, default freeze
point, whether it loads pretrained weights), read from the class's attributes. The config
layer imports no torch, so it cannot ask the classes themselves; this is how it learns of a
user's backbone. A backbone of one's own, registered from one's own module imported before
`lookfeel.load_config` (for the ``lookfeel`` command and the processes it starts: a plugin,
`lookfeel.plugins`), trains through ``model.backbone: <name>``::

    from lookfeel.models import Backbone, register_backbone

    @register_backbone("tiny")
    class Tiny(Backbone):
        freeze_points = {"none": 0}
        ...
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, overload

from lookfeel.config.model import BackboneSpec, register_backbone_spec
from lookfeel.models.alexnet import AlexNet
from lookfeel.models.backbone import Backbone, BackboneError
from lookfeel.models.compact import CompactCNN
from lookfeel.models.resnet import ResNet18
from lookfeel.plugins import check_registry_name

__all__ = ["BACKBONES", "create_backbone", "list_backbones", "register_backbone"]


class _Backbones(dict[str, type[Backbone]]):
    """`BACKBONES`: a dict whose ``BACKBONES[name] = cls`` registers (`register_backbone`), as
    earlier versions of this page told users to register a backbone."""

    def __setitem__(self, name: str, cls: type[Backbone]) -> None:
        register_backbone(name, cls)


BACKBONES: dict[str, type[Backbone]] = _Backbones()
"""Name -> backbone class (`register_backbone` adds to it). Every class takes
``in_channels``, ``stem``, ``freeze``, ``dropout`` and ``width`` keywords."""


def _spec(name: str, cls: type[Backbone]) -> BackboneSpec:
    """What the config checks of ``cls``, from its attributes."""
    points = getattr(cls, "freeze_points", None)
    if not isinstance(points, dict) or not points:
        raise TypeError(
            f"backbone {name!r}: {cls.__qualname__}.freeze_points must be a dict of freeze "
            'point -> stages in the trunk, e.g. {"none": 0}'
        )
    for point, cut in points.items():
        # The stages themselves are made only when the class is built (`create_backbone`
        # checks each count against them then); a count that is no count is refused now.
        if isinstance(cut, bool) or not isinstance(cut, int) or cut < 0:
            raise BackboneError(
                f"backbone {name!r}: {cls.__qualname__}.freeze_points[{point!r}] is {cut!r}; "
                "a freeze point's value is the number of stages in the trunk, an int >= 0"
            )
    try:
        return BackboneSpec(
            name,
            tuple(points),
            default_freeze=cls.default_freeze,
            loads_pretrained=cls.loads_pretrained,
            takes_width=cls.takes_width,
            pretrained_width=cls.pretrained_width,
        )
    except ValueError as e:
        raise TypeError(f"{cls.__qualname__}: {e}") from None


@overload
def register_backbone(name: str) -> Callable[[type[Backbone]], type[Backbone]]: ...
@overload
def register_backbone(name: str, cls: type[Backbone]) -> type[Backbone]: ...
def register_backbone(
    name: str, cls: type[Backbone] | None = None
) -> type[Backbone] | Callable[[type[Backbone]], type[Backbone]]:
    """Register a `Backbone` subclass under ``name``, for `create_backbone` and the config.

    Reads the class's ``freeze_points`` and, where set, ``default_freeze``,
    ``loads_pretrained``, ``takes_width``, ``pretrained_width`` and ``min_size``. Registering
    the same class again (a module imported twice) changes nothing.

    Args:
        name: the value of ``model.backbone`` that selects it; also set as the class's
            ``name`` when it has none.
        cls: the class; without it, a decorator: ``@register_backbone("tiny")``.

    Returns:
        ``cls`` (or the decorator).

    Raises:
        PluginError: ``name`` cannot be given as ``model.backbone`` in a config (it must be
            letters, digits, ``_``, ``-`` and ``.``, beginning with a letter:
            `lookfeel.plugins.check_registry_name`); refused by the decorator form too.
        TypeError: ``cls`` is not a `Backbone` subclass, its attributes are inconsistent, or it
            defines ``forward``, ``trunk`` or ``head`` (lookfeel runs the stages given to
            ``_set_stages``, never these: an override would be ignored without a word).
        BackboneError: a ``freeze_points`` value is not an int >= 0 (one beyond the stages
            the class builds is refused when it is built: `create_backbone`).
        ValueError: another class is registered under ``name``, or ``cls`` is named otherwise.
    """
    check_registry_name(name, "backbone", "model.backbone")
    if cls is None:
        return lambda c: register_backbone(name, c)
    if not (isinstance(cls, type) and issubclass(cls, Backbone)):
        raise TypeError(f"backbone {name!r}: expected a Backbone subclass, got {cls!r}")
    for klass in cls.__mro__[: cls.__mro__.index(Backbone)]:
        defined = [m for m in _RUN_BY_LOOKFEEL if m in vars(klass)]
        if defined:
            raise TypeError(
                f"backbone {name!r}: {klass.__qualname__} defines {defined[0]}(), which lookfeel "
                "never calls (it runs the stages given to _set_stages): make it a stage"
            )
    known = dict.get(BACKBONES, name)
    if known is not None and _where(known) != _where(cls):
        raise ValueError(f"backbone {name!r} is already registered ({_where(known)})")
    own = cls.__dict__.get("name")
    if own is not None and own != name:
        raise ValueError(f"backbone {name!r}: {cls.__qualname__} is named {own!r}")
    register_backbone_spec(_spec(name, cls))
    cls.name = name
    dict.__setitem__(BACKBONES, name, cls)
    return cls


_RUN_BY_LOOKFEEL = ("forward", "trunk", "head")
"""`Backbone` methods lookfeel runs as the base class defines them (`Branch` calls `trunk` and
`head`, which run the stages): a subclass must not define them."""


def _where(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


for _cls in (AlexNet, CompactCNN, ResNet18):
    register_backbone(_cls.name, _cls)


def list_backbones() -> list[str]:
    """Names `create_backbone` accepts, sorted."""
    return sorted(BACKBONES)


def create_backbone(name: str, **kwargs: Any) -> Backbone:
    """Build a backbone by name, with random weights (see `load_pretrained` for weights).

    Args:
        name: one of `list_backbones`.
        **kwargs: ``in_channels`` (1 or 3), ``stem`` (``replicate`` | ``sum``), ``freeze``
            (a freeze point; ``None`` for the backbone's default), ``dropout``, ``width``.

    Returns:
        The backbone; ``backbone(x)`` maps (N, in_channels, H, W) in [0, 1] to
        (N, backbone.embed_dim), and equals ``backbone.head(backbone.trunk(x))``.

    Raises:
        ValueError: an unknown name (listing the known ones) or a bad keyword value.
        BackboneError: the class breaks the `Backbone` contract, e.g. a ``freeze_points``
            value above the number of stages it gave ``_set_stages`` (which would freeze
            stages that do not exist: checked here, as the stages exist only once built).
    """
    if name not in BACKBONES:
        raise ValueError(
            f"unknown backbone {name!r}; expected one of: {', '.join(list_backbones())}"
        )
    backbone = BACKBONES[name](**kwargs)
    stages = len(backbone._stages)
    for point, cut in type(backbone).freeze_points.items():
        if cut > stages:
            raise BackboneError(
                f"{backbone._who()}: freeze point {point!r} puts {cut} stages in the trunk, "
                f"but the backbone has {stages} (the stages given to _set_stages); a freeze "
                f"point's value is at most {stages}"
            )
    return backbone
