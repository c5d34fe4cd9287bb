"""The recipe a run uses when none is named: chosen by what the dataset folder holds.

``lookfeel train`` and ``lookfeel cv`` take ``--config``; without it they train the shipped
recipe for the data they are given:

- depth, colour and/or touch of the same fabrics (two or more senses: a ``lookfeel synth`` world,
  or a user's visuo-tactile recordings): ``configs/synth_cross.yaml``, the recipe that connects
  the senses, on the senses the folder holds (colour and touch without depth: with the
  colour-touch term the recipe otherwise leaves to depth's bridge, ``loss.pair_weights={}``);
- touch alone (GelSight presses or videos, as ``physiclear``): ``configs/physiclear.yaml``;
- depth alone (Kinect drapes, as GelFabric's): ``configs/real_depth.yaml``, the leak-free recipe.

Colour photos alone have no shipped recipe: name one with ``--config``.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from lookfeel.config._core import ConfigError
from lookfeel.modality import Modality

__all__ = ["Recipe", "default_recipe", "recipe_path"]


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
