"""Arguments that several commands share, defined once: argparse types and option groups.

A command module calls these from its ``add_parser``; the help text says what the option means
for that command where it differs.
"""

from __future__ import annotations

import argparse
import fnmatch
import importlib
import os
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from lookfeel.config.model import EMBED_BATCH
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality, parse_modalities
from lookfeel.shell import shell_quote

if TYPE_CHECKING:
    from lookfeel.config._core import Override

    Subparsers = argparse._SubParsersAction[argparse.ArgumentParser]
else:  # generic only in typeshed
    Subparsers = argparse._SubParsersAction
"""What ``ArgumentParser.add_subparsers`` returns: each command module adds its parser to it."""


class Choices:
    """The allowed values of an option, read from the module that defines them when first needed.

    argparse reads ``choices`` only to check a value given on the command line or to write help
    and errors, provided the option has a ``metavar`` (without one, ``add_argument`` lists the
    choices at once). Importing the defining module then, not when the parser is built, keeps
    ``lookfeel --help`` and every other command from loading torch, matplotlib or scikit-learn
    for options they never see. Name the values in the help with ``%(choices)s``.

    Args:
        module: the module that defines the values, e.g. ``"lookfeel.evaluate"``.
        name: the name of a collection of strings there (a dict gives its keys), e.g. ``"SPLITS"``.
    """

    def __init__(self, module: str, name: str) -> None:
        self.module, self.name = module, name
        self._values: tuple[str, ...] | None = None

    def values(self) -> tuple[str, ...]:
        """The allowed values, in the defining module's order."""
        if self._values is None:
            self._values = tuple(getattr(importlib.import_module(self.module), self.name))
        return self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self.values())

    def __contains__(self, value: object) -> bool:
        return value in self.values()

    def __len__(self) -> int:
        return len(self.values())


def _modalities(text: str) -> tuple[Modality, ...]:
    """``"depth,touch"`` -> ``(Modality.DEPTH, Modality.TOUCH)`` (an argparse type)."""
    try:
        return parse_modalities(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def number(
    kind: type[int] | type[float], low: float, high: float | None = None, open_low: bool = False
) -> Callable[[str], float]:
    """An argparse ``type`` for a number within bounds: ``number(float, 0)`` is ``>= 0``,
    ``number(float, 0, 1, open_low=True)`` is in (0, 1]; a value outside is argparse's one-line
    usage error naming the flag."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {kind.__name__}, got {text!r}") from None
        if (value <= low if open_low else value < low) or (high is not None and value > high):
            if high is not None:
                want = f"in {'(' if open_low else '['}{low:g}, {high:g}]"
            else:
                want = f"{'>' if open_low else '>='} {low:g}"
            raise argparse.ArgumentTypeError(f"must be {want}, got {text}")
        return value

    return parse


def number_list(what: str) -> Callable[[str], list[int]]:
    """An argparse ``type`` for a comma-separated list of integers >= 0, each given once, in
    the order given: ``number_list("seed")("0,1")`` is ``[0, 1]``. A negative, a repeat or
    anything but integers is argparse's one-line usage error naming the flag and ``what``
    (``--seeds`` of ``cv`` and ``reproduce``: numpy's generators take no negative seed, as
    ``train.seed`` refuses one; a repeat would train the same run twice)."""

    def parse(text: str) -> list[int]:
        try:
            values = [int(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a comma-separated list of integers"
            ) from None
        if not values:
            raise argparse.ArgumentTypeError("an empty list")
        negative = [v for v in values if v < 0]
        if negative:
            raise argparse.ArgumentTypeError(
                f"a {what} must be an integer >= 0, got {', '.join(map(str, negative))}"
            )
        repeated = sorted({v for v in values if values.count(v) > 1})
        if repeated:
            raise argparse.ArgumentTypeError(
                f"{what} {', '.join(map(str, repeated))} given more than once"
            )
        return values

    return parse


class NameList(Choices):
    """The allowed names of an option that takes several (`add_name_list`), read as `Choices`
    reads them. argparse checks each value against ``choices`` after its ``type`` made it a
    list of names, each already checked: a list is in it when every name is."""

    def __contains__(self, value: object) -> bool:
        if isinstance(value, list):
            return all(name in self.values() for name in value)
        return value in self.values()


class _Flatten(argparse.Action):
    """Store the names of every value given (each a list, `add_name_list`) as one list, each
    name once, in the order given."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[object] | None,
        option_string: str | None = None,
    ) -> None:
        names = [n for value in values or () for n in (value if isinstance(value, list) else [])]
        setattr(namespace, self.dest, list(dict.fromkeys(names)))


