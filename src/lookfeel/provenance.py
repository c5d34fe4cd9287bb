"""What made a result: the software versions every output records beside its numbers.

A checkpoint, ``cv.json``, ``reproduce``'s ``results.json`` and ``evaluate``'s ``metrics.json``
(in its ``info``) keep `software_versions` so that a number read months later says which
lookfeel, PyTorch and Python gave it (the same seed gives the same numbers only with the same
software, machine and number of CPU threads: README, "Training").
"""

from __future__ import annotations

import platform

__all__ = ["plugin_modules_of", "software_versions"]


def software_versions() -> dict[str, str]:
    """``{"lookfeel": ..., "torch": ..., "python": ...}``, the versions running now."""
    import torch

    from lookfeel import __version__

    return {
        "lookfeel": __version__,
        "torch": str(torch.__version__),
        "python": platform.python_version(),
    }


def plugin_modules_of(backbone: str, loss_kind: str) -> list[str]:
    """The modules, other than lookfeel's own and a script's ``__main__``, that registered
    ``backbone`` and ``loss_kind`` in this process: what a checkpoint records so that loading
    it where they are not loaded can name them (`lookfeel.checkpoint.load_model`)."""
    from lookfeel.losses.combined import PAIR_LOSSES
    from lookfeel.models.registry import BACKBONES

    found = [dict.get(BACKBONES, backbone), PAIR_LOSSES.get(loss_kind)]
    modules = [getattr(x, "__module__", None) for x in found if x is not None]
    return sorted({m for m in modules if m and m != "__main__" and not m.startswith("lookfeel.")})
