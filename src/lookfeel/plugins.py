"""Plugins: a user's own modules that register backbones or losses, loaded in every process.

A backbone or loss of one's own is registered by importing the module that defines it
(`lookfeel.models.register_backbone`, `lookfeel.losses.register_loss`). Importing it in a
script before calling lookfeel works in that process only: the processes lookfeel starts
afresh (``lookfeel reproduce --workers N`` trains in spawned workers, ``torchrun`` starts
every rank anew) never see that import. `load_plugins` imports such modules in whichever
process calls it, from two places that every new process finds again:

- the environment variable ``LOOKFEEL_PLUGINS``: module names separated by commas
  (``LOOKFEEL_PLUGINS=my_ext,lab.backbones``), inherited by every process started from this
  one. ``lookfeel --plugin my_ext ...`` adds to it. A module is found on ``sys.path``: for
  the ``lookfeel`` command, put its folder on ``PYTHONPATH`` (``python -m lookfeel`` also
  finds one in the current folder);
- the entry points of group ``lookfeel.plugins`` that installed packages declare, in their
  ``pyproject.toml``::

      [project.entry-points."lookfeel.plugins"]
      my_ext = "my_ext"              # a module: importing it is the work
      other = "my_pkg.setup:register"  # a function: called with no arguments

`lookfeel.cli.main` calls it before any command runs, and so does each of ``reproduce``'s
worker processes when it starts. Library code calls it too, lazily: when the config meets
a ``model.backbone`` or ``loss.kind`` nobody has registered (``load_config``, ``load_model``,
``build_library`` in a script of one's own), so a plugin named in either place loads in any
process without a call of one's own. A module named in ``LOOKFEEL_PLUGINS`` or by
``--plugin`` that cannot be imported is a `PluginError` naming where it was asked for
(``--plugin`` for a module that option added). An installed entry point that cannot be loaded
or run is a `PluginWarning` instead, and lookfeel goes on without it: a broken package one
did not name for this command must not stop every command (``lookfeel data info`` included).
A backbone or loss name a config cannot give is refused when registered
(`check_registry_name`). This module imports no torch (the plugins themselves may).
"""

from __future__ import annotations

import importlib
import importlib.metadata
import os
import re
import sys
import types
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from lookfeel.errors import LookfeelError, caller_stacklevel, error_line

__all__ = [
    "ENTRY_POINT_GROUP",
    "ENV_VAR",
    "PluginError",
    "PluginWarning",
    "add_plugin_modules",
    "check_registry_name",
    "load_plugins",
    "plugin_modules",
    "trained_with_hint",
    "unknown_name_hint",
]

ENV_VAR = "LOOKFEEL_PLUGINS"
"""The environment variable naming plugin modules, separated by commas."""

ENTRY_POINT_GROUP = "lookfeel.plugins"
"""The entry-point group whose entries `load_plugins` loads."""

_MODULE_NAME = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*\Z")

_loaded_modules: set[str] = set()
"""The modules of ``LOOKFEEL_PLUGINS`` this process has imported."""
_entry_points_loaded = False
"""Whether this process has loaded the ``lookfeel.plugins`` entry points."""
_entry_point_names: list[str] = []
"""The names of the entry points this process has loaded (for `unknown_name_hint`)."""
_entry_point_failures: list[str] = []
"""The entry points this process failed to load, each as ``entry point 'name' = 'value' did
not load (why)`` (for `unknown_name_hint`: the name asked for may be one that such a plugin
registers)."""
_from_option: dict[str, str] = {}
"""Module -> the option that added it to ``LOOKFEEL_PLUGINS`` in this process (``--plugin``):
an error about it names that option."""
_loading = False
"""Whether `load_plugins` is running (a plugin's import that meets an unknown name itself
must not start it again)."""


class PluginError(LookfeelError):
    """A plugin module named in ``LOOKFEEL_PLUGINS`` or by ``--plugin`` cannot be imported, or
    a backbone or loss is registered under a name a config cannot give."""


class PluginWarning(UserWarning):
    """An installed entry point of group ``lookfeel.plugins`` cannot be loaded or run; lookfeel
    goes on without it (the message names it, its package and the error)."""


_REGISTRY_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_.-]*\Z")
"""A name a config gives as it is (``model.backbone=my_net``, ``backbone: my-net.v2``)."""


