"""One way to make and save a figure: the Agg canvas, fixed size and DPI, one style.

Figures are built with the object-oriented API (`matplotlib.figure.Figure` on an Agg canvas),
never through pyplot, so nothing global is touched and plotting is safe in threads and servers.
A figure's pixel size is ``figsize * DPI`` exactly (no tight bounding box), and the same
arrays give the same PNG bytes.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from lookfeel.atomic import atomic_write_bytes

DPI = 100
"""Dots per inch of every saved figure: a (w, h)-inch figure is (100 w, 100 h) pixels."""

_STYLE: dict[Any, Any] = {
    "font.size": 10.0,
    "axes.titlesize": 11.0,
    "axes.labelsize": 10.0,
    "xtick.labelsize": 9.0,
    "ytick.labelsize": 9.0,
    "legend.fontsize": 9.0,
    "figure.titlesize": 12.0,
    "axes.spines.top": False,
    "axes.spines.right": False,
}


@contextmanager
def style() -> Iterator[None]:
    """The plots' style (readable font sizes), applied while a figure is built."""
    with matplotlib.rc_context(_STYLE):
        yield


def new_figure(width_in: float, height_in: float) -> Figure:
    """A figure of ``width_in`` x ``height_in`` inches on an Agg canvas (no pyplot), each side
    made a whole number of pixels (`_whole_pixels`)."""
    fig = Figure(figsize=(_whole_pixels(width_in), _whole_pixels(height_in)), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _whole_pixels(inches: float) -> float:
    """``inches`` rounded to whole pixels at `DPI`, a hair above them: 8.06 in is 805.9999 px in
    floating point, which matplotlib before 3.11.1 cut to 805 px and later versions round to
    806; 806.001 px is 806 for both."""
    return (round(inches * DPI) + 1e-3) / DPI


def figure_png(fig: Figure) -> bytes:
    """The figure as PNG bytes, ``figsize * DPI`` pixels, without a timestamp."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    return buf.getvalue()


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write the figure as a PNG atomically (its folder is created).

    Returns:
        The path written.
    """
    return atomic_write_bytes(path, figure_png(fig))
