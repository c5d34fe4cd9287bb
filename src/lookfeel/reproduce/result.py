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
