"""``python -m lookfeel`` is the ``lookfeel`` command."""

from lookfeel.cli import run

raise SystemExit(run())
