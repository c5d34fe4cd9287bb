"""What made a result: the software versions every output records beside its numbers.

A checkpoint, ``cv.json``, ``reproduce``'s ``results.json`` and ``evaluate``'s ``metrics.json``
keep `software_versions` so that a number read months later says which lookfeel, PyTorch and
Python gave it (the same seed gives the same numbers only with the same software, machine and
number of CPU threads: README, "Training").
"""

from __future__ import annotations

import platform


def software_versions() -> dict[str, str]:
    """``{"lookfeel": ..., "torch": ..., "python": ...}``, the versions running now."""
    import torch

    from lookfeel import __version__

    return {
        "lookfeel": __version__,
        "torch": str(torch.__version__),
        "python": platform.python_version(),
    }
