"""The recipe a run uses when none is named: chosen by what the dataset folder holds.

``lookfeel train`` and ``lookfeel cv`` take ``--config``; without it they train the shipped
recipe for the data they are given:

- depth, colour and/or touch of the same fabrics (two or more senses: a ``lookfeel synth`` world,
  or a user's visuo-tactile recordings): ``configs/synth_cross.yaml``, the recipe that connects
  the senses, on the senses the folder holds (colour and touch without depth: with the
  colour-touch term the recipe otherwise leaves to depth's bridge, ``loss.pair_weights={}``);
- touch alone (GelSight presses or videos, as ``physiclear``): ``configs/physiclear.yaml``;
- depth alone (Kinect drapes, as GelFabric's): ``configs/real_depth.yaml``, the leak-free recipe.

Colour photos alone have no shipped recipe: name one with ``--config``. A recipe chosen so keeps
only the class heads whose columns the dataset's labels.csv has (`fit_class_heads`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

import yaml

from lookfeel.config._core import ConfigError, apply_overrides
from lookfeel.modality import Modality

__all__ = ["Recipe", "default_recipe", "fit_class_heads", "recipe_path"]


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


def recipe_path(name: str) -> Path:
    """The shipped config (or folder of them) ``configs/<name>`` in the installed package."""
    return Path(str(resources.files("lookfeel") / "configs" / name))


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
    data = apply_overrides(yaml.safe_load(recipe.path.read_text()) or {}, recipe.overrides)
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
