"""Training: overfitting, determinism, kill-and-resume, errors, and 2-process DDP."""

from __future__ import annotations

import json
import os
import random
import re
import shlex
import statistics
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.checkpoint import load_model
from lookfeel.cli import main
from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.data import DatasetError, ImageLoader, scan
from lookfeel.devices import DeviceError
from lookfeel.embedding import embed_catalog
from lookfeel.metrics import pairwise_distances, pick_k_of_n_exact
from lookfeel.modality import Modality
from lookfeel.models import BranchEnsemble
from lookfeel.train import TrainingDiverged, TrainResult, member_config, train

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tiny_dataset(tmp_path_factory.mktemp("train") / "data", fabrics=6, drapes=3)


def _config(*overrides: str) -> RunConfig:
    return load_config(RunConfig, TINY, list(overrides))


def _states_equal(a: Path, b: Path, atol: float = 0.0) -> bool:
    sa = torch.load(a, weights_only=True)["model"]
    sb = torch.load(b, weights_only=True)["model"]
    return sa.keys() == sb.keys() and all(
        torch.allclose(sa[k].float(), sb[k].float(), atol=atol, rtol=0) for k in sa
    )


def test_overfits_a_tiny_set(tmp_path: Path):
    root = write_tiny_dataset(tmp_path / "d", fabrics=4, drapes=3, fold_presses=3, flat_presses=0)
    losses: list[float] = []
    cfg = _config(
        "train.split=none",
        "train.views=[depth,touch]",
        "train.steps=400",  # 200 left both the base and this sampler at the thresholds' edge
        "train.lr=0.01",
        "train.batch_size=16",
        "data.presses=1",
    )
    result = train(cfg, root, tmp_path / "run", on_step=lambda s, v: losses.append(v["loss"]))
    first, last = statistics.mean(losses[:5]), statistics.mean(losses[-20:])
    # BatchNorm's batch noise leaves a floor at 0.24-0.33 of the start in this few-second
    # budget, where the last bits of rounding (the memory layout, the thread count) decide
    # the 20-step mean; a run that does not learn stays near 1. The pick below is the proof.
    assert last < 0.5 * first
    trained = load_model(result.last_checkpoint)
    emb = embed_catalog(trained.model, scan(root), ImageLoader(trained.config.data))
    touch, depth = emb[Modality.TOUCH], emb[Modality.DEPTH]
    dist = pairwise_distances(touch.embeddings, depth.embeddings)
    res = pick_k_of_n_exact(dist, touch.fabric_ids, depth.fabric_ids, n=4)
    assert res.mean[0] == pytest.approx(1.0)


