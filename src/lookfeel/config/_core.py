"""Strict conversion between config dataclasses, plain dicts, YAML files and ``--set`` overrides.

Each concern owns one dataclass and its defaults (minGPT). `from_dict` is strict: an unknown key
or a value of the wrong type raises `ConfigError` naming the dotted key, so a typo in a YAML
file or a ``--set`` flag never passes silently (nanoGPT's configurator, without its ``exec``).

Example:
    >>> from lookfeel.config import DataConfig
    >>> cfg = load_config(DataConfig, overrides=["image_size=64", "augment.color.gamma=[0.5,2]"])
    >>> cfg.image_size
    64
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import types
import typing
from collections.abc import Mapping, Sequence
from enum import Enum
from importlib import resources
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

import yaml

from lookfeel.atomic import atomic_write_text
from lookfeel.errors import LookfeelError
from lookfeel.modality import Pair
from lookfeel.plugins import PluginError

__all__ = [
    "ConfigError",
    "Override",
    "apply_overrides",
    "check_choices",
    "config_file",
    "from_dict",
    "load_config",
    "parse_pairs",
    "recipe_path",
    "save_config",
    "shipped_configs",
    "to_dict",
]

T = TypeVar("T")


class ConfigError(LookfeelError):
    """A configuration key or value is wrong; the message names the dotted key."""


@dataclasses.dataclass(frozen=True)
class Override:
    """An override whose value is taken as it is, not parsed as YAML: what a command-line flag
    such as ``lookfeel train --pretrained PATH`` sets. A path is any text (``/w/a: b.pth`` or
    ``*r18.pth`` would be a mapping or a broken alias as YAML), and an error about the key
    names the flag the user typed, not a ``--set`` they never wrote.

    Attributes:
        key: the dotted key (``model.pretrained``).
        value: its value, as the config field takes it (a string for a path).
        given: what the user typed, which an error about ``key`` begins with
            (``--pretrained 'w/a: b.pth'``).
    """

    key: str
    value: Any
    given: str


# --------------------------------------------------------------------------------------------
# Generic strict conversion between dataclasses and plain dicts.


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _not_one_of(key: str, value: Any, allowed: Sequence[Any]) -> ConfigError:
    return ConfigError(f"{key}: {value!r} is not one of {', '.join(str(a) for a in allowed)}")


def _choices(tp: Any) -> tuple[tuple[Any, ...], bool] | None:
    """The allowed values of a ``Literal`` field type, and whether it is a tuple of them.

    ``Literal["a", "b"]``, ``Literal[...] | None`` and ``tuple[Literal[...], ...]`` have choices;
    any other type has none (None).
    """
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Literal:
        return args, False
    if origin in (Union, types.UnionType):
        inner = [_choices(a) for a in args if a is not type(None)]
        return inner[0] if len(inner) == 1 else None
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        one = _choices(args[0])
        return (one[0], True) if one is not None and not one[1] else None
    return None


def check_choices(config: Any, section: str) -> None:
    """Check every ``Literal`` field of a config dataclass (also when built directly in code).

    Each config's ``__post_init__`` calls this first, so a choice outside its ``Literal`` raises
    however the config was made: loaded by `from_dict` or constructed by hand.

    Args:
        config: a config dataclass instance.
        section: its dotted key in a `RunConfig` (``"loss"``), used in the message.

    Raises:
        ConfigError: ``"{section}.{field}: 'x' is not one of a, b"``.
    """
    hints = typing.get_type_hints(type(config))
    for f in dataclasses.fields(config):
        found = _choices(hints[f.name])
        if found is None:
            continue
        allowed, many = found
        value = getattr(config, f.name)
        for v in value if many else (value,):
            if v is not None and v not in allowed:
                raise _not_one_of(f"{section}.{f.name}", v, allowed)


def parse_pairs(values: Sequence[str], key: str) -> tuple[Pair, ...]:
    """Parse ``("touch_to_depth", ...)`` into `Pair` values (for a config built in code).

    Raises:
        ConfigError: ``"{key}: 'x' is not a modality pair ..."``.
    """
    try:
        return tuple(Pair.parse(v) for v in values)
    except ValueError as e:
        raise ConfigError(f"{key}: {e}") from None


def _convert(value: Any, tp: Any, key: str) -> Any:
    """Convert a plain YAML value to type ``tp``; raise `ConfigError` naming ``key``."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if origin is Literal:
        # The type is checked here; whether the value is one of the choices, by the config's
        # own check_choices, which names the key as the config's section does.
        return _convert(value, type(args[0]), key)
    if tp is Pair:
        if isinstance(value, Pair):
            return value
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a pair query_to_gallery, got {value!r}")
        try:
            return Pair.parse(value)
        except ValueError as e:
            raise ConfigError(f"{key}: {e}") from None
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(value, arg, key)
            except ConfigError as e:
                errors.append(str(e))
        raise ConfigError(
            errors[0] if len(errors) == 1 else f"{key}: {value!r} fits no type of {tp}"
        )
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        if isinstance(value, tp):
            return value
        return from_dict(tp, value, prefix=key)
    if isinstance(tp, type) and issubclass(tp, Enum):
        if isinstance(value, tp):
            return value
        try:
            return tp(value)
        except ValueError:
            valid = ", ".join(str(m.value) for m in tp)
            raise ConfigError(f"{key}: {value!r} is not one of {valid}") from None
    if origin is tuple:
        if isinstance(value, str) or not isinstance(value, Sequence):
            value = [value] if not isinstance(value, str) else [v for v in value.split(",") if v]
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{key}: expected {len(args)} values, got {len(value)} ({value!r})")
        return tuple(
            _convert(v, a, f"{key}[{i}]") for i, (v, a) in enumerate(zip(value, args, strict=True))
        )
    if origin is list:
        if not isinstance(value, Sequence) or isinstance(value, str):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        return [_convert(v, args[0], f"{key}[{i}]") for i, v in enumerate(value)]
    if origin in (dict, Mapping):
        if not isinstance(value, Mapping):
            raise ConfigError(f"{key}: expected a mapping, got {value!r}")
        kt, vt = args
        return {
            _convert(k, kt, f"{key}.{k}"): _convert(v, vt, f"{key}.{k}") for k, v in value.items()
        }
    if tp is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "false", "yes", "no", "1", "0"):
            return value.lower() in ("true", "yes", "1")
        raise ConfigError(f"{key}: expected true or false, got {value!r}")
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, str):
                try:
                    return int(value)
                except ValueError:
                    pass
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        try:
            return float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{key}: expected a number, got {value!r}") from None
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{key}: unsupported type {_type_name(tp)}")  # pragma: no cover


