"""benchmarks/bench_synth_depth_inputs.py: the summary of registered depth inputs."""

from __future__ import annotations

import numpy as np
import pytest
from benchmarks.bench_synth_depth_inputs import BANDS, summarise


def test_summary_reads_widths_heights_and_spreads_of_known_drapes() -> None:
    """Two fabrics, two drapes each: rectangles of known width and height in the top half.
    Widths and heights per band, the cloth share and its spread between and within fabrics
    come out as drawn; the bottom half, with no cloth, reads 0."""
    size = 64
    x = np.zeros((4, size, size), np.float32)
    widths = [10, 12, 30, 34]
    for i, w in enumerate(widths):
        x[i, : size // 2, :w] = 100.0 + 10 * i
    fabric = np.array([1, 1, 2, 2])
    tops = np.array([[250.0, 300.0], [260.0, 300.0], [250.0, 310.0], [260.0, 310.0]])
    caps = np.array([0.0, 6.0, 5.0, 8.0])
    shift = np.array([[0.0, 0.0], [1.0, 6.0], [-2.0, 5.0], [0.5, 8.0]])
    s = summarise({"x": x, "fabric": fabric, "tops": tops, "cap_rows": caps, "top_shift": shift})
    assert s["images"] == 4 and s["fabrics"] == 2
    assert s["width_by_row"][: BANDS // 2] == [pytest.approx(np.mean(widths))] * (BANDS // 2)
    assert s["width_by_row"][BANDS // 2 :] == [0.0] * (BANDS // 2)
    # Median over cloth pixels: 10 + 12 at 100 and 110 mm, 30 at 120, 34 at 130.
    assert s["height_by_row"][: BANDS // 2] == [120.0] * (BANDS // 2)
    share = np.array(widths) * (size // 2) / size**2
    assert s["cloth_share"]["median"] == pytest.approx(np.median(share), abs=1e-3)
    between = np.std([share[:2].mean(), share[2:].mean()])
    assert s["cloth_share"]["between_fabrics_sd"] == pytest.approx(between, abs=1e-3)
    within = np.sqrt(np.mean([share[:2].var(), share[2:].var()]))
    assert s["cloth_share"]["within_fabric_sd"] == pytest.approx(within, abs=1e-3)
    # The first rows' top varies within each fabric (10 mm apart), the highest row's between.
    assert s["top_mm"]["first_rows"]["within_fabric_sd"] == pytest.approx(5.0)
    assert s["top_mm"]["first_rows"]["between_fabrics_sd"] == pytest.approx(0.0)
    assert s["top_mm"]["highest_row"]["within_fabric_sd"] == pytest.approx(0.0)
    assert s["top_mm"]["highest_row"]["between_fabrics_sd"] == pytest.approx(5.0)
    # Three of the four images have a cap; the top moves down by the cap's rows.
    assert s["cap"]["images_with_cap"] == pytest.approx(0.75)
    assert s["cap"]["rows_median_p10_p90"][0] == pytest.approx(5.5)
    assert s["cap"]["top_down_px_median_p10_p90"][0] == pytest.approx(5.5)
    assert s["cap"]["top_sideways_px_abs_p90"] == pytest.approx(np.percentile([0, 1, 2, 0.5], 90))
