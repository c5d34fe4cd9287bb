"""Confusion matrices between fabrics or clusters (paper Figure 8)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from lookfeel.plots._figure import new_figure, style

__all__ = ["confusion_figure"]


def _runs(groups: Sequence[object]) -> list[tuple[int, int, object]]:
    """Consecutive runs of equal group labels: (start, stop, label)."""
    out: list[tuple[int, int, object]] = []
    start = 0
    for i in range(1, len(groups) + 1):
        if i == len(groups) or groups[i] != groups[start]:
            out.append((start, i, groups[start]))
            start = i
    return out


def _ticks(ax: Axes, n: int, labels: Sequence[str], axis: str, max_ticks: int) -> None:
    if n > max_ticks:  # too many to read: every k-th
        step = int(np.ceil(n / max_ticks))
        idx = list(range(0, n, step))
    else:
        idx = list(range(n))
    size = 9.0 if n <= 20 else 7.0
    if axis == "x":
        long = n > 12 or max((len(s) for s in labels), default=0) > 3
        ax.set_xticks(idx, [labels[i] for i in idx], rotation=90 if long else 0, fontsize=size)
    else:
        ax.set_yticks(idx, [labels[i] for i in idx], fontsize=size)


def confusion_figure(
    matrix: ArrayLike,
    row_labels: Sequence[object],
    col_labels: Sequence[object],
    *,
    row_groups: Sequence[object] | None = None,
    col_groups: Sequence[object] | None = None,
    title: str = "Confusion",
    xlabel: str = "gallery fabric",
    ylabel: str = "query fabric",
    colorbar_label: str = "mean P(match)",
    group_name: str = "cluster",
    max_ticks: int = 40,
    annotate: bool | None = None,
) -> Figure:
    """A confusion matrix as an image, with group (cluster) blocks outlined.

    Args:
        matrix: (R, C) values, e.g. the mean probability that a query of row fabric a is
            matched to column fabric b (`lookfeel.metrics.confusion_matrix`).
        row_labels, col_labels: a label per row and column (fabric or cluster ids).
        row_groups, col_groups: the group (cluster) of each row and column, in the matrix's
            order (sort rows and columns by group first: `lookfeel.metrics.order_by_cluster`);
            white lines separate the groups and the top axis names them.
        title, xlabel, ylabel, colorbar_label: texts.
        group_name: what a group is called on the top axis.
        max_ticks: at most this many tick labels per axis (every k-th beyond).
        annotate: write each cell's value; default when the matrix is at most 12 x 12.

    Returns:
        A 7.5 x 6.5 inch figure (750 x 650 px when saved).

    Raises:
        ValueError: the labels or groups do not fit the matrix.
    """
    m: NDArray[np.float64] = np.asarray(matrix, dtype=np.float64)
    if m.ndim != 2:
        raise ValueError(f"matrix must be 2-D; got shape {m.shape}")
    n_r, n_c = m.shape
    if len(row_labels) != n_r or len(col_labels) != n_c:
        raise ValueError(
            f"{len(row_labels)} row and {len(col_labels)} column labels for a {m.shape} matrix"
        )
    for name, groups, n in (("row_groups", row_groups, n_r), ("col_groups", col_groups, n_c)):
        if groups is not None and len(groups) != n:
            raise ValueError(f"{name} has {len(groups)} entries for {n} {name[:3]}s")
    if annotate is None:
        annotate = max(n_r, n_c) <= 12
    with style():
        fig = new_figure(7.5, 6.5)
        ax = fig.add_subplot(1, 1, 1)
        finite = m[np.isfinite(m)]
        vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
        im = ax.imshow(m, cmap="viridis", vmin=0.0, vmax=vmax, interpolation="nearest")
        ax.set_aspect("auto" if max(n_r, n_c) > 3 * min(n_r, n_c) else "equal")
        _ticks(ax, n_c, [str(x) for x in col_labels], "x", max_ticks)
        _ticks(ax, n_r, [str(x) for x in row_labels], "y", max_ticks)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        for side in ("top", "right"):
            ax.spines[side].set_visible(True)
        if row_groups is not None:
            for start, _, _ in _runs(list(row_groups))[1:]:
                ax.axhline(start - 0.5, color="white", linewidth=1.2)
        if col_groups is not None:
            runs = _runs(list(col_groups))
            for start, _, _ in runs[1:]:
                ax.axvline(start - 0.5, color="white", linewidth=1.2)
            top = ax.secondary_xaxis("top")
            top.set_xticks(
                [(a + b - 1) / 2 for a, b, _ in runs],
                [str(g) for _, _, g in runs],
                fontsize=8.0 if len(runs) > 8 else 9.0,
            )
            top.set_xlabel(group_name)
        if annotate:
            for i in range(n_r):
                for j in range(n_c):
                    v = m[i, j]
                    if not np.isfinite(v):
                        continue
                    colour = "black" if v > 0.6 * vmax else "white"
                    ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=8, color=colour)
        cbar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
        cbar.set_label(colorbar_label)
        ax.set_title(title)
        fig.tight_layout()
    return fig
