"""Reliability diagram: is a match probability of 0.7 right 70% of the time?"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from lookfeel.plots._figure import new_figure, style

__all__ = ["reliability_figure"]


def reliability_figure(
    edges: ArrayLike,
    confidence: ArrayLike,
    accuracy: ArrayLike,
    count: ArrayLike,
    *,
    ece: float | None = None,
    title: str = "Reliability",
    xlabel: str = "confidence: P of the predicted fabric",
) -> Figure:
    """Accuracy per confidence bin against the diagonal, and how many predictions fall in each.

    Args:
        edges: (B + 1,) bin edges over [0, 1].
        confidence: (B,) mean confidence per bin (NaN when empty).
        accuracy: (B,) fraction correct per bin (NaN when empty).
        count: (B,) predictions per bin.
        ece: expected calibration error, shown in the title when given.
        title, xlabel: texts.

    Returns:
        A 6 x 6.5 inch figure (600 x 650 px when saved).

    Raises:
        ValueError: the arrays do not have B + 1 and B entries.
    """
    e = np.asarray(edges, dtype=np.float64).reshape(-1)
    conf = np.asarray(confidence, dtype=np.float64).reshape(-1)
    acc = np.asarray(accuracy, dtype=np.float64).reshape(-1)
    n = np.asarray(count, dtype=np.float64).reshape(-1)
    b = len(e) - 1
    if b < 1 or not len(conf) == len(acc) == len(n) == b:
        raise ValueError(
            f"need B + 1 edges and B values; got {len(e)} edges, {len(conf)}, {len(acc)}, "
            f"{len(n)} values"
        )
    left, width = e[:-1], np.diff(e)
    filled = n > 0
    with style():
        fig = new_figure(6.0, 6.5)
        grid = fig.add_gridspec(2, 1, height_ratios=(3, 1), hspace=0.08)
        ax = fig.add_subplot(grid[0])
        hist = fig.add_subplot(grid[1], sharex=ax)
        ax.plot([0, 1], [0, 1], color="grey", linestyle="--", linewidth=1, label="calibrated")
        ax.bar(
            left[filled],
            np.nan_to_num(acc[filled]),
            width=width[filled],
            align="edge",
            color="#1f77b4",
            edgecolor="black",
            linewidth=0.6,
            alpha=0.85,
            label="accuracy in bin",
        )
        ax.plot(
            conf[filled],
            acc[filled],
            color="#d62728",
            marker="o",
            linestyle="none",
            label="(mean confidence, accuracy)",
        )
        ax.set_xlim(0.0, 1.0)
        ax.set_ylim(0.0, 1.0)
        ax.set_ylabel("accuracy: predicted fabric is right")
        ax.legend(loc="upper left", frameon=False)
        ax.tick_params(labelbottom=False)
        ax.set_title(title if ece is None else f"{title}  (ECE = {ece:.3f})")
        hist.bar(left, n, width=width, align="edge", color="grey", edgecolor="black", lw=0.6)
        hist.set_xlabel(xlabel)
        hist.set_ylabel("predictions")
        fig.subplots_adjust(left=0.13, right=0.96, top=0.93, bottom=0.09)
    return fig
