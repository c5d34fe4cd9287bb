"""Training tuples: Y = 0/1 semantics and ratio, multi-press touch, Siamese slots, seeding."""

import shutil
from pathlib import Path

import pytest
import torch
from torch.utils.data import DataLoader

from lookfeel.config import AugmentConfig, DataConfig
from lookfeel.data import DatasetError, ImageLoader, ImageStore, TupleDataset, scan
from lookfeel.modality import Modality, PressKind

D, C, T = Modality.DEPTH, Modality.COLOR, Modality.TOUCH


def _ds(root: Path, views=(D, C, T), length=200, seed=0, **cfg) -> TupleDataset:
    config = DataConfig(image_size=16, **cfg)
    return TupleDataset(scan(root), ImageLoader(config), views, length=length, seed=seed)


def test_same_and_different_fabric_tuples(tiny_dataset: Path):
    ds = _ds(tiny_dataset, same_fraction=0.25)
    ys = []
    for i in range(len(ds)):
        y, fabrics, items = ds.draw(i)
        ys.append(y)
        if y == 0.0:
            assert len(set(fabrics)) == 1
        else:
            assert len(set(fabrics)) == 3  # every pair in D3 is a negative
        for fid, picked in zip(fabrics, items, strict=True):
            assert all(it.fabric_id == fid for it in picked)
    assert 0.15 < ys.count(0.0) / len(ys) < 0.35


def test_item_layout_and_batching(tiny_dataset: Path):
    ds = _ds(tiny_dataset, length=8, presses=3)
    sample = ds[0]
    assert sample["inputs"]["depth"].shape == (1, 16, 16)
    assert sample["inputs"]["color"].shape == (3, 16, 16)
    assert sample["inputs"]["touch"].shape == (3, 3, 16, 16)  # (P, C, S, S)
    assert sample["properties"]["depth"].shape == (4,)
    batch = next(iter(DataLoader(ds, batch_size=4)))
    assert batch["inputs"]["touch"].shape == (4, 3, 3, 16, 16)
    assert batch["y"].shape == batch["fabric_ids"]["color"].shape == (4,)
    assert batch["clusters"]["depth"].dtype == torch.int64


def test_presses_are_distinct_fold_presses_of_one_fabric(tiny_dataset: Path):
    ds = _ds(tiny_dataset, views=(T,), same_fraction=1.0, presses=3)
    for i in range(20):
        _, _, (presses,) = ds.draw(i)
        assert len({it.press for it in presses}) == 3
        assert {it.kind for it in presses} == {PressKind.FOLD}


def test_siamese_slots_take_distinct_items(tiny_dataset: Path):
    ds = _ds(tiny_dataset, views=(D, D), same_fraction=1.0)
    for i in range(20):
        _, fabrics, (a, b) = ds.draw(i)
        assert fabrics[0] == fabrics[1] and a[0] != b[0]
    assert set(ds[0]["inputs"]) == {"depth", "depth.1"}


def test_seeded_by_seed_and_index(tiny_dataset: Path):
    a, b = _ds(tiny_dataset, seed=1), _ds(tiny_dataset, seed=1)
    assert [a.draw(i) for i in range(30)] == [b.draw(i) for i in range(30)]
    assert torch.equal(a[5]["inputs"]["color"], b[5]["inputs"]["color"])
    first = [a.draw(i) for i in range(30)]
    assert [a.draw(i) for i in range(30, 60)] != first
    assert [_ds(tiny_dataset, seed=2).draw(i) for i in range(30)] != first


def test_augmentation_is_seeded_and_off_for_validation(tiny_dataset: Path):
    aug = {C: AugmentConfig(gamma=(0.5, 2.0), permute_channels=True)}
    config = DataConfig(image_size=16, augment=aug)
    catalog, loader = scan(tiny_dataset), ImageLoader(config)
    train = TupleDataset(catalog, loader, (D, C), length=10, seed=0)
    again = TupleDataset(catalog, loader, (D, C), length=10, seed=0)
    plain = TupleDataset(catalog, loader, (D, C), length=10, seed=0, augment=False)
    x, x2, x0 = (
        train[3]["inputs"]["color"],
        again[3]["inputs"]["color"],
        plain[3]["inputs"]["color"],
    )
    assert torch.equal(x, x2)
    assert not torch.allclose(x, x0)
    assert torch.equal(train[3]["inputs"]["depth"], plain[3]["inputs"]["depth"])  # not listed


def test_clear_errors_for_unusable_catalogs(tiny_dataset: Path):
    with pytest.raises(DatasetError, match=r"none of the 6 fabrics \(1, 2, 3 and 3 more\) has"):
        _ds(tiny_dataset, touch_kinds=(PressKind.RAND,))
    small = scan(tiny_dataset).subset([1, 2])
    with pytest.raises(DatasetError, match="3 slots from different fabrics need at least"):
        TupleDataset(small, ImageLoader(DataConfig(image_size=16)), (D, C, T), length=4)


