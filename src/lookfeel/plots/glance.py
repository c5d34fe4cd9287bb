"""The evaluation at a glance: a touch query, the drapes and photos nearest to it, and what it
predicts the fabric feels like beside what it is."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from lookfeel.plots._figure import new_figure, style
from lookfeel.plots.examples import QUERY_COLOUR, TRUE_COLOUR, _show

__all__ = ["GlanceLook", "GlanceRow", "glance_figure"]

CELL_IN = 1.2
"""Inches per image."""
FEEL_IN = 2.9
"""Inches of the text column (what the query feels like)."""


@dataclass(frozen=True)
class GlanceLook:
    """One look modality's nearest fabrics for a query, nearest first.

    Attributes:
        name: what the images are, e.g. ``"depth"``.
        images: one image per fabric shown ((H, W) in [0, 1] or (H, W, 3) RGB).
        labels: text under each image, e.g. ``"1. F12"``.
        true: whether each image is of the query's own fabric (framed green).
        note: a line beside the row, e.g. ``"true fabric: 3rd of 18"``.
    """

    name: str
    images: Sequence[NDArray[np.generic]]
    labels: Sequence[str]
    true: Sequence[bool]
    note: str = ""


@dataclass(frozen=True)
class GlanceRow:
    """One touch query: its image, its nearest looks, and what it feels like.

    Attributes:
        query_image: the touch image.
        query_label: text under it.
        looks: one `GlanceLook` per look modality (one row of images each).
        feel: lines of ``(label, predicted, true)`` text (empty: no column).
        feel_title: the text column's heading.
    """

    query_image: NDArray[np.generic]
    query_label: str
    looks: Sequence[GlanceLook]
    feel: Sequence[tuple[str, str, str]] = ()
    feel_title: str = ""


def glance_figure(rows: Sequence[GlanceRow], title: str) -> Figure:
    """Each query a block: the touch image left, a row of nearest images per look modality
    (the query's own fabric framed green), and a column of predicted against true labels.

    Args:
        rows: the queries (each with the same number of looks, of at most ``shown`` images).
        title: figure title.

    Returns:
        A figure ``CELL_IN`` per image column plus ``FEEL_IN`` for the text, about 1.5 in per
        look row (5 images, 2 looks, 3 queries: 1046 x 1110 px when saved).

    Raises:
        ValueError: no rows, rows with different looks, or a look whose labels do not match its
            images.
    """
    if not rows:
        raise ValueError("no glance queries to draw")
    n_looks = len(rows[0].looks)
    if n_looks == 0 or any(len(r.looks) != n_looks for r in rows):
        raise ValueError("every glance row needs the same number of look rows (at least one)")
    shown = max(len(look.images) for r in rows for look in r.looks)
    for r in rows:
        for look in r.looks:
            if not (len(look.images) == len(look.labels) == len(look.true)):
                raise ValueError(f"look {look.name!r}: images, labels and true flags differ")
    feel = any(r.feel for r in rows)
    look_in, gap_in, top_in = 1.5, 0.6, 0.8
    height = top_in + len(rows) * n_looks * look_in + (len(rows) - 1) * gap_in + 0.1
    width = CELL_IN * (shown + 1.3) + (FEEL_IN if feel else 0.0)
    with style():
        fig = new_figure(width, height)
        outer = fig.add_gridspec(
            len(rows),
            1,
            left=0.01,
            right=0.99,
            top=1.0 - top_in / height,
            bottom=0.1 / height,
            hspace=gap_in / (n_looks * look_in),
        )
        ratios = [1.0, 0.3] + [1.0] * shown + ([FEEL_IN / CELL_IN] if feel else [])
        for i, r in enumerate(rows):
            grid = outer[i].subgridspec(
                n_looks, len(ratios), width_ratios=ratios, wspace=0.08, hspace=0.45
            )
            ax = fig.add_subplot(grid[:, 0])
            _show(ax, r.query_image, QUERY_COLOUR, 3.0)
            ax.set_xlabel(r.query_label, fontsize=8.5, color=QUERY_COLOUR)
            for k, look in enumerate(r.looks):
                for j, (image, label, true) in enumerate(
                    zip(look.images, look.labels, look.true, strict=True)
                ):
                    ax = fig.add_subplot(grid[k, j + 2])
                    _show(ax, image, TRUE_COLOUR if true else None, 4.0)
                    ax.set_xlabel(
                        label,
                        fontsize=8.5,
                        color=TRUE_COLOUR if true else "black",
                        fontweight="bold" if true else "normal",
                    )
                    if j == 0:
                        ax.set_ylabel(look.name, fontsize=9.0)
                        if look.note:  # runs on over the row's other images
                            ax.set_title(look.note, fontsize=8.5, loc="left", pad=3.0)
            if feel:
                ax = fig.add_subplot(grid[:, -1])
                ax.set_axis_off()
                lines = [r.feel_title, ""] if r.feel_title else []
                width_name = max((len(n) for n, _, _ in r.feel), default=0)
                lines.append(f"{'':<{width_name}}  {'predicted':>9}  {'true':>7}")
                lines += [f"{n:<{width_name}}  {p:>9}  {t:>7}" for n, p, t in r.feel]
                ax.text(
                    0.02,
                    0.95,
                    "\n".join(lines),
                    va="top",
                    ha="left",
                    family="monospace",
                    fontsize=8.5,
                    transform=ax.transAxes,
                )
        fig.suptitle(title)
    return fig
