"""Decoding in worker processes (`lookfeel.data.decode_pool`, ``data.decode``): the same
arrays as threads, the same one-line errors and warnings, in order while the caller embeds."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.config import DataConfig, ModelConfig
from lookfeel.data import ImageError, ImageLoader, scan
from lookfeel.data.catalog import Item
from lookfeel.data.images import ArrayLoader
from lookfeel.data.video import TruncatedVideoWarning
from lookfeel.embedding import embed_catalog, embed_items
from lookfeel.modality import Modality
from lookfeel.models import create_model

from ._tiny import write_tiny_dataset


def _held(loader: ImageLoader, items) -> np.ndarray:
    return np.stack([loader.embed_array(it) for it in items])


@pytest.mark.parametrize("modality", [Modality.DEPTH, Modality.COLOR, Modality.TOUCH])
def test_processes_decode_the_same_arrays_as_threads(
    tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch, modality: Modality
):
    items = scan(tiny_dataset).items(modality)
    threads = ImageLoader(DataConfig(image_size=16, workers=2, decode="threads"))
    processes = ImageLoader(DataConfig(image_size=16, workers=2, decode="processes"))
    assert processes._uses_processes(len(items), 2)
    assert threads.preload(items) == processes.preload(items) == len(items)
    # Everything is held now: reading it decodes nothing more in this process.
    monkeypatch.setattr(ImageLoader, "_preprocess_file", lambda *a: pytest.fail("decoded again"))
    a, b = _held(threads, items), _held(processes, items)
    assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)


def test_decoding_in_processes_leaves_the_callers_torch_rng_alone(tiny_dataset: Path):
    # A DataLoader draws its workers' seed from torch's global RNG unless given its own: a
    # training run's dropout then shifted with whether its images decoded in processes.
    items = scan(tiny_dataset).items(Modality.DEPTH)
    loader = ImageLoader(DataConfig(image_size=16, workers=2, decode="processes"))
    torch.manual_seed(3)
    before = torch.get_rng_state()
    assert loader.preload(items) == len(items)
    assert torch.equal(torch.get_rng_state(), before)


def test_auto_uses_processes_for_many_files_only(tiny_config: DataConfig):
    loader = ImageLoader(tiny_config)  # decode: auto
    assert not loader._uses_processes(10, 2)
    assert loader._uses_processes(256, 2) == (os.name == "posix" and os.uname().sysname == "Linux")
    assert not loader._uses_processes(10_000, 1)
    arrays = ArrayLoader(DataConfig(image_size=16, decode="processes"), {}, Modality.DEPTH)
    assert not arrays._uses_processes(10_000, 2)  # its arrays live in this process only


def test_a_bad_file_in_a_worker_fails_as_in_one_process(tmp_path: Path):
    root = write_tiny_dataset(tmp_path / "d", fabrics=4)
    items = scan(root).items(Modality.COLOR)
    bad = items[5].path
    bad.write_bytes(bad.read_bytes()[:60])  # truncated after the scan
    for decode in ("threads", "processes"):
        loader = ImageLoader(DataConfig(image_size=16, workers=2, decode=decode))
        with pytest.raises(ImageError, match=f"{bad.name}: file is truncated") as e:
            loader.preload(items)
        assert e.value.path == bad


@pytest.mark.parametrize("decode", ["threads", "processes"])
def test_a_worker_warns_in_the_caller_as_in_one_process(tmp_path: Path, decode: str):
    pytest.importorskip("av")
    from ._video import PRESS, object_press, write_video

    good = write_video(tmp_path / "whole.mkv", object_press(1, PRESS, t=60))
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(good.read_bytes()[: int(good.stat().st_size * 0.6)])
    items = [Item(Modality.TOUCH, 1, (p,), None, p.stem) for p in (good, cut)]
    loader = ImageLoader(DataConfig(image_size=16, workers=2, decode=decode))
    with pytest.warns(TruncatedVideoWarning) as caught:
        assert loader.preload(items) == 2
    assert [str(w.message).split(": ")[0] for w in caught] == [str(cut)]


def test_preload_stream_says_what_is_ready_in_order(tmp_path: Path):
    root = write_tiny_dataset(tmp_path / "d", fabrics=12, drapes=10)
    items = scan(root).items(Modality.DEPTH)
    loader = ImageLoader(DataConfig(image_size=16, workers=2, decode="processes"))
    counts = list(loader.preload_stream(items))
    assert len(counts) > 1 and counts == sorted(counts) and counts[-1] == len(items)
    assert list(loader.preload_stream(items)) == [len(items)]  # all held: nothing to wait for
    # A control's loader serves its own arrays: ready without decoding them.
    given = {items[0].path: np.zeros((16, 16), np.float32)}
    control = ArrayLoader(DataConfig(image_size=16, workers=2), given, Modality.DEPTH)
    assert list(control.preload_stream(items))[-1] == len(items)


def test_embedding_from_processes_equals_threads(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    model = create_model(
        ModelConfig(backbone="compact", width=4, embed_dim=8),
        [Modality.DEPTH, Modality.COLOR, Modality.TOUCH],
    )
    got = {}
    for decode in ("threads", "processes"):
        loader = ImageLoader(DataConfig(image_size=16, workers=2, decode=decode))
        got[decode] = embed_catalog(model, catalog, loader, batch_size=4)
    for m, e in got["threads"].items():
        assert e.items == got["processes"][m].items
        np.testing.assert_array_equal(e.embeddings, got["processes"][m].embeddings)
        # As on a GPU: each batch embedded as soon as its images are decoded.
        loader = ImageLoader(DataConfig(image_size=16, workers=2, decode="processes"))
        items = list(e.items)
        streamed = embed_items(model, items, loader, 4, ready=loader.preload_stream(items))
        np.testing.assert_array_equal(streamed, e.embeddings)
