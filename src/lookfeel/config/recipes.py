"""The recipe a run uses when none is named: chosen by what the dataset folder holds.

``lookfeel train`` and ``lookfeel cv`` take ``--config``; without it they train the shipped
recipe for the data they are given:

- depth, colour and/or touch of the same fabrics (two or more senses: a ``lookfeel synth`` world,
  or a user's visuo-tactile recordings): ``configs/synth_cross.yaml``, the recipe that connects
  the senses, on the senses the folder holds (colour and touch without depth: with the
  colour-touch term the recipe otherwise leaves to depth's bridge, ``loss.pair_weights={}``);
- touch alone (GelSight presses or videos, as ``physiclear``): ``configs/physiclear.yaml``;
- depth alone (Kinect drapes, as GelFabric's): ``configs/real_depth.yaml``, the leak-free recipe.

Colour photos alone have no shipped recipe: name one with ``--config``. A recipe chosen so is
fitted to the dataset: it keeps only the class heads whose columns the dataset's labels.csv has
(`fit_class_heads`), and (`fit_dataset`) reads touch presses recorded as videos as
physiclear.yaml does, trains on the press kinds the data holds, maps raw depth from a range
that holds it, adds class heads for labels.csv's columns of words, and deals a small dataset's
fabrics into its folds.
"""

from __future__ import annotations

import json
import os
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeGuard

import yaml

from lookfeel.config._core import (
    ConfigError,
    apply_overrides,
    config_file,
    recipe_path,
    shipped_configs,
)
from lookfeel.modality import REPRINTS, Modality
from lookfeel.shell import set_flag

if TYPE_CHECKING:
    import numpy as np

    from lookfeel.data.catalog import Catalog
    from lookfeel.data.problems import Problem

DEPTH_RANGE_SAMPLE = 200
"""Depth maps decoded (evenly spaced over the dataset's) to tell how much of the depth lies
inside the range raw depth is mapped from (`depth_samples`): enough for that share and the
percentiles, well under a second on GelFabric."""

__all__ = [
    "DEPTH_RANGE_SAMPLE",
    "Recipe",
    "UnreadSense",
    "config_file",
    "covering_depth_range",
    "default_recipe",
    "depth_in_range",
    "depth_samples",
    "fit_class_heads",
    "fit_dataset",
    "recipe_path",
    "shipped_configs",
    "unread_senses",
]


@dataclass(frozen=True)
class Recipe:
    """A shipped run config and the overrides that fit it to a dataset.

    Attributes:
        name: the config's file name under ``configs/`` (``synth_cross.yaml``).
        path: where that file is in the installed package.
        overrides: ``--set`` style overrides applied before the user's own.
        reason: one line saying why this recipe was chosen, for the user.
    """

    name: str
    path: Path
    overrides: tuple[str, ...]
    reason: str


@dataclass(frozen=True)
class UnreadSense:
    """A sense whose folder holds files of which the scan read none (`unread_senses`).

    Attributes:
        modality: the sense (depth, colour or touch).
        folder: its folder (``depth/``; the first, for touch's several).
        files: how many entries of its folders were skipped or refused.
        first: the first of them, with why (``F0001_1.tif: not an image``).
    """

    modality: Modality
    folder: Path
    files: int
    first: Problem

    @property
    def why(self) -> str:
        """``all 12 depth file(s) of depth/ were skipped or unreadable (e.g. F0001.tif: ...)``."""
        name = "" if self.first.path is None else f"{self.first.path.name}: "
        return (
            f"all {self.files} {self.modality.value} file(s) of {self.folder.name}/ were skipped "
            f"or unreadable (e.g. {name}{self.first.message})"
        )


