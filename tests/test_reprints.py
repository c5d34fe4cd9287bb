"""Re-printed photos (``reprints/``, ``data.color_reprints``): training draws a photo's renders
under other prints instead of the photo; evaluation, and a dataset without them, read the
photos."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.cli import main
from lookfeel.config import DataConfig, RunConfig, load_config
from lookfeel.data import ImageLoader, ImageStore, scan
from lookfeel.data.files import ImageError
from lookfeel.modality import REPRINTS, Modality, reprint_path
from lookfeel.train import train

from ._tiny import write_rgb, write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


def _with_reprints(root: Path, n: int) -> Path:
    """Give every photo ``n`` renders, each a colour no photo has (fabric id + 100 r)."""
    for photo in sorted((root / "color").iterdir()):
        fabric, k = (int(x) for x in photo.stem[1:].split("_"))
        for r in range(1, n + 1):
            write_rgb(reprint_path(photo, r), fabric + 100 * r, k)
    return root


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = write_tiny_dataset(tmp_path_factory.mktemp("reprints") / "data", fabrics=6, drapes=2)
    return _with_reprints(root, 2)


def _draws(root: Path, reprints: int, seeds: int = 20) -> tuple[list[int], list[int]]:
    """The colour store's rows of each photo's image, and the rows training drew over seeds."""
    loader = ImageLoader(DataConfig(image_size=16, color_reprints=reprints))
    items = scan(root).items(Modality.COLOR)
    store = ImageStore(loader, items, views=True)
    rows = torch.tensor(store.rows(Modality.COLOR, items))
    drawn = [
        int(r)
        for s in range(seeds)
        for r in store.draw_views(Modality.COLOR, rows, np.random.default_rng(s))
    ]
    return rows.tolist(), drawn


def test_training_draws_every_reprint_and_never_the_photo(world: Path) -> None:
    images, drawn = _draws(world, reprints=2)
    assert images == [3 * i for i in range(12)]  # each photo, then its two renders
    assert set(drawn) == {r + k for r in images for k in (1, 2)}
    assert _draws(world, reprints=1)[1] == [r + 1 for _ in range(20) for r in range(0, 24, 2)]
    images, drawn = _draws(world, reprints=0)
    assert set(drawn) == set(images) == set(range(12))


def test_a_drawn_reprint_is_the_render_on_disk(world: Path) -> None:
    loader = ImageLoader(DataConfig(image_size=16, color_reprints=2))
    photo = scan(world).items(Modality.COLOR)[0]
    views = loader.views(photo)
    assert views.shape == (3, 16, 16, 3)
    assert np.array_equal(views[0], loader.array(photo.path, Modality.COLOR))
    assert np.array_equal(
        views[2],
        ImageLoader(DataConfig(image_size=16)).array(reprint_path(photo.path, 2), Modality.COLOR),
    )
    assert not np.array_equal(views[1], views[0])


def test_a_missing_reprint_is_one_line_naming_it(world: Path, tmp_path: Path, capsys) -> None:
    root = tmp_path / "data"
    shutil.copytree(world, root)
    for gone in (root / REPRINTS).glob("*_2_r2.png"):  # of every fabric, trained on or not
        gone.unlink()
    loader = ImageLoader(DataConfig(image_size=16, color_reprints=2))
    photo = next(it for it in scan(root).items(Modality.COLOR) if it.path.name == "F0003_2.png")
    with pytest.raises(ImageError, match="F0003_2_r2.png: missing: data.color_reprints = 2"):
        loader.views(photo)
    assert (
        main(
            [
                "train",
                "--config",
                str(TINY),
                "--data",
                str(root),
                "--out",
                str(tmp_path / "run"),
                "--set",
                "data.color_reprints=2",
                "--set",
                "train.steps=2",
            ]
        )
        == 1
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "_2_r2.png: missing" in err[0] and "--reprints 2" in err[0]
    assert "its folder holds 1 " in err[0] and "data.color_reprints=1 or fewer" in err[0]


def _weights(run: Path) -> dict[str, torch.Tensor]:
    return torch.load(run / "checkpoints" / "last.pt", weights_only=True)["model"]


def test_reprints_change_training_and_a_dataset_without_them_trains_on_its_photos(
    world: Path, tmp_path: Path
) -> None:
    plain = write_tiny_dataset(tmp_path / "plain", fabrics=6, drapes=2)
    steps = "train.steps=4"
    photos = _weights(train(load_config(RunConfig, TINY, [steps]), plain, tmp_path / "a").run_dir)
    with pytest.warns(UserWarning, match=f"has no {REPRINTS}/ folder"):
        asked = train(
            load_config(RunConfig, TINY, [steps, "data.color_reprints=1"]), plain, tmp_path / "b"
        )
    same = _weights(asked.run_dir)
    assert [k for k in photos if not torch.equal(photos[k], same[k])] == []

    reprinted = _weights(
        train(
            load_config(RunConfig, TINY, [steps, "data.color_reprints=1"]), world, tmp_path / "c"
        ).run_dir
    )
    unprinted = _weights(
        train(load_config(RunConfig, TINY, [steps]), world, tmp_path / "d").run_dir
    )
    changed = [k for k in reprinted if not torch.equal(reprinted[k], unprinted[k])]
    assert any(k.startswith("branches.color.") for k in changed)  # the renders were trained on


def test_data_info_counts_the_reprints(world: Path, tmp_path: Path) -> None:
    from lookfeel.data.summary import format_summary

    assert "; 24 re-printed renders in reprints/ (training views)" in format_summary(scan(world))
    plain = write_tiny_dataset(tmp_path / "plain", fabrics=2, drapes=1)
    assert "re-printed" not in format_summary(scan(plain))


def test_the_recipe_chooser_reads_as_many_reprints_as_every_photo_has(
    world: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """QA: `lookfeel synth --reprints 1` then `lookfeel train --data world` (no --config) failed
    on the recipe's 4 renders of a photo (data.color_reprints: 4); the chooser adapted only to
    a world without reprints/. It reads the renders every photo has (the fewest any has), none
    with a warning naming a photo that has none, and never a number the user set."""
    import argparse

    from lookfeel.cli._args import run_config_source

    def chosen(root: Path, *sets: str) -> tuple[int, str]:
        args = argparse.Namespace(data=root, config=None, set=list(sets))
        path, overrides = run_config_source(args)
        assert path.name == "synth_cross.yaml"
        return load_config(RunConfig, path, overrides).data.color_reprints, capsys.readouterr().err

    root = tmp_path / "one"
    shutil.copytree(world, root)
    for second in (root / REPRINTS).glob("*_r2.png"):
        second.unlink()
    n, err = chosen(root)
    assert n == 1 and "reprints/ holds 1 re-printed render of each photo, not the recipe's 4" in err
    photo = scan(root).items(Modality.COLOR)[0]
    views = ImageLoader(DataConfig(image_size=16, color_reprints=n)).views(photo)
    assert len(views) == 2  # the photo, then its one render: training reads them
    assert chosen(root, "data.color_reprints=3")[0] == 3  # the user's own number is kept

    n, err = chosen(world)  # 2 of each photo (the fewest): the recipe's 4 are not there
    assert n == 2 and "holds 2 re-printed renders of each photo" in err
    (root / REPRINTS / "F0002_1_r1.png").unlink()  # of one photo, none
    with pytest.warns(UserWarning) as said:
        n, err = chosen(root)
    assert n == 0 and "trained on the photos (data.color_reprints=0)" in err
    assert [str(w.message).split(": ")[:2] for w in said] == [
        [f"{root / REPRINTS}", "holds no re-printed render of F0002_1.png (no F0002_1_r1.png)"]
    ]
    shutil.rmtree(root / REPRINTS)
    n, err = chosen(root)
    assert n == 0 and "no reprints/ folder: trained on the photos" in err
