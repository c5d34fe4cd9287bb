"""benchmarks/bench_depth_swap.py: where a composite's cloth differs from the image's own."""

from __future__ import annotations

import numpy as np
from benchmarks.bench_depth_swap import mask_changes


def test_mask_changes_counts_the_lost_cloth_by_height_and_by_edge() -> None:
    # A 12 x 12 cloth in a 20 x 20 image: its bottom 3 rows lie on the floor (10 mm above
    # it), the rest hangs (100 mm).
    own = np.zeros((20, 20), np.float32)
    own[4:16, 4:16] = 100.0
    own[13:16, 4:16] = 10.0
    above_floor = own.copy()
    comp = own.copy()
    comp[13:16, 4:16] = 0.0  # the foot on the floor is lost: 36 pixels
    comp[4, 8] = 0.0  # one rim pixel of the hanging cloth
    comp[2, 2] = 50.0  # one pixel gained
    out = mask_changes([own], [comp], [above_floor])
    assert out["own_cloth"] == 144
    assert out["lost"] == 37
    assert out["gained"] == 1
    assert out["lost_by_height"] == {"0-15 mm": 36, "15-30 mm": 0, "30-60 mm": 0, "60-inf mm": 1}
    by_edge = out["lost_by_edge"]
    assert sum(by_edge.values()) == 37
    # Rim pixels (next to the background): row 15 (12), the foot's two side columns in rows
    # 13-14 (4), and the hanging rim pixel: 17; the rest lie 2-3 pixels in.
    assert by_edge["0-1.5 px"] == 17
    assert by_edge["1.5-3.5 px"] == 20
    assert out["lost_fraction"]["p50"] == round(37 / 144, 4)


def test_mask_changes_of_an_unchanged_composite_loses_nothing() -> None:
    own = np.zeros((8, 8), np.float32)
    own[2:6, 2:6] = 40.0
    out = mask_changes([own, own], [own.copy(), own.copy()], [own, own])
    assert (out["lost"], out["gained"]) == (0, 0)
    assert sum(out["lost_by_height"].values()) == 0
    assert out["lost_fraction"] == {"p50": 0.0, "p75": 0.0, "p90": 0.0}
