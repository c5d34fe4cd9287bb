"""Command-line text that a message suggests (``--set "train.views=[depth,touch]"``), quoted
so that it can be typed as printed.

A message that says what to type is read on any system: the same words work in bash, zsh,
Windows' cmd.exe and PowerShell when an argument that needs quotes has double quotes around it
and holds none of ``"``, ``$``, a backquote, ``!``, ``%`` or ``\\`` (which each of those shells
reads inside double quotes). Single quotes do not travel: cmd.exe keeps them as part of the
argument, so ``--set 'train.views=[touch,touch]'`` sets the key ``'train.views``.

`set_flag` writes a suggested ``--set KEY=VALUE`` and `portable_quote` one argument so;
`shell_quote` quotes for the shell of the system it runs on, for text that double quotes alone
cannot carry (a Windows path's backslashes, a word with ``$`` or ``"``). This module imports
nothing of lookfeel's: data, config and the workflows all write such messages.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess

__all__ = ["WINDOWS", "portable_quote", "set_flag", "shell_quote"]

WINDOWS = os.name == "nt"
"""Whether commands are typed into Windows' cmd.exe or PowerShell (`shell_quote`)."""

_CMD_SPECIAL = frozenset("&|<>^()")
"""Characters cmd.exe acts on outside double quotes."""

_BARE = re.compile(r"[A-Za-z0-9_.:=+/-]+")
"""An argument that needs no quotes in any of the shells: PowerShell splits at commas and
reads braces, zsh refuses an unmatched ``[...]`` and bash expands ``{a,b}``."""

_NOT_IN_DOUBLE = frozenset('"$`!%\\')
"""Characters that one of bash, zsh, cmd.exe or PowerShell reads inside double quotes."""


def shell_quote(text: str, windows: bool | None = None) -> str:
    """``text`` as one argument of a command a message suggests, quoted for the shell the
    user types it into: POSIX quoting (``'a b'``, ``shlex.quote``) where that shell is sh,
    bash or zsh; on Windows (``windows``, by default `WINDOWS`), where cmd.exe keeps single
    quotes as part of the argument, double quotes as ``subprocess.list2cmdline`` writes them
    (``"a b"``), also around an argument holding one of cmd.exe's operators (``&|<>^()``).
    Nothing is quoted that needs no quotes (``--set train.steps=3``)."""
    if not (WINDOWS if windows is None else windows):
        return shlex.quote(text)
    quoted = subprocess.list2cmdline([text])
    if quoted.startswith('"') or not _CMD_SPECIAL.intersection(text):
        return quoted
    # in quotes, backslashes before the closing quote are doubled (list2cmdline's rule)
    body = quoted.rstrip("\\")
    return '"' + body + "\\" * (2 * (len(quoted) - len(body))) + '"'


def portable_quote(text: str) -> str:
    """``text`` as one argument that bash, zsh, cmd.exe and PowerShell all read as ``text``:
    bare where it needs no quotes (``train.steps=3``), else in double quotes
    (``"train.views=[depth,touch]"``); text that double quotes cannot carry in every one of
    them (holding ``"``, ``$``, a backquote, ``!``, ``%``, ``\\`` or a control character) is
    quoted for this system's shell instead (`shell_quote`)."""
    if _BARE.fullmatch(text):
        return text
    if _NOT_IN_DOUBLE.intersection(text) or any(ord(c) < 32 or ord(c) == 127 for c in text):
        return shell_quote(text)
    return f'"{text}"'


def set_flag(setting: str) -> str:
    """The ``--set`` flag a message suggests for ``setting`` (``KEY=VALUE``), as it can be
    typed: ``--set "train.views=[touch,touch]"``, ``--set train.steps=3`` (`portable_quote`)."""
    return f"--set {portable_quote(setting)}"
