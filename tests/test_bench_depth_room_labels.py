"""benchmarks/bench_depth_room_labels.py: the room alone as a property probe."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from benchmarks.bench_depth_room_labels import measure

from ._scene import write_scene_dataset


@pytest.fixture(scope="module")
def rooms(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """8 fabrics, each in its own session: the room moves 3 mm a fabric; the drapes vary alike
    in every session. Thickness grows with the fabric's number (as the room moves), stretchiness
    alternates (the room cannot tell it)."""
    return write_scene_dataset(tmp_path_factory.mktemp("rooms") / "data", 8, 2, 32, 3.0, 0.3)


def _run(cv: Path, train: list[int], val: list[int], model_r2: float) -> None:
    run = cv / "seed0-fold0"
    run.mkdir(parents=True)
    (run / "split.json").write_text(json.dumps({"train": train, "val": val}), encoding="utf-8")
    labels = ("thickness_mm", "density", "stiffness", "stretchiness")
    model = {c: {"r2": model_r2} for c in labels}
    (run / "result.json").write_text(
        json.dumps({"properties": {"depth": {"model": model}}}), encoding="utf-8"
    )


def test_the_room_predicts_a_label_that_follows_the_session_and_not_one_that_does_not(
    rooms: Path, tmp_path: Path
):
    _run(tmp_path / "cv", [1, 2, 4, 5, 7, 8], [3, 6], 0.25)
    out = measure(tmp_path / "cv", rooms)
    assert out["runs"] == 1 and out["background_pixels"] > 0
    r2 = out["mean_r2"]
    assert r2["thickness_mm"]["room"] > 0.8  # 0.5 mm a fabric, as the room moves
    assert r2["stretchiness"]["room"] < 0.2  # odd or even fabric: not the room's
    assert r2["thickness_mm"]["model"] == 0.25  # the run's own probe, read back beside it


def test_one_room_for_every_session_predicts_nothing(tmp_path: Path):
    one_room = write_scene_dataset(tmp_path / "data", 8, 2, 32, 0.0, 0.3)
    _run(tmp_path / "cv", [1, 2, 4, 5, 7, 8], [3, 6], 0.25)
    r2 = measure(tmp_path / "cv", one_room)["mean_r2"]
    assert all(r2[c]["room"] < 0.2 for c in r2)


def test_a_cv_folder_without_runs_is_one_clear_error(rooms: Path, tmp_path: Path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match="no finished runs"):
        measure(tmp_path / "empty", rooms)
