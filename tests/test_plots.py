"""Figures: pixel sizes, determinism, what is drawn, and errors on inputs that do not fit."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_hex
from PIL import Image

from lookfeel.plots import (
    GlanceLook,
    GlanceRow,
    PickRow,
    confusion_figure,
    figure_png,
    glance_figure,
    pick_examples_figure,
    presses_figure,
    reliability_figure,
    save_figure,
)
from lookfeel.plots.examples import TRUE_COLOUR


def _size(png: bytes) -> tuple[int, int]:
    with Image.open(io.BytesIO(png)) as im:
        return im.size


def _confusion(n: int = 6) -> np.ndarray:
    rng = np.random.default_rng(0)
    m = rng.random((n, n)) + 3 * np.eye(n)
    return m / m.sum(axis=1, keepdims=True)


def test_confusion_figure_is_written_with_its_size_and_is_deterministic(tmp_path: Path):
    m = _confusion()
    labels = [str(i) for i in (1, 4, 2, 5, 3, 6)]
    groups = [0, 0, 1, 1, 2, 2]

    def make() -> bytes:
        fig = confusion_figure(m, labels, labels, row_groups=groups, col_groups=groups)
        return figure_png(fig)

    path = save_figure(
        confusion_figure(m, labels, labels, row_groups=groups, col_groups=groups),
        tmp_path / "sub" / "c.png",
    )
    assert path.is_file()
    with Image.open(path) as im:
        assert im.size == (750, 650)
    assert make() == make()


def test_confusion_figure_draws_cluster_blocks_and_values():
    m = _confusion()
    labels = [str(i) for i in range(6)]
    fig = confusion_figure(m, labels, labels, row_groups=[0, 0, 1, 1, 2, 2], col_groups=[0] * 6)
    ax = fig.axes[0]
    # Two white separators between three row groups, none between one column group.
    assert len([ln for ln in ax.lines if to_hex(ln.get_color()) == "#ffffff"]) == 2
    values = [t.get_text() for t in ax.texts]
    assert len(values) == 36 and f"{m[0, 0]:.2f}" in values
    assert fig.axes[-1].get_ylabel() == "mean P(match)"  # the colour bar is labelled


def test_confusion_figure_thins_ticks_for_many_fabrics():
    n = 100
    m = np.eye(n)
    labels = [str(i) for i in range(n)]
    fig = confusion_figure(m, labels, labels, max_ticks=40)
    ax = fig.axes[0]
    assert 20 <= len(ax.get_xticks()) <= 40
    assert not ax.texts  # too many cells to annotate
    assert _size(figure_png(fig)) == (750, 650)


def test_confusion_figure_rejects_labels_that_do_not_fit():
    with pytest.raises(ValueError, match="labels"):
        confusion_figure(np.eye(3), ["a", "b"], ["a", "b", "c"])
    with pytest.raises(ValueError, match="row_groups"):
        confusion_figure(np.eye(3), ["a", "b", "c"], ["a", "b", "c"], row_groups=[0, 1])
    with pytest.raises(ValueError, match="2-D"):
        confusion_figure(np.ones(3), ["a"], ["a"])


def test_presses_figure_size_lines_and_errors():
    p = [1, 2, 3]
    fig = presses_figure(
        p,
        {"touch → depth": [0.3, 0.4, 0.5], "touch → color": [0.2, 0.3, 0.35]},
        low={"touch → depth": [0.2, 0.3, 0.4]},
        high={"touch → depth": [0.4, 0.5, 0.6]},
        chance=[0.1, 0.1, 0.1],
    )
    ax = fig.axes[0]
    legend = {t.get_text() for t in ax.get_legend().get_texts()}
    assert legend == {"chance", "touch → depth", "touch → color"}
    assert ax.get_xlabel().startswith("presses")
    assert _size(figure_png(fig)) == (650, 450)
    with pytest.raises(ValueError, match="curve"):
        presses_figure(p, {"a": [0.1, 0.2]})
    with pytest.raises(ValueError, match="chance"):
        presses_figure(p, {"a": [0.1, 0.2, 0.3]}, chance=[0.1])


def test_reliability_figure_size_title_and_errors():
    edges = np.linspace(0, 1, 11)
    conf = np.full(10, np.nan)
    acc = np.full(10, np.nan)
    count = np.zeros(10)
    conf[[2, 8]], acc[[2, 8]], count[[2, 8]] = [0.25, 0.85], [0.2, 0.9], [5, 7]
    fig = reliability_figure(edges, conf, acc, count, ece=0.0417, title="R")
    assert "ECE = 0.042" in fig.axes[0].get_title()
    assert len(fig.axes[0].patches) == 2  # one bar per filled bin
    assert _size(figure_png(fig)) == (600, 650)
    with pytest.raises(ValueError, match="B \\+ 1 edges"):
        reliability_figure(edges, conf[:5], acc, count)


def _row(true_index: int, n: int = 10) -> PickRow:
    rng = np.random.default_rng(true_index)
    return PickRow(
        query_image=rng.integers(0, 255, (16, 16, 3), dtype=np.uint8),
        query_label="query: touch F1",
        candidate_images=[rng.random((16, 16)) for _ in range(n)],
        candidate_labels=[f"{i + 1}. F{i}\nD = {0.1 * i:.2f}" for i in range(n)],
        true_index=true_index,
    )


def test_pick_examples_frame_the_true_candidate_in_green():
    rows = [_row(0), _row(3), _row(9), _row(1)]
    fig = pick_examples_figure(rows)
    green = [ax for ax in fig.axes if to_hex(ax.spines["left"].get_edgecolor()) == TRUE_COLOUR]
    assert len(green) == len(rows)
    # The green frames sit in the true candidates' columns (query, gap, then candidates).
    columns = sorted(ax.get_subplotspec().colspan.start - 2 for ax in green)
    assert columns == sorted(r.true_index for r in rows)
    assert len(fig.axes) == len(rows) * 11
    assert _size(figure_png(fig)) == (1425, 740)


def test_pick_examples_reject_bad_rows():
    with pytest.raises(ValueError, match="no pick examples"):
        pick_examples_figure([])
    bad = _row(0)
    with pytest.raises(ValueError, match="out of range"):
        pick_examples_figure(
            [PickRow(bad.query_image, "q", bad.candidate_images, bad.candidate_labels, 10)]
        )
    with pytest.raises(ValueError, match="same number"):
        pick_examples_figure([_row(0), _row(0, n=5)])
    with pytest.raises(ValueError, match="image must be"):
        pick_examples_figure(
            [PickRow(np.zeros((4, 4, 2)), "q", bad.candidate_images, bad.candidate_labels, 0)]
        )


def _glance_row(true_at: int | None, feel: bool = True) -> GlanceRow:
    rng = np.random.default_rng(1)
    looks = [
        GlanceLook(
            name,
            [rng.random((16, 16)) for _ in range(5)],
            [f"{i + 1}. F{i}" for i in range(5)],
            [i == true_at for i in range(5)],
            note="the true one ranks 2",
        )
        for name in ("depth", "color")
    ]
    rows = [("thickness_mm", "1.2", "1.5"), ("stiffness", "2", "?")] if feel else []
    return GlanceRow(rng.random((16, 16, 3)), "query: touch F1", looks, rows, "Feels like")


def test_glance_figure_frames_the_true_fabric_and_shows_the_feel():
    fig = glance_figure([_glance_row(1), _glance_row(None), _glance_row(4)], "At a glance")
    green = [ax for ax in fig.axes if to_hex(ax.spines["left"].get_edgecolor()) == TRUE_COLOUR]
    assert len(green) == 2 * 2  # two looks of the two rows whose true fabric is shown
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert sum("thickness_mm" in t and "1.5" in t for t in texts) == 3
    assert _size(figure_png(fig)) == (1046, 1110)
    without = glance_figure([_glance_row(0, feel=False)], "At a glance")
    assert _size(figure_png(without)) == (756, 390)  # no feel column, one query


def test_glance_figure_rejects_bad_rows():
    with pytest.raises(ValueError, match="no glance queries"):
        glance_figure([], "t")
    row = _glance_row(0)
    with pytest.raises(ValueError, match="same number of look rows"):
        glance_figure([row, GlanceRow(row.query_image, "q", row.looks[:1])], "t")
    bad = GlanceLook("depth", row.looks[0].images, ["1."], [True])
    with pytest.raises(ValueError, match="images, labels and true flags differ"):
        glance_figure([GlanceRow(row.query_image, "q", [bad])], "t")


def test_a_figure_is_whole_pixels_whether_matplotlib_cuts_or_rounds():
    """QA (lowest versions): glance.png was 805 px wide with matplotlib < 3.11.1, 806 after:
    its 1.2 * (3 + 1.3) + 2.9 inches are 805.9999 px, which older versions cut, newer round."""
    from lookfeel.plots._figure import DPI, new_figure

    for inches in [1.2 * (3 + 1.3) + 2.9, 0.29 * 10, 3.3, 7.000001, 6.9999]:
        fig = new_figure(inches, 2.0)
        px = fig.get_figwidth() * DPI
        assert int(px) == round(px) == round(inches * DPI)  # matplotlib < 3.11.1 cuts
        assert fig.get_figheight() * DPI >= 200
