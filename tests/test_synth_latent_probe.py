"""What a trained model's embeddings reveal of a world's latents (`lookfeel.synth.latent_probe`):
a planted latent is read and an unplanted one is not, classes beside their majority, and the
command line on a trained checkpoint with its one-line errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lookfeel.synth import latent_probe as lp


def _truth(n: int, rng: np.random.Generator) -> dict[int, dict[str, Any]]:
    return {
        f: {
            "fabric_id": f,
            "thickness_mm": float(np.exp(rng.uniform(-1.0, 1.5))),
            "sheen": float(rng.uniform(0, 1)),
            "stretchiness": 0.5,  # the same for all: R^2 undefined
            "material": ["silk", "wool", "cotton"][f % 3],
            "weave": ["plain", "twill"][int(rng.integers(0, 2))],
        }
        for f in range(1, n + 1)
    }


def _items(
    truth: dict[int, dict[str, Any]], ids: list[int], rng: np.random.Generator, per: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """Embeddings that carry log thickness and the material (one-hot) and noise, never sheen or
    weave; ``per`` items a fabric."""
    rows, fab = [], []
    for f in ids:
        t = truth[f]
        onehot = np.eye(3)[["silk", "wool", "cotton"].index(t["material"])]
        for _ in range(per):
            noise = rng.standard_normal(6)
            rows.append(np.concatenate([[np.log(t["thickness_mm"])], 2.0 * onehot, noise]))
            fab.append(f)
    return np.asarray(rows), np.asarray(fab)


LATENTS = ("log_thickness_mm", "sheen", "stretchiness", "material", "weave")
"""What `_truth` gives a fabric, as the probe names it."""


def test_a_planted_latent_is_read_and_an_unplanted_one_is_not() -> None:
    rng = np.random.default_rng(0)
    truth = _truth(60, rng)
    train_ids, test_ids = list(range(1, 46)), list(range(46, 61))
    train = {"touch": _items(truth, train_ids, rng)}
    test = {"touch": _items(truth, test_ids, rng)}
    out = lp.probe_latents(truth, train, test)
    s = out["scores"]["touch"]
    assert set(s) == {*LATENTS}
    assert s["log_thickness_mm"] > 0.95  # planted, probed as its log
    assert s["sheen"] < 0.2  # not in the embeddings
    assert s["stretchiness"] is None  # constant: R^2 undefined
    assert s["material"] == 1.0 and out["majority"]["material"] < 0.5
    assert out["fabrics"] == {"touch": [45, 15]}


def test_the_probe_is_fitted_on_the_training_fabrics_only() -> None:
    """Held-out embeddings shuffled across fabrics: a probe that had seen them would still
    read them; one fitted on the training fabrics scores below 0."""
    rng = np.random.default_rng(1)
    truth = _truth(60, rng)
    train = {"depth": _items(truth, list(range(1, 46)), rng)}
    emb, fab = _items(truth, list(range(46, 61)), rng)
    shuffled = {"depth": (emb, rng.permutation(np.unique(fab)).repeat(4))}
    out = lp.probe_latents(truth, train, shuffled)
    assert out["scores"]["depth"]["log_thickness_mm"] < 0.0


@pytest.fixture(scope="module")
def world_and_checkpoint(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The tiny trained run's dataset, copied, with a ``synth.json`` of known truth."""
    from ._library import tiny_run

    data, ckpt = tiny_run()
    world = tmp_path_factory.mktemp("latent") / "world"
    shutil.copytree(data, world)
    rng = np.random.default_rng(2)
    fabrics = list(_truth(6, rng).values())
    (world / "synth.json").write_text(
        json.dumps({"status": "complete", "fabrics": fabrics}), encoding="utf-8"
    )
    return world, ckpt


def test_a_trained_checkpoint_gives_every_latent_of_every_modality_deterministically(
    world_and_checkpoint: tuple[Path, Path],
) -> None:
    world, ckpt = world_and_checkpoint
    a = lp.latent_table(world, [ckpt, ckpt])
    b = lp.latent_table(world, [ckpt])
    assert set(a["mean"]) == {"depth", "color", "touch"}
    for m in a["mean"]:
        assert set(a["mean"][m]) == {
            "log_thickness_mm",
            "sheen",
            "stretchiness",
            "material",
            "weave",
        }
        assert a["mean"][m] == b["mean"][m]  # the same checkpoint twice: the same numbers
        assert a["std"][m]["sheen"] == 0.0
        assert a["runs"][0]["fabrics"][m] == [4, 2]  # the tiny run holds 2 fabrics out
    text = lp.format_latent_table(a)
    assert "| log_thickness_mm |" in text and "material (accuracy; majority" in text


def test_cli_writes_json_and_bad_input_is_one_line(
    world_and_checkpoint: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    world, ckpt = world_and_checkpoint
    out = tmp_path / "latents.json"
    assert lp.main([str(world), str(ckpt), "--json", str(out), "--pixels", "--workers", "1"]) == 0
    result = json.loads(out.read_text(encoding="utf-8"))
    assert result["checkpoints"] == [str(ckpt)]
    # the image statistics probed on the same fabrics as the embeddings
    assert result["pixels"]["runs"][0]["fabrics"] == result["runs"][0]["fabrics"]
    assert set(result["pixels"]["mean"]["touch"]) == {*LATENTS}
    assert "| latent | depth | color | touch | depth pixels |" in capsys.readouterr().out
    for bad_world, bad_ckpt in ((tmp_path / "nowhere", ckpt), (world, tmp_path / "missing.pt")):
        assert lp.main([str(bad_world), str(bad_ckpt)]) == 2
        err = capsys.readouterr().err
        named = bad_world if bad_world != world else bad_ckpt
        assert err.count("\n") == 1 and str(named) in err and "Traceback" not in err
