"""benchmarks/bench_demo_seeds.py: the demo's cross-modal run at several seeds and precisions."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from benchmarks.bench_demo_seeds import main, measure

from ._tiny import write_tiny_dataset

SHRINK = (
    "train.steps=2",
    "train.split=stratified",
    "train.val_fabrics=3",
    "data.image_size=32",
    "data.color_reprints=0",
)


@pytest.mark.filterwarnings("ignore:pick 10")  # 3 held-out fabrics
def test_every_precision_and_seed_is_trained_and_summarised(tmp_path: Path):
    world = write_tiny_dataset(tmp_path / "world", fabrics=8, drapes=2)
    result = measure(world, [0, 1], ["auto", "fp32"], tmp_path / "runs", SHRINK, n_boot=20)
    runs = result["runs"]
    assert [(r["precision"], r["seed"]) for r in runs] == [
        ("auto", 0),
        ("auto", 1),
        ("fp32", 0),
        ("fp32", 1),
    ]
    pairs = runs[0]["pairs"]
    senses = ("depth", "color", "touch")
    assert set(pairs) == {f"{a}_to_{b}" for a in senses for b in senses if a != b}
    saved = yaml.safe_load(
        (tmp_path / "runs" / "fp32-seed1" / "config.yaml").read_text(encoding="utf-8")
    )
    assert (saved["train"]["seed"], saved["model"]["precision"]) == (1, "fp32")
    assert saved["train"]["steps"] == 2 and saved["model"]["width"] == 16  # the demo's, shrunk
    # On a CPU both precisions are fp32: the same seed gives the same numbers.
    assert runs[2]["pairs"] == runs[0]["pairs"] and runs[3]["pairs"] == runs[1]["pairs"]
    summary = result["summary"]
    for precision in ("auto", "fp32"):
        s = summary[precision]
        assert s["seeds"] == 2
        for pair, v in s["pairs"].items():
            values = [r["pairs"][pair]["mapped"] for r in runs if r["precision"] == precision]
            assert v["low"] == pytest.approx(min(values), abs=1e-4)
            assert v["high"] == pytest.approx(max(values), abs=1e-4)
            assert v["low"] <= v["mean"] <= v["high"]


def test_bad_arguments_name_the_option(capsys: pytest.CaptureFixture[str]):
    for argv, option in (
        (["--seeds", "0,x"], "--seeds"),
        (["--precision", "fp16"], "--precision"),
        (["--world", "/nonexistent/world"], "--world"),
        (["--fabrics", "28"], "--fabrics"),
        (["--set", "train.bogus=1"], "unknown key train.bogus"),
        (["--set", "train.lr"], "expected key=value"),
    ):
        with pytest.raises(SystemExit):
            main(argv)
        assert option in capsys.readouterr().err


def test_a_rendered_world_is_the_demo_kind_and_is_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import benchmarks.bench_demo_seeds as bench

    from lookfeel.demo import demo_world

    rendered: list[object] = []
    monkeypatch.setattr(bench, "generate", lambda config, out, progress: rendered.append(config))
    measured: list[object] = []

    def fake_measure(world, seeds, precisions, work, overrides):
        measured.append(overrides)
        return {"runs": []}

    monkeypatch.setattr(bench, "measure", fake_measure)
    out = tmp_path / "r.json"
    argv = ["--fabrics", "70", "--world-seed", "3", "--seeds", "0", "--out", str(out)]
    assert main([*argv, "--set", "train.lr=0.002", "--set", "model.embed_dim=64"]) == 0
    assert measured == [["train.lr=0.002", "model.embed_dim=64"]]
    assert rendered == [demo_world(70, 3)]
    saved = yaml.safe_load(out.read_text(encoding="utf-8"))  # JSON is YAML
    world = demo_world(70, 3)
    assert saved["world"] == {
        "fabrics": 70,
        "test_fabrics": 23,
        "seed": 3,
        "drapes": world.drapes,
        "presses_flat": world.presses_flat,
        "presses_fold": world.presses_fold,
    }
    assert saved["overrides"] == ["train.lr=0.002", "model.embed_dim=64"]