def unread_senses(catalog: Catalog) -> list[UnreadSense]:
    """The senses of which ``catalog`` has no item although their folders hold files: every
    one skipped (``.tif`` depth maps, a subfolder of frames) or refused (a damaged PNG, with
    the headers checked), so a run on the folder goes without that sense.

    Hidden files (``.DS_Store``) are not counted."""
    from lookfeel.data.layout import folder_modality

    found: dict[Modality, list[tuple[Path, Problem]]] = {}
    refused = [p for p in catalog.problems if p.severity == "error"]
    for problem in (*catalog.skipped, *refused):
        path = problem.path
        if path is None or path.name.startswith(".") or path.parent.parent != catalog.root:
            continue  # not an entry of a folder of the layout (a whole folder, labels.csv)
        sense = folder_modality(path.parent.name)
        if sense is not None and not catalog.items(sense[0]):
            found.setdefault(sense[0], []).append((path, problem))
    out = []
    for m in Modality:
        if m in found:
            path, first = min(found[m], key=lambda x: str(x[0]))
            out.append(UnreadSense(m, path.parent, len(found[m]), first))
    return out


def default_recipe(modalities: set[Modality] | frozenset[Modality], root: Path) -> Recipe:
    """The shipped recipe for a dataset holding ``modalities`` (see the module's docstring).

    Raises:
        ConfigError: the folder holds no images, or only colour photos.
    """
    held = [m for m in Modality if m in modalities]  # depth, colour, touch
    words = ", ".join(m.value for m in held)
    if len(held) >= 2:
        views = "[" + ",".join(m.value for m in held) + "]"
        # Without depth nothing bridges colour and touch but their own term: keep it.
        bridge = () if Modality.DEPTH in held else ("loss.pair_weights={}",)
        return Recipe(
            "synth_cross.yaml",
            recipe_path("synth_cross.yaml"),
            (f"train.views={views}", *bridge),
            f"{root} holds {words}: the cross-modal recipe on those senses",
        )
    if held == [Modality.TOUCH]:
        return Recipe(
            "physiclear.yaml",
            recipe_path("physiclear.yaml"),
            (),
            f"{root} holds touch alone: the real-touch recipe",
        )
    if held == [Modality.DEPTH]:
        return Recipe(
            "real_depth.yaml",
            recipe_path("real_depth.yaml"),
            (),
            f"{root} holds depth alone: the leak-free depth recipe",
        )
    if held == [Modality.COLOR]:
        raise ConfigError(
            f"{root} holds colour photos alone, for which no recipe is shipped; pass --config"
        )
    raise ConfigError(
        f"{root} holds no depth, colour or touch images to choose a recipe for; "
        f"run `lookfeel data check {root}` on it"
    )


def _resolved(recipe: Recipe) -> dict[str, Any]:
    """The recipe's config file with its overrides applied, as plain data."""
    return apply_overrides(
        yaml.safe_load(recipe.path.read_text(encoding="utf-8")) or {}, recipe.overrides
    )


def _gives(given: Sequence[str], key: str) -> bool:
    """Whether one of the user's overrides ``given`` sets ``key`` (``train.folds``) or a mapping
    above it (``train={...}``)."""
    parts = key.split(".")
    above = {".".join(parts[: i + 1]) for i in range(len(parts))}
    return any(s.partition("=")[0].strip() in above for s in given)


