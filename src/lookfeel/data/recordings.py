"""Touch recordings in a dataset run: leave out the videos that hold no press, and say which.

A press video that decodes but shows no press (too short, no contact or a change of the
sensor's light alone, contact from its first frame: `lookfeel.data.video.NoPressError`) is a
recording that went wrong, not a broken dataset: one among hundreds should not stop a
training run, a cross-validation or an embedding. `drop_unpressed` decodes every touch video
once (the loader keeps the result for the run) and returns the catalog without those, with one
warning naming each file and why. A video that cannot be decoded at all is still an error.
`lookfeel data check` lists them as warnings.
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

from lookfeel.data.catalog import Catalog, Item
from lookfeel.data.images import ImageLoader
from lookfeel.data.video import NoPressError, is_video
from lookfeel.modality import Modality

__all__ = ["Unpressed", "drop_unpressed", "find_unpressed"]


@dataclass(frozen=True)
class Unpressed:
    """A touch video left out, and why (the `NoPressError`'s reason)."""

    item: Item
    reason: str


def find_unpressed(
    catalog: Catalog, loader: ImageLoader, *, views: bool = False
) -> list[Unpressed]:
    """Decode every touch video of ``catalog`` with ``loader`` (kept in its cache) and return
    those with no press. With ``views`` it decodes each video's training views
    (`ImageLoader.views`, its image among them), so that a training run decodes each once.

    Raises:
        VideoError: a video cannot be decoded at all (naming it).
    """
    videos = [it for it in catalog.items(Modality.TOUCH) if is_video(loader.frame_path(it))]

    def check(item: Item) -> Unpressed | None:
        try:
            if views:
                loader.views(item)
            else:
                loader.embed_array(item)  # what embedding will read next
        except NoPressError as e:
            return Unpressed(item, e.reason)
        return None

    if len(videos) < 8 or loader.config.workers <= 1:
        found = [check(it) for it in videos]
    else:
        with ThreadPoolExecutor(loader.config.workers) as pool:
            found = list(pool.map(check, videos))
    return [u for u in found if u is not None]


def drop_unpressed(
    catalog: Catalog, loader: ImageLoader, warn: bool = True, *, views: bool = False
) -> Catalog:
    """The catalog without its touch videos that hold no press (a warning names each);
    ``views`` as in `find_unpressed`.

    Raises:
        VideoError: a video cannot be decoded at all.
    """
    bad = find_unpressed(catalog, loader, views=views)
    if not bad:
        return catalog
    if warn:
        listed = "; ".join(f"{u.item.path.name} ({u.reason})" for u in bad[:5])
        more = f"; and {len(bad) - 5} more" if len(bad) > 5 else ""
        warnings.warn(
            f"{len(bad)} of {len(catalog.items(Modality.TOUCH))} touch videos hold no press "
            f"and are left out: {listed}{more}",
            stacklevel=2,
        )
    dropped = {u.item for u in bad}
    keep = [it for m in catalog.modalities for it in catalog.items(m) if it not in dropped]
    return catalog.with_items(keep)
