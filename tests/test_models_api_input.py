"""The model and query API used from Python: every input error is one `LookfeelError` line,
a loaded model refuses images of another size than it was trained on, and a touch query of
stacked frames says when frames of its press are missing."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
import torch

from lookfeel.checkpoint import load_model
from lookfeel.config import DataConfig, ModelConfig
from lookfeel.errors import LookfeelError
from lookfeel.index.query import load_query_image, query_batch
from lookfeel.modality import Modality
from lookfeel.models import ModelInputError, create_model
from lookfeel.models.embedder import SlotError

from ._tiny import write_rgb

torch.set_num_threads(2)

COMPACT = ModelConfig(backbone="compact", width=4)


def _one_line_error(e: BaseException) -> str:
    text = str(e)
    assert isinstance(e, LookfeelError) and isinstance(e, ValueError), type(e)
    assert "\n" not in text and not text.startswith(("'", '"')), text
    return text


@pytest.fixture(scope="module")
def model() -> torch.nn.Module:
    """A colour and touch model reading 3 frames of a press stacked (9 channels), as the
    default synthetic recipe's, built for training: it knows no input size."""
    return create_model(
        COMPACT, [Modality.COLOR, Modality.TOUCH], load_weights=False, touch_channels=9
    ).eval()


@pytest.mark.parametrize(
    ("inputs", "says"),
    [
        (
            {"color": torch.rand(1, 1, 32, 32)},
            r"^slot 'color': expected \(B, 3, H, W\), got \(1, 1",
        ),
        (
            {"color": torch.rand(3, 32, 32)},
            r"^slot 'color': expected \(B, 3, H, W\), got \(3, 32, 32\) \(one image\? x\[None\]",
        ),
        (
            {"touch": torch.rand(1, 9, 32, 32)},
            r"^slot 'touch': touch input must be \(B, P, 9, H, W\).*got \(1, 9, 32, 32\) "
            r"\(one press\? x\[:, None\] adds the press axis\)$",
        ),
        (
            {"touch": torch.rand(1, 1, 3, 32, 32)},
            r"^slot 'touch': .*got \(1, 1, 3, 32, 32\) \(this model reads 3 frames of each "
            r"press stacked as channels",
        ),
    ],
    ids=["one-channel colour", "no batch axis", "touch without press axis", "touch 3 channels"],
)
def test_a_wrong_image_shape_is_one_model_input_error_line(model, inputs, says):
    """QA: these were plain ValueErrors, not the LookfeelErrors the README promises."""
    with torch.inference_mode(), pytest.raises(ModelInputError, match=says) as e:
        model(inputs)
    _one_line_error(e.value)


def test_a_slot_of_no_branch_is_a_slot_error_still_a_key_error_with_a_clean_line(model):
    """QA: an unknown slot or a missing branch raised a KeyError, printed in extra quotes."""
    x = torch.rand(1, 3, 32, 32)
    with pytest.raises(SlotError) as e:
        model({"colour": x})
    text = _one_line_error(e.value)
    assert isinstance(e.value, KeyError) and isinstance(e.value, ModelInputError)
    assert text.startswith("slot 'colour' names no modality: expected depth, color, touch")
    assert text.endswith("this model has color, touch")
    with pytest.raises(KeyError, match="no depth branch") as e:
        model({"depth": torch.rand(1, 1, 32, 32)})
    text = _one_line_error(e.value)
    assert text == "slot 'depth': this model has no depth branch (it has: color, touch)"
    with pytest.raises(SlotError, match="'depth.1': this model has no depth branch"):
        model.branch("depth.1")


def test_a_tensor_in_place_of_the_dict_of_slots_says_so(model):
    """QA: ``model(x)`` raised AttributeError: 'Tensor' object has no attribute 'items'."""
    x = torch.rand(1, 3, 32, 32)
    for call in (model, model.trunk):
        with pytest.raises(ModelInputError) as e:
            call(x)
        text = _one_line_error(e.value)
        assert text == (
            "the model takes a dict of slot -> images ({'color': x}; its slots: color, touch), "
            "got a Tensor"
        )


