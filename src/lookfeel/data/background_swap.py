"""The background control: each image's background replaced by another fabric's, cloth kept.

A model that recognises the material, not the capture session, scores the same on such images;
one that reads the wall or the floor drops (issue #12: 0.890 -> 0.802 top-1 when only the wall
is swapped). `swap_backgrounds` builds the swapped batch from cloth masks (from
`lookfeel.data.register.register_depth` or any other segmentation):

- every image ``i`` is paired with an image ``j`` of *another* fabric, drawn uniformly and
  reproducibly from ``seed``;
- the output is image ``i`` where ``i`` shows cloth, and image ``j``'s background elsewhere;
- where ``j`` shows cloth but ``i`` does not, ``j``'s background is unknown: it is taken from
  ``rooms[j]`` (the fitted empty room) when given, else from ``j``'s nearest background pixel.

So no pixel of the output comes from ``i``'s background or from any cloth but ``i``'s.
`register_items` decodes and registers depth files into the masks and rooms this needs.

Registered depth (``data.depth_input: registered``) never shows the room to the network; the
swap reaches it only through registering the composite image again, which fits a room to an
image no camera saw (this cloth on its own floor, in front of the partner's walls). So for
registered runs there is a second control, the **room control**: image ``i`` is registered, as
it was taken, against the room fitted on its partner ``j``'s own image (`register_in_room` with
``j``'s planes; the same partner as the swap), with no fit on a composite. What registration
takes from the room (the floor's tilt, which pixels are cloth, where the drape's top is) then
comes from another session's fit. It is not a capture either: where the two sessions' rooms
differ by more than the margin, room pixels become cloth or cloth is lost, as a registration
error of that size would do. A model that reads the drape's shape alone loses only what those
pixels change; raw pixels of the same images show how much that is.

`BackgroundControl` applies this to a run's depth items as ``lookfeel cv`` and ``lookfeel
evaluate`` score them: each file is decoded and registered (`lookfeel.data.register`; cloth
as the run's ``data.depth_cloth`` says), the backgrounds are swapped in millimetres, and each
swapped image goes through the run's own preprocessing (`preprocess_depth`: raw depth is
mapped as always, registered depth is registered again, in the swapped room). Its `loader`
serves those arrays in place of the files, so the model and the raw-pixel baseline see
swapped images exactly as they see the originals.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from lookfeel.config import DataConfig
from lookfeel.data.catalog import Item
from lookfeel.data.images import (
    ArrayLoader,
    ImageLoader,
    decode_depth,
    fill_holes,
    preprocess_depth,
    registered_to_unit,
)
from lookfeel.data.register import (
    Intrinsics,
    Plane,
    RegistrationError,
    drape_mask,
    placed_heights,
    register_configured,
    register_depth,
    register_in_room,
    registered_intrinsics,
)
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality

F32 = NDArray[np.float32]

__all__ = [
    "BackgroundControl",
    "RegisteredBatch",
    "SwappedBatch",
    "pair_other_fabric",
    "register_items",
    "swap_backgrounds",
]


@dataclass(frozen=True)
class SwappedBatch:
    """`swap_backgrounds`' result.

    Attributes:
        images: (N, H, W) the swapped images, dtype of the input.
        partner: (N,) index of the image whose background each image received.
    """

    images: NDArray[np.generic]
    partner: NDArray[np.int64]


def pair_other_fabric(fabric_ids: ArrayLike, seed: int = 0) -> NDArray[np.int64]:
    """(N,) for each item, a uniformly drawn index of an item of another fabric.

    Deterministic for a given ``seed`` and ``fabric_ids``.

    Raises:
        LookfeelError: fewer than two fabrics (no other fabric to draw from).
    """
    fab = np.asarray(fabric_ids).reshape(-1)
    n = len(fab)
    if len(np.unique(fab)) < 2:
        raise LookfeelError(
            f"background swap needs images of two or more fabrics; got {len(np.unique(fab))}"
        )
    rng = np.random.default_rng(seed)
    order = np.argsort(fab, kind="stable")
    sorted_fab = fab[order]
    starts = np.searchsorted(sorted_fab, fab, side="left")
    ends = np.searchsorted(sorted_fab, fab, side="right")
    own = ends - starts
    # A uniform draw among the n - own items of other fabrics: draw a rank among them and
    # skip over the own fabric's block in the fabric-sorted order.
    r = np.floor(rng.random(n) * (n - own)).astype(np.int64)
    pos = np.where(r < starts, r, r + own)
    return order[pos].astype(np.int64)


def swap_backgrounds(
    images: ArrayLike,
    cloth: ArrayLike,
    fabric_ids: ArrayLike,
    *,
    seed: int = 0,
    rooms: ArrayLike | None = None,
) -> SwappedBatch:
    """Replace each image's background with another fabric's image's background (module doc).

    Args:
        images: (N, H, W) depth images (any dtype; e.g. millimetres or [0, 1]).
        cloth: (N, H, W) bool, True where the image shows cloth.
        fabric_ids: (N,) each image's fabric.
        seed: seeds the pairing.
        rooms: optional (N, H, W) each image's empty room (same units as ``images``), used
            where the partner's own cloth hides its background.

    Returns:
        A `SwappedBatch`.

    Raises:
        LookfeelError: shapes disagree, or fewer than two fabrics.
    """
    x = np.asarray(images)
    m = np.asarray(cloth, dtype=bool)
    fab = np.asarray(fabric_ids).reshape(-1)
    if x.ndim != 3 or m.shape != x.shape or len(fab) != len(x):
        raise LookfeelError(
            f"background swap: images {x.shape}, cloth masks {m.shape} and {len(fab)} fabric "
            "ids must agree as (N, H, W), (N, H, W), (N,)"
        )
    room = None if rooms is None else np.asarray(rooms)
    if room is not None and room.shape != x.shape:
        raise LookfeelError(f"background swap: rooms {room.shape} must match images {x.shape}")
    partner = pair_other_fabric(fab, seed)
    out = x.copy()
    for i, j in enumerate(partner):
        back = _background_of(x[j], m[j], None if room is None else room[j])
        out[i] = np.where(m[i], x[i], back)
    return SwappedBatch(out, partner)


def _background_of(
    image: NDArray[np.generic], cloth: NDArray[np.bool_], room: NDArray[np.generic] | None
) -> NDArray[np.generic]:
    """The image with its cloth replaced by the room (or the nearest background pixel)."""
    if not cloth.any():
        return image
    if room is not None:
        return np.where(cloth, room, image).astype(image.dtype)
    if cloth.all():  # no background at all: nothing better than the image itself
        return image
    idx = ndimage.distance_transform_edt(cloth, return_distances=False, return_indices=True)
    return image[tuple(idx)]


class BackgroundControl:
    """Background-swapped depth inputs of a run's items, preprocessed as the run's config says.

    Args:
        config: the run's data config (its depth preprocessing, registered or raw, and its
            registration settings).
        seed: seeds the pairing of each image with another fabric's (`pair_other_fabric`).

    Registrations and control arrays are kept, so scoring the same items again (another
    training seed of the same fold) costs nothing.

    Example:
        >>> control = BackgroundControl(lm.config.data)
        >>> swapped = control.loader(items)  # embed_items(model, items, swapped)
        >>> in_other_rooms = control.room_loader(items)  # registered runs only
    """

    def __init__(self, config: DataConfig, seed: int = 0) -> None:
        self.config = config
        self.seed = seed
        self._scenes: dict[Path, tuple[np.ndarray, np.ndarray, np.ndarray, tuple[Plane, ...]]] = {}
        self._swapped: dict[tuple[Path, ...], dict[Path, np.ndarray]] = {}
        self._rooms: dict[tuple[Path, ...], dict[Path, np.ndarray]] = {}

    @property
    def has_room_control(self) -> bool:
        """Whether `room_loader` applies: the run registers its depth."""
        return self.config.depth_input == "registered"

    def _scene(self, item: Item) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[Plane, ...]]:
        """(depth mm with holes filled, cloth mask, fitted room mm, room planes) of one depth
        file."""
        got = self._scenes.get(item.path)
        if got is None:
            d = decode_depth(item.path)
            try:
                reg = register_configured(d, self.config)
            except RegistrationError as e:
                raise RegistrationError(f"{item.path}: background control: {e}") from None
            cloth = drape_mask(reg.cloth) if self.config.depth_cloth == "drape" else reg.cloth
            got = (fill_holes(d).astype(np.float32), cloth, reg.room, reg.planes)
            self._scenes[item.path] = got
        return got

    def _scenes_of(
        self, items: Sequence[Item]
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[Plane, ...]]]:
        """`_scene` of every item (in threads), all of one size.

        Raises:
            LookfeelError: images of different sizes, or a file whose room cannot be fitted
                (named).
        """
        with ThreadPoolExecutor(max(1, self.config.workers)) as pool:
            scenes = list(pool.map(self._scene, items))
        first = scenes[0][0].shape if scenes else None
        for it, s in zip(items, scenes, strict=True):
            if s[0].shape != first:
                raise LookfeelError(
                    f"{it.path}: background control needs depth images of one size; this one "
                    f"is {s[0].shape}, the first {first}"
                )
        return scenes

    def arrays(self, items: Sequence[Item]) -> dict[Path, np.ndarray]:
        """Each depth item's swapped image, preprocessed (file -> (S, S) float32).

        Raises:
            LookfeelError: fewer than two fabrics, images of different sizes, or a file whose
                room cannot be fitted (named).
        """
        key = tuple(it.path for it in items)
        if key in self._swapped:
            return self._swapped[key]
        workers = max(1, self.config.workers)
        scenes = self._scenes_of(items)
        fab = np.array([it.fabric_id for it in items], dtype=np.int64)
        out = swap_backgrounds(
            np.stack([s[0] for s in scenes]),
            np.stack([s[1] for s in scenes]),
            fab,
            seed=self.seed,
            rooms=np.stack([s[2] for s in scenes]),
        )

        def prep(i: int) -> np.ndarray:
            try:
                return preprocess_depth(out.images[i], self.config)
            except RegistrationError as e:
                raise RegistrationError(
                    f"{items[i].path}: background control (background of "
                    f"{items[int(out.partner[i])].path.name}): {e}"
                ) from None

        with ThreadPoolExecutor(workers) as pool:
            arrays = dict(zip(key, pool.map(prep, range(len(items))), strict=True))
        self._swapped[key] = arrays
        return arrays

    def loader(self, items: Sequence[Item]) -> ImageLoader:
        """A loader serving ``items``' swapped images in place of their files (module doc)."""
        return ArrayLoader(self.config, self.arrays(items), Modality.DEPTH)

    def room_arrays(self, items: Sequence[Item]) -> dict[Path, np.ndarray]:
        """The room control (module doc): each depth item registered in the room fitted on its
        partner's own image (the partner `arrays` swaps in), then kept, moved and mapped as
        the run's config says (file -> (S, S) float32).

        Raises:
            LookfeelError: the run does not register its depth, fewer than two fabrics, images
                of different sizes, or a file whose room cannot be fitted (named).
        """
        if not self.has_room_control:
            raise LookfeelError(
                "room control: the run's depth is not registered (data.depth_input: "
                f"{self.config.depth_input}); use the background swap"
            )
        key = tuple(it.path for it in items)
        if key in self._rooms:
            return self._rooms[key]
        scenes = self._scenes_of(items)
        fab = np.array([it.fabric_id for it in items], dtype=np.int64)
        partner = pair_other_fabric(fab, self.seed)
        cfg = self.config

        def prep(i: int) -> np.ndarray:
            depth = scenes[i][0]
            reg = register_in_room(
                depth,
                scenes[int(partner[i])][3],
                registered_intrinsics(depth.shape, cfg),
                margin_mm=cfg.depth_margin_mm,
            )
            height = placed_heights(reg, cfg)
            return registered_to_unit(height, cfg)

        with ThreadPoolExecutor(max(1, cfg.workers)) as pool:
            arrays = dict(zip(key, pool.map(prep, range(len(items))), strict=True))
        self._rooms[key] = arrays
        return arrays

    def room_loader(self, items: Sequence[Item]) -> ImageLoader:
        """A loader serving `room_arrays` in place of ``items``' files."""
        return ArrayLoader(self.config, self.room_arrays(items), Modality.DEPTH)