def check_registry_name(name: object, what: str, key: str) -> None:
    """Refuse a backbone or loss ``name`` that a config cannot give as the value of ``key``
    (``model.backbone``, ``loss.kind``): it must be letters, digits, ``_``, ``-`` and ``.``,
    beginning with a letter, and not a word YAML reads as something else (``yes``, ``null``).

    Every way of registering applies it: `lookfeel.models.register_backbone` and
    `lookfeel.losses.register_loss`, and the config's own registries beneath them
    (`lookfeel.config.model.register_backbone_spec`, `lookfeel.config.loss.register_loss_kind`).

    Args:
        name: the name being registered.
        what: what it names, for the message (``backbone``, ``loss``).
        key: the config key that selects it.

    Raises:
        PluginError: in one line naming ``name`` and the rule.
    """
    rule = "only letters, digits, _, - and ., beginning with a letter (e.g. my_net)"
    where = f"{what} name {name!r} cannot be written as {key} in a config"
    if not (isinstance(name, str) and _REGISTRY_NAME.match(name)):
        raise PluginError(f"{where}: use {rule}")
    import yaml  # only here: most commands never register a name of their own

    read = yaml.safe_load(name)
    if read != name:
        raise PluginError(f"{where}, which reads it as {read!r}: choose another name of {rule}")


def plugin_modules(value: str | None = None) -> list[str]:
    """The module names in ``value`` (default: ``LOOKFEEL_PLUGINS``), in order, each once;
    spaces and empty entries are ignored."""
    if value is None:
        value = os.environ.get(ENV_VAR, "")
    names: list[str] = []
    for part in value.split(","):
        name = part.strip()
        if name and name not in names:
            names.append(name)
    return names


def load_plugins() -> None:
    """Import every module named in ``LOOKFEEL_PLUGINS``, then load every entry point of group
    ``lookfeel.plugins`` (a module is imported; a function is called with no arguments).

    It does the work once per process: a second call imports only modules added to
    ``LOOKFEEL_PLUGINS`` since (``lookfeel --plugin`` adds to it), and loads no entry point
    again. Besides `lookfeel.cli.main` and ``reproduce``'s workers, the config calls it when
    it meets a ``model.backbone`` or ``loss.kind`` nobody has registered
    (`lookfeel.config.model.backbone_spec`, `lookfeel.config.LossConfig`), so a script of
    one's own that calls lookfeel gets the plugins as the ``lookfeel`` command does.

    An entry point that cannot be loaded or run is a `PluginWarning` in one line (its name,
    value, package and error), and the others load: an installed package one did not name
    for this command must not stop it. Its name is remembered for `unknown_name_hint`.

    Raises:
        PluginError: a module of ``LOOKFEEL_PLUGINS`` cannot be imported (its own error in one
            line, and where in it when the module itself failed).
    """
    global _entry_points_loaded, _loading
    if _loading:
        return  # called again from inside a plugin's import: the outer call does the work
    _loading = True
    try:
        for name in plugin_modules():
            if name not in _loaded_modules:
                _import(name)
                _loaded_modules.add(name)
        if not _entry_points_loaded:
            for ep in _entry_points():
                try:
                    _load_entry_point(ep)
                except PluginError as e:
                    why = error_line(e.__cause__ or e)
                    failed = f"entry point {ep.name!r} = {ep.value!r} did not load ({why})"
                    _entry_point_failures.append(failed)
                    warnings.warn(
                        f"{e}; lookfeel goes on without it",
                        PluginWarning,
                        stacklevel=caller_stacklevel(),
                    )
                else:
                    _entry_point_names.append(ep.name)
            _entry_points_loaded = True
    finally:
        _loading = False


def unknown_name_hint() -> str:
    """What to do about a backbone or loss name no plugin registered, for the config's error
    (called after `load_plugins`): the ways to register one's own, which plugins were loaded
    without registering it, and which entry points failed to load (one of them may be the
    plugin that registers it)."""
    hint = (
        "one of your own: import its module first, or name it in LOOKFEEL_PLUGINS or "
        "lookfeel --plugin"
    )
    loaded = [m for m in plugin_modules() if m in _loaded_modules]
    loaded += [f"entry point {n}" for n in _entry_point_names]
    if loaded:
        hint += f"; the plugins loaded ({', '.join(loaded)}) register no such name"
    else:
        hint += ", which lookfeel.plugins.load_plugins() imports"
    return "; ".join([hint, *_entry_point_failures])


def trained_with_hint(modules: Iterable[object]) -> str:
    """What to add to an error about a trained run's config that does not load: the plugin
    modules the run was trained with (its checkpoint's ``plugins``) that this process has not
    imported, and how to load them; ``""`` when it has imported them all.

    Example: ``" (the run was trained with the plugin module my_ext: lookfeel --plugin my_ext,
    with its folder on PYTHONPATH)"``.
    """
    missing = [str(m) for m in modules if str(m) not in sys.modules]
    if not missing:
        return ""
    return (
        f" (the run was trained with the plugin module {', '.join(missing)}: "
        f"lookfeel --plugin {missing[0]}, with its folder on PYTHONPATH)"
    )


