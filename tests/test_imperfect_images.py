"""QA pointed lookfeel at imperfect folders and three things were accepted without a word: a
greyscale photo or GelSight frame among colour ones, an all-zero depth PNG trained on as a blank
drape, and images of 1x1 px. `data check` now warns of the first and third, and every run that
decodes images warns once of the second (`BlankDepthWarning`)."""

from __future__ import annotations

import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.cli import run as cli_run
from lookfeel.config import DataConfig
from lookfeel.data import check_dataset, scan
from lookfeel.data.check import MIN_SIDE
from lookfeel.data.images import BlankDepthWarning, ImageLoader
from lookfeel.modality import Modality

from ._library import TINY
from ._tiny import write_tiny_dataset

COLOUR_WHY = (
    "(a photo's colours are part of what the colour network reads, and a grey image gives the "
    "same value in each channel)"
)
TOUCH_WHY = (
    "(GelSight's and DIGIT's colours carry the surface's slopes, and a grey frame gives the "
    "same value in each channel)"
)


def _warned(root: Path, word: str) -> list[tuple[str, str]]:
    """``data check``'s warnings of ``root`` whose message holds ``word``: (file name, text)."""
    said = check_dataset(root, workers=1).warnings
    return [(p.path.name if p.path else "", p.message) for p in said if word in p.message]


def _grey_rgb(path: Path, size: tuple[int, int] = (24, 24)) -> None:
    """A grey image stored as colour: red, green and blue equal everywhere (not constant)."""
    w, h = size
    g = np.random.default_rng(zlib.crc32(path.name.encode())).integers(0, 255, (h, w), np.uint8)
    Image.fromarray(np.repeat(g[..., None], 3, axis=-1)).save(path)


# ---- grey still images among colour ones ---------------------------------------------------


def test_grey_colour_and_touch_images_among_colour_ones_are_a_warning_per_modality(
    tiny_dataset: Path,
):
    root = tiny_dataset
    assert _warned(root, "no colour") == []
    # a greyscale photo (mode L): read as colour with red, green and blue equal
    photo = root / "color" / "F0002_1.png"
    Image.fromarray(np.full((24, 24), 90, np.uint8)).convert("L").save(photo)
    assert Image.open(photo).mode == "L"
    assert _warned(root, "no colour") == [
        (
            "F0002_1.png",
            "this colour image has no colour (grey), unlike the other 17: a model reads it "
            f"unlike them {COLOUR_WHY}; use a colour original, or leave it out",
        )
    ]
    # grey frames stored as colour in touch/, and three more grey photos (one with alpha)
    for name in ("F0003_fold_01_300.png", "F0003_fold_02_300.png"):
        _grey_rgb(root / "touch" / name, (32, 24))
    for name in ("F0004_1.png", "F0004_2.png"):
        _grey_rgb(root / "color" / name)
    Image.fromarray(np.full((24, 24), 7, np.uint8)).convert("LA").save(
        root / "color" / "F0005_1.png"
    )
    assert _warned(root, "no colour") == [
        (
            "F0002_1.png",
            "4 of the 18 colour images have no colour (grey), unlike the other 14: F0002_1.png, "
            f"F0004_1.png, F0004_2.png and 1 more; a model reads them unlike the others "
            f"{COLOUR_WHY}; use colour originals, or leave them out",
        ),
        (
            "F0003_fold_01_300.png",
            "2 of the 90 touch frames have no colour (grey), unlike the other 88: "
            "F0003_fold_01_300.png, F0003_fold_02_300.png; a model reads them unlike the "
            f"others {TOUCH_WHY}; use colour originals, or leave them out",
        ),
    ]


def test_depth_and_all_grey_images_get_no_grey_warning(tiny_dataset: Path):
    """Depth is one channel by nature; images all grey are read alike by the model trained on
    them (only a mix is read unlike)."""
    for photo in (tiny_dataset / "color").glob("*.png"):
        _grey_rgb(photo)
    assert _warned(tiny_dataset, "no colour") == []


def test_a_synthetic_world_gets_no_warning(tmp_path: Path):
    from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate

    config = SynthConfig(
        fabrics=4, drapes=2, presses_flat=1, presses_fold=2, contact_sheet=False, reprints=0,
        workers=1, **SIZE_PRESETS["tiny"],
    )  # fmt: skip
    world = tmp_path / "world"
    generate(config, world, progress=False)
    catalog = check_dataset(world, workers=1)
    assert {m: len(catalog.items(m)) for m in catalog.modalities} == {
        Modality.DEPTH: 8,
        Modality.COLOR: 8,
        Modality.TOUCH: 12,
    }
    assert catalog.problems == ()


# ---- tiny images ---------------------------------------------------------------------------


def test_images_smaller_than_min_side_are_one_warning_per_modality(tiny_dataset: Path):
    root = tiny_dataset
    assert _warned(root, " px") == []
    depth = root / "depth" / "F0001_Depth_New_000001.png"
    Image.fromarray(np.full((1, 1), 1000, np.uint16)).save(depth)  # one valid pixel
    Image.fromarray(np.full((1, 1, 3), (200, 30, 10), np.uint8)).save(
        root / "color" / "F0002_1.png"
    )
    for k, name in enumerate(["F0001_fold_01_100.png", "F0001_fold_02_100.png"]):
        Image.fromarray(np.full((12, 40, 3), (9, 80 + k, 200), np.uint8)).save(
            root / "touch" / name
        )
    for k in (1, 2, 3):  # the smallest side that is not warned of
        Image.fromarray(np.full((MIN_SIDE, MIN_SIDE, 3), (k, 50, 99), np.uint8)).save(
            root / "color" / f"F0003_{k}.png"
        )
    why = "enlarged to the network's input (data.image_size, mostly 64 to 320 px)"
    assert _warned(root, " px") == [
        (
            "F0002_1.png",
            f"this colour image is 1x1 px: smaller than {MIN_SIDE} px on its shorter side; it "
            f"holds no texture, and is {why}; use the full-size file, or leave it out",
        ),
        (
            "F0001_Depth_New_000001.png",
            f"this depth image is 1x1 px: smaller than {MIN_SIDE} px on its shorter side; it "
            f"holds no texture, and is {why}; use the full-size file, or leave it out",
        ),
        (
            "F0001_fold_01_100.png",
            f"this touch frame is 40x12 px, and 1 more are smaller than {MIN_SIDE} px on their "
            "shorter side too: F0001_fold_02_100.png; they hold no texture, and each is "
            f"{why}; use the full-size files, or leave them out",
        ),
    ]


