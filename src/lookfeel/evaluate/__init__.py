"""Evaluation workflow: score embeddings by the paper's section 5 and write a report.

    >>> result = evaluate_checkpoint("runs/x/checkpoints/last.pt", "data/", split="val")
    >>> result.metrics["touch_to_depth_top1"], result.metrics["touch_to_depth_top1_chance"]
    >>> write_report(result, "runs/x/eval")  # metrics.json, report.md, figures/*.png

Metric keys (flat floats, `EvalResult.metrics`), for every ordered modality pair
``{q}_to_{g}`` (same-modality pairs included):

- ``top{k}`` exact pick k of n, ``top{k}_sampled``/``_sampled_se`` the paper's sampled
  protocol, ``top{k}_released``/``_released_se`` the released code's variant (flag),
  ``top{k}_chance``;
- ``map``, ``recall{k}``, ``median_rank``, each with ``_chance``; ``_ci_low``/``_ci_high`` for
  the exact top-k, map, recall and median rank (bootstrap over test fabrics);
- ``n_queries``, ``n_fabrics``, ``n_effective``;
- calibration: ``c``, ``c_fitted``, ``c_fit_fabrics`` (the reference fabrics c was fitted on;
  NaN when not fitted), ``fabric_accuracy`` (+ ``_chance``), ``confidence``, ``ece``, ``nll``
  (+ ``_chance``, ``_se``: its standard error over the test fabrics), ``overconfident`` (1
  where the NLL is above chance's by more than twice that, or twice chance's);
- ``touch_to_{g}_presses{P}_*``: the pick and gallery keys for touch queries pooling P presses;
- ``property_{modality}_{label}_{knn|ridge}_{r2|spearman|mae|mae_chance|n_test}`` (``n_test``:
  the labelled test fabrics the scores are over; the report shows no Spearman over fewer than
  ``lookfeel.metrics.properties.MIN_SPEARMAN``), and ``property_{modality}_{label}_knn_k``: the
  neighbours the k-NN averaged (``probe_k``, at most half the reference fabrics);
- ``selected_on_split`` (a checkpoint's evaluation): 1 when the checkpoint is a run's
  ``best.pt`` and the test items include those it was chosen on (the run's validation
  fabrics, or held-out items), its scores there optimistic (said in the printed lines and the
  report); else 0;
- beside them (`lookfeel.evaluate.controls`, as ``lookfeel cv``): ``{q}_to_{q}_raw_pixels_top{k}``
  (raw pixels, pairs of one modality), ``{pair}_top{k}_swapped``/``_room`` (the background
  control, pairs with depth) and ``{pair}_top{k}_untouched`` (the untouched control, pairs
  with touch from press videos), each with ``_ci_low``/``_ci_high``.
"""

from lookfeel.embedding import PressPooler
from lookfeel.evaluate.core import evaluate_embeddings, max_pool_presses
from lookfeel.evaluate.embeddings_file import (
    EmbeddingFileError,
    EmbeddingSet,
    embedded_from_arrays,
    load_embeddings,
    save_embeddings,
)
from lookfeel.evaluate.from_checkpoint import (
    SPLITS,
    embed_checkpoint,
    evaluate_checkpoint,
    evaluate_embedding_file,
    pools_final_embedding,
)
from lookfeel.evaluate.report import ReportFiles, summary_lines, write_metrics, write_report
from lookfeel.evaluate.result import CalibrationResult, EvalResult, PickExample, PressCurve

__all__ = [
    "SPLITS",
    "CalibrationResult",
    "EmbeddingFileError",
    "EmbeddingSet",
    "EvalResult",
    "PickExample",
    "PressCurve",
    "PressPooler",
    "ReportFiles",
    "embed_checkpoint",
    "embedded_from_arrays",
    "evaluate_checkpoint",
    "evaluate_embedding_file",
    "evaluate_embeddings",
    "load_embeddings",
    "max_pool_presses",
    "pools_final_embedding",
    "save_embeddings",
    "summary_lines",
    "write_metrics",
    "write_report",
]
