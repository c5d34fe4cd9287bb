"""Checkpoints: written atomically, read safely, and enough on their own to rebuild the model.

A checkpoint is a plain dict saved with `torch.save` and read with ``weights_only=True``:

    version, step, config (the resolved RunConfig as plain data), modalities, label_columns,
    split (fabric ids on each side), model (state dict), optimizer, scheduler, loss (state
    dicts), rng (torch CPU generator state), best (the best validation value so far),
    touch_input (what the touch branch was trained on: `TOUCH_VIDEOS`, `TOUCH_FRAMES` or
    `TOUCH_BOTH`; absent in checkpoints from before it was recorded, and for a model without
    a touch branch), data_fingerprint (the dataset trained on, `Catalog.fingerprint`; absent
    before it was recorded), rank_columns (label column -> the ranks its training data held,
    for the columns of ranks; absent before session 50), shapes (modality name -> the shape of
    its training items, `lookfeel.index.query.shape_record`, for a query turned against them
    to be warned of; none for a modality whose items come in more than one orientation;
    absent before session 51), software (the lookfeel, torch and Python versions that wrote
    it, `lookfeel.provenance.software_versions`; absent before session 53), grey_presses (of
    the press videos the touch branch was trained on, how many (``videos``) and how many had
    no colour (``grey``, `lookfeel.data.video.Press.grey`), for a query of the other kind to
    be warned of; none for a model trained on frame images, or on videos read from a disk
    cache written before the flag was kept; absent before session 56)

Wherever a checkpoint is read (`read_checkpoint`, `load_model`, `init_from_checkpoint`, and so
every command's ``--checkpoint``), a training run's folder may stand for its
``checkpoints/last.pt`` (`checkpoint_file`): the last checkpoint, the one every run writes (an
ensemble, ``model.members``, writes its merged model there too, and no ``best.pt``).
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from lookfeel.atomic import atomic_write
from lookfeel.config import ConfigError, RunConfig, from_dict
from lookfeel.config.loss import unregistered_loss_kinds_allowed
from lookfeel.data.files import VIDEO_SUFFIXES
from lookfeel.devices import resolve_device
from lookfeel.errors import LookfeelError, load_problem
from lookfeel.modality import Modality
from lookfeel.models import Embedder, create_model
from lookfeel.plugins import trained_with_hint

__all__ = [
    "CHECKPOINT_VERSION",
    "RUN_CHECKPOINT",
    "TOUCH_BOTH",
    "TOUCH_FRAMES",
    "TOUCH_VIDEOS",
    "CheckpointError",
    "LoadedModel",
    "checkpoint_file",
    "grey_presses_of",
    "init_from_checkpoint",
    "load_model",
    "non_finite_tensors",
    "read_checkpoint",
    "save_checkpoint",
    "touch_input_of",
]

CHECKPOINT_VERSION = 1

RUN_CHECKPOINT = Path("checkpoints") / "last.pt"
"""Where in a training run's folder its last checkpoint lies: what a run folder given as a
checkpoint stands for (`checkpoint_file`)."""

TOUCH_VIDEOS = "videos"
"""A touch branch trained on press videos only (``videos/<object>_<n>.mov``): each press read as
its video's frames are read (by default their change from the no-contact frames,
``data.video_reference: subtract``)."""
TOUCH_FRAMES = "frames"
"""A touch branch trained on still GelSight frames only (``touch/`` images: GelFabric, the
synthetic world)."""
TOUCH_BOTH = "videos and frames"
"""A touch branch trained on both kinds of press."""


def touch_input_of(paths: Iterable[str | os.PathLike[str]]) -> str | None:
    """What a touch branch trained on these press files saw: `TOUCH_VIDEOS`, `TOUCH_FRAMES` or
    `TOUCH_BOTH` (a video by its suffix, `VIDEO_SUFFIXES`); None for no files.

    Recorded in checkpoints as ``touch_input`` so that a query of the other kind can be refused
    (`lookfeel.index.query.check_touch_query`).
    """
    kinds = {Path(p).suffix.lower() in VIDEO_SUFFIXES for p in paths}
    if not kinds:
        return None
    if kinds == {True}:
        return TOUCH_VIDEOS
    return TOUCH_FRAMES if kinds == {False} else TOUCH_BOTH


def grey_presses_of(grey: Iterable[bool | None]) -> dict[str, int] | None:
    """The ``grey_presses`` record of the press videos a touch branch was trained on, from
    whether each had no colour as training read it (`lookfeel.data.images.ImageLoader.is_grey`):
    how many videos and how many grey. None for no video, or where one is not known (its image
    read from a disk cache entry written before the flag was kept: no video is decoded again
    to ask)."""
    flags = list(grey)
    if not flags or None in flags:
        return None
    return {"videos": len(flags), "grey": sum(1 for g in flags if g)}


class CheckpointError(LookfeelError):
    """A checkpoint file cannot be used; the message names the file."""


def save_checkpoint(path: str | os.PathLike[str], state: dict[str, Any]) -> Path:
    """Write ``state`` to ``path`` atomically (a kill mid-write leaves the old file intact)."""
    return atomic_write(path, lambda f: torch.save({"version": CHECKPOINT_VERSION, **state}, f))


def checkpoint_file(path: str | os.PathLike[str]) -> Path:
    """The checkpoint file ``path`` names: ``path`` itself, or, for a folder, the training
    run's last checkpoint in it (`RUN_CHECKPOINT`: ``RUN/checkpoints/last.pt``). Nothing is
    read; a path that is no file is left for `read_checkpoint` to refuse.

    Raises:
        CheckpointError: a folder with no ``checkpoints/last.pt``.
    """
    p = Path(path)
    if not p.is_dir():
        return p
    last = p / RUN_CHECKPOINT
    if not last.is_file():
        raise CheckpointError(
            f"{p}: a folder with no {RUN_CHECKPOINT.as_posix()}: give a checkpoint file (a "
            "run's checkpoints/last.pt or best.pt)"
        )
    return last


def read_checkpoint(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a checkpoint safely (``weights_only``: no code in the file is run).

    Args:
        path: a checkpoint file, or a training run's folder for its ``checkpoints/last.pt``
            (`checkpoint_file`).

    Raises:
        CheckpointError: missing, unreadable, or not a lookfeel checkpoint; a folder with no
            ``checkpoints/last.pt``.
    """
    p = checkpoint_file(path)
    if not p.is_file():
        raise CheckpointError(f"{p}: checkpoint not found")
    try:
        state = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types for a damaged or foreign file
        raise CheckpointError(f"{p}: not a readable checkpoint ({_unreadable(e, p)})") from None
    if not isinstance(state, dict) or "config" not in state or "model" not in state:
        raise CheckpointError(f"{p}: not a lookfeel checkpoint (no config and model inside)")
    if state.get("version", 0) > CHECKPOINT_VERSION:
        raise CheckpointError(
            f"{p}: written by a newer lookfeel (checkpoint version {state['version']}); upgrade"
        )
    return state