def _mapping(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _count(value: Any) -> TypeGuard[int]:
    """Whether ``value`` is a count (an int >= 1, not a bool): else the config's own checks
    refuse it, and nothing is fitted to it."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


def _fit_folds(
    n: int, folds: int, size: int | None, yours_folds: bool, yours_size: bool
) -> tuple[list[str], list[str]]:
    """The fold overrides (and what to say of them) for ``n`` fabrics and the run's ``folds``
    of ``size`` (the user's, where ``yours_*``, else the recipe's): the user's own numbers are
    kept and said as theirs, never replaced by the recipe's."""
    overrides: list[str] = []
    said: list[str] = []
    deal = size is not None and not yours_size and n < folds * size
    final_size = None if deal else size
    fewer = folds
    if not yours_folds:
        # Each fold holds out at least 2 (pick 1 of 2 at least; `cv` refuses fewer), but never
        # fewer than 2 folds.
        fewer = max(2, min(folds, n // 2 if final_size is None else n // final_size))
        if final_size is not None and fewer * final_size > n:
            fewer = folds  # no count of folds of that size fits: the split's error says so
    if deal:
        overrides.append("train.fold_size=null")
        if fewer != folds:
            overrides.append(f"train.folds={fewer}")
        if yours_folds:
            said.append(
                f"{n} fabrics to train on, fewer than your {folds} folds (train.folds) of the "
                f"recipe's {size}: your {folds} folds dealing them all (train.fold_size=null)"
            )
        else:
            said.append(
                f"{n} fabrics to train on, fewer than the recipe's {folds} folds of {size}: "
                f"{fewer} folds dealing them all (train.fold_size=null"
                + (f", train.folds={fewer})" if fewer != folds else ")")
            )
    elif fewer != folds:
        overrides.append(f"train.folds={fewer}")
        of = "" if final_size is None else f" of your {final_size} (train.fold_size)"
        said.append(
            f"{n} fabrics to train on, too few for the recipe's {folds} folds{of}: "
            f"{fewer} folds (train.folds={fewer})"
        )
    if yours_folds and final_size is None and n // folds < 2:
        use = f": use train.folds={n // 2} or fewer (cv --folds {n // 2})" if n >= 4 else ""
        said.append(
            f"your train.folds={folds} leaves {n // folds} of the {n} fabrics held out in some "
            f"fold, fewer than the 2 a fold must hold out to be scored (`lookfeel cv` refuses "
            f"it){use}"
        )
    return overrides, said


def _fit_reprints(catalog: Catalog, wants: int) -> tuple[list[str], list[str]]:
    """The ``data.color_reprints`` override (and what to say of it) for a recipe that reads
    ``wants`` re-printed renders of each colour photo (`lookfeel.modality.reprint_path`): none
    where the dataset has them all; else the number every photo has (the fewest any has,
    counting ``_r1``, ``_r2`` ... in order, as training reads them), 0 with a warning where
    a photo has none although ``reprints/`` is there."""
    from lookfeel.modality import reprint_path

    folder = catalog.root / REPRINTS
    if not folder.is_dir():
        return ["data.color_reprints=0"], [
            f"no {REPRINTS}/ folder: trained on the photos (data.color_reprints=0)"
        ]
    photos = [it.path for it in catalog.items(Modality.COLOR)]
    if not photos:
        return [], []
    try:
        names = {e.name for e in os.scandir(folder) if e.is_file()}
    except OSError:
        names = set()

    def present(photo: Path) -> int:
        n = 0
        while n < wants and reprint_path(photo, n + 1).name in names:
            n += 1
        return n

    counts = {p: present(p) for p in photos}
    have = min(counts.values())
    if have >= wants:
        return [], []
    short = [p for p, n in counts.items() if n == have]
    setting = f"data.color_reprints={have}"
    if have == 0:
        others = len(short) - 1
        more = f" (nor of {others} other photo{'s' if others > 1 else ''})" if others else ""
        warnings.warn(
            f"{folder}: holds no re-printed render of {short[0].name}{more} (no "
            f"{reprint_path(short[0], 1).name}): training on the photos themselves ({setting}), "
            f"not on the recipe's {wants} renders of each; make the world with `lookfeel synth "
            f"--reprints {wants}`, or give --set data.color_reprints=N yourself",
            stacklevel=3,
        )
        return [setting], [f"a photo has no re-printed render: trained on the photos ({setting})"]
    renders = f"{have} re-printed render{'s' if have > 1 else ''}"
    if len(short) == len(photos):
        said = f"{REPRINTS}/ holds {renders} of each photo, not the recipe's {wants}: {setting}"
    else:
        said = (
            f"{REPRINTS}/ holds {renders} of {short[0].name} (the fewest of any photo), not "
            f"the recipe's {wants}: {setting}"
        )
    return [setting], [said]


def _presses(counts: Counter[str], kinds: Sequence[str]) -> str:
    """``20 fold presses``, ``20 flat and 4 rand presses``."""
    return " and ".join(f"{counts[k]} {k}" for k in kinds) + " presses"


def _fit_touch_kinds(catalog: Catalog, kinds: Sequence[str]) -> tuple[list[str], list[str]]:
    """The ``data.touch_kinds`` override (and what to say of it) for a recipe that trains on
    the touch presses of ``kinds`` (its own, or `DataConfig`'s fold): where no press of the
    dataset is of them (only flat presses), or some fabric has presses of other kinds only,
    every kind the dataset holds; where the dataset holds other kinds beside them, the recipe's
    kinds kept, saying how many presses are left out and how to use them. Presses of no stated
    kind (an object's video in ``videos/``) are of every kind: nothing to fit."""
    counts = Counter(it.kind.value for it in catalog.items(Modality.TOUCH) if it.kind is not None)
    want = set(kinds)
    held = sorted(counts)
    if not held or want.issuperset(held):
        return [], []
    used = [k for k in held if k in want]
    others = [k for k in held if k not in want]
    theirs = "/".join(kinds)
    every = f"data.touch_kinds=[{','.join(held)}]"
    if not used:
        return [every], [
            f"touch: {_presses(counts, held)}, no {theirs} press (the recipe's "
            f"data.touch_kinds): trains on those ({every})"
        ]
    lacking = [
        f
        for f in catalog.fabrics
        if (its := f.items.get(Modality.TOUCH, ()))
        and all(it.kind is not None and it.kind.value not in want for it in its)
    ]
    if lacking:
        n = len(lacking) - 1
        nor = f"; nor have {n} other{'s' if n > 1 else ''}" if n else ""
        return [every], [
            f"{lacking[0].display_name} has no {theirs} press (the recipe's data.touch_kinds"
            f"{nor}): trains on the {_presses(counts, held)} ({every})"
        ]
    return [], [
        f"trains on the {_presses(counts, used)} (the recipe's data.touch_kinds); "
        f"{_presses(counts, others)} left out: {set_flag(every)} to use them"
    ]


def depth_samples(
    catalog: Catalog, most: int = DEPTH_RANGE_SAMPLE
) -> list[tuple[int, int, np.ndarray]]:
    """Samples of the valid pixels of up to ``most`` of ``catalog``'s depth maps, evenly spaced
    over them, as ``lookfeel data check`` samples each (`lookfeel.data.check.decode_problem`:
    pixels inside the default range, valid pixels, about 2,000 of them); maps with no valid
    pixel, or whose values do not read as millimetres, are left out (``data check`` warns of
    them)."""
    from lookfeel.data.check import decode_problem

    paths = [p for it in catalog.items(Modality.DEPTH) for p in it.frames]
    step = -(-len(paths) // most) or 1
    decoded = [decode_problem(p, Modality.DEPTH) for p in paths[::step]]
    return [d.depth for d in decoded if d.depth is not None]


def depth_in_range(
    samples: Sequence[tuple[int, int, np.ndarray]], low: float, high: float
) -> float:
    """The share of the valid pixels of the maps ``samples`` (`depth_samples`) that lie within
    ``low``..``high`` mm: each map's sampled share, weighted by its valid pixels; 1 when there
    are none."""
    import numpy as np

    total = sum(s[1] for s in samples)
    if not total:
        return 1.0
    inside = sum(
        s[1] * float(np.mean((s[2] >= low) & (s[2] <= high))) for s in samples if s[2].size
    )
    return inside / total


def covering_depth_range(
    samples: Sequence[tuple[int, int, np.ndarray]],
) -> tuple[int, int, float]:
    """(data.depth_min_mm, data.depth_range_mm, median) that cover the 2nd to 98th percentile
    of the sampled valid depth pixels (`depth_samples`), rounded outward to 10 mm."""
    import math

    import numpy as np

    low, mid, high = np.percentile(np.concatenate([s[2] for s in samples]), [2, 50, 98])
    start = 10 * math.floor(float(low) / 10)
    return start, max(10, 10 * math.ceil(float(high) / 10) - start), float(mid)


def _fit_depth_range(catalog: Catalog, low: float, span: float) -> tuple[list[str], list[str]]:
    """The ``data.depth_min_mm`` and ``data.depth_range_mm`` overrides (and what to say of
    them) for a recipe that maps raw depth from ``low`` to ``low + span`` mm: none where at
    least `lookfeel.data.check.MIN_IN_RANGE` of a sample of the valid pixels lies inside
    (GelFabric: 77%); else the range covering their 2nd to 98th percentile (depth from another
    camera pose, 1.6 m away, which the default range would read as a constant image)."""
    from lookfeel.data.check import MIN_IN_RANGE

    samples = depth_samples(catalog)
    if not samples:
        return [], []
    share = depth_in_range(samples, low, low + span)
    if share >= MIN_IN_RANGE:
        return [], []
    start, width, median = covering_depth_range(samples)
    settings = [f"data.depth_min_mm={start}", f"data.depth_range_mm={width}"]
    return settings, [
        f"{share:.0%} of the depth maps' valid pixels lie inside the recipe's {low:,.0f}-"
        f"{low + span:,.0f} mm (their median: {median:,.0f} mm): raw depth mapped from their "
        f"2nd-98th percentile, {start:,}-{start + width:,} mm "
        f"({', '.join(settings)})"
    ]


def _fit_text_heads(catalog: Catalog) -> tuple[list[str], list[str]]:
    """The ``model.class_heads`` override (and what to say of it) for a recipe with no class
    head, on a dataset whose labels.csv has columns of words (``material``): a head for each
    column that has something to learn across fabrics (two classes or more held by two
    fabrics or more each), so that ``lookfeel predict`` answers it as ``lookfeel match``
    does from the library's neighbours; a word of each column left without one, and why."""
    if not catalog.text_columns:
        return [], []
    noun = "object" if any(f.name is not None for f in catalog.fabrics) else "fabric"
    heads: list[str] = []
    said: list[str] = []
    for col in catalog.text_columns:
        members = Counter(k for f in catalog.fabrics if (k := f.class_of(col)) is not None)
        shared = sum(1 for n in members.values() if n >= 2)
        if shared >= 2:
            heads.append(col)
            continue
        if len(members) < 2:
            one = "one class" if members else "no value"
            why = f"{one} among the {noun}s, nothing to tell apart"
        elif not shared:
            why = f"every {noun} has its own word (descriptions, not classes)"
        else:
            why = (
                f"only 1 of its {len(members)} classes is held by 2 {noun}s or more, too few "
                "to learn"
            )
        said.append(f"no class head for labels.csv's {col}: {why}")
    if not heads:
        return [], said
    setting = f"model.class_heads={json.dumps(heads, ensure_ascii=False)}"
    words = ", ".join(heads)
    said.insert(
        0,
        f"class heads for labels.csv's words: {words} ({setting}), so that `lookfeel predict` "
        "answers them as `lookfeel match` does",
    )
    return [setting], said


def fit_dataset(recipe: Recipe, catalog: Catalog, given: Sequence[str] = ()) -> Recipe:
    """``recipe`` with the overrides that let it run on ``catalog``, the reason saying which.

    A shipped recipe is written for the data it was tuned on; chosen for a user's data it is
    changed where that data differs (a config the user names is used as written):

    - touch presses recorded as videos (``touch/F0001_fold_1502.mp4``) where the recipe stacks
      a press's frame images (synth_cross.yaml's ``data.touch_frames``: a synthetic press's
      three frames): one image a press, read as configs/physiclear.yaml reads its videos
      (``data.touch_frames=[]`` and physiclear.yaml's ``data.video_*`` settings the recipe does
      not set: training views across the contact span, evaluation averaging them);
    - no ``reprints/`` folder where the recipe trains on re-printed photos
      (``data.color_reprints``, a synthetic world's): the photos themselves, said once here
      rather than warned at every run; a ``reprints/`` folder with fewer renders of a photo
      than the recipe reads (``lookfeel synth --reprints 1``): the number every photo has
      (the fewest any has), and 0 with a warning naming a photo that has none;
    - touch presses of no kind the recipe trains on (``data.touch_kinds``, by default fold:
      a rig that recorded flat presses only), or a fabric with none of them: every kind the
      dataset holds; presses of other kinds beside the recipe's (a synthetic world's flat
      presses): the recipe's kinds kept, said with how many presses are left out and the
      ``--set`` that uses them (`_fit_touch_kinds`; presses of no stated kind, PhysiCLeAR's
      ``videos/<object>_<n>.mov``, are of every kind);
    - raw depth (``data.depth_input: raw``) of which fewer than
      `lookfeel.data.check.MIN_IN_RANGE` of the valid pixels lie inside the range it is mapped
      from (``data.depth_min_mm`` to ``+ data.depth_range_mm``, 800-1,300 mm by default; depth
      from another camera pose, 1.6 m away): the range covering the 2nd to 98th percentile of
      a sample of them (`depth_samples`), rounded to 10 mm. GelFabric (77% inside) and a
      synthetic world keep the recipe's;
    - columns of words in labels.csv (``material``) where the recipe has no class head: a
      class head for each that two or more classes of two or more fabrics each let it learn
      (`_fit_text_heads`), so that ``lookfeel predict`` answers it as ``lookfeel match``
      answers it from a library's neighbours; a column left without one is said, with why;
    - fewer fabrics than the recipe's folds test (synth_cross.yaml: 5 folds of 18, chosen from
      a paper-size world's 100 training fabrics; ``lookfeel train`` trains fold 0, ``cv`` all):
      folds that deal every fabric (``train.fold_size=null``), and with fewer than two fabrics
      a fold, fewer folds (``train.folds``: at least 2 held out in each, as ``cv`` needs, and
      never fewer than 2 folds). The paper split's test fabrics, never trained
      on, are not counted. A single fabric is left to the split's own error.

    The user's own overrides ``given`` (``--set``, and ``cv``'s ``--folds`` and
    ``--fold-size`` as ``train.folds=`` and ``train.fold_size=``), applied after the recipe's,
    are taken as they are: a key they set is neither overridden nor said to be the recipe's
    choice (``cv --folds 3``: 3 folds, dealing the fabrics when the recipe's size does not fit,
    and a word when 3 folds would hold out fewer than 2 fabrics in one).

    Returns:
        ``recipe`` itself when nothing needs changing or saying, else a copy with the
        overrides added and the reason extended.
    """
    from lookfeel.config.data import DataConfig
    from lookfeel.data.files import VIDEO_SUFFIXES
    from lookfeel.data.splits import paper_split

    data = _resolved(recipe)
    d, t = _mapping(data.get("data")), _mapping(data.get("train"))
    # The run's values: the recipe's with the user's overrides on top.
    ours = apply_overrides(data, given) if given else data
    t_run = _mapping(ours.get("train"))
    views = {str(v) for v in t_run.get("views") or ()}
    overrides: list[str] = []
    said: list[str] = []
    touch = catalog.items(Modality.TOUCH) if Modality.TOUCH.value in views else []
    if any(it.path.suffix.lower() in VIDEO_SUFFIXES for it in touch):
        settings = ["data.touch_frames=[]"] if d.get("touch_frames") else []
        reads = yaml.safe_load(recipe_path("physiclear.yaml").read_text(encoding="utf-8"))["data"]
        settings += [
            f"data.{k}={v if isinstance(v, str) else json.dumps(v)}"
            for k, v in reads.items()
            if k.startswith("video_") and k not in d
        ]
        settings = [s for s in settings if not _gives(given, s.partition("=")[0])]
        if settings:
            overrides += settings
            said.append(f"touch videos read as physiclear.yaml does ({', '.join(settings)})")
    if touch and not _gives(given, "data.touch_kinds"):
        kinds = d.get("touch_kinds") or [k.value for k in DataConfig().touch_kinds]
        more, words = _fit_touch_kinds(catalog, [str(k) for k in kinds])
        overrides += more
        said += words
    wants = d.get("color_reprints")
    if Modality.COLOR.value in views and _count(wants) and not _gives(given, "data.color_reprints"):
        more, words = _fit_reprints(catalog, wants)
        overrides += more
        said += words
    d_run, default = _mapping(ours.get("data")), DataConfig()
    if (
        Modality.DEPTH.value in views
        and d_run.get("depth_input", default.depth_input) == "raw"
        and not _gives(given, "data.depth_min_mm")
        and not _gives(given, "data.depth_range_mm")
    ):
        low = d_run.get("depth_min_mm", default.depth_min_mm)
        span = d_run.get("depth_range_mm", default.depth_range_mm)
        if isinstance(low, int | float) and isinstance(span, int | float) and span > 0:
            more, words = _fit_depth_range(catalog, float(low), float(span))
            overrides += more
            said += words
    folds, size = t_run.get("folds", 5), t_run.get("fold_size")
    if t.get("split") == "fold" and _count(folds) and (size is None or _count(size)):
        n = len(paper_split(catalog).train) or len(catalog.ids)
        if n >= 2:
            yours = _gives(given, "train.folds"), _gives(given, "train.fold_size")
            more, words = _fit_folds(n, folds, size, *yours)
            overrides += more
            said += words
    if not _mapping(data.get("model")).get("class_heads") and not _gives(
        given, "model.class_heads"
    ):
        more, words = _fit_text_heads(catalog)
        overrides += more
        said += words
    if not overrides and not said:
        return recipe
    return replace(
        recipe,
        overrides=(*recipe.overrides, *overrides),
        reason="; ".join([recipe.reason, *said]),
    )


def fit_class_heads(recipe: Recipe, columns: Sequence[str] | None) -> Recipe:
    """``recipe`` keeping only the class heads (``model.class_heads``) whose columns the dataset
    has, with the reason saying which it kept and which it left.

    A shipped recipe names the columns of the data it was tuned on (physiclear.yaml:
    PhysiCLeAR's hardness, roughness, bumpiness and material); a user's recordings may label
    fewer (a DIGIT dataset with hardness and material). For a recipe chosen for the data only:
    a config the user names is used as written, where a missing column is an error. The
    recipe's ``model.class_temperature`` of a column left needs no change (a column with no
    head is ignored), nor its ``model.num_properties: auto`` (the numeric columns there are).

    Args:
        recipe: a recipe from `default_recipe`.
        columns: the label columns of the dataset's labels.csv (numbers and words, as
            `lookfeel.data.Catalog` reads them); None when it has no labels.csv.

    Returns:
        ``recipe`` itself when it names no class head missing from ``columns``; else a copy
        with a ``model.class_heads`` override of those that are (possibly none).
    """
    data = _resolved(recipe)
    named = [str(c) for c in (data.get("model") or {}).get("class_heads") or ()]
    have = set(columns or ())
    kept = [c for c in named if c in have]
    left = [c for c in named if c not in have]
    if not left:
        return recipe
    why = (
        f"the recipe's {', '.join(left)} {'is' if len(left) == 1 else 'are'} not in labels.csv"
        if columns is not None
        else f"no labels.csv for the recipe's {', '.join(left)}"
    )
    return replace(
        recipe,
        # JSON's list of strings is YAML's too: a column named like YAML (`1e3`, `a: b`) stays
        # the string it is.
        overrides=(*recipe.overrides, f"model.class_heads={json.dumps(kept, ensure_ascii=False)}"),
        reason=f"{recipe.reason}; class heads: {', '.join(kept) or 'none'} ({why})",
    )
