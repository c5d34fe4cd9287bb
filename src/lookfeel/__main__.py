"""``python -m lookfeel`` is the ``lookfeel`` command."""

from lookfeel.cli import main

raise SystemExit(main())
