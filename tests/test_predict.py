"""`lookfeel.predict.predict_files` called from Python: modalities by name, single paths, the
wording of its errors."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch

from lookfeel.checkpoint import LoadedModel, load_model
from lookfeel.config import RunConfig, load_config
from lookfeel.modality import Modality, ModalityError
from lookfeel.predict import PredictError, predict_files
from lookfeel.train import train

from ._library import TINY

pytestmark = pytest.mark.filterwarnings("ignore:.*probabilities are as trained, not calibrated")


@pytest.fixture(scope="module")
def heads(run, tmp_path_factory: pytest.TempPathFactory) -> LoadedModel:
    """`run`'s dataset under a tiny model with a class head (stretchiness), a few steps."""
    data, _ = run
    overrides = ["model.class_heads=[stretchiness]", "train.steps=2", "train.split=none"]
    config = load_config(
        RunConfig, TINY, [*overrides, "train.val_every=0", "train.checkpoint_every=0"]
    )
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as `tests._library.tiny_run`: faster on a shared CPU
    try:
        result = train(config, data, tmp_path_factory.mktemp("heads") / "run")
    finally:
        torch.set_num_threads(threads)
    return load_model(result.last_checkpoint)


def test_a_modality_by_name_and_a_single_path_are_taken_as_meant(run, heads: LoadedModel):
    data, _ = run
    photo = data / "color/F0003_2.png"
    [want] = predict_files(heads, [photo], Modality.COLOR)
    assert want.modality == "color" and "stretchiness" in want.properties
    for paths in (str(photo), photo):  # one file, not one per character of its name
        assert predict_files(heads, paths, "color") == [want]
    press = data / "touch/F0004_fold_02_400.png"
    [touch] = predict_files(heads, str(press), "touch", together=True)
    assert touch.paths == [str(press)] and touch.modality == "touch"
    with pytest.raises(ModalityError, match="unknown modality 'colour'; expected one of"):
        predict_files(heads, [photo], "colour")
    with pytest.raises(PredictError, match="no input file given"):
        predict_files(heads, [])


def test_errors_name_the_cli_flag_and_the_python_argument(run, heads: LoadedModel, tmp_path: Path):
    data, _ = run
    photo = str(data / "color/F0003_2.png")
    loose = shutil.copy(photo, tmp_path / "F0003_2.png")  # no folder says what it shows
    with pytest.raises(PredictError, match=r"F0003_2.png: say which .* --modality \(modality\)"):
        predict_files(heads, [loose])
    with pytest.raises(PredictError, match=r"^--together \(together\) pools touch presses"):
        predict_files(heads, [photo, photo], Modality.COLOR, together=True)


def test_a_checkpoint_path_is_loaded_and_a_device_checked_first(run, heads: LoadedModel):
    from lookfeel.devices import DeviceError

    data, _ = run
    photo = data / "color/F0003_2.png"
    [want] = predict_files(heads, photo, "color")
    for path in (heads.path, str(heads.path)):  # as `evaluate_checkpoint` takes it
        assert predict_files(path, photo, "color") == [want]
    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        predict_files(heads, photo, "color", device="tpu")


def test_the_modality_is_guessed_from_the_layouts_folder_or_a_depth_png(
    run, heads: LoadedModel, tmp_path: Path
):
    """QA: a file of the dataset's own touch/ folder needed --modality with a model of three
    senses, and the docstring's "a 16-bit PNG is depth" was not done."""
    from lookfeel.predict import guess_modality

    data, _ = run
    have = list(heads.model.modalities)
    assert len(have) == 3
    for folder, m in (
        ("touch", Modality.TOUCH),
        ("color", Modality.COLOR),
        ("depth", Modality.DEPTH),
    ):
        some = sorted((data / folder).iterdir())[0]
        assert guess_modality(some, have) is m
    depth = shutil.copy(sorted((data / "depth").iterdir())[0], tmp_path / "drape.png")
    assert guess_modality(Path(depth), have) is Modality.DEPTH  # 16-bit greyscale, anywhere
    photo = shutil.copy(data / "color/F0003_2.png", tmp_path / "photo.png")
    with pytest.raises(PredictError, match="say which modality"):
        guess_modality(Path(photo), have)  # 8-bit RGB outside the layout: it does not say
