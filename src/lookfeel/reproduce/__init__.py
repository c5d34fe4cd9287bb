"""`reproduce`: the paper's experiments as configs, run on data, reported beside its numbers."""

from lookfeel.reproduce.paper import PAPER_FINDINGS, TABLE_1, TABLE_2, TABLE_3, TABLE_4
from lookfeel.reproduce.result import ReproduceResult
from lookfeel.reproduce.run import BUDGETS, EXPERIMENTS, Experiment, headline, reproduce

__all__ = [
    "BUDGETS",
    "EXPERIMENTS",
    "PAPER_FINDINGS",
    "TABLE_1",
    "TABLE_2",
    "TABLE_3",
    "TABLE_4",
    "Experiment",
    "ReproduceResult",
    "headline",
    "reproduce",
]