def test_fabrics_lacking_an_item_are_a_line_each_when_few_and_one_line_when_many(
    tiny_dataset: Path,
):
    """QA: flat presses only under data.touch_kinds fold gave a line per fabric and no fix.
    A few fabrics lacking keep a line each (which ones matters); more are one counted line,
    naming the first few; both give the --set of the press kinds that trains on them."""
    fold = (PressKind.FOLD,)
    for f in (1, 2):
        for p in (tiny_dataset / "touch").glob(f"F{f:04d}_fold_*"):
            p.unlink()
    fix = '--set "data.touch_kinds=[flat,fold]" trains on every kind the data holds'
    few = [str(p) for p in scan(tiny_dataset).lacking([T], fold)]
    assert few == [
        f"{tiny_dataset / 'touch'}: fabric {f} has no touch (fold presses) item; its presses "
        f"are flat (the run's data.touch_kinds asks fold): {fix}"
        for f in (1, 2)
    ]
    for f in (3, 4, 5):
        for p in (tiny_dataset / "touch").glob(f"F{f:04d}_fold_*"):
            p.unlink()
    with pytest.raises(DatasetError) as info:
        _ds(tiny_dataset, touch_kinds=fold)
    assert str(info.value) == (
        f"{tiny_dataset / 'touch'}: 5 of the 6 fabrics (1, 2, 3 and 2 more) have no touch (fold "
        f"presses) item; their presses are flat (the run's data.touch_kinds asks fold): {fix}"
    )
    # Every fabric lacking a modality: one line, with no press kind to suggest.
    shutil.rmtree(tiny_dataset / "depth")
    assert [p.message for p in scan(tiny_dataset).subset([1, 2, 3, 4]).lacking([D], fold)] == [
        "none of the 4 fabrics (1, 2, 3, 4) has a depth item"
    ]


def test_image_store_holds_one_row_per_item_or_press(tiny_dataset: Path):
    catalog, loader = scan(tiny_dataset), ImageLoader(DataConfig(image_size=16))
    depth, touch = catalog.items(D), catalog.items(T, loader.config.touch_kinds)
    assert len(depth) == 18 and len(touch) == 18  # fold presses by default
    assert len(catalog.items(T, [PressKind.FLAT])) == 12
    store = ImageStore(loader, [*depth, *touch, *depth[:3]])  # duplicates held once
    assert store.modalities == (D, T) and depth[0] in store
    assert store.rows(T, touch[4:6]) == [4, 5]
    x = store.batch(T, store.rows(T, touch[4:6]))
    assert x.shape == (2, 3, 16, 16) and x.dtype == torch.float32
    assert torch.equal(x[0], loader.load(touch[4]))  # exactly the loader's tensor
    d = store.batch(D, [17])
    assert d.shape == (1, 1, 16, 16) and torch.equal(d[0], loader.load(depth[17]))
    with pytest.raises(KeyError):
        store.rows(C, depth[:1])


def test_a_drawn_batch_keeps_the_tuple_rules_and_its_targets(tiny_dataset: Path):
    import numpy as np

    ds = _ds(tiny_dataset, views=(D, D, T), same_fraction=0.5, presses=3)
    b = ds.draw_batch(np.random.default_rng(7), 300)
    assert b.y.shape == (300,) and b.fabrics.shape == (300, 3)
    assert [p.shape for p in b.items] == [(300, 1), (300, 1), (300, 3)]
    same = b.y == 0.0
    assert 0.4 < same.mean() < 0.6
    assert (b.fabrics[same] == b.fabrics[same][:, :1]).all()
    assert all(len(set(row)) == 3 for row in b.fabrics[~same])
    for j, m in enumerate(ds.views):  # every item is of its slot's fabric
        ids = np.array([[ds.pool_items[m][i].fabric_id for i in row] for row in b.items[j]])
        assert (ids == np.array(ds.fabric_ids)[b.fabrics[:, j]][:, None]).all()
    assert (b.items[0] != b.items[1]).all()  # the Siamese depth slots: two images
    assert all(len(set(row)) == 3 for row in b.items[2])  # three distinct presses
    targets = ds.batch_targets(b.fabrics[:5])
    assert targets["fabric_ids"]["depth.1"].tolist() == [ds.fabric_ids[i] for i in b.fabrics[:5, 1]]
    assert targets["properties"]["touch"].shape == (5, 4)
    again = ds.draw_batch(np.random.default_rng(7), 300)
    assert all(np.array_equal(x, y) for x, y in zip(b.items, again.items, strict=True))


def test_pool_items_is_the_one_list_of_what_a_modality_draws(tiny_dataset: Path):
    """One name for the items a slot draws from (QA F19): `pool_items`, fabric by fabric, which
    the training batches index; the near-duplicate method `pools_items` is gone."""
    ds = _ds(tiny_dataset, length=4)
    assert not hasattr(ds, "pools_items")
    catalog = scan(tiny_dataset)
    for m in (D, C, T):
        assert ds.pool_items[m] == [it for f in catalog.fabrics for it in f.items_of(m, ds.kinds)]
