"""The paper's published numbers, as data, each cited by its table.

All are top-k accuracies of "pick 1 of 10" (paper section 5.1), on the 18 test fabrics, except
Table 4's "seen" side: the held-out share of the training fabrics' own images. The
paper names a matching task ``A2B``; we read it as query modality A matched against candidates
of modality B (``a_to_b``): Table 3 lists both ``Gel2Color`` and ``Color2Gel`` with different
values, so the order matters, and section 5.1 describes Figure 7 as a GelSight input matched to
depth or colour candidates. ``Gel`` is touch. Figure 7's bar heights are not given in the text,
so they are not here.
"""

from __future__ import annotations

__all__ = ["MODEL_COLUMNS", "PAPER_FINDINGS", "TABLE_1", "TABLE_2", "TABLE_3", "TABLE_4"]

MODEL_COLUMNS = ("flat", "cross_modal", "auxiliary", "multi_input")
"""Columns of Tables 1 and 2 (and the models of Figure 7), by config name."""

TABLE_1: dict[str, dict[str, float]] = {
    # Table 1: "the average top 1 precision on test set for the pick 1 from 10 experiment of
    # matching other modalities".
    "depth_to_touch": {
        "flat": 0.3063,
        "cross_modal": 0.4292,
        "auxiliary": 0.4318,
        "multi_input": 0.4576,
    },
    "color_to_touch": {
        "flat": 0.2681,
        "cross_modal": 0.3742,
        "auxiliary": 0.4022,
        "multi_input": 0.4124,
    },
    "depth_to_color": {
        "flat": 0.4133,
        "cross_modal": 0.4329,
        "auxiliary": 0.4141,
        "multi_input": 0.4417,
    },
    "color_to_depth": {
        "flat": 0.4050,
        "cross_modal": 0.4240,
        "auxiliary": 0.4070,
        "multi_input": 0.4306,
    },
}

TABLE_2: dict[str, dict[str, float]] = {
    # Table 2: top-1, "matching a single modality".
    "depth_to_depth": {
        "flat": 0.6030,
        "cross_modal": 0.6265,
        "auxiliary": 0.6224,
        "multi_input": 0.6459,
    },
    "color_to_color": {
        "flat": 0.7941,
        "cross_modal": 0.7831,
        "auxiliary": 0.7968,
        "multi_input": 0.8247,
    },
    "touch_to_touch": {
        "flat": 0.8025,
        "cross_modal": 0.7672,
        "auxiliary": 0.8090,
        "multi_input": 0.9351,
    },
}

TABLE_3: dict[str, dict[str, float]] = {
    # Table 3: top-1 "before and after data augmentation on the color images".
    "touch_to_color": {
        "cross_modal": 0.3954,
        "cross_modal_aug": 0.4359,
        "multi_input": 0.4303,
        "multi_input_aug": 0.4937,
    },
    "color_to_touch": {
        "cross_modal": 0.3742,
        "cross_modal_aug": 0.4088,
        "multi_input": 0.4124,
        "multi_input_aug": 0.4264,
    },
    "depth_to_color": {
        "cross_modal": 0.4329,
        "cross_modal_aug": 0.4674,
        "multi_input": 0.4417,
        "multi_input_aug": 0.4924,
    },
    "color_to_depth": {
        "cross_modal": 0.4240,
        "cross_modal_aug": 0.4607,
        "multi_input": 0.4306,
        "multi_input_aug": 0.4624,
    },
}

TABLE_4: dict[str, dict[str, float]] = {
    # Table 4: depth-to-depth, "seen fabrics" (the 20% held-out items of the training fabrics)
    # and "novel fabrics" (the 18 test fabrics).
    "snn_depth": {"seen_top1": 0.482, "seen_top3": 0.660, "novel_top1": 0.554, "novel_top3": 0.729},
    "cross_modal_depth_touch": {
        "seen_top1": 0.608,
        "seen_top3": 0.786,
        "novel_top1": 0.606,
        "novel_top3": 0.786,
    },
}

PAPER_FINDINGS = {
    "above_chance": "every network matches touch to depth and colour above chance (section 5.1)",
    "model_order": "Multi-input > Auxiliary > Cross-modal > Flat on touch-to-depth (Figure 7)",
    "depth_beats_color": "touch matches depth better than colour (Figure 7, Table 1)",
    "within_beats_across": "matching within one modality is much higher than across (Tables 1-2)",
    "augmentation_helps_color": "colour augmentation improves the pairs with colour (Table 3)",
    "touch_helps_depth": "joint training with touch improves depth-to-depth (Table 4)",
}
"""The paper's claims that `lookfeel reproduce` checks on our numbers."""
