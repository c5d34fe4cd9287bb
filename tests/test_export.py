"""ONNX export: a file per branch, dynamic batch and presses, equal to PyTorch in onnxruntime."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch

from lookfeel.checkpoint import load_model, read_checkpoint, save_checkpoint
from lookfeel.cli import main
from lookfeel.export import ExportError, export_onnx
from lookfeel.modality import Modality, ModalityError

from ._library import tiny_run


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    _, ckpt = tiny_run()
    out = tmp_path_factory.mktemp("export") / "onnx"
    export_onnx(ckpt, out)
    return ckpt, out


def test_each_branch_equals_pytorch_for_any_batch_and_presses(exported):
    ckpt, out = exported
    model = load_model(ckpt).model
    assert sorted(p.name for p in out.iterdir()) == [
        "color.onnx", "depth.onnx", "export.json", "touch.onnx",
    ]  # fmt: skip
    gen = torch.Generator().manual_seed(1)
    shapes = {
        Modality.DEPTH: [(1, 1, 32, 32), (7, 1, 32, 32)],
        Modality.COLOR: [(2, 3, 32, 32), (5, 3, 32, 32)],
        Modality.TOUCH: [(1, 1, 3, 32, 32), (4, 3, 3, 32, 32), (2, 6, 3, 32, 32)],
    }
    for m, cases in shapes.items():
        session = ort.InferenceSession(str(out / f"{m.value}.onnx"))
        [inp] = session.get_inputs()
        assert inp.name == ("presses" if m is Modality.TOUCH else "image")
        assert inp.shape[0] == "batch" and (m is not Modality.TOUCH or inp.shape[1] == "presses")
        for shape in cases:
            x = torch.rand(*shape, generator=gen)
            with torch.inference_mode():
                want = model({m.value: x})[m.value].numpy()
            got = session.run(None, {inp.name: x.numpy()})[0]
            assert got.shape == (shape[0], 16)
            np.testing.assert_allclose(got, want, atol=1e-4, rtol=0)
    meta = json.loads((out / "export.json").read_text(encoding="utf-8"))
    assert meta["embed_dim"] == 16 and meta["data"]["image_size"] == 32
    assert meta["branches"]["touch"]["shape"] == ["batch", "presses", 3, 32, 32]
    assert all(b["max_abs_diff_vs_torch"] < 1e-4 for b in meta["branches"].values())


def test_export_some_branches(exported, tmp_path: Path):
    ckpt, _ = exported
    [branch] = export_onnx(ckpt, tmp_path / "one", modalities=[Modality.DEPTH], check=False)
    assert branch.modality is Modality.DEPTH and branch.max_abs_diff is None
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == ["depth.onnx", "export.json"]
    # The check runs the PyTorch module after export: the exporter restores the module's mode,
    # so a wrapper left in train mode would run BatchNorm on batch statistics and differ here.
    [checked] = export_onnx(ckpt, tmp_path / "two", modalities=[Modality.TOUCH])
    assert checked.max_abs_diff is not None and checked.max_abs_diff < 1e-4
    with pytest.raises(ValueError, match=r"color branch: ONNX outputs differ from PyTorch's"):
        export_onnx(ckpt, tmp_path / "three", modalities=[Modality.COLOR], atol=-1.0)
    assert not (tmp_path / "three" / "color.onnx").exists()


def test_modalities_may_be_named_and_a_missing_branch_creates_nothing(exported, tmp_path: Path):
    """QA: ``modalities=["color"]`` crashed (``'str' object has no attribute 'value'``) after
    creating an empty output folder; a modality may be given by its name, as elsewhere."""
    ckpt, _ = exported
    branches = export_onnx(ckpt, tmp_path / "named", modalities=["color", "depth", "color"])
    assert [b.modality for b in branches] == [Modality.COLOR, Modality.DEPTH]  # each once
    assert sorted(p.name for p in (tmp_path / "named").iterdir()) == [
        "color.onnx", "depth.onnx", "export.json",
    ]  # fmt: skip
    [one] = export_onnx(ckpt, tmp_path / "one", modalities="touch", check=False)  # one, as is
    assert one.modality is Modality.TOUCH
    # A model without the branch: one line, and no folder left behind.
    state = read_checkpoint(ckpt)
    state["modalities"] = ["depth"]
    state["model"] = {k: v for k, v in state["model"].items() if k.startswith("branches.depth.")}
    depth_only = save_checkpoint(tmp_path / "depth_only.pt", state)
    for asked in (["color"], [Modality.COLOR]):
        with pytest.raises(ExportError) as e:
            export_onnx(depth_only, tmp_path / "none", modalities=asked)
        assert str(e.value) == "the model has no color branch (it has: depth)"
        assert not (tmp_path / "none").exists()
    # A folder that cannot be made (a file where a folder above it should be): one line.
    (tmp_path / "afile").write_text("mine\n", encoding="utf-8")
    under_a_file = tmp_path / "afile" / "sub"
    with pytest.raises(ExportError) as e:
        export_onnx(ckpt, under_a_file, modalities=["depth"], check=False)
    assert str(e.value) == f"{under_a_file}: cannot create the export's folder (Not a directory)"


def test_a_bad_modality_or_out_is_one_line_before_the_checkpoint_is_read(tmp_path: Path):
    missing = tmp_path / "missing.pt"  # never read: the arguments are refused first
    with pytest.raises(ModalityError, match=r"^unknown modality 'colour'; expected one of"):
        export_onnx(missing, tmp_path / "out", modalities=["colour"])
    a_file = tmp_path / "afile"
    a_file.write_text("mine\n", encoding="utf-8")
    with pytest.raises(ExportError) as e:
        export_onnx(missing, a_file)
    assert str(e.value) == f"{a_file}: exists and is not a folder (the export's output folder)"
    assert a_file.read_text(encoding="utf-8") == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_cli_export(exported, tmp_path: Path, capsys):
    ckpt, _ = exported
    out = tmp_path / "cli"
    assert main(["export", "--checkpoint", str(ckpt), "--format", "onnx", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert (
        "touch.onnx: presses (batch x presses x 3 x 32 x 32) -> embedding (batch x 16)" in printed
    )
    assert "depth.onnx: image (batch x 1 x 32 x 32) -> embedding (batch x 16)" in printed
    assert (out / "depth.onnx").is_file()
    assert main(["export", "--checkpoint", str(tmp_path / "none.pt"), "--out", str(out)]) == 1
    assert "checkpoint not found" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["export", "--checkpoint", str(ckpt), "--format", "tflite", "--out", str(out)])


def test_views_graph_equals_lookfeel_embedding_of_a_press_video(exported, tmp_path: Path):
    # A run with data.video_embed: views embeds a press from V views, averaged inside the
    # branch (and normalised after, when the run normalises): the graph must take them all.
    ckpt, _ = exported
    state = read_checkpoint(ckpt)
    state["config"]["data"].update(video_embed="views", video_views=4)
    views_ckpt = save_checkpoint(tmp_path / "views.pt", state)
    [touch] = export_onnx(views_ckpt, tmp_path / "onnx", modalities=[Modality.TOUCH])
    assert touch.input_name == "views"
    assert touch.input_shape == ["batch", "presses", "views", 3, 32, 32]
    model = load_model(views_ckpt).model
    session = ort.InferenceSession(str(touch.path))
    gen = torch.Generator().manual_seed(2)
    for shape in [(1, 1, 5, 3, 32, 32), (3, 2, 7, 3, 32, 32)]:
        x = torch.rand(*shape, generator=gen)
        with torch.inference_mode():
            want = model({"touch": x})["touch"].numpy()
            first_view = model({"touch": x[:, :, 0]})["touch"].numpy()
        got = session.run(None, {"views": x.numpy()})[0]
        np.testing.assert_allclose(got, want, atol=1e-4, rtol=0)
        assert np.abs(got - first_view).max() > 1e-3  # the views really are averaged
    meta = json.loads((tmp_path / "onnx" / "export.json").read_text(encoding="utf-8"))
    assert meta["branches"]["touch"]["input"] == "views"
    assert meta["data"]["video_embed"] == "views" and meta["data"]["video_views"] == 4


def test_colour_branch_takes_data_color_size(exported, tmp_path: Path):
    ckpt, _ = exported
    state = read_checkpoint(ckpt)
    state["config"]["data"].update(color_size=40)
    sized = save_checkpoint(tmp_path / "sized.pt", state)
    branches = {b.modality: b for b in export_onnx(sized, tmp_path / "onnx", check=False)}
    assert branches[Modality.COLOR].input_shape == ["batch", 3, 40, 40]
    assert branches[Modality.DEPTH].input_shape == ["batch", 1, 32, 32]
    session = ort.InferenceSession(str(branches[Modality.COLOR].path))
    x = torch.rand(3, 3, 40, 40, generator=torch.Generator().manual_seed(3))
    with torch.inference_mode():
        want = load_model(sized).model({"color": x})["color"].numpy()
    np.testing.assert_allclose(session.run(None, {"image": x.numpy()})[0], want, atol=1e-4)


def test_opsets_outside_the_supported_range_are_refused_before_anything_runs(
    exported, tmp_path: Path, capsys
):
    from torch.onnx import _constants

    from lookfeel.export import MIN_OPSET, ExportError, supported_opsets

    opsets = supported_opsets()
    assert opsets[0] == MIN_OPSET == 13
    assert opsets[-1] == _constants.ONNX_TORCHSCRIPT_EXPORTER_MAX_OPSET  # torch's own limit
    ckpt, _ = exported
    for bad in ("5", "99", str(opsets[-1] + 1)):
        with pytest.raises(SystemExit) as e:
            main(
                ["export", "--checkpoint", str(ckpt), "--out", str(tmp_path / bad), "--opset", bad]
            )
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert f"argument --opset: must be in [13, {opsets[-1]}]" in err and f"got {bad}" in err
    with pytest.raises(ExportError, match=rf"^opset 12: .* opsets 13 to {opsets[-1]} with torch"):
        export_onnx(ckpt, tmp_path / "lib", opset=12)
    assert not any(tmp_path.iterdir())
    # Both ends of the range export the touch branch (the one that needs 13).
    for opset in (opsets[0], opsets[-1]):
        [touch] = export_onnx(
            ckpt, tmp_path / str(opset), modalities=[Modality.TOUCH], opset=opset, check=False
        )
        assert touch.path.is_file()


def test_an_exporter_failure_is_one_line_naming_the_branch_and_opset(
    exported, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd
):
    # Below 13 the touch branch's press pooling (Tensor.unflatten) cannot be exported: let
    # opset 12 through the range check to see torch's own failure reported.
    monkeypatch.setattr("lookfeel.export.MIN_OPSET", 9)
    ckpt, _ = exported
    out = tmp_path / "onnx"
    assert main(["export", "--checkpoint", str(ckpt), "--out", str(out), "--opset", "12"]) == 1
    captured = capfd.readouterr()
    assert captured.err == (
        "lookfeel: touch branch: the ONNX export at opset 12 failed: UnsupportedOperatorError: "
        "Exporting the operator 'aten::unflatten' to ONNX opset version 12 is not supported\n"
    )
    assert "graph" not in captured.out  # torch's dump of its graph is not shown
    # Neither depth.onnx nor color.onnx without the touch branch, nor the folder.
    assert not out.exists()


def test_an_alexnet_touch_branch_exports_with_dynamic_presses(tmp_path: Path):
    """The paper's backbone: its adaptive pooling to 6x6 needs the map's size, which the
    exporter loses once presses are folded into the batch; a 6x6 map is passed through."""
    from torch import nn

    from lookfeel.config import RunConfig, load_config
    from lookfeel.models import create_model
    from lookfeel.models.alexnet import _PoolTo6

    pool, reference = _PoolTo6(), nn.AdaptiveAvgPool2d((6, 6))
    for size in (6, 7, 13):  # 6x6 untouched; other sizes pooled as torchvision pools them
        x = torch.rand(2, 4, size, size)
        assert torch.equal(pool(x), reference(x))
    config = load_config(RunConfig, None, ["model.backbone=alexnet", "model.freeze=none"])
    model = create_model(config.model, [Modality.TOUCH], load_weights=False).eval()
    branch = model.branch("touch")
    x = torch.rand(1, 2, 3, 227, 227)
    path = tmp_path / "touch.onnx"
    torch.onnx.export(
        branch,
        (x,),
        path,
        dynamo=False,
        input_names=["presses"],
        output_names=["embedding"],
        dynamic_axes={"presses": {0: "batch", 1: "presses"}, "embedding": {0: "batch"}},
        opset_version=17,
    )
    session = ort.InferenceSession(str(path))
    y = torch.rand(2, 3, 3, 227, 227)
    with torch.inference_mode():
        want = branch(y).numpy()
    np.testing.assert_allclose(session.run(None, {"presses": y.numpy()})[0], want, atol=1e-4)