def add_name_list(parser: argparse.ArgumentParser, flag: str, choices: NameList, help: str) -> None:
    """An option naming one or more of ``choices``, comma-separated, space-separated or both
    (``--only flat,auxiliary``, ``--only flat auxiliary``): a list of names each once, or None
    when the option is not given. Given with no name it is argparse's usage error, as is a name
    not in ``choices`` (named with the allowed ones). Name the values in ``help`` with
    ``%(choices)s``."""

    def names(text: str) -> list[str]:
        found = [n.strip() for n in text.split(",") if n.strip()]
        if not found:
            raise argparse.ArgumentTypeError(f"no name in {text!r}")
        for name in found:
            if name not in choices.values():
                allowed = ", ".join(map(repr, choices))
                raise argparse.ArgumentTypeError(
                    f"invalid choice: {name!r} (choose from {allowed})"
                )
        return found

    parser.add_argument(
        flag,
        nargs="+",
        type=names,
        action=_Flatten,
        default=None,
        choices=choices,
        metavar="NAME",
        help=help,
    )


def add_modalities(parser: argparse.ArgumentParser, flag: str, what: str, default: str) -> None:
    """An option naming modalities, e.g. ``--require depth,touch``: a tuple of `Modality`, or None
    when it is not given (``default`` says what that means)."""
    help = f"{what}, e.g. depth,touch (default: {default})"
    parser.add_argument(flag, type=_modalities, default=None, metavar="MODALITIES", help=help)


def add_set(parser: argparse.ArgumentParser, help: str) -> None:
    """The repeatable ``--set KEY=VALUE`` config override."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=help)


def add_json(parser: argparse.ArgumentParser, help: str = "print as JSON") -> None:
    """``--json``: machine-readable output instead of lines for a person."""
    parser.add_argument("--json", action="store_true", help=help)


class OutPathError(Exception):
    """An ``--out`` this user cannot write (a file where a folder goes, a folder where a file
    goes, a folder above that is a file or read-only), found as the command line is read by
    `out_folder` and `out_file`. Not a ``ValueError``, which argparse would turn into a usage
    error (exit 2): `lookfeel.cli.main` prints it as it prints a `LookfeelError`, ``lookfeel:
    <message>``, and exits 1, as for every other path the command cannot use."""


def _under_a_folder(path: Path) -> None:
    """Refuse ``path`` when what already exists of it, or of the folders above it, is a file
    or a folder this user cannot write in (read-only, or another's; a temporary file is
    created and removed there to be sure): said before the command starts its work, not as a
    traceback when it first writes.

    Raises:
        OutPathError: ``--out PATH: ...`` naming what is in the way.
    """
    for above in (path, *path.parents):
        if not above.exists():
            continue
        if not above.is_dir():
            if above == path:
                continue  # a file `out_file` writes over (`out_folder` refused it): its folder
            raise OutPathError(f"--out {path}: {above} is a file, not a folder to write in")
        if not os.access(above, os.W_OK | os.X_OK):
            raise OutPathError(
                f"--out {path}: cannot write in {above}: it is read-only for this user"
            )
        try:  # what permissions do not show: a read-only mount, /proc, root on a foreign share
            with tempfile.TemporaryFile(dir=above):
                pass
        except OSError as e:
            raise OutPathError(
                f"--out {path}: cannot write in {above}: {e.strerror or e}"
            ) from None
        return


def out_folder(text: str) -> Path:
    """``--out`` of a command that writes a folder (a run, a report, a library): an argparse
    ``type`` that raises `OutPathError` (exit 1) for a path this user cannot write there."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise OutPathError(
            f"--out {path} exists and is not a folder; this command writes a folder: choose "
            "another --out"
        )
    _under_a_folder(path)
    return path