def from_dict(cls: type[T], data: Mapping[str, Any] | None, prefix: str = "") -> T:
    """Build dataclass ``cls`` from a plain mapping, strictly.

    Args:
        cls: a dataclass type.
        data: keys are field names; missing fields keep their defaults.
        prefix: dotted key of ``data`` in a larger config, used in error messages.

    Raises:
        ConfigError: an unknown key, or a value that does not fit its field's type.
    """
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{prefix or 'config'}: expected a mapping, got {data!r}")
    assert dataclasses.is_dataclass(cls)
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - names)
    if unknown:
        where = f"{prefix}." if prefix else ""
        raise ConfigError(
            f"unknown key {where}{unknown[0]!s}; valid keys here: {', '.join(sorted(names))}"
        )
    kwargs = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        kwargs[name] = _convert(value, hints[name], key)
    try:
        return cls(**kwargs)
    except (ConfigError, PluginError):  # a plugin the config loaded: its own one line
        raise
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{prefix or cls.__name__}: {e}") from None


def to_dict(obj: Any) -> Any:
    """Turn a config dataclass into plain YAML/JSON-able data (enums become their values)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Enum):
        return obj.value
    if isinstance(obj, Pair):
        return str(obj)
    if isinstance(obj, Mapping):
        return {to_dict(k): to_dict(v) for k, v in obj.items()}
    if isinstance(obj, (tuple, list)):
        return [to_dict(v) for v in obj]
    return obj


def apply_overrides(data: dict[str, Any], overrides: Sequence[str | Override]) -> dict[str, Any]:
    """Apply ``key.sub=value`` overrides (values parsed as YAML) and `Override` values (taken as
    they are) to a nested plain dict, in order.

    Returns a new dict; ``data`` is not modified.

    Raises:
        ConfigError: an override without ``=``, or one that descends into a non-mapping.
    """
    import copy

    out = copy.deepcopy(data)
    for item in overrides:
        if isinstance(item, Override):
            key, shown = item.key, item.given
        elif "=" not in item:
            raise ConfigError(f"override {item!r}: expected key=value, e.g. data.image_size=64")
        else:
            key, shown = item.partition("=")[0], repr(item)
        parts = key.strip().split(".")
        if not all(parts):
            raise ConfigError(f"override {shown}: empty key part")
        node = out
        for i, p in enumerate(parts[:-1]):
            nxt = node.setdefault(p, {})
            if nxt is None:
                nxt = node[p] = {}
            if not isinstance(nxt, dict):
                raise ConfigError(f"override {shown}: {'.'.join(parts[: i + 1])} is not a mapping")
            node = nxt
        if isinstance(item, Override):
            node[parts[-1]] = copy.deepcopy(item.value)
            continue
        raw = item.partition("=")[2]
        try:
            node[parts[-1]] = yaml.safe_load(raw) if raw.strip() else None
        except yaml.YAMLError as e:
            raise ConfigError(
                f"override {item!r}: the value is not valid YAML ({_yaml_problem(e)})"
            ) from None
    return out


def _yaml_problem(e: yaml.YAMLError) -> str:
    """A YAML error in one line: what is wrong and where (PyYAML's own text spans several
    lines and quotes the source)."""
    problem = getattr(e, "problem", None)
    mark = getattr(e, "problem_mark", None)
    if problem and mark is not None:
        return f"{problem} at line {mark.line + 1}, column {mark.column + 1}"
    return " ".join(line.strip() for line in str(e).splitlines() if line.strip())


def recipe_path(name: str) -> Path:
    """The shipped config (or folder of them) ``configs/<name>`` in the installed package."""
    return Path(str(resources.files("lookfeel") / "configs" / name))


def shipped_configs() -> list[str]:
    """The shipped configs' names, as `config_file` takes them (``physiclear``, ``paper/flat``)."""
    root = recipe_path("")
    return sorted(p.relative_to(root).with_suffix("").as_posix() for p in root.rglob("*.yaml"))