@dataclass(frozen=True)
class RegisteredBatch:
    """`register_items`' result: (N, H, W) arrays, one row per item.

    Attributes:
        depth: the decoded depth (mm, holes filled).
        cloth: the cloth masks.
        room: the fitted rooms' depth (mm).
        height: the registered images (mm above the fitted floor, 0 off the cloth).
    """

    depth: F32
    cloth: NDArray[np.bool_]
    room: F32
    height: F32


def register_items(
    items: Sequence[Item], intrinsics: Intrinsics | None = None, **kwargs: float
) -> RegisteredBatch:
    """Decode and register depth items (all of one size), e.g. for `swap_backgrounds`.

    Args:
        items: depth items.
        intrinsics: the camera (default: GelFabric's, scaled to the images).
        **kwargs: passed to `register_depth` (margin_mm, inlier_mm ...).

    Raises:
        RegistrationError: naming the file whose room could not be fitted, or whose size
            differs from the first item's.
    """
    rows = []
    shape = None
    for it in items:
        d = decode_depth(it.path)
        if shape is not None and d.shape != shape:
            raise RegistrationError(f"{it.path}: depth image is {d.shape}, the first is {shape}")
        shape = d.shape
        try:
            reg = register_depth(d, intrinsics, **kwargs)  # type: ignore[arg-type]
        except RegistrationError as e:
            raise RegistrationError(f"{it.path}: {e}") from None
        rows.append((fill_holes(d).astype(np.float32), reg.cloth, reg.room, reg.height))
    if not rows:
        empty = np.zeros((0, 0, 0), np.float32)
        return RegisteredBatch(empty, empty.astype(bool), empty, empty)
    depth, cloth, room, height = (np.stack(col) for col in zip(*rows, strict=True))
    return RegisteredBatch(depth, cloth, room, height)
