"""Pick examples like the paper's Figure 6: a query and its candidates, sorted by distance."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from lookfeel.plots._figure import new_figure, style

__all__ = ["QUERY_COLOUR", "TRUE_COLOUR", "PickRow", "pick_examples_figure"]

ROW_IN, TOP_IN, BOTTOM_IN = 1.6, 0.55, 0.45
"""Inches per row of images, above the first row (title), below the last (its labels)."""
TRUE_COLOUR = "#2ca02c"
QUERY_COLOUR = "#1f77b4"


@dataclass(frozen=True)
class PickRow:
    """One query and its candidates, in the order shown (nearest first).

    Attributes:
        query_image: (H, W) in [0, 1] (depth, shown grey) or (H, W, 3) RGB (uint8 or [0, 1]).
        query_label: text under the query, e.g. ``"touch, fabric 12"``.
        candidate_images: one image per candidate.
        candidate_labels: text under each candidate, e.g. ``"F12  D=1.23"``.
        true_index: which candidate is the query's fabric (framed in green).
    """

    query_image: NDArray[np.generic]
    query_label: str
    candidate_images: Sequence[NDArray[np.generic]]
    candidate_labels: Sequence[str]
    true_index: int


def _show(ax: Axes, image: NDArray[np.generic], frame: str | None, width: float) -> None:
    a = np.asarray(image)
    if a.ndim == 2:
        ax.imshow(a, cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
    elif a.ndim == 3 and a.shape[2] == 3:
        ax.imshow(a, interpolation="nearest")
    else:
        raise ValueError(f"an image must be (H, W) or (H, W, 3); got shape {a.shape}")
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(True)
        spine.set_color(frame or "#bbbbbb")
        spine.set_linewidth(width if frame else 0.8)


def pick_examples_figure(rows: Sequence[PickRow], title: str = "Pick 1 of 10") -> Figure:
    """A grid: each row a query, a gap, then its candidates nearest first; the true one green.

    Args:
        rows: the queries to show (all with the same number of candidates).
        title: figure title.

    Returns:
        A figure 1.25 in per column (query, gap, candidates) and 1.6 in per row, plus 1 in for
        the title and the last labels (e.g. 10 candidates, 4 rows: 1425 x 740 px when saved).

    Raises:
        ValueError: no rows, rows of different lengths, labels not matching images, or a
            true index out of range.
    """
    if not rows:
        raise ValueError("no pick examples to draw")
    n = len(rows[0].candidate_images)
    for r in rows:
        if len(r.candidate_images) != n or len(r.candidate_labels) != n:
            raise ValueError("every row needs the same number of candidates and labels")
        if not 0 <= r.true_index < n:
            raise ValueError(f"true_index {r.true_index} is out of range for {n} candidates")
    cell = 1.25
    height = ROW_IN * len(rows) + TOP_IN + BOTTOM_IN
    with style():
        fig = new_figure(cell * (n + 1.4), height)
        grid = fig.add_gridspec(
            len(rows),
            n + 2,
            width_ratios=[1.0, 0.4] + [1.0] * n,
            left=0.01,
            right=0.99,
            top=1.0 - TOP_IN / height,
            bottom=BOTTOM_IN / height,
            wspace=0.08,
            hspace=0.5,
        )
        for i, r in enumerate(rows):
            ax = fig.add_subplot(grid[i, 0])
            _show(ax, r.query_image, QUERY_COLOUR, 3.0)
            ax.set_xlabel(r.query_label, fontsize=8.5, color=QUERY_COLOUR)
            for j in range(n):
                ax = fig.add_subplot(grid[i, j + 2])
                true = j == r.true_index
                _show(ax, r.candidate_images[j], TRUE_COLOUR if true else None, 4.0)
                ax.set_xlabel(
                    r.candidate_labels[j],
                    fontsize=8.5,
                    color=TRUE_COLOUR if true else "black",
                    fontweight="bold" if true else "normal",
                )
        fig.suptitle(title)
    return fig