def add_plugin_modules(names: Iterable[str], option: str = "--plugin") -> None:
    """Add modules to ``LOOKFEEL_PLUGINS`` in this process's environment (which the processes
    it starts inherit) for `load_plugins` to import; an error about one of them names
    ``option``, which the user gave them with.

    Raises:
        PluginError: a name that is not a module name (a file's path, say), naming ``option``.
    """
    names = plugin_modules(",".join(names))
    for name in names:
        _check_name(name, option)
    have = plugin_modules()
    added = [n for n in names if n not in have]
    for name in added:
        _from_option[name] = option
    if added:
        os.environ[ENV_VAR] = ",".join(have + added)


def _reset() -> None:
    """Forget what `load_plugins` has done in this process (for tests)."""
    global _entry_points_loaded, _loading
    _loaded_modules.clear()
    _entry_point_names.clear()
    _entry_point_failures.clear()
    _from_option.clear()
    _entry_points_loaded = False
    _loading = False


def _check_name(name: str, option: str) -> None:
    """Refuse a ``name`` given with ``option`` that is not a module name, in one line; for
    the path of a ``.py`` file, say how to name its module instead."""
    if _MODULE_NAME.match(name) and not name.endswith(".py"):
        return
    where = f"{option}: "
    path = Path(name)
    if path.suffix == ".py" and path.stem.isidentifier():
        folder = str(path.parent)
        named = f"{ENV_VAR}={path.stem}" if option == ENV_VAR else f"lookfeel {option} {path.stem}"
        raise PluginError(
            f"{where}{name!r} is a file, not a module name: put its folder on PYTHONPATH and "
            f"name the module (PYTHONPATH={folder} {named})"
        )
    raise PluginError(
        f"{where}{name!r} is not a module name (e.g. my_ext or lab.backbones, not a file); "
        "put its folder on PYTHONPATH and name the module"
    )


def _import(name: str) -> None:
    """Import plugin module ``name`` from ``LOOKFEEL_PLUGINS``, or say in one line why not
    (blaming the option that added it, when one did)."""
    option = _from_option.get(name, ENV_VAR)
    _check_name(name, option)
    where = f"{option}: "
    try:
        importlib.import_module(name)
    except Exception as e:
        missing = isinstance(e, ModuleNotFoundError) and _is_itself(name, e.name)
        hint = "; is its folder on PYTHONPATH?" if missing else ""
        raise PluginError(f"{where}cannot import {name!r} ({_why(e, not missing)}){hint}") from e


def _is_itself(name: str, missing: str | None) -> bool:
    """Whether the module found missing is ``name`` or a package above it (not a module that
    ``name`` itself imports)."""
    return missing is not None and (name == missing or name.startswith(missing + "."))


def _entry_points() -> Iterable[importlib.metadata.EntryPoint]:
    """The installed entry points of `ENTRY_POINT_GROUP`, each once."""
    seen: set[tuple[str, str]] = set()
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if (ep.name, ep.value) not in seen:  # a package found twice on sys.path
            seen.add((ep.name, ep.value))
            yield ep


def _load_entry_point(ep: importlib.metadata.EntryPoint) -> None:
    """Load entry point ``ep`` (import its module; call its object when it is a function), or
    raise `PluginError` saying in one line why not (`load_plugins` warns with it)."""
    package = getattr(getattr(ep, "dist", None), "name", None)
    where = f"entry point {ep.name!r} ({ENTRY_POINT_GROUP})"
    where += f" of package {package}: " if package else ": "
    try:
        obj: Any = ep.load()
    except Exception as e:
        raise PluginError(f"{where}cannot load {ep.value!r} ({_why(e, True)})") from e
    if isinstance(obj, types.ModuleType) or not callable(obj):
        return  # importing it was the work
    try:
        obj()
    except Exception as e:
        raise PluginError(f"{where}{ep.value}() failed ({_why(e, True)})") from e


def _why(e: BaseException, locate: bool) -> str:
    """``e`` in one line; with ``locate``, the file and line of the plugin's code it was raised
    at (the innermost frame outside the import machinery and lookfeel's own code: a name that
    `register_backbone` refuses is named at the plugin's line that registers it), so that a
    bug in a plugin can be found without its traceback."""
    if not locate:
        return str(e)  # "No module named 'x'" says it all
    text = error_line(e)
    if isinstance(e, SyntaxError) and e.filename:
        return f"{text}, at {e.filename}:{e.lineno}"
    at = own = None
    tb = e.__traceback__
    while tb is not None:
        filename = tb.tb_frame.f_code.co_filename
        if not (filename.startswith("<frozen") or filename in _MACHINERY):
            at = f"{filename}:{tb.tb_lineno}"
            if not filename.startswith(_LOOKFEEL):
                own = at
        tb = tb.tb_next
    at = own or at
    return f"{text}, at {at}" if at else text


_MACHINERY = {__file__, importlib.__file__, importlib.metadata.__file__}
"""Files whose frames are the import machinery, not a plugin's code."""
_LOOKFEEL = os.path.dirname(os.path.abspath(__file__)) + os.sep
"""lookfeel's own code: where a plugin's error is raised, not where its cause is."""