def config_file(path: str | os.PathLike[str]) -> Path:
    """The file ``--config`` names: ``path`` where it exists, else the shipped config it names
    from any folder: ``physiclear``, ``physiclear.yaml``, ``configs/physiclear.yaml`` or
    ``configs/paper/flat.yaml`` read ``configs/`` of the installed package (`recipe_path`).

    Raises:
        ConfigError: no such file, and no shipped config of that name (the message lists them).
    """
    p = Path(path)
    if p.exists():
        return p
    parts = p.parts[1:] if p.parts[:1] == ("configs",) else p.parts
    if parts and not p.is_absolute() and ".." not in parts:
        rel = Path(*parts)
        name = rel.name if rel.suffix in (".yaml", ".yml") else rel.name + ".yaml"
        shipped = recipe_path(rel.with_name(name).as_posix())
        if shipped.is_file():
            return shipped
    raise ConfigError(
        f"{p}: no such config file, nor a shipped config of that name (shipped: "
        f"{', '.join(shipped_configs())}; name one as e.g. --config physiclear)"
    )


def load_config(
    cls: type[T],
    path: str | os.PathLike[str] | None = None,
    overrides: Sequence[str | Override] = (),
) -> T:
    """Defaults, then the YAML file at ``path`` (if any), then dotted ``overrides``
    (``key=value`` text parsed as YAML, or an `Override` taken as it is).

    ``path`` means what ``--config`` means on the command line (`config_file`): a file that
    exists is read as it is; else the shipped config of that name, from any folder
    (``"configs/tiny.yaml"``, ``"tiny.yaml"``, ``"tiny"``, ``"paper/flat"``).

    Example:
        >>> from lookfeel.config import RunConfig
        >>> load_config(RunConfig, "configs/tiny.yaml").train.steps  # also outside a checkout
        20

    Raises:
        ConfigError: naming the file and key when the YAML is unreadable or wrong, or the
            path when there is no such file nor a shipped config of that name (listing those).
    """
    data: dict[str, Any] = {}
    if path is not None:
        p = Path(path)
        if not p.exists():
            with contextlib.suppress(ConfigError):  # else said below: it cannot be read
                p = config_file(p)
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError as e:
            raise ConfigError(
                f"{p}: not UTF-8 text (byte {e.start}: {e.reason}); save it as UTF-8"
            ) from None
        except OSError as e:
            shipped = (
                "" if p.exists() else f", nor a shipped config ({', '.join(shipped_configs())})"
            )
            raise ConfigError(f"{p}: cannot read config file ({e.strerror}){shipped}") from None
        try:
            loaded = yaml.safe_load(text)
        except yaml.YAMLError as e:
            raise ConfigError(f"{p}: not valid YAML: {_yaml_problem(e)}") from None
        if loaded is not None and not isinstance(loaded, dict):
            raise ConfigError(f"{p}: the top level must be a mapping of keys to values")
        data = loaded or {}
    data = apply_overrides(data, overrides)
    try:
        return from_dict(cls, data)
    except ConfigError as e:
        message = str(e)
        # A value given with --set (or a flag) is blamed on it, not on the file it overrode.
        for given in reversed(overrides):
            if isinstance(given, Override):
                key, shown = given.key.strip(), given.given
            else:
                key, shown = given.partition("=")[0].strip(), f"--set {given}"
            named = message.startswith((f"{key}:", f"{key}.", f"{key}[")) or message.startswith(
                f"unknown key {key}"
            )
            if named:
                raise ConfigError(f"{shown}: {message}") from None
        if path is not None:
            raise ConfigError(f"{path}: {message}") from None
        raise


def save_config(config: Any, path: str | os.PathLike[str]) -> None:
    """Write a config as YAML atomically (a temp file in the same folder, then a rename)."""
    atomic_write_text(path, yaml.safe_dump(to_dict(config), sort_keys=False))
