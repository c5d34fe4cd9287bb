"""The ``lookfeel`` command: flags become config objects here; library code never sees argv.

Commands (``lookfeel COMMAND --help`` gives each one's options):

  data info ROOT      what a dataset holds: fabrics, items per modality and press kind, labels
  data check ROOT     decode every file and report every problem; exit 1 if there is an error
  data leakage ROOT   does the background alone (no cloth) identify the fabric? per modality
  synth OUT           generate a synthetic visuo-tactile fabric world in the dataset layout
  train               train a model from a run config on a dataset (one process or torchrun)
  cv                  cross-validate a config over fabric-disjoint folds, beside pixels and chance
  reproduce           run every experiment of the paper and report ours beside its numbers
  embed               embed a dataset's items with a trained checkpoint into an .npz file
  evaluate            score a checkpoint or an embeddings file: metrics.json, report.md, figures
  index build         embed a dataset into a calibrated fabric library (for match, serve)
  index info LIBRARY  what a library holds and how it is calibrated
  match IMAGE...      which library fabric an image shows, how it looks and feels, its properties
  predict INPUT...    what a video or image feels like: each property with its probability
  serve               web page and JSON API to match images against a library
  export              export each modality branch of a checkpoint (ONNX)
  demo                the whole system on a generated synthetic world, in minutes

Each command module (``data``, ``synth``, ..., ``demo``) holds ``add_parser(subparsers)``, which
defines the command's options, beside ``run(args) -> int``, its handler; the module's docstring
is the command's purpose, then its ``--help`` description. ``_args`` holds what several commands
share, and `Choices` reads an option's values (splits, budgets, ...) from the module that defines
them. A handler imports the library when it runs, so that ``lookfeel --help`` and each command
load only what they use. An error a user can cause is a `LookfeelError`: handlers let it through,
and `main` prints ``lookfeel: <message>`` and returns 1, as it does for an ``--out`` this user
cannot write (`_args.OutPathError`, raised as the command line is read); a mistake in the
command line itself is argparse's usage error (usage, then ``lookfeel ...: error: ...``, on
stderr; exit 2), a bare ``lookfeel`` included. Before a command runs, `main` imports
the user's plugin modules (``--plugin MODULE``, ``LOOKFEEL_PLUGINS``, entry points:
`lookfeel.plugins`), which register backbones and losses of their own. The console script
(`run`) shows each warning as one line too, ``lookfeel: warning: <message>``, once, and
prints a character that stdout's encoding lacks (an ASCII or Windows code page) as an escape.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence
from typing import TextIO

from lookfeel import __version__
from lookfeel.cli import (
    cv,
    data,
    demo,
    embed,
    evaluate,
    export,
    index,
    match,
    predict,
    reproduce,
    serve,
    synth,
    train,
)
from lookfeel.cli._args import OutPathError
from lookfeel.errors import LookfeelError

__all__ = ["build_parser", "main", "run"]

_COMMANDS = (
    data,
    synth,
    train,
    cv,
    reproduce,
    embed,
    evaluate,
    index,
    match,
    predict,
    serve,
    export,
    demo,
)
"""The command modules, in the order ``lookfeel --help`` lists them."""


def _command_list() -> str:
    """The list of commands in this module's docstring, for ``lookfeel --help``."""
    doc = __doc__ or ""  # None under ``python -OO``
    start = doc.find("Commands")
    if start < 0:
        return ""
    end = doc.find("\n\n", doc.find("\n\n", start) + 2)
    return doc[start:end]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``lookfeel`` command: every command module adds its own."""
    parser = argparse.ArgumentParser(
        prog="lookfeel",
        usage="%(prog)s [-h] [--version] [--plugin MODULE] COMMAND ...",
        description="Connect how fabrics look (colour, depth) with how they feel (GelSight).\n\n"
        + _command_list(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"lookfeel {__version__}")
    parser.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="import MODULE first (your own backbone or loss); repeatable",  # LOOKFEEL_PLUGINS
    )
    # The description lists the commands with their purpose; argparse's own list would repeat
    # them without the actions of `data` and `index`.
    subparsers = parser.add_subparsers(
        dest="command", metavar="COMMAND", help=argparse.SUPPRESS, prog=parser.prog
    )
    for command in _COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except OutPathError as e:  # an --out this user cannot write: as any path, not usage
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    if args.command is None:  # as argparse says of a group without its action (`lookfeel data`)
        parser.print_usage(sys.stderr)
        commands = _command_list()
        if commands:  # none under ``python -OO``
            print(f"\n{commands}\n", file=sys.stderr)
        print(
            f"{parser.prog}: error: the following arguments are required: COMMAND", file=sys.stderr
        )
        return 2
    try:
        _load_plugins(args.plugin)
        status: int = args.func(args)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
    except LookfeelError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C: what was written is whole (atomic writes); runs resume
        print("lookfeel: interrupted", file=sys.stderr)
        return 130  # 128 + SIGINT, as a shell reports a command stopped by it
    except BrokenPipeError:  # `lookfeel ... | head`: the reader has what it wanted
        # Point stdout at /dev/null so that Python's own flush at exit does not fail again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a shell reports a command killed by it
    except OSError as e:
        if e.filename is None:
            raise  # not about a file: a bug, whose traceback says where
        # The system refused a file (permissions, a read-only or full disk): say which.
        print(f"lookfeel: {e.filename}: {e.strerror or e}", file=sys.stderr)
        return 1
    return status


def _load_plugins(modules: Sequence[str]) -> None:
    """Add the ``--plugin`` modules to ``LOOKFEEL_PLUGINS`` in this process's environment, which
    the processes it starts inherit (reproduce's workers, a run's decoders), then import every
    plugin (`lookfeel.plugins.load_plugins`); an error about a ``--plugin`` module names the
    option. The current folder is not added to ``sys.path``: the module is found as Python
    finds any (``PYTHONPATH``, an installed package, and the current folder under
    ``python -m lookfeel``). A ``.py`` file's path is refused with the module name and the
    ``PYTHONPATH`` to give instead: importing a file by its path would reach this process only
    (the processes it starts find plugins by module name), and could import a second copy of
    a module that is also on ``sys.path``."""
    from lookfeel.plugins import add_plugin_modules, load_plugins

    add_plugin_modules(modules, "--plugin")
    load_plugins()


def _print_any_text() -> None:
    """Make stdout and stderr write a character their encoding lacks as a ``\\u`` escape
    instead of failing: an ASCII or Windows code page stdout (Windows' redirected output)
    cannot encode "±", "∝" or a user's label in Chinese, and the command ended in Python's
    ``UnicodeEncodeError``. Only a text stream that can be reconfigured and would fail
    (``errors="strict"``) changes; ``surrogateescape`` (file names on a C locale) stays."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if callable(reconfigure) and getattr(stream, "errors", None) == "strict":
            reconfigure(errors="backslashreplace")


def _one_line_warnings() -> None:
    """Show every warning as ``lookfeel: warning: <message>`` on stderr, each message once.

    Python's own display adds the library's file, line and source line, which mean nothing to
    someone running the command, and repeats a warning that several runs raise alike (each of
    a recipe's three networks, each fold of a cross-validation)."""
    shown: set[str] = set()

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        text = str(message)
        if text in shown:
            return
        shown.add(text)
        print(f"lookfeel: warning: {text}", file=sys.stderr if file is None else file, flush=True)

    warnings.showwarning = show


def run(argv: Sequence[str] | None = None) -> int:
    """The ``lookfeel`` console script and ``python -m lookfeel``: `main` with warnings shown
    as one line each (`main` alone leaves them to Python and to whoever calls it), on a
    stdout and stderr that print any text (`_print_any_text`)."""
    _print_any_text()
    with warnings.catch_warnings():
        _one_line_warnings()
        return main(argv)
