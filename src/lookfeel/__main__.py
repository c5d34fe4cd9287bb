"""``python -m lookfeel`` is the ``lookfeel`` command (importing this module runs nothing:
documentation tools and ``pytest --doctest-modules`` import every module)."""

from lookfeel.cli import run

if __name__ == "__main__":
    raise SystemExit(run())
