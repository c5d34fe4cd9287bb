"""The sensor's own light as a shortcut: score touch with nothing touching the sensor.

Every recording of one object is usually made in one session, and between sessions a GelSight's
gel, light and camera drift: on the 401 PhysiCLeAR videos the no-contact frame alone, before
any press, picks the right object 1 of 10 at 0.86 top-1 from raw pixels (chance 0.10). A model
fed raw frames can learn the session instead of the touch.

`UntouchedControl` gives, for each press video, the image the run's preprocessing would make of
a moment with no contact: with ``data.video_reference: subtract``, the last no-contact frame
minus the mean of the ones before it (only drift and noise remain); with ``none``, the raw
no-contact frame itself (the sensor's light pattern). `lookfeel cv` embeds these in place of the
presses and scores them (``model_untouched``, ``raw_pixels_untouched``): a model that reads
the contact, not the session, falls to chance there.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from lookfeel.config import DataConfig
from lookfeel.data.catalog import Item
from lookfeel.data.images import ArrayLoader, ImageLoader, preprocess_rgb
from lookfeel.data.video import detect_press, difference_image, is_video, read_video
from lookfeel.modality import Modality

__all__ = ["UntouchedControl", "untouched_image"]


def untouched_image(path: Path, config: DataConfig) -> np.ndarray:
    """(S, S, 3) uint8: what the run's preprocessing makes of ``path``'s no-contact frames.

    Raises:
        VideoError: the video cannot be decoded or holds no press (naming it).
    """
    frames = read_video(path, rotate=config.video_rotate)
    span = detect_press(frames, path)
    a, b = span.reference
    if config.video_reference == "none":
        image = frames[a]
    elif b - a >= 2:
        earlier = frames[a : b - 1].astype(np.float32).mean(0)
        image = difference_image(frames[b - 1], earlier, config.video_gain)
    else:
        image = difference_image(frames[a], frames[a].astype(np.float32), config.video_gain)
    return preprocess_rgb(image, Modality.TOUCH, config)


class UntouchedControl:
    """Untouched inputs of a run's touch videos, preprocessed as the run's config says (kept,
    so another seed of the same fold costs nothing).

    Example:
        >>> control = UntouchedControl(lm.config.data)
        >>> if control.applies(items):
        ...     emb = embed_items(model, items, control.loader(items))
    """

    def __init__(self, config: DataConfig) -> None:
        self.config = config
        self._arrays: dict[Path, np.ndarray] = {}

    @staticmethod
    def applies(items: Sequence[Item]) -> bool:
        """Whether the items are press videos (frames of a press have no untouched moment)."""
        return bool(items) and all(
            it.modality is Modality.TOUCH and is_video(it.path) for it in items
        )

    def loader(self, items: Sequence[Item]) -> ImageLoader:
        """A loader serving each item's untouched image in place of its press."""
        todo = [it.path for it in items if it.path not in self._arrays]
        with ThreadPoolExecutor(max(1, self.config.workers)) as pool:
            done = pool.map(lambda p: untouched_image(p, self.config), todo)
            self._arrays.update(zip(todo, done, strict=True))
        arrays = {it.path: self._arrays[it.path] for it in items}
        return ArrayLoader(self.config, arrays, Modality.TOUCH)