def out_file(text: str) -> Path:
    """``--out`` of a command that writes one file: an argparse ``type`` that raises
    `OutPathError` (exit 1) for a path this user cannot write there."""
    path = Path(text)
    if path.is_dir():
        raise OutPathError(
            f"--out {path} is a folder; name the file to write (e.g. {path / 'embeddings.npz'})"
        )
    _under_a_folder(path)
    return path


class OutError(LookfeelError):
    """An ``--out`` that would write into what the user made: the dataset folder, a file the
    command did not write, or a folder that holds something else. Raised before any work."""


def check_out_beside_data(out: Path, data: Path | None) -> None:
    """Refuse an ``--out`` that is the ``--data`` dataset folder or lies inside it (symbolic
    links followed, and by the folders' identity on disk: ``--data ~/Data --out ~/data/run``
    on a disk that ignores case, as macOS's and Windows' do; `lookfeel.data.paths`): lookfeel
    never writes into a dataset.

    Raises:
        OutError: naming both paths.
    """
    if data is None:
        return
    from lookfeel.data.paths import lies_within

    if lies_within(out, data):
        raise OutError(
            f"--out {out} lies inside the dataset folder {data} (--data); lookfeel writes "
            "nothing into a dataset: choose an --out outside it"
        )


def check_out_folder(out: Path, data: Path | None, holds: Sequence[str], what: str) -> None:
    """Before a command writes the folder ``out``: refuse it inside ``--data``
    (`check_out_beside_data`), and refuse a folder that already holds files unless it holds
    this command's own output, one of the names or patterns ``holds`` (a run's
    ``split.json``, ``checkpoints`` ...: what a rerun or ``--resume`` continues; a path with a
    ``/`` names a file below the top, such as an interrupted report's figure list), as
    ``index build`` refuses a folder that is not a library. Names beginning with a dot are not
    counted (a temp file of an atomic write; lookfeel writes no other).

    Args:
        out: the ``--out`` folder (need not exist).
        data: the ``--data`` dataset folder, or None where the command has none.
        holds: names or glob patterns of what the command writes in ``out``.
        what: what the folder should then be, for the message (``"a lookfeel run"``).

    Raises:
        OutError: in one line naming the folder and what it lacks.
    """
    check_out_beside_data(out, data)
    if not out.is_dir():
        return
    names = [p.name for p in out.iterdir() if not p.name.startswith(".")]
    if not names or any(fnmatch.fnmatch(n, pattern) for n in names for pattern in holds):
        return
    if any("/" in pattern and (out / pattern).exists() for pattern in holds):
        return  # a file below the top that only this command writes
    marks = ", ".join(holds)
    raise OutError(
        f"--out {out}: the folder holds files and is not {what} (none of {marks}); nothing "
        "in it is changed: choose a new or empty folder"
    )


def clear_stale_temps(out: Path, *below: str) -> None:
    """Remove the temp files a killed write left in the command's own ``out`` folder (and the
    subfolders ``below``), once `check_out_folder` took it for the command's: a rerun that
    finishes leaves none behind (`lookfeel.atomic.remove_stale_temps_in`)."""
    from lookfeel.atomic import remove_stale_temps_in

    for folder in (out, *(out / b for b in below)):
        remove_stale_temps_in(folder)


EMBEDDINGS_KEYS = ("meta.npy", "embeddings_*.npy")
"""What every ``.npz`` that ``lookfeel embed`` writes holds (zip entries): an existing file is
replaced only when it holds both (see `check_embeddings_out`)."""


