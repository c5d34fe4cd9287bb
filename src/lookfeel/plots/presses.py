"""Accuracy against the number of pooled touch presses (the Multi-input Net's question)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from lookfeel.plots._figure import new_figure, style

__all__ = ["presses_figure"]


def presses_figure(
    presses: ArrayLike,
    curves: Mapping[str, ArrayLike],
    *,
    low: Mapping[str, ArrayLike] | None = None,
    high: Mapping[str, ArrayLike] | None = None,
    chance: ArrayLike | None = None,
    title: str = "Touch queries: accuracy against presses",
    xlabel: str = "presses per touch query (element-wise max)",
    ylabel: str = "top-1 accuracy, pick 1 of 10",
) -> Figure:
    """One line per curve (e.g. per gallery modality) against P, with intervals and chance.

    Args:
        presses: (P,) press counts on the x axis.
        curves: name -> (P,) values (NaN where a count was not scored).
        low, high: name -> (P,) interval ends, drawn as error bars.
        chance: (P,) chance level, drawn as a dashed grey line.
        title, xlabel, ylabel: texts.

    Returns:
        A 6.5 x 4.5 inch figure (650 x 450 px when saved).

    Raises:
        ValueError: a curve's length differs from ``presses``.
    """
    x = np.asarray(presses, dtype=np.float64).reshape(-1)
    for name, y in curves.items():
        if np.asarray(y).reshape(-1).shape != x.shape:
            raise ValueError(f"curve {name!r} has {np.asarray(y).size} values for {len(x)} presses")
    with style():
        fig = new_figure(6.5, 4.5)
        ax = fig.add_subplot(1, 1, 1)
        colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]
        # Curves side by side around each P, so their error bars do not hide each other.
        dodge = 0.05 * (np.arange(len(curves)) - (len(curves) - 1) / 2)
        for i, (name, y) in enumerate(curves.items()):
            c = colours[i % len(colours)]
            yv = np.asarray(y, dtype=np.float64).reshape(-1)
            yerr = None
            if low is not None and high is not None and name in low and name in high:
                lo = np.asarray(low[name], dtype=np.float64).reshape(-1)
                hi = np.asarray(high[name], dtype=np.float64).reshape(-1)
                yerr = np.nan_to_num(np.stack([yv - lo, hi - yv]).clip(min=0.0))
            ax.errorbar(
                x + dodge[i], yv, yerr=yerr, color=c, marker="o", capsize=4, lw=2, label=name
            )
        if chance is not None:
            ch = np.asarray(chance, dtype=np.float64).reshape(-1)
            if ch.shape != x.shape:
                raise ValueError(f"chance has {ch.size} values for {len(x)} presses")
            ax.plot(x, ch, color="black", linestyle="--", lw=1.2, zorder=5, label="chance")
        ax.set_xticks(x, [str(int(v)) for v in x])
        ax.set_ylim(0.0, 1.02)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(axis="y", alpha=0.3)
        if curves:
            ax.legend(loc="best", frameon=False)
        fig.tight_layout()
    return fig