def test_run_directory_and_determinism(data: Path, tmp_path: Path):
    a = train(_config(), data, tmp_path / "a")
    b = train(_config(), data, tmp_path / "b")
    run = tmp_path / "a"
    assert sorted(p.name for p in run.iterdir()) == [
        "checkpoints",
        "config.yaml",
        "metrics.jsonl",
        "split.json",
    ]
    assert load_config(RunConfig, run / "config.yaml") == _config()
    split = json.loads((run / "split.json").read_text(encoding="utf-8"))
    assert len(split["val"]) == 2 and not set(split["val"]) & set(split["train"])
    lines = [
        json.loads(x) for x in (run / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    steps = [x["step"] for x in lines if "loss" in x]
    assert steps == [5, 10, 15, 20]
    assert any("val/touch_to_depth_top1" in x for x in lines)
    assert a.best_checkpoint is not None and a.best_checkpoint.exists()
    other = [
        json.loads(x)
        for x in (tmp_path / "b" / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    assert [x["loss"] for x in lines if "loss" in x] == [x["loss"] for x in other if "loss" in x]
    assert _states_equal(a.last_checkpoint, b.last_checkpoint)
    c = train(_config("train.seed=1"), data, tmp_path / "c")
    assert not _states_equal(a.last_checkpoint, c.last_checkpoint)


def _tensors(state: object, prefix: str = "") -> dict[str, torch.Tensor]:
    """Every tensor in a checkpoint, by path."""
    if isinstance(state, torch.Tensor):
        return {prefix: state}
    if isinstance(state, dict):
        return {k: v for key, x in state.items() for k, v in _tensors(x, f"{prefix}/{key}").items()}
    if isinstance(state, (list, tuple)):
        return {k: v for i, x in enumerate(state) for k, v in _tensors(x, f"{prefix}/{i}").items()}
    return {}


def _embedding_change(a: Path, b: Path, data: Path) -> float:
    """The largest relative change, over modalities, between two trained models' embeddings of
    ``data`` (|e_a - e_b| / |e_a| over all its items): rounding alone moves a few steps of
    Adam by 1e-6 to 1e-3 of it (more with one thread than two), another model by about 1."""
    ma, mb = load_model(a), load_model(b)
    ea = embed_catalog(ma.model, scan(data), ImageLoader(ma.config.data))
    eb = embed_catalog(mb.model, scan(data), ImageLoader(mb.config.data))
    return max(
        float(
            np.linalg.norm(ea[m].embeddings - eb[m].embeddings) / np.linalg.norm(ea[m].embeddings)
        )
        for m in ea
    )


class _Kill(Exception):
    pass


def _unbroken_and_killed(cfg: RunConfig, data: Path, tmp_path: Path) -> TrainResult:
    """Train ``cfg`` whole in ``tmp_path/unbroken`` (returned), and again in ``tmp_path/broken``
    killed during step 13 (its last checkpoint: step 10)."""
    unbroken = train(cfg, data, tmp_path / "unbroken")

    def kill(step: int, _: object) -> None:
        if step == 13:
            raise _Kill

    with pytest.raises(_Kill):
        train(cfg, data, tmp_path / "broken", on_step=kill)
    return unbroken


@pytest.mark.parametrize(
    "overrides",
    [
        (),  # full network, pixels through a DataLoader
        (  # frozen trunk cached, augmented colour copies, dropout drawing from the RNG
            "model.freeze=to_block4",
            "model.dropout=0.3",
            "data.augment.color.gamma=[0.5,2.0]",
            "data.augment.color.permute_channels=true",
        ),
        (  # the model default dropout 0.5; pixels augmented live on the device
            "model.dropout=0.5",
            "data.augment.color.crop_p=0.5",
            "data.augment.touch.hflip_p=0.5",
            "data.augment.touch.gamma=[0.5,2.0]",
        ),
        (  # cached trunk, dropout 0.5, augmented colour through the trunk every step
            "model.freeze=to_block4",
            "model.dropout=0.5",
            "train.augment_copies=0",
            "data.augment.color.gamma=[0.5,2.0]",
            "data.augment.color.crop_p=0.5",
        ),
    ],
    ids=["full", "cached", "full-dropout-augment", "cached-dropout-live-augment"],
)
def test_kill_and_resume_equals_unbroken_run(data: Path, tmp_path: Path, overrides):
    cfg = _config(*overrides)
    unbroken = _unbroken_and_killed(cfg, data, tmp_path)
    assert torch.load(tmp_path / "broken/checkpoints/last.pt", weights_only=True)["step"] == 10
    resumed = train(cfg, data, tmp_path / "broken", resume=True)
    assert _states_equal(unbroken.last_checkpoint, resumed.last_checkpoint)
    a = torch.load(unbroken.last_checkpoint, weights_only=True)
    b = torch.load(resumed.last_checkpoint, weights_only=True)
    tensors_a, tensors_b = _tensors(a), _tensors(b)  # model, optimiser, RNG: bit for bit
    assert tensors_a.keys() == tensors_b.keys() and len(tensors_a) > 20
    assert [k for k in tensors_a if not torch.equal(tensors_a[k], tensors_b[k])] == []
    timing = ("steps_per_s", "trunk_cache_s")

    def log(run: Path) -> list[dict[str, object]]:
        lines = (run / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
        return [{k: v for k, v in json.loads(x).items() if k not in timing} for x in lines]

    assert log(tmp_path / "broken") == log(tmp_path / "unbroken")  # the log is continuous


def test_a_resume_on_other_data_is_refused(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: a run killed on one dataset resumed on another (a new --data, or the same names
    rendered again) without a word, and its checkpoint then named only the second. Refused
    before any press video is decoded (`drop_unpressed`: a minute for PhysiCLeAR's)."""
    import shutil

    from lookfeel.train import loop

    cfg = _config()
    _unbroken_and_killed(cfg, data, tmp_path)
    other = Path(shutil.copytree(data, tmp_path / "other"))
    image = sorted((other / "depth").iterdir())[0]
    image.write_bytes(image.read_bytes() + b"\0")  # the same names, another file
    before = (tmp_path / "broken/checkpoints/last.pt").read_bytes()
    decoded = []
    drop = loop.drop_unpressed
    monkeypatch.setattr(loop, "drop_unpressed", lambda *a, **k: decoded.append(1) or drop(*a, **k))
    with pytest.raises(ConfigError, match=r"--resume \(resume=True\): .*last\.pt was trained on "
                       r"another dataset than .*other, or on this one before"):  # fmt: skip
        train(cfg, other, tmp_path / "broken", resume=True)
    assert decoded == []
    assert (tmp_path / "broken/checkpoints/last.pt").read_bytes() == before
    moved = Path(shutil.copytree(data, tmp_path / "moved"))  # a moved copy is the same data
    train(cfg, moved, tmp_path / "broken", resume=True)


def test_a_resume_may_cache_and_decode_otherwise_and_is_told_of_other_threads(
    data: Path, tmp_path: Path
):
    """QA: a run resumed on another number of CPU threads ended silently away from the
    unbroken run, while a resume with another cache folder, decoding or progress bar (the same
    numbers) was refused as a changed config."""
    threads = torch.get_num_threads()
    cfg = _config("train.threads=1")
    unbroken = _unbroken_and_killed(cfg, data, tmp_path)
    assert torch.load(tmp_path / "broken/checkpoints/last.pt", weights_only=True)["threads"] == 1
    same = _config(
        "train.threads=1",
        f"data.cache_dir={tmp_path / 'cache'}",
        "data.decode=processes",
        "data.workers=1",
        "train.progress=false",
    )
    stale = tmp_path / "broken/checkpoints/.last.pt.k1ll3d.tmp"  # a kill mid-write leaves it
    stale.write_bytes(b"half a checkpoint")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the same thread count: no word
        resumed = train(same, data, tmp_path / "broken", resume=True)
    assert _states_equal(unbroken.last_checkpoint, resumed.last_checkpoint)
    assert not stale.exists()
    assert torch.get_num_threads() == threads  # given back
    more = _config("train.threads=2", "train.steps=24")
    with pytest.warns(UserWarning, match=r"trained on 1 CPU thread\(s\) and resumes on 2: .*"
                      r"train.threads=1"):  # fmt: skip
        train(more, data, tmp_path / "broken", resume=True)


def test_a_run_resumes_without_its_pretrained_file_or_named_from_elsewhere(
    data: Path, tmp_path: Path
):
    """A resumed run takes every weight from its checkpoint: the weights file it started from
    is not read again, and naming it another way (from another folder) is no change."""
    from lookfeel.models import create_backbone

    weights = tmp_path / "resnet18.pth"
    torch.save(create_backbone("resnet18").state_dict(), weights)
    net = ["model.backbone=resnet18", "model.width=null", "data.image_size=32"]
    train(_config(*net, f"model.pretrained={weights}", "train.steps=2"), data, tmp_path / "run")
    weights.rename(tmp_path / "moved.pth")  # gone from where the run named it
    longer = _config(*net, "model.pretrained=moved.pth", "train.steps=3")
    resumed = train(longer, data, tmp_path / "run", resume=True)
    assert load_model(resumed.last_checkpoint).step == 3
    with pytest.raises(ConfigError, match=r"data.image_size \(32 -> 40\)"):  # others: refused
        train(_config(*net[:2], "data.image_size=40", "train.steps=4"), data, tmp_path / "run",
              resume=True)  # fmt: skip


def test_a_run_saved_in_nchw_layout_resumes_channels_last(data: Path, tmp_path: Path):
    """A run killed before training went channels-last on the CPU (session 26) holds its Adam
    state in NCHW layout. Resumed now, its convolutions are channels-last and the state is laid
    out alike (`_state_like_params`): a fused update over two layouts would move the wrong
    weights (about 0.1 off in a step). The resumed run ends where the unbroken NCHW run does,
    up to the two layouts' rounding."""
    unbroken = _unbroken_and_killed(_config("train.channels_last=false"), data, tmp_path)
    last = tmp_path / "broken/checkpoints/last.pt"
    state = torch.load(last, weights_only=True)
    conv = next(v for v in state["optimizer"]["state"].values() if v["exp_avg"].dim() == 4)
    assert conv["exp_avg"].is_contiguous()  # written in NCHW
    del state["config"]["train"]["channels_last"]  # as a checkpoint from before the key
    torch.save(state, last)
    (tmp_path / "broken/config.yaml").write_text(
        "\n".join(
            line
            for line in (tmp_path / "broken/config.yaml").read_text(encoding="utf-8").splitlines()
            if "channels_last" not in line
        )
        + "\n",
        encoding="utf-8",
    )
    resumed = train(_config(), data, tmp_path / "broken", resume=True)
    after = torch.load(resumed.last_checkpoint, weights_only=True)
    conv = next(v for v in after["optimizer"]["state"].values() if v["exp_avg"].dim() == 4)
    assert conv["exp_avg"].is_contiguous(memory_format=torch.channels_last)
    assert _embedding_change(unbroken.last_checkpoint, resumed.last_checkpoint, data) < 0.01
    assert not _states_equal(unbroken.last_checkpoint, resumed.last_checkpoint)  # another layout


def test_channels_last_is_a_layout_not_another_model(data: Path, tmp_path: Path):
    """``train.channels_last`` changes how the weights lie in memory, not what is learned: the
    two layouts end a run within rounding of each other, and each layout is reproducible."""
    steps = ("train.steps=6", "train.val_every=0")
    a = train(_config(*steps), data, tmp_path / "a")
    b = train(_config(*steps), data, tmp_path / "b")
    c = train(_config(*steps, "train.channels_last=false"), data, tmp_path / "c")
    weights = torch.load(a.last_checkpoint, weights_only=True)["model"]
    conv = next(v for v in weights.values() if v.dim() == 4 and v.shape[1] > 1)
    assert conv.is_contiguous(memory_format=torch.channels_last) and not conv.is_contiguous()
    assert _states_equal(a.last_checkpoint, b.last_checkpoint)
    assert 0 < _embedding_change(a.last_checkpoint, c.last_checkpoint, data) < 0.01


ENSEMBLE = ("model.members=2", "train.steps=4")


def test_an_ensemble_trains_its_members_as_separate_runs_and_embeds_as_one(
    data: Path, tmp_path: Path
):
    cfg = _config(*ENSEMBLE)
    result = train(cfg, data, tmp_path / "ens")
    single = train(member_config(cfg, 0), data, tmp_path / "single")
    # Member 0 is the plain run of the same seed; member 1 has its own seed, so other weights.
    assert _states_equal(tmp_path / "ens/members/0/checkpoints/last.pt", single.last_checkpoint)
    assert member_config(cfg, 1).train.seed != cfg.train.seed
    assert member_config(cfg, 1).model.members == 1
    assert not _states_equal(
        tmp_path / "ens/members/0/checkpoints/last.pt",
        tmp_path / "ens/members/1/checkpoints/last.pt",
    )
    trained = load_model(result.last_checkpoint)
    assert trained.config.model.members == 2 and trained.step == 4
    assert set(result.validation) >= {"depth_to_depth_top1", "touch_to_depth_top1"}
    branch = trained.model.branch("touch")
    assert isinstance(branch, BranchEnsemble)
    for k, member in enumerate(branch.member_branches()):  # each member holds its run's weights
        own = torch.load(tmp_path / f"ens/members/{k}/checkpoints/last.pt", weights_only=True)
        for name, value in member.state_dict().items():
            assert torch.equal(value, own["model"][f"branches.touch.{name}"])
    emb = embed_catalog(trained.model, scan(data), ImageLoader(trained.config.data))
    parts = embed_catalog(
        load_model(single.last_checkpoint).model, scan(data), ImageLoader(trained.config.data)
    )
    touch = emb[Modality.TOUCH].embeddings
    assert touch.shape[1] == 2 * 16  # two members of embed_dim 16, side by side
    first = parts[Modality.TOUCH].embeddings  # member 0's own, scaled by 1/sqrt(2)
    assert torch.allclose(
        torch.from_numpy(touch[:, :16]), torch.from_numpy(first) / 2**0.5, atol=1e-5
    )


def test_an_ensemble_resumes_keeping_finished_members(data: Path, tmp_path: Path):
    cfg = _config(*ENSEMBLE)
    unbroken = train(cfg, data, tmp_path / "unbroken")
    broken = tmp_path / "broken"
    train(member_config(cfg, 0), data, broken / "members/0")  # finished before the kill
    half = member_config(_config(*ENSEMBLE, "train.steps=2"), 1)
    train(half, data, broken / "members/1")  # killed half way
    done = (broken / "members/0/checkpoints/last.pt").stat().st_mtime_ns
    with pytest.raises(ConfigError, match="already holds a run; pass --resume"):
        train(cfg, data, broken)
    resumed = train(cfg, data, broken, resume=True)
    assert (broken / "members/0/checkpoints/last.pt").stat().st_mtime_ns == done  # kept
    assert _states_equal(unbroken.last_checkpoint, resumed.last_checkpoint)
    with pytest.raises(ConfigError, match=r"^--resume \(resume=True\): no run in .* to resume"):
        train(cfg, data, tmp_path / "new", resume=True)
    with pytest.raises(ConfigError, match="model.members: must be >= 1"):
        _config("model.members=0")


def test_run_errors_are_clear(data: Path, tmp_path: Path):
    train(_config("train.steps=2", "train.val_every=0"), data, tmp_path / "run")
    # Each names the Python argument beside the CLI flag (QA: a library error said only flags).
    with pytest.raises(ConfigError, match=r"already holds a run .* pass --resume \(resume=True\) "
                       r"to continue it, or choose another --out \(out=\.\.\.\)$"):  # fmt: skip
        train(_config(), data, tmp_path / "run")
    with pytest.raises(ConfigError, match=r"^--resume \(resume=True\): the config differs from "
                       r"the run's .* train.lr \(0.001 -> 0.5\)"):  # fmt: skip
        train(_config("train.lr=0.5"), data, tmp_path / "run", resume=True)
    with pytest.raises(ConfigError, match=r"^--resume \(resume=True\): no checkpoint at .* to "
                       "resume from"):  # fmt: skip
        train(_config(), data, tmp_path / "new", resume=True)
    with pytest.raises(DatasetError, match="none of the paper's test fabrics"):
        train(_config("train.split=paper"), data, tmp_path / "paper")
    with pytest.raises(ConfigError, match="num_properties=2, but labels.csv has 4"):
        train(_config("model.num_properties=2"), data, tmp_path / "props")


def test_views_the_data_lacks_are_one_line_beside_its_other_problems(tmp_path: Path):
    """train() as a library call: a sense of train.views that the data holds no item of is
    one line naming train.views and the --set that fits (not a line per fabric), and the
    scan's other problems still follow it."""
    touch = write_tiny_dataset(tmp_path / "touch", fabrics=4, drapes=1, flat_presses=0)
    for sense in ("depth", "color"):
        for p in (touch / sense).iterdir():
            p.unlink()
        (touch / sense).rmdir()
    bad = sorted((touch / "touch").glob("*.png"))[0]
    bad.write_bytes(b"not an image")
    cfg = _config("train.val_pairs=[depth_to_touch,touch_to_touch]")
    with pytest.raises(DatasetError) as info:
        train(cfg, touch, tmp_path / "run")
    lines = str(info.value).splitlines()
    assert lines[0] == f"2 problem(s) in {touch}:"
    assert lines[1] == (
        f"  {touch}: the run's train.views [depth, color, touch] use depth and color, of which "
        'the data holds no item (it holds touch alone): --set "train.views=[touch,touch]" '
        '--set "train.val_pairs=[touch_to_touch]" trains on what it holds'
    )
    assert lines[2].startswith(f"  {bad}: ") and len(lines) == 3
    assert not (tmp_path / "run").exists()


def test_the_class_heads_a_message_gives_read_back_as_the_columns(tmp_path: Path):
    """The --set of class heads that the labels have reads back, through the config parser,
    as those columns, even where a bare word would read as YAML's true or a number."""
    from lookfeel.train.loop import resolve_classes

    root = write_tiny_dataset(tmp_path / "d", fabrics=4, drapes=1)
    (root / "labels.csv").write_text(
        "fabric_id,yes,1e3,stiffness\n1,0,foam,0.5\n2,1,wood,1.5\n3,0,foam,2\n4,1,wood,1\n",
        encoding="utf-8",
    )
    catalog = scan(root)
    asked = _config("model.class_heads=['yes',roughness,'1e3']")
    with pytest.raises(ConfigError) as info:
        resolve_classes(catalog, asked)
    message = str(info.value)
    assert message.startswith(
        "model.class_heads: 'roughness' is not a column of labels.csv (have: yes, stiffness, "
        "1e3); give the heads your labels have: --set "
    )
    given = shlex.split(message.partition("--set ")[2].partition(", or")[0])
    assert load_config(RunConfig, TINY, given).model.class_heads == ("yes", "1e3")
    assert message.endswith(', or --set "model.class_heads=[]" for none')
    # No column of classes at all: no head.
    (root / "labels.csv").write_text(
        "fabric_id,stiffness\n1,0.5\n2,1.5\n3,2\n4,1\n", encoding="utf-8"
    )
    with pytest.raises(ConfigError, match=r"two classes or more to learn: --set "
                       r'"model.class_heads=\[\]" for no head$'):  # fmt: skip
        resolve_classes(scan(root), asked)


def _strict_json_lines(path: Path) -> list[dict]:
    """metrics.jsonl read as JSON proper: Python's bare NaN and Infinity are refused."""

    def refuse(name: str) -> None:
        raise ValueError(f"{path}: {name} is not JSON")

    return [
        json.loads(x, parse_constant=refuse) for x in path.read_text(encoding="utf-8").splitlines()
    ]


def test_a_diverging_run_stops_with_one_line_and_keeps_its_last_finite_checkpoint(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    out = tmp_path / "nan"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    sets = ["train.steps=30", "train.lr=1e8", "train.log_every=1", "train.checkpoint_every=1"]
    assert main([*args, *(a for s in sets for a in ("--set", s))]) == 1
    err = capsys.readouterr().err
    said = re.fullmatch(
        r"lookfeel: train: the loss became (NaN|infinite) at step (\d+), in its term "
        r"depth_color_touch_loss \(train\.lr=1e\+08 too high\?\); the last finite checkpoint "
        r"is kept at (.+) \(step (\d+)\)\n",
        err,
    )
    assert said is not None, err
    bad, kept, at = int(said[2]), Path(said[3]), int(said[4])
    assert kept == out / "checkpoints" / "last.pt" and at == bad - 1
    assert load_model(kept).step == at  # finite weights: it loads
    lines = _strict_json_lines(out / "metrics.jsonl")
    assert lines[-1]["step"] == bad and lines[-1]["loss"] is None  # null, not NaN
    assert all(x["loss"] is not None for x in lines[:-1] if "loss" in x)

    # Read only at log steps: the line names the window, and nothing was written before it.
    with pytest.raises(TrainingDiverged) as e:
        train(_config("train.lr=1e8", "train.checkpoint_every=0"), data, tmp_path / "early")
    assert re.fullmatch(
        r"train: the loss became (NaN|infinite) between steps 1 and 5, in its term "
        r"depth_color_touch_loss \(train\.lr=1e\+08 too high\?\); no checkpoint was written "
        r"before it \(train\.checkpoint_every=0\)",
        str(e.value),
    )
    assert not (tmp_path / "early" / "checkpoints").exists()


def test_non_finite_weights_are_never_written_over_a_checkpoint(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Weights that turn NaN in the very step a checkpoint is due (its loss, computed before
    the update, still finite) stop the run; the previous checkpoint stays as it was."""
    import lookfeel.train.loop as loop

    steps = []
    step = loop.train_step

    def poisoned(run: loop.TrainRun, batch: dict) -> dict:
        terms = step(run, batch)
        steps.append(1)
        if len(steps) == 10:
            next(run.net.parameters()).data.fill_(float("nan"))
        return terms

    monkeypatch.setattr(loop, "train_step", poisoned)
    out = tmp_path / "run"
    cfg = _config("train.checkpoint_every=5", "train.val_every=0")
    with pytest.raises(TrainingDiverged) as e:
        train(cfg, data, out)
    last = out / "checkpoints" / "last.pt"
    assert str(e.value) == (
        "train: the weights became NaN at step 10 (train.lr=0.001 too high?); the last finite "
        f"checkpoint is kept at {last} (step 5)"
    )
    assert load_model(last).step == 5


def test_cli_train_then_load_and_embed(data: Path, tmp_path: Path, capsys):
    out = tmp_path / "cli"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    assert main([*args, "--set", "train.steps=4", "--set", "train.val_every=2"]) == 0
    printed = capsys.readouterr().out
    assert "Trained 4 steps" in printed and "val touch_to_depth_top1" in printed
    assert "  validation on 2 held-out fabrics (one press a touch query; " in printed
    loaded = load_model(out / "checkpoints" / "best.pt")
    assert loaded.config.train.steps == 4 and loaded.step in (2, 4)
    assert loaded.model.modalities == (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)
    assert main([*args, "--set", "train.lr=2"]) == 1
    assert "already holds a run" in capsys.readouterr().err
    alexnet = ["--set", "model.backbone=alexnet", "--set", "model.width=null"]
    alexnet += ["--set", "data.image_size=64"]  # its least is 63: 32 px is refused first
    weights = ["--pretrained", str(tmp_path / "missing.pth")]
    assert main([*args[:-1], str(tmp_path / "p"), *alexnet, *weights]) == 1
    assert "missing.pth" in capsys.readouterr().err


def test_a_run_on_stacked_touch_frames_embeds_and_answers_queries_alike(data: Path, tmp_path: Path):
    from lookfeel.data import ImageError
    from lookfeel.index.query import load_query_bytes, load_query_image

    cfg = _config("train.steps=2", "train.val_every=0", "data.touch_frames=[0,-1]")
    result = train(cfg, data, tmp_path / "run")
    loaded = load_model(result.last_checkpoint)
    assert loaded.config.data.touch_frames == (0, -1)
    assert loaded.model.branch("touch").in_channels == 6
    catalog = scan(data)
    loader = ImageLoader(loaded.config.data)
    touch = embed_catalog(loaded.model, catalog, loader)[Modality.TOUCH]
    press = touch.items[0]
    assert len(touch.embeddings) == len(catalog.items(Modality.TOUCH, cfg.data.touch_kinds))
    # A query names one frame file of a press; its other frames are read beside it.
    query = load_query_image(press.frames[-1], Modality.TOUCH, loaded.config.data)
    assert torch.equal(query, loader.load(press))
    with torch.inference_mode():
        again = loaded.model({"touch": query[None, None]})["touch"][0]
    torch.testing.assert_close(again, torch.from_numpy(touch.embeddings[0]), atol=1e-5, rtol=0)
    with pytest.raises(ImageError, match=r"up.png: this model reads frames \[0, -1\]"):
        load_query_bytes(press.frames[-1].read_bytes(), "up.png", Modality.TOUCH, cfg.data)


def test_two_processes_agree_with_one(data: Path, tmp_path: Path):
    """torchrun --nproc_per_node 2 on the same global batch gives one process's weights.

    Like the paper's set-up (AlexNet cached to fc6, fc7 trained), the trainable part here has
    no BatchNorm: BatchNorm statistics are per process under DDP, so runs would differ by design.
    """
    common = ["--config", str(TINY), "--data", str(data), "--set", "train.steps=6"]
    common += ["--set", "train.val_every=0", "--set", "train.progress=false"]
    common += ["--set", "model.freeze=to_block4"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"}
    single = [sys.executable, "-m", "lookfeel", "train", *common, "--out", str(tmp_path / "one")]
    subprocess.run(single, check=True, env=env, capture_output=True, timeout=240)
    multi = [
        sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
        "-m", "lookfeel", "train", *common, "--out", str(tmp_path / "two"),
    ]  # fmt: skip
    proc = subprocess.run(multi, env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # One process reports the run they trained together.
    assert proc.stdout.count("Trained 6 steps; run in") == 1, proc.stdout
    assert _states_equal(
        tmp_path / "one/checkpoints/last.pt", tmp_path / "two/checkpoints/last.pt", atol=1e-5
    )


def test_init_from_another_run_copies_matching_weights(data: Path, tmp_path: Path):
    from lookfeel.checkpoint import CheckpointError, init_from_checkpoint
    from lookfeel.models import create_model

    source = train(_config("train.views=[depth,depth]", "train.split=none"), data, tmp_path / "a")
    # Same architecture: every tensor is copied, so the fresh model equals the source run's.
    cfg = _config("train.views=[depth,depth]")
    model = create_model(cfg.model, [Modality.DEPTH])
    assert init_from_checkpoint(model, source.last_checkpoint) == []
    saved = torch.load(source.last_checkpoint, weights_only=True)["model"]
    assert all(torch.equal(model.state_dict()[k], v) for k, v in saved.items())
    # A different projection size: the backbone is copied, the projection starts fresh (and
    # training says so), and a model with no branch in common is refused.
    # The warning counts what was copied (QA: it said only how many were not).
    with pytest.warns(UserWarning, match=r"copied 26 of 28 tensors from .*; 2 start fresh"):
        train(
            _config(
                "train.views=[depth,depth]",
                "train.steps=2",
                "model.embed_dim=12",
                f"model.init_from={source.last_checkpoint}",
            ),
            data,
            tmp_path / "b",
        )
    touch_only = create_model(cfg.model, [Modality.TOUCH])
    with pytest.raises(CheckpointError, match="no weight fits this model"):
        init_from_checkpoint(touch_only, source.last_checkpoint)
    # A branch the other run lacks starts fresh; one it has with another backbone or width
    # (a few BatchNorm counters fit, no weight) is refused (QA: it copied 3 of 84 and went on).
    both = create_model(cfg.model, [Modality.DEPTH, Modality.TOUCH])
    assert all(".touch." in k for k in init_from_checkpoint(both, source.last_checkpoint))
    wider = create_model(_config("model.width=4").model, [Modality.DEPTH])
    with pytest.raises(
        CheckpointError,
        match=r"only 5 of this model's 28 depth branch tensors "
        r"fit its weights \(another model.backbone or model.width\?\)",
    ):
        init_from_checkpoint(wider, source.last_checkpoint)


def test_a_backbone_and_a_loss_of_ones_own_train_through_the_config(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: a backbone and a loss registered from one's own module, as a researcher would, were
    refused by the config; and a checkpoint trained with a loss this process lacks must still
    load to embed (the loss plays no part there), while training with it is refused."""
    from lookfeel.losses import register_loss
    from lookfeel.models import register_backbone

    from ._registry import MeanTripletLoss, TinyViT, restored_registries

    out = tmp_path / "mine"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    sets = ["model.backbone=tinyvit", "model.width=8", "loss.kind=meantriplet", "train.steps=4"]
    args += [a for x in sets for a in ("--set", x)]
    with restored_registries():
        register_backbone("tinyvit", TinyViT)
        with restored_registries():
            register_loss("meantriplet", lambda c: MeanTripletLoss(c.triplet_margin))
            assert main(args) == 0, capsys.readouterr().err
        with pytest.warns(UserWarning, match="loss.kind: 'meantriplet' is not registered"):
            loaded = load_model(out / "checkpoints" / "last.pt")
        assert loaded.config.loss.kind == "meantriplet" and loaded.model.embed_dim == 16
        # A library of it opens for matching, which never builds the loss either.
        from lookfeel.index import Library, build_library

        with pytest.warns(UserWarning, match="loss.kind: 'meantriplet' is not registered"):
            build_library(out / "checkpoints" / "last.pt", data, tmp_path / "lib", folds=2)
            library = Library.open(tmp_path / "lib")
        assert library.config.loss.kind == "meantriplet"
        assert main([*args[:-2], "--set", "train.steps=6", "--resume"]) == 1
        assert "loss.kind: 'meantriplet' is not one of contrastive" in capsys.readouterr().err


def test_a_non_finite_loss_term_is_named(data: Path, tmp_path: Path):
    """QA: a loss of one's own whose term turned NaN was reported as the loss, with only the
    learning rate to suspect (session 54: the loss is named as the first suspect)."""
    from lookfeel.losses import register_loss

    from ._registry import NaNTermLoss, restored_registries

    with restored_registries(), pytest.raises(TrainingDiverged) as e:
        register_loss("nanterm", lambda c: NaNTermLoss())
        train(_config("loss.kind=nanterm", "train.checkpoint_every=0"), data, tmp_path / "r")
    assert str(e.value).startswith(
        "train: the loss became NaN between steps 1 and 5, in its term broken_loss (does the "
        "loss 'nanterm' divide by zero, say a mean over pairs a batch may lack? or "
        "train.lr=0.001 too high?)"
    )


def test_embedding_from_the_device_store_equals_from_the_loader(data: Path):
    import numpy as np

    from lookfeel.data import ImageStore
    from lookfeel.embedding import embed_items
    from lookfeel.models import create_model

    cfg = _config()
    model = create_model(cfg.model, [Modality.TOUCH, Modality.DEPTH])
    loader = ImageLoader(cfg.data)
    for m in (Modality.TOUCH, Modality.DEPTH):
        items = scan(data).items(m)
        store = ImageStore(loader, items)
        a = embed_items(model, items, loader, batch_size=5)
        b = embed_items(model, items, loader, batch_size=5, store=store)
        assert a.shape == (len(items), 16) and np.array_equal(a, b)
        c = embed_items(model, items, loader, batch_size=7, store=store)  # other batches
        np.testing.assert_allclose(a, c, atol=1e-5, rtol=0)
    assert model.training  # eval only inside


def test_cuda_graph_flag_changes_nothing_off_cuda(data: Path, tmp_path: Path):
    """``train.cuda_graph`` only applies on CUDA: on CPU the run is bit for bit the eager one."""
    eager = train(_config("train.steps=6", "train.val_every=0"), data, tmp_path / "eager")
    flag = _config("train.steps=6", "train.val_every=0", "train.cuda_graph=true")
    graphed = train(flag, data, tmp_path / "graphed")
    a = _tensors(torch.load(eager.last_checkpoint, weights_only=True))
    b = _tensors(torch.load(graphed.last_checkpoint, weights_only=True))
    assert a.keys() == b.keys() and [k for k in a if not torch.equal(a[k], b[k])] == []


def test_tree_map_pairs_nested_batches():
    from lookfeel.train.loop import _tree_map

    a = {"inputs": {"depth": torch.zeros(2)}, "y": torch.ones(2)}
    b = {"inputs": {"depth": torch.full((2,), 3.0)}, "y": torch.full((2,), 4.0)}
    out = _tree_map(lambda x, y: x + y, a, b)
    assert torch.equal(out["inputs"]["depth"], torch.full((2,), 3.0))
    assert torch.equal(out["y"], torch.full((2,), 5.0))


def test_precision_travels_with_the_checkpoint_and_a_cpu_run_ignores_it(data: Path, tmp_path: Path):
    auto = train(_config("train.steps=3"), data, tmp_path / "auto")
    fp32 = train(_config("train.steps=3", "model.precision=fp32"), data, tmp_path / "fp32")
    assert load_model(fp32.last_checkpoint).model.precision == "fp32"
    assert load_model(auto.last_checkpoint).model.precision == "auto"
    # On a CPU both are fp32: the same weights to the bit.
    assert _states_equal(auto.last_checkpoint, fp32.last_checkpoint)


@pytest.mark.parametrize("fails", [False, True], ids=["returns", "raises"])
def test_train_gives_back_the_callers_cudnn_autotuner_setting(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fails: bool
):
    """On CUDA a run turns cuDNN's autotuner on for its fixed shapes; whatever runs after it (an
    evaluation's batches of every size) must get the caller's setting back, on error too."""
    import lookfeel.train.loop as loop

    def tuned_run(*args: object, **kwargs: object) -> str:
        torch.backends.cudnn.benchmark = True  # as `_train` does on CUDA
        if fails:
            raise RuntimeError("the run failed")
        return "trained"

    monkeypatch.setattr(loop, "_train", tuned_run)
    monkeypatch.setattr(torch.backends.cudnn, "benchmark", False)
    if fails:
        with pytest.raises(RuntimeError, match="the run failed"):
            train(_config("train.steps=1"), data, tmp_path / "run")
    else:
        assert train(_config("train.steps=1"), data, tmp_path / "run") == "trained"
    assert torch.backends.cudnn.benchmark is False


def _draws() -> tuple[torch.Tensor, float, float]:
    """The next numbers of torch's, NumPy's and Python's global generators."""
    return torch.rand(3), float(np.random.random()), random.random()


@pytest.mark.parametrize("fails", [False, True], ids=["returns", "raises"])
def test_train_gives_back_the_callers_random_numbers_and_thread_count(
    data: Path, tmp_path: Path, fails: bool
):
    """A run seeds torch's generator from train.seed and sets train.threads; the caller's
    stream went on from the run's seed and its thread count stayed the run's (QA: with user
    seeds 123 and 456, the numbers drawn after train were the same). Now both come back as
    they were, when the run ends and when it raises; the ensemble's draws too."""
    threads = torch.get_num_threads()
    torch.set_num_threads(3)  # not the run's 1
    try:
        for extra in [()] if fails else [(), ("model.members=2",)]:
            torch.manual_seed(123)
            np.random.seed(4)
            random.seed(5)
            expected = _draws()
            torch.manual_seed(123)
            np.random.seed(4)
            random.seed(5)
            run = ["train.steps=2", "train.val_every=0", "train.threads=1", *extra]
            out = tmp_path / f"run{len(extra)}"
            if fails:  # diverges at its first log step, after the seed and the threads
                with pytest.raises(TrainingDiverged):
                    train(_config(*run, "train.lr=1e8"), data, out)
            else:
                train(_config(*run), data, out)
            after = _draws()
            assert torch.equal(after[0], expected[0]) and after[1:] == expected[1:]
            assert torch.get_num_threads() == 3
    finally:
        torch.set_num_threads(threads)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_a_cuda_run_gives_back_the_callers_cuda_random_numbers(data: Path, tmp_path: Path):
    torch.cuda.manual_seed(7)
    expected = torch.rand(3, device="cuda")
    torch.cuda.manual_seed(7)
    cfg = _config("train.steps=2", "train.val_every=0", "train.device=cuda", "model.dropout=0.3")
    train(cfg, data, tmp_path / "a")
    assert torch.equal(torch.rand(3, device="cuda"), expected)
    again = train(cfg, data, tmp_path / "b")  # the run's own seed still decides its dropout
    assert _states_equal(tmp_path / "a" / "checkpoints" / "last.pt", again.last_checkpoint)


def test_a_device_this_pytorch_lacks_is_refused_in_one_line(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
):
    """train.device=cuda on a CPU build of PyTorch raised RuntimeError (QA); the CLI printed a
    traceback. Now it is a `DeviceError`, said before the data are read."""
    monkeypatch.setattr(torch.version, "cuda", None)  # a CPU build, on any machine
    monkeypatch.setattr(torch.version, "hip", None)
    with pytest.raises(DeviceError, match=r"^train\.device 'cuda': this PyTorch has no CUDA"):
        train(_config("train.device=cuda"), tmp_path / "no-data", tmp_path / "run")
    out = tmp_path / "cli"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    assert main([*args, "--set", "train.device=cuda"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lookfeel: train.device 'cuda': this PyTorch has no CUDA (torch ")
    assert err.count("\n") == 1 and not out.exists()


def test_an_image_smaller_than_the_backbone_takes_is_refused_before_the_data_are_read(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """alexnet at 32 px (the tiny config's size) trained until the trunk cache's first forward
    pass and died with a 40-line traceback (QA). Now `train` refuses it first: the dataset
    given here does not exist, and the size, not the data, is what it names."""
    alexnet = ("model.backbone=alexnet", "model.width=null")
    for extra in ((), ("model.members=2",)):  # an ensemble's too, before its first member
        with pytest.raises(ConfigError, match=r"^data\.image_size=32 is below the 63 px"):
            train(_config(*alexnet, *extra), tmp_path / "no-data", tmp_path / "run")
        assert not (tmp_path / "run").exists()
    out = tmp_path / "cli"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    assert main([*args, "--set", "data.image_size=8"]) == 1  # compact needs 16
    assert capsys.readouterr().err == (
        "lookfeel: data.image_size=8 is below the 16 px on each side that "
        "model.backbone=compact accepts; set data.image_size to at least 16, or choose "
        "another model.backbone\n"
    )
    assert not out.exists()


def test_a_cluster_the_head_has_no_class_for_is_refused_naming_it(data: Path, tmp_path: Path):
    # The tiny fabrics' cluster8 column holds 0, 1 and 2 ((id - 1) % 3).
    cfg = _config("model.cluster_head=true", "model.num_clusters=2", "train.steps=1")
    with pytest.raises(ConfigError, match=r"labels.csv: fabric F0003 is in cluster 2, and the "
                       r"cluster head has model.num_clusters=2 \(clusters 0-1\); set "
                       r"model.num_clusters=3$"):  # fmt: skip
        train(cfg, data, tmp_path / "run")
    three = _config("model.cluster_head=true", "model.num_clusters=3", "train.steps=1")
    assert train(three, data, tmp_path / "ok").steps == 1


def test_a_folder_of_the_user_s_own_config_is_not_a_run_to_write_into(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `train --config exp1/config.yaml --out exp1` replaced the user's commented config
    with the resolved one: a folder holding a config.yaml was taken for a run. A run writes
    split.json beside it; a folder without is refused, unchanged."""
    exp = tmp_path / "exp1"
    exp.mkdir()
    mine = "# my experiment: keep these notes\n" + TINY.read_text(encoding="utf-8")
    (exp / "config.yaml").write_text(mine, encoding="utf-8")
    code = main(
        ["train", "--config", str(exp / "config.yaml"), "--data", str(data), "--out", str(exp)]
    )
    assert code == 1
    err = capsys.readouterr().err
    assert f"--out {exp}: the folder holds files and is not a lookfeel run" in err
    assert (exp / "config.yaml").read_text(encoding="utf-8") == mine and [
        p.name for p in exp.iterdir()
    ] == ["config.yaml"]


def test_a_resume_into_a_read_only_run_is_refused_before_training(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: a resume whose checkpoints/ was read-only trained for 40 s, then failed on its
    first checkpoint, leaving log lines of steps never saved: refused before any step."""
    from lookfeel import atomic

    cfg = _config("train.steps=10", "train.checkpoint_every=5")
    train(cfg, data, tmp_path / "run")
    checkpoints = tmp_path / "run" / "checkpoints"
    real = os.access
    monkeypatch.setattr(
        atomic.os, "access", lambda p, m, **k: False if Path(p) == checkpoints else real(p, m, **k)
    )
    steps: list[int] = []
    longer = _config("train.steps=20", "train.checkpoint_every=5")
    with pytest.raises(PermissionError) as e:
        train(longer, data, tmp_path / "run", resume=True, on_step=lambda s, _: steps.append(s))
    assert e.value.filename == str(checkpoints) and steps == []


def test_a_run_stopped_while_writing_its_first_last_pt_resumes_from_best_pt(
    data: Path, tmp_path: Path
):
    """QA: killed while its first last.pt was written (best.pt of that step was written just
    before), a run refused --resume ("stopped before its first checkpoint") and its steps were
    trained again. It resumes from best.pt, and ends as an unbroken run does."""
    cfg = _config()
    unbroken = _unbroken_and_killed(cfg, data, tmp_path)  # broken: checkpoints of step 10
    checkpoints = tmp_path / "broken" / "checkpoints"
    assert torch.load(checkpoints / "best.pt", weights_only=True)["step"] == 10
    (checkpoints / "last.pt").unlink()  # as if killed while writing it
    with pytest.raises(ConfigError, match="already holds a run"):
        train(cfg, data, tmp_path / "broken")  # not started again over it either
    resumed = train(cfg, data, tmp_path / "broken", resume=True)
    assert _states_equal(unbroken.last_checkpoint, resumed.last_checkpoint)


def test_a_run_that_fails_before_its_first_checkpoint_leaves_its_folder_as_found(
    data: Path, tmp_path: Path
):
    """QA: a run that failed before its first checkpoint left config.yaml, split.json and
    metrics.jsonl behind, so the folder looked like a run. What the run made goes (the
    folders above it too); a folder it was given keeps the user's files; a run of an
    ensemble goes as a whole."""

    def kill(step: int, _: object) -> None:
        raise _Kill

    cfg = _config("train.steps=4", "train.checkpoint_every=2", "train.val_every=0")
    with pytest.raises(_Kill):
        train(cfg, data, tmp_path / "new" / "run", on_step=kill)
    assert not (tmp_path / "new").exists()
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes\n", encoding="utf-8")
    (mine / "checkpoints").mkdir()
    with pytest.raises(_Kill):
        train(cfg, data, mine, on_step=kill)
    assert sorted(p.name for p in mine.iterdir()) == ["checkpoints", "notes.txt"]
    assert (mine / "notes.txt").read_text(encoding="utf-8") == "my notes\n"
    with pytest.raises(_Kill):
        train(_config(*ENSEMBLE), data, tmp_path / "ensemble", on_step=kill)
    assert not (tmp_path / "ensemble").exists()


def test_a_run_killed_after_its_first_checkpoint_keeps_its_files_and_resumes(
    data: Path, tmp_path: Path
):
    """What a failed run removes (above) never touches a run with a checkpoint: it resumes."""

    def kill(step: int, _: object) -> None:
        if step == 3:
            raise _Kill

    cfg = _config(
        "train.steps=4", "train.checkpoint_every=2", "train.val_every=0", "train.log_every=1"
    )
    run = tmp_path / "run"
    with pytest.raises(_Kill):
        train(cfg, data, run, on_step=kill)
    assert {"config.yaml", "split.json", "metrics.jsonl", "checkpoints"} <= {
        p.name for p in run.iterdir()
    }
    assert torch.load(run / "checkpoints" / "last.pt", weights_only=True)["step"] == 2
    resumed = train(cfg, data, run, resume=True)
    assert resumed.steps == 4
    assert torch.load(resumed.last_checkpoint, weights_only=True)["step"] == 4
