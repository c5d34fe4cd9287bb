"""Grey (colourless) press videos: whether one is grey is known from its one decoding (kept
with its image, in memory and in the disk cache), a checkpoint records whether its model was
trained on grey presses, and a query video is warned of only where it is of the other kind."""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from lookfeel.checkpoint import load_model, read_checkpoint, save_checkpoint
from lookfeel.config import DataConfig, RunConfig, load_config
from lookfeel.data import ImageLoader, scan
from lookfeel.data import images as images_module
from lookfeel.index import Library, Matcher, build_library
from lookfeel.index.match import COLOUR_VIDEO, GREY_VIDEO
from lookfeel.modality import Modality
from lookfeel.predict import predict_files
from lookfeel.serve import ServeConfig, background_server, create_app
from lookfeel.train import train

from ._video import PRESS, grey_and_colour_presses, object_press, write_objects, write_video

pytestmark = pytest.mark.filterwarnings("ignore:.*probabilities are as trained, not calibrated")

OBJECTS = {"foam": ("0", "fabric"), "cork": ("1", "wood"), "tile": ("2", "metal")}
TINY = [
    "data.image_size=32", "model.width=4", "model.embed_dim=8", "train.steps=2",
    "train.batch_size=8", "train.checkpoint_every=0", "model.class_heads=[hardness, material]",
]  # fmt: skip


@pytest.fixture(scope="module")
def presses(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One press as a colour video, a grey one (one channel) and one stored as colour with
    red, green and blue equal."""
    pytest.importorskip("av")
    return grey_and_colour_presses(tmp_path_factory.mktemp("presses"))


def _count_read_press(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    calls: list[str] = []
    real = images_module.read_press

    def counting(path, *args, **kwargs):
        calls.append(Path(path).name)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(images_module, "read_press", counting)
    return calls


@pytest.mark.parametrize("embed", ["image", "views"])
def test_a_loader_keeps_whether_a_press_video_is_grey_in_memory_and_in_its_cache(
    presses: dict[str, Path], embed: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    config = DataConfig(image_size=32, video_views=4, video_embed=embed)
    grey = {"colour": False, "grey": True, "stored": True}
    cache = tmp_path / "cache"
    loader = ImageLoader(config, cache)
    assert loader.is_grey(presses["grey"]) is None  # not read yet
    for p in presses.values():
        loader.embed_file(p, Modality.TOUCH)
    assert {k: loader.is_grey(p) for k, p in presses.items()} == grey

    # From the disk cache: nothing is decoded, and the flag comes back with the image.
    decoded = _count_read_press(monkeypatch)
    again = ImageLoader(config, cache)
    for p in presses.values():
        again.embed_file(p, Modality.TOUCH)
    assert decoded == [] and {k: again.is_grey(p) for k, p in presses.items()} == grey
    facts = sorted(cache.rglob("*.json"))
    assert facts and json.loads(facts[0].read_text(encoding="utf-8")) in (
        {"grey": True},
        {"grey": False},
    )

    # A cache entry written before the flag was kept still loads; the flag is then unknown.
    for f in facts:
        f.unlink()
    old = ImageLoader(config, cache)
    for p in presses.values():
        old.embed_file(p, Modality.TOUCH)
    assert decoded == [] and {old.is_grey(p) for p in presses.values()} == {None}

    # A decoding worker's loader hands the flag on with the images (`take`, `adopt`).
    other = ImageLoader(config)
    other.adopt(presses["grey"], loader.take(presses["grey"]))
    assert other.is_grey(presses["grey"]) is True


def test_press_videos_decoded_in_worker_processes_keep_their_flag(grey_data: Path):
    items = scan(grey_data).items(Modality.TOUCH)
    loader = ImageLoader(DataConfig(image_size=32, decode="processes", workers=2))
    assert loader.preload(items) == len(items)
    assert {loader.is_grey(it.path) for it in items} == {True}


@pytest.fixture(scope="module")
def grey_data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Recordings of 3 objects, 2 grey press videos each (a camera set to greyscale)."""
    pytest.importorskip("av")
    return write_objects(tmp_path_factory.mktemp("grey_recordings"), OBJECTS, 2, grey=True)


@pytest.fixture(scope="module")
def grey_model(grey_data: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(checkpoint, library): the recipe trained for 2 steps on grey presses only, and a
    library of them."""
    root = tmp_path_factory.mktemp("grey_model")
    recipe = Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml"
    ck = train(load_config(RunConfig, recipe, TINY), grey_data, root / "run").last_checkpoint
    build_library(ck, grey_data, root / "lib")
    return ck, root / "lib"


def _lines(call: Callable[[], object]) -> list[str]:
    """What ``call`` warns of a press video's colour."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in said if "colour" in str(w.message)]


def test_a_model_trained_on_grey_presses_is_warned_of_a_colour_query_not_a_grey_one(
    grey_model: tuple[Path, Path], presses: dict[str, Path], tmp_path: Path
):
    ck, lib = grey_model
    loaded = load_model(ck)
    assert loaded.grey_presses == {"videos": 6, "grey": 6} and loaded.trained_on_grey
    colour, grey, stored = presses["colour"], presses["grey"], presses["stored"]
    also = write_video(tmp_path / "also.mov", object_press(2, PRESS, t=14))

    def predicted(paths: list[Path], together: bool = False) -> list[str]:
        return _lines(lambda: predict_files(loaded, paths, "touch", together=together))

    assert predicted([colour]) == [f"{colour}: {COLOUR_VIDEO}"]
    assert predicted([grey]) == [] == predicted([stored])
    assert predicted([grey, colour, also], together=True) == [
        f"{colour} (and 1 other colour video): {COLOUR_VIDEO}"
    ]

    matcher = Matcher(Library.open(lib))
    assert matcher.trained_on_grey is True

    def matched(paths: list[Path]) -> list[str]:
        return _lines(lambda: matcher.match_files(paths, Modality.TOUCH, top=2))

    assert matched([colour]) == [f"{colour}: {COLOUR_VIDEO}"]
    assert matched([grey, stored]) == []

    with background_server(create_app(Library.open(lib), ServeConfig(), matcher)) as url:

        def served(paths: list[Path]) -> list[str]:
            r = httpx.post(
                url + "/api/match",
                data={"modality": "touch", "top": "2"},
                files=[("files", (p.name, p.read_bytes(), "video/mp4")) for p in paths],
            )
            assert r.status_code == 200, r.text
            return [w for w in r.json()["warnings"] if "colour" in w]

        assert served([colour, also]) == [f"colour.mov (and 1 other colour video): {COLOUR_VIDEO}"]
        assert served([grey]) == []


def test_a_checkpoint_without_the_record_warns_of_grey_presses_as_before(
    grey_model: tuple[Path, Path], presses: dict[str, Path], tmp_path: Path
):
    ck, _ = grey_model
    state = read_checkpoint(ck)
    del state["grey_presses"]
    old = load_model(save_checkpoint(tmp_path / "old.pt", state))
    assert old.grey_presses is None and old.trained_on_grey is None
    colour, grey = presses["colour"], presses["grey"]
    assert _lines(lambda: predict_files(old, [grey, colour], "touch")) == [f"{grey}: {GREY_VIDEO}"]
    # A record this version cannot read (a newer lookfeel's) is left out, not refused.
    for record in ({"videos": 2, "grey": 3}, {"share": 0.5}, [6, 6], {"videos": True, "grey": 0}):
        state["grey_presses"] = record
        assert load_model(save_checkpoint(tmp_path / "newer.pt", state)).grey_presses is None