def test_query_batch_refuses_no_image_and_images_of_different_shapes():
    """QA: mixed sizes gave torch's RuntimeError "stack expects each tensor to be equal size",
    and no image a plain ValueError."""
    with pytest.raises(ModelInputError, match="^query_batch: no image given") as e:
        query_batch([], "color")
    _one_line_error(e.value)
    mixed = [torch.rand(3, 32, 32), torch.rand(3, 32, 32), torch.rand(3, 16, 16)]
    with pytest.raises(ModelInputError) as e:
        query_batch(mixed, "color")
    assert _one_line_error(e.value) == (
        "query_batch: image 2 is (3, 16, 16) and image 0 (3, 32, 32): every image of a query "
        "must have one shape; load_query_image reads each file at the model's size"
    )
    with pytest.raises(ModelInputError, match=r"image 1 is \(9, 8, 8\) and image 0 \(3, 8, 8\)"):
        query_batch([torch.rand(3, 8, 8), torch.rand(9, 8, 8)], "touch")
    views = [torch.rand(2, 3, 8, 8), torch.rand(4, 3, 8, 8)]
    with pytest.raises(ModelInputError, match=r"different numbers of views \[2, 4\]"):
        query_batch(views, "touch")
    with pytest.raises(ModelInputError, match=r"image 0 is \(8, 8\); expected a \(C, S, S\)"):
        query_batch([torch.rand(8, 8)], "depth")
    # What it takes still stacks: a single image counts as every view of its press.
    both = query_batch([torch.rand(3, 8, 8), torch.rand(4, 3, 8, 8)], "touch")
    assert both.shape == (1, 2, 4, 3, 8, 8)


def test_a_loaded_model_refuses_images_of_another_size_than_trained_on(run):
    """QA: a colour model trained at 64 px embedded a 256 px image without complaint, 2.1 away
    from the same photo at 64 px where another fabric was 5.3 away (its ONNX export refuses
    it)."""
    _, ckpt = run
    loaded = load_model(ckpt)
    side = loaded.config.data.image_size
    assert loaded.model.input_sizes == {m.value: side for m in loaded.model.modalities}
    ok = {"color": torch.rand(2, 3, side, side), "touch": torch.rand(2, 1, 3, side, side)}
    with torch.inference_mode():
        assert loaded.model(ok)["color"].shape == (2, loaded.model.embed_dim)
        for slot, x in (
            ("color", torch.rand(1, 3, 2 * side, 2 * side)),
            ("depth", torch.rand(1, 1, side, side + 8)),
            ("touch", torch.rand(1, 2, 3, side + 8, side + 8)),
        ):
            h, w = x.shape[-2:]
            with pytest.raises(ModelInputError) as e:
                loaded.model({slot: x})
            assert _one_line_error(e.value) == (
                f"slot '{slot}': this model was trained on {slot} images of {side}x{side} "
                f"pixels, got {h}x{w}; lookfeel.index.query.load_query_image(path, '{slot}', "
                "loaded.config.data) resizes an image to it for you"
            )
            with pytest.raises(ModelInputError, match=f"trained on {slot} images of {side}x"):
                loaded.model.trunk({slot: x[:, :1] if slot == "touch" else x})
        # On purpose: with the record cleared any size is embedded, as a model being trained.
        loaded.model.input_sizes.clear()
        assert loaded.model({"color": torch.rand(1, 3, 2 * side, 2 * side)})["color"].shape[0] == 1


def test_a_model_built_for_training_takes_any_size(model):
    assert model.input_sizes == {}
    with torch.inference_mode():
        for side in (16, 40):
            assert model({"color": torch.rand(1, 3, side, side)})["color"].shape[0] == 1


def _press(folder: Path, frames: list[int]) -> list[Path]:
    paths = [folder / f"F0001_fold_{fr:02d}_5.png" for fr in frames]
    for k, p in enumerate(paths):
        write_rgb(p, 1, k, size=(32, 24))
    return paths


def test_a_stacked_touch_query_says_once_which_frames_of_its_press_are_missing(tmp_path: Path):
    """QA: a touch query with only one frame on disk, for a model reading 3 frames of a press
    (data.touch_frames), was silently read as that frame three times."""
    config = DataConfig(image_size=16, touch_frames=(0, 1, 2))
    [lone] = _press(tmp_path / "lone", [1])
    with pytest.warns(UserWarning) as said:
        x = load_query_image(lone, Modality.TOUCH, config)
    assert [str(w.message) for w in said] == [
        f"{lone}: data.touch_frames reads frames [0, 1, 2] of each press, and this press has 1 "
        "frame in its folder: the nearest frame is read in place of each of the 2 missing"
    ]
    assert x.shape == (config.touch_channels, 16, 16) == (9, 16, 16)
    assert torch.equal(x[:3], x[3:6]) and torch.equal(x[:3], x[6:])  # the one frame, reused
    two = _press(tmp_path / "two", [1, 2])
    with pytest.warns(UserWarning, match=r"has 2 frames in its folder: .* each of the 1 missing"):
        load_query_image(two[0], Modality.TOUCH, DataConfig(image_size=16, touch_frames=(-3, -1)))
    full = _press(tmp_path / "full", [1, 2, 3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        x = load_query_image(full[1], Modality.TOUCH, config)
    # As the docstrings say: 3 channels per frame read, presses stacked behind a batch axis.
    assert query_batch([x, x], Modality.TOUCH).shape == (1, 2, 9, 16, 16)
    for doc in (load_query_image.__doc__, query_batch.__doc__):
        assert "touch_channels" in (doc or "") and "(3, S, S) for colour and touch" not in doc