# ---- blank depth in runs -------------------------------------------------------------------


def _blank(root: Path, *names: str) -> list[Path]:
    """Overwrite ``names`` in ``root``/depth with depth images of no valid pixel (all 0)."""
    out = []
    for name in names:
        path = root / "depth" / name
        Image.fromarray(np.zeros((24, 24), np.uint16)).save(path)
        out.append(path)
    return out


BLANK_NAMES = (
    "F0002_Depth_New_000001.png",
    "F0004_Depth_New_000000.png",
    "F0006_Depth_New_000005.png",
)
"""Blank in `_six_drapes`: the 8th, 19th and 36th depth image (36 make two chunks of worker
processes, `lookfeel.data.decode_pool`)."""


def _six_drapes(tmp_path: Path) -> Path:
    """The tiny dataset with 6 drapes a fabric (36 depth images), three of them blank."""
    root = write_tiny_dataset(tmp_path / "six", drapes=6, fold_presses=1, flat_presses=0)
    _blank(root, *BLANK_NAMES)
    return root


def _message(first: Path, more: int) -> str:
    """The warning's known text, as a user reads it (written out, not rebuilt by the code)."""
    if not more:
        return (
            f"{first}: depth image has no valid pixel (every pixel 0, no reading): it is read as "
            "a blank input, which a run trains on and embeds as if it were a drape; leave it out "
            "or record it again (`lookfeel data check` names every such file)"
        )
    assert more == 2
    return (
        f"{first}: depth image has no valid pixel (every pixel 0, no reading), as have 2 more "
        "depth images read with it: each is read as a blank input, which a run trains on and "
        "embeds as if it were a drape; leave them out or record them again (`lookfeel data "
        "check` names every such file)"
    )


def _blank_warnings(caught: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, BlankDepthWarning)]


@pytest.mark.parametrize("decode", ["one", "threads", "processes"])
def test_blank_depth_is_warned_once_naming_the_first_and_counting_the_rest(
    tmp_path: Path, decode: str
):
    """In one thread, in threads, or in two worker processes (which send the note back with
    the file's entries, not a warning each), and read again from the disk cache: one warning,
    naming the first in the order given."""
    root = _six_drapes(tmp_path)
    first = root / "depth" / BLANK_NAMES[0]
    items = scan(root).items(Modality.DEPTH)
    assert len(items) == 36
    workers = 1 if decode == "one" else 2
    config = DataConfig(
        image_size=16, workers=workers, decode="auto" if decode == "one" else decode
    )
    for _ in range(2):  # built, then from the disk cache
        loader = ImageLoader(config, cache_dir=tmp_path / "cache")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert loader.preload(items) == len(items)
            assert loader.preload(items) == 0
            loader.load(items[0])
        assert _blank_warnings(caught) == [_message(first, 2)]
        blank = loader.load(next(it for it in items if it.path == first))
        assert not blank.any()  # read as a blank input, as before


def test_blank_depth_read_alone_is_warned_once_for_the_loader(tiny_dataset: Path):
    first, second = _blank(tiny_dataset, *BLANK_NAMES[:2])
    loader = ImageLoader(DataConfig(image_size=16), cache_dir=None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for path in sorted((tiny_dataset / "depth").glob("*.png")):
            loader.array(path, Modality.DEPTH)
    assert _blank_warnings(caught) == [_message(min(first, second), 0)]


def test_depth_with_a_valid_pixel_or_constant_is_not_blank(tmp_path: Path):
    """Only an image with no valid pixel is blank: one constant input (a flat wall, or all
    beyond the mapped range) or a single reading among holes is not."""
    files = {
        "flat.png": np.full((24, 24), 1000, np.uint16),
        "far.png": np.full((24, 24), 5000, np.uint16),
        "one.png": np.pad(np.full((1, 1), 1000, np.uint16), ((5, 18), (7, 16))),
    }
    loader = ImageLoader(DataConfig(image_size=16), cache_dir=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlankDepthWarning)
        for name, d in files.items():
            Image.fromarray(d).save(tmp_path / name)
            loader.array(tmp_path / name, Modality.DEPTH)


def test_train_says_it_once_as_a_lookfeel_warning(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `train` used an all-zero depth PNG as a blank drape without a word. (Its training
    and validation fabrics are decoded apart: the one warning counts those of the first.)"""
    blank = _blank(tiny_dataset, "F0002_Depth_New_000001.png", "F0005_Depth_New_000002.png")
    argv = [
        "train",
        "--config",
        str(TINY),
        "--data",
        str(tiny_dataset),
        "--out",
        str(tmp_path / "run"),
    ]
    argv += ["--set", "train.steps=2", "--set", "train.val_every=0", "--set", "data.workers=1"]
    assert cli_run(argv) == 0
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "no valid pixel" in line]
    assert len(said) == 1
    assert any(said[0].startswith(f"lookfeel: warning: {p}: depth image has no") for p in blank)