def _written_by_embed(path: Path) -> bool:
    """Whether ``path`` is an ``.npz`` (zip) holding every entry of `EMBEDDINGS_KEYS`."""
    try:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False
    return all(any(fnmatch.fnmatch(n, key) for n in names) for key in EMBEDDINGS_KEYS)


def check_embeddings_out(out: Path, data: Path | None) -> None:
    """Before ``lookfeel embed`` writes the file ``out``: refuse it inside ``--data``
    (`check_out_beside_data`); refuse an existing file unless it is an embeddings file that
    lookfeel wrote (an ``.npz`` holding ``meta`` and an ``embeddings_<modality>`` array: a
    rerun replaces its own output, never a user's CSV, photo or other archive); and refuse a
    name that does not end in ``.npz`` (the file is an npz archive whatever it is named).

    Raises:
        OutError: in one line naming the file and suggesting another.
    """
    check_out_beside_data(out, data)
    npz = out.suffix.lower() == ".npz"
    other = out.with_name(f"{out.stem}-embeddings.npz") if npz else out.with_suffix(".npz")
    if out.exists() and not _written_by_embed(out):
        raise OutError(
            f"--out {out}: the file exists and is not an embeddings file lookfeel wrote (an "
            f".npz holding meta and embeddings_<modality>); it is kept: choose another --out, "
            f"e.g. {other}"
        )
    if not npz:
        raise OutError(
            f"--out {out}: an embeddings file is an .npz archive; name it so, e.g. {other}"
        )


def add_data_out(parser: argparse.ArgumentParser, out_help: str, file: bool = False) -> None:
    """The required ``--data`` (a dataset folder) and ``--out`` (what the command writes: a
    folder, or with ``file`` one file)."""
    parser.add_argument("--data", type=Path, required=True, help="dataset folder")
    out_type = out_file if file else out_folder
    parser.add_argument("--out", type=out_type, required=True, help=out_help)


def add_run_config(parser: argparse.ArgumentParser, out_help: str) -> None:
    """``--config`` (a run config YAML), ``--data``, ``--out`` and ``--set`` of a training run."""
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        help="run config YAML, or a shipped one by name from any folder (physiclear, "
        "configs/paper/flat.yaml); default: the shipped recipe for what --data holds "
        "(two or more senses: synth_cross.yaml on them; touch alone: physiclear.yaml; depth "
        "alone: real_depth.yaml)",
    )
    add_data_out(parser, out_help)
    add_set(parser, "override a config key, e.g. --set train.steps=100 (repeatable)")
    parser.add_argument(
        "--quiet",
        action="append_const",
        dest="set",
        const="train.progress=false",
        help="no progress bar (the same as --set train.progress=false; bars are drawn only "
        "where stderr is a terminal anyway)",
    )


def path_flag(key: str, flag: str, path: Path) -> Override:
    """The config override a path-valued flag (``--pretrained PATH``) makes: ``key`` set to the
    path made absolute (a run's config.yaml then names the file from any folder), taken as it
    is rather than parsed as YAML (a path may hold ``: `` or begin ``*``), and an error about
    ``key`` naming the flag as typed (``--pretrained 'w/a: b.pth': model.pretrained: ...``)."""
    from lookfeel.config._core import Override

    return Override(key, os.path.abspath(path), f"{flag} {shell_quote(str(path))}")


def _sets_key(sets: list[str], key: str) -> bool:
    """Whether one of the ``--set`` overrides gives ``key`` (``model.class_heads``) or a
    mapping above it (``model={...}``)."""
    parts = key.split(".")
    above = {".".join(parts[: i + 1]) for i in range(len(parts))}
    return any(s.partition("=")[0].strip() in above for s in sets)


