"""Figures of evaluation results: functions of arrays that return matplotlib figures.

Built on the Agg canvas without pyplot (no global state); `save_figure` writes a PNG of
exactly ``figsize * 100`` pixels, atomically, and the same arrays give the same bytes.

- `confusion_figure`: fabric or cluster confusion, groups outlined (paper Figure 8).
- `glance_figure`: a touch query, its nearest drapes and photos, what it feels like vs truth.
- `pick_examples_figure`: a query and its candidates by distance, the true one green (Figure 6).
- `presses_figure`: accuracy against pooled touch presses (the Multi-input Net).
- `reliability_figure`: accuracy against confidence of ``P ∝ exp(-c D^2)`` (section 5.2).
"""

from lookfeel.plots._figure import DPI, figure_png, save_figure
from lookfeel.plots.confusion import confusion_figure
from lookfeel.plots.examples import PickRow, pick_examples_figure
from lookfeel.plots.glance import GlanceLook, GlanceRow, glance_figure
from lookfeel.plots.presses import presses_figure
from lookfeel.plots.reliability import reliability_figure

__all__ = [
    "DPI",
    "GlanceLook",
    "GlanceRow",
    "PickRow",
    "confusion_figure",
    "figure_png",
    "glance_figure",
    "pick_examples_figure",
    "presses_figure",
    "reliability_figure",
    "save_figure",
]
