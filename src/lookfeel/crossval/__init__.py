"""Fabric-disjoint cross-validation: train one config on every fold (and seed), score the fabrics
each fold held out, and put the model beside the raw-pixel baseline and chance.

The folds are ``train.folds`` cluster-stratified folds of ``train.fold_size`` fabrics (5 of 18:
five test sets chosen as the paper chose its 18); each must hold out at least 2 fabrics (or
objects: `MIN_HELD_OUT`), else cv refuses before training. Each run trains on the other
fabrics, is scored by its *last* checkpoint (no choice is made on the held-out fabrics), and
reports, per pair:

- pick 1 of 10 among the held-out fabrics (exact expectation), top-1 and top-3; touch pools
  ``presses`` presses of one fabric when that is above 1 (the Multi-input Net: default the
  config's ``data.presses``; each fabric's presses in seeded disjoint groups, embedded by the
  model's own press pooling, as `lookfeel evaluate` does), as a query and as the candidates
  of another sense's queries (the paper's Multi-input Net takes three presses wherever it
  embeds touch); touch to touch picks among single presses;
- the same for raw pixels (nearest neighbour on the preprocessed images; same-modality pairs);
- chance;
- for a model with a depth branch, the **background control** (on by default): the same
  queries scored again with every depth image's background replaced by another fabric's, the
  cloth kept (`lookfeel.data.background_swap.BackgroundControl`), for the model and for raw pixels
  (``model_swapped_top1``, ``raw_pixels_swapped_top1`` ...). A model that reads the cloth, not
  the room, scores the same; one that reads the capture session drops. When the rooms cannot
  be fitted the control is skipped and the summary says why (``background_control``). For
  registered depth also the **room control**: every depth image registered against the room
  fitted on its partner's own image, with no refit of a composite (``model_room_top1``,
  ``raw_pixels_room_top1`` ...): another session's registration of the same cloth;
- for touch recorded as press videos, the **untouched control** (always on): the same queries
  with every press replaced by a moment of its video with no contact
  (`lookfeel.data.touch_control.UntouchedControl`; ``model_untouched_top1``,
  ``raw_pixels_untouched_top1`` ...). The sensor's own light and drift identify a recording
  session; a model that reads the contact falls to chance there;
- when the fabrics have labels, the same queries matched in **label space**
  (``model_labels_top1``, `lookfeel.metrics.label_space`): each modality's embeddings mapped
  onto the labels by a ridge fitted on the run's training fabrics only, a query matched to the
  gallery item whose predicted labels are nearest;
- for pairs of two modalities, the same queries matched through a **cross-modal map**
  (``model_mapped_top1``, `lookfeel.metrics.cross_map`; no labels needed): each modality's
  embeddings carried into the other's by linear maps fitted on the run's training fabrics.

Over runs, each number gets its mean, its spread over runs, and a 95% interval from a bootstrap
that resamples the held-out fabrics (all their queries together); with ``n_boot`` 0
(``--n-boot 0``) none is drawn: the numbers stand alone, their intervals null in ``cv.json``.
A pair none of whose queries has an item of its own fabric to find (touch to touch when every
held-out fabric's presses all went into its query) gets no numbers but the reason
(``not_scored`` in ``cv.json``). Each held-out fabric (or object) also gets its own top-1 over
every query it made in every run, beside raw pixels (``per_item`` in ``cv.json``; the worst few
in ``cv.md``): which items the model cannot tell apart.
Physical properties are predicted from the fabric-mean embeddings of the held-out fabrics by a
ridge probe fitted on the training fabrics of the same fold (R^2 and Spearman per label), again
beside raw pixels and, with depth and the background control on, beside the **room alone**
(`RoomProbe`: the same probe on each raw depth image's background pixels, no cloth). Where the
background follows the labels (as when each fabric was captured in its own session), the room
predicts them, and a model's probe is only as good as its lead over the room's.
Each run keeps every held-out fabric's prediction (``held_out`` in ``result.json``): a seed's
folds together predict each held-out fabric once, and R^2 and Spearman over them all get a 95%
interval resampling fabrics (the mean over seeds and the interval of that mean, as the class
tables), beside chance: each fold's training mean predicted for its held-out fabrics. Pooled
over folds, chance is not 0 but below it, R^2 and Spearman alike: a fold's training mean lies
away from that fold's held-out fabrics (a known bias of cross-validated R^2 and correlation:
chance's Spearman is -1 where each fold holds out one fabric), and the model's pooled scores
carry the same bias, so they are read against chance's, not against 0. Over fewer than 10 fabrics
(`lookfeel.reproduce.report.MIN_FABRICS`, reproduce's rule) ``cv.md`` says the intervals say
little. In ``cv.json``, per modality, method and label under ``properties``: ``pooled`` holds
what ``cv.md`` shows (``pooled.r2.mean`` and ``pooled.r2.ci95``, likewise ``spearman``,
``chance_r2``, ``chance_spearman``; ``pooled.per_seed_held_out``, the fabrics each seed's
numbers are over; ``pooled.runs``, the runs that predicted them); ``r2`` and ``spearman``
(with ``r2_std``, ``spearman_std``) are the mean and spread of each run's own score, over its
own held-out fabrics, and ``per_run`` lists those scores run by run.
For a model with class heads (``model.class_heads``: hardness 0/1/2, material ...), each held-out
press's class is read from the heads, one press at a time and with every press of an object
pooled, beside a 5-nearest-neighbour probe on the embeddings and on raw pixels and the training
majority class: accuracy (95% interval resampling held-out objects) and macro-F1.

What cv writes is strict JSON: a number no run could score is ``null``
(`lookfeel.atomic.finite_or_null`), and ``cv.md`` says ``n/a`` and why.

Every run lives in ``OUT/seed{S}-fold{F}/`` and its scores in ``result.json`` there; a rerun
skips finished runs and resumes an interrupted one, so a killed cross-validation loses at most
the steps since a run's last checkpoint.

The code: `lookfeel.crossval.run` (the folds, each run's config, `cross_validate`),
`lookfeel.crossval.score` (one run's scores: `score_checkpoint`, `RoomProbe`),
`lookfeel.crossval.summary` (the runs pooled into ``cv.json``) and `lookfeel.crossval.report`
(``cv.md``: `format_cv_summary`).
"""

from lookfeel.crossval.report import WORST_ITEMS, format_cv_summary
from lookfeel.crossval.run import MIN_HELD_OUT, REPORT, RESULT, SUMMARY, cross_validate
from lookfeel.crossval.score import RoomProbe, score_checkpoint
from lookfeel.crossval.summary import (
    CALIBRATION_BINS,
    CLASS_METHODS,
    CONTROL_SEED,
    MIN_SPEARMAN,
    PER_ITEM_METHODS,
)

__all__ = [
    "CALIBRATION_BINS",
    "CLASS_METHODS",
    "CONTROL_SEED",
    "MIN_HELD_OUT",
    "MIN_SPEARMAN",
    "PER_ITEM_METHODS",
    "REPORT",
    "RESULT",
    "SUMMARY",
    "WORST_ITEMS",
    "RoomProbe",
    "cross_validate",
    "format_cv_summary",
    "score_checkpoint",
]