def run_config_source(args: argparse.Namespace) -> tuple[Path, list[str]]:
    """The config file and overrides of a training run: ``--config`` as given, or (without it)
    the shipped recipe for what ``--data`` holds (`lookfeel.config.recipes`), said on stderr.

    A recipe chosen so is fitted to the folder's data (`fit_dataset`: touch videos, the press
    kinds the data holds, no reprints/, depth outside the range raw depth is mapped from,
    class heads for labels.csv's columns of words where the recipe has none, fewer fabrics
    than its folds) and keeps only the class heads whose columns the folder's labels.csv has
    (`fit_class_heads`: physiclear.yaml's hardness, roughness, bumpiness and material on a
    dataset labelled with hardness and material alone trains those two); neither touches the
    class heads when ``--set`` names ``model.class_heads``. A ``--config`` the user named is
    used as written, where a class head's missing column is an error.

    Raises:
        ConfigError: no recipe fits the folder's senses.
        DatasetError: ``--data`` is not a folder.
    """
    if args.config is not None:
        from lookfeel.config.recipes import config_file

        return config_file(args.config), list(args.set)
    from lookfeel.config.recipes import default_recipe, fit_class_heads, fit_dataset
    from lookfeel.data.layout import scan

    catalog = scan(args.data, check_headers=False)
    held = {m for fabric in catalog.fabrics for m, items in fabric.items.items() if items}
    recipe = fit_dataset(default_recipe(held, args.data), catalog, args.set)
    if not _sets_key(args.set, "model.class_heads"):
        has_labels = (Path(args.data) / "labels.csv").is_file()
        columns = [*catalog.label_columns, *catalog.text_columns] if has_labels else None
        recipe = fit_class_heads(recipe, columns)
    print(f"No --config: configs/{recipe.name} ({recipe.reason})", file=sys.stderr)
    return recipe.path, [*recipe.overrides, *args.set]


def add_device(parser: argparse.ArgumentParser) -> None:
    """``--device``: where a trained model runs, on every command that runs one (checked by
    `lookfeel.devices.resolve_device`: a device this machine lacks is one line)."""
    parser.add_argument("--device", default="cpu", help="torch device (default cpu)")


def add_forward(parser: argparse.ArgumentParser, device: bool = True) -> None:
    """``--batch-size`` (and ``--device``) of the forward passes that embed images."""
    parser.add_argument(
        "--batch-size",
        type=number(int, 1),
        default=EMBED_BATCH,
        help=f"images per forward pass (default {EMBED_BATCH})",
    )
    if device:
        add_device(parser)


def add_library(parser: argparse.ArgumentParser) -> None:
    """``--index`` (a library folder) and ``--checkpoint`` (its model, if it moved)."""
    parser.add_argument("--index", type=Path, required=True, help="library folder")
    parser.add_argument(
        "--checkpoint", type=Path, default=None, help="the library's checkpoint, if it moved"
    )


def add_command(
    subparsers: Subparsers, name: str, doc: str | None, run: Callable[[argparse.Namespace], int]
) -> argparse.ArgumentParser:
    """Add the command ``name``, run by ``run``.

    Its ``--help`` describes it with ``doc`` (its module's docstring) but for the first paragraph,
    the one-line purpose that the package docstring lists.
    """
    description = (doc or "").partition("\n\n")[2].strip() or None  # doc is None under -OO
    parser = subparsers.add_parser(name, description=description)
    parser.set_defaults(func=run, command_parser=parser)
    return parser


def usage_error(args: argparse.Namespace, message: str) -> int:
    """argparse's usage error of the command that read ``args`` (`add_command`), for a mistake
    only its handler sees (an option that needs another): the command's usage line, then
    ``lookfeel COMMAND: error: <message>``, on stderr. Returns 2, argparse's exit status, for
    the handler to return."""
    parser: argparse.ArgumentParser = args.command_parser
    parser.print_usage(sys.stderr)
    print(f"{parser.prog}: error: {message}", file=sys.stderr)
    return 2


def add_choice(
    parser: argparse.ArgumentParser, flag: str, choices: Choices, default: str | None, help: str
) -> None:
    """An option taking one of ``choices``, which it names in ``help`` with ``%(choices)s``.

    The ``metavar`` (the flag's name in capitals) keeps argparse from reading the choices when
    the option is added.
    """
    metavar = flag.lstrip("-").upper()
    parser.add_argument(flag, choices=choices, default=default, metavar=metavar, help=help)