def _unreadable(e: Exception, p: Path) -> str:
    """Why torch could not read ``p``, for a person: a zip archive that ``torch.save`` did not
    write (an ``.npz``) or one cut short is said in words, not as torch's internal error
    (``[enforce fail at inline_container.cc:180]``, ``PytorchStreamReader failed ...``)."""
    text = str(e)
    if "inline_container" not in text and "PytorchStreamReader" not in text:
        return load_problem(e, p)
    try:
        with zipfile.ZipFile(p) as z:
            names = z.namelist()
    except (OSError, zipfile.BadZipFile):
        return "a damaged PyTorch checkpoint: its zip archive cannot be read, as when cut short"
    if not any(n.endswith("/data.pkl") for n in names):
        return (
            "not a PyTorch checkpoint file: a zip archive, but not one torch.save writes, such "
            "as an .npz of NumPy arrays"
        )
    return "a damaged PyTorch checkpoint: a file inside its zip archive cannot be read"


@dataclass(frozen=True)
class LoadedModel:
    """A model rebuilt from a checkpoint, with what it was trained on."""

    path: Path
    config: RunConfig
    model: Embedder
    step: int
    label_columns: tuple[str, ...]
    split: dict[str, Any]
    """The run's split.json: ``kind``, ``train`` and ``val`` fabric ids; for the ``seen`` split
    also ``val_items`` (held-out item paths) and ``novel`` (held-out fabric ids)."""
    label_stats: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Per label column, the training fabrics' (mean, std) the property head's targets were
    standardised with (empty in checkpoints from before it was saved)."""
    data_fingerprint: str | None = None
    """`lookfeel.data.Catalog.fingerprint` of the dataset the run trained on (None in
    checkpoints from before it was recorded): a split of the run's (its held-out fabrics)
    names the same fabrics only in that dataset."""
    software: dict[str, str] = field(default_factory=dict)
    """The lookfeel, torch and Python versions that wrote the checkpoint
    (`lookfeel.provenance.software_versions`; empty in checkpoints from before session 53)."""
    chosen_by: str | None = None
    """The validation score a run chose this checkpoint by (``val/touch_to_depth_top1``: its
    ``best.pt``, session 54 on), None for any other checkpoint and older ``best.pt`` files."""
    touch_input: str | None = None
    """What the touch branch was trained on: `TOUCH_VIDEOS`, `TOUCH_FRAMES` or `TOUCH_BOTH`;
    None in checkpoints from before it was recorded (queries are then not checked against
    it) and for a model without a touch branch."""
    rank_columns: dict[str, tuple[int, ...]] = field(default_factory=dict)
    """The label columns of ranks (``hardness`` 0/1/2: `lookfeel.data.labels.is_rank_column`)
    and the ranks the training data held, sorted: a property head's number for one is read
    as the nearest of them (`lookfeel.predict`). Empty in checkpoints from before session 50,
    whose ranks are then answered as numbers."""
    shapes: dict[Modality, dict[str, Any]] = field(default_factory=dict)
    """Per modality, the shape of the items it was trained on (`lookfeel.index.query.
    shape_record`: their one orientation and most common size), for a query turned against
    them to be warned of (`lookfeel.index.query.warn_orientation`). Empty in checkpoints from
    before session 51, whose queries are then not checked; a modality whose items came in
    more than one orientation has none."""
    grey_presses: dict[str, int] | None = None
    """Of the press videos the touch branch was trained on, how many (``videos``) and how many
    had no colour (``grey``: `lookfeel.data.video.Press.grey`): `trained_on_grey`. None for a
    model trained on frame images, without a touch branch, or from before session 56."""

    @property
    def trained_on_grey(self) -> bool | None:
        """Whether most of the press videos the model was trained on had no colour (grey):
        ``predict`` and ``match`` then warn of a colour query video, else of a grey one
        (`lookfeel.index.match.warn_grey_videos`). None where `grey_presses` is not recorded:
        every grey query video is warned of, as before the record."""
        if self.grey_presses is None:
            return None
        return 2 * self.grey_presses["grey"] > self.grey_presses["videos"]


def non_finite_tensors(tensors: Mapping[str, Any]) -> list[str]:
    """The names of the floating-point tensors that hold NaN or infinity (a diverged run's
    weights, or a damaged file's), in the order given.

    Args:
        tensors: a state dict (name -> tensor) on one device; entries that are not float
            tensors are skipped. One device sync in all (the per-tensor flags are stacked on
            the device first), so a training run checks its weights before every checkpoint
            for little.
    """
    named = [
        (k, v) for k, v in tensors.items() if isinstance(v, torch.Tensor) and v.is_floating_point()
    ]
    if not named:
        return []
    finite = torch.stack([v.isfinite().all() for _, v in named]).tolist()
    return [k for (k, _), ok in zip(named, finite, strict=True) if not ok]


def _refuse_non_finite(path: str | os.PathLike[str], tensors: Mapping[str, Any]) -> None:
    """Raise `CheckpointError` naming ``path`` when its weights hold NaN or infinity: a model
    built from them would embed every item as NaN, silently or with a traceback later."""
    bad = non_finite_tensors(tensors)
    if bad:
        more = f" and {len(bad) - 1} more" if len(bad) > 1 else ""
        raise CheckpointError(
            f"{path}: its weights hold NaN or infinity ({bad[0]}{more}): the run diverged or "
            "the file is damaged; use an earlier checkpoint of the run"
        )


def init_from_checkpoint(model: Embedder, path: str | os.PathLike[str]) -> list[str]:
    """Start ``model`` from another run's weights (``model.init_from``: e.g. pre-training on
    the synthetic world, then training on real data).

    Every parameter and buffer whose name and shape match is copied; the rest (a head of
    another size, a branch the other run lacks) keep their fresh initialisation. A branch
    both have must take at least half of its tensors from the checkpoint: fewer means another
    backbone or width (3 of a branch's 84 tensors, say), whose few matching names would start
    the run from a mix that no run trained.

    Returns:
        The names of the tensors that were not copied.

    ``path`` may be the other run's folder, for its ``checkpoints/last.pt``
    (`checkpoint_file`).

    Raises:
        CheckpointError: the file is not a checkpoint, its weights hold NaN or infinity, no
            tensor of it fits this model, or fewer than half of a shared branch's do.
    """
    path = checkpoint_file(path)
    source = read_checkpoint(path)["model"]
    _refuse_non_finite(path, source)
    own = model.state_dict()
    fits = {k: v for k, v in source.items() if k in own and own[k].shape == v.shape}
    if not fits:
        raise CheckpointError(
            f"{path}: no weight fits this model (its branches or backbone differ: the "
            f"checkpoint has e.g. {', '.join(list(source)[:3])})"
        )
    for branch in model.branches:
        prefix = f"branches.{branch}."
        mine = [k for k in own if k.startswith(prefix)]
        if not any(k.startswith(prefix) for k in source):
            continue  # a branch the other run lacks starts fresh
        copied = sum(k in fits for k in mine)
        if 2 * copied < len(mine):
            raise CheckpointError(
                f"{path}: only {copied} of this model's {len(mine)} {branch} branch tensors fit "
                "its weights (another model.backbone or model.width?); model.init_from starts "
                "a run from one of the same architecture"
            )
    model.load_state_dict(fits, strict=False)
    return [k for k in own if k not in fits]


def load_model(path: str | os.PathLike[str], device: torch.device | str = "cpu") -> LoadedModel:
    """Rebuild the trained model from a checkpoint alone, in eval mode.

    The model knows the size of the images it was trained on (``data.image_size``,
    ``data.color_size``: `lookfeel.models.Embedder.input_sizes`) and refuses images of
    another size; `lookfeel.index.query.load_query_image` reads a file at that size.

    Args:
        path: a checkpoint a run wrote (``RUN/checkpoints/best.pt`` or ``last.pt``), or the
            run's folder ``RUN`` for its ``last.pt`` (`checkpoint_file`; the model's `path` is
            then that file).
        device: where the model runs: ``cpu``, ``cuda``, ``cuda:1``, a ``torch.device``, or
            ``auto`` (`lookfeel.devices.resolve_device`).

    Raises:
        DeviceError: the device is unknown to torch or not usable here (checked first).
        CheckpointError: naming the file, when it cannot be read, does not fit its config, or
            its weights hold NaN or infinity; a folder with no ``checkpoints/last.pt``.

    Example:
        >>> from lookfeel.checkpoint import load_model
        >>> from lookfeel.index.query import load_query_image, query_batch
        >>> loaded = load_model("run/checkpoints/best.pt")
        >>> x = load_query_image("photo.png", "color", loaded.config.data)  # floats in [0, 1]
        >>> with torch.no_grad():
        ...     emb = loaded.model({"color": query_batch([x], "color")})["color"]  # (1, D)
    """
    device = resolve_device(device)
    path = checkpoint_file(path)
    state = read_checkpoint(path)
    try:
        # The loss plays no part here: a run trained with a loss this process has not
        # registered (a user's own module) loads, with a warning.
        with unregistered_loss_kinds_allowed():
            config = from_dict(RunConfig, state["config"])
    except ConfigError as e:
        hint = trained_with_hint(state.get("plugins") or ())
        raise CheckpointError(f"{path}: its config does not load: {e}{hint}") from None
    modalities = [Modality(m) for m in state.get("modalities", config.train.modalities)]
    model = create_model(
        config.model,
        modalities,
        load_weights=False,
        touch_channels=config.data.touch_channels,
        # Images of another size than trained on are refused (`Embedder.input_sizes`).
        input_sizes={m: config.data.size_of(m) for m in modalities},
    )
    try:
        model.load_state_dict(state["model"])
    except RuntimeError as e:
        raise CheckpointError(f"{path}: weights do not fit the model of its config: {e}") from None
    _refuse_non_finite(path, state["model"])
    model.to(device).eval()
    return LoadedModel(
        path=path,
        config=config,
        model=model,
        step=int(state.get("step", 0)),
        label_columns=tuple(state.get("label_columns", ())),
        label_stats={
            k: (float(v[0]), float(v[1])) for k, v in state.get("label_stats", {}).items()
        },
        split=dict(state.get("split", {})),
        touch_input=_touch_input(path, state.get("touch_input")),
        rank_columns={
            str(c): tuple(int(r) for r in ranks)
            for c, ranks in (state.get("rank_columns") or {}).items()
        },
        data_fingerprint=state.get("data_fingerprint"),
        software={str(k): str(v) for k, v in (state.get("software") or {}).items()},
        chosen_by=str(state["chosen_by"]) if state.get("chosen_by") is not None else None,
        shapes=_shapes(state.get("shapes")),
        grey_presses=_grey_presses(state.get("grey_presses")),
    )


def _grey_presses(value: object) -> dict[str, int] | None:
    """The checkpoint's ``grey_presses`` record (None when absent). One this version cannot
    read (a newer lookfeel's, or counts that do not add up) is left out: queries are then
    warned of as without it."""
    if not isinstance(value, Mapping):
        return None
    videos, grey = value.get("videos"), value.get("grey")
    if type(videos) is not int or type(grey) is not int or not 0 <= grey <= videos or not videos:
        return None
    return {"videos": videos, "grey": grey}


def _shapes(value: object) -> dict[Modality, dict[str, Any]]:
    """The checkpoint's ``shapes`` record (empty when absent). A modality this version does not
    know, or an entry that is not a mapping (a newer lookfeel's), is left out: its queries are
    then not checked, as `lookfeel.index.query.warn_orientation` leaves out a record it cannot
    read."""
    if not isinstance(value, Mapping):
        return {}
    known = {m.value: m for m in Modality}
    return {
        known[str(k)]: dict(v)
        for k, v in value.items()
        if str(k) in known and isinstance(v, Mapping)
    }


def _touch_input(path: str | os.PathLike[str], value: object) -> str | None:
    """The checkpoint's ``touch_input`` record, checked (None when absent)."""
    if value is None:
        return None
    if value not in (TOUCH_VIDEOS, TOUCH_FRAMES, TOUCH_BOTH):
        raise CheckpointError(
            f"{path}: touch_input is {value!r}; expected {TOUCH_VIDEOS!r}, {TOUCH_FRAMES!r} or "
            f"{TOUCH_BOTH!r} (a damaged checkpoint, or one from a newer lookfeel)"
        )
    return str(value)
