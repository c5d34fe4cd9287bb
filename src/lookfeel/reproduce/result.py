"""What a reproduction produced (shared by `lookfeel.reproduce.run` and its report)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["ReproduceResult"]


@dataclass
class ReproduceResult:
    """What a reproduction produced."""

    out: Path
    report: Path
    results: dict[str, Any] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    findings: dict[str, dict[str, Any]] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    """``results.json``'s ``meta``: the dataset folder (``data_root``), budget and settings;
    ``only`` (the experiments asked for, None: all) and ``earlier`` (those not asked for,
    reported from finished runs found in ``out``); ``minutes`` (this reproduction's) and
    ``runs`` with ``run_minutes`` (the runs behind the results and their own time, training
    and scoring, summed); ``n_boot``, ``workers`` (as asked, 0: the default) and
    ``workers_resolved`` (how many trained at once), ``data_fingerprint``
    (`lookfeel.data.Catalog.fingerprint`) and ``software``
    (`lookfeel.provenance.software_versions`)."""
