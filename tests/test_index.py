"""The fabric library: search backends, calibration, building (sharded, resumable), opening."""

from __future__ import annotations

import json
import math
import shutil
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lookfeel.checkpoint import load_model
from lookfeel.cli import main
from lookfeel.data import DatasetError, ImageLoader, scan
from lookfeel.embedding import embed_catalog
from lookfeel.index import (
    AUTO_FAISS_MIN_ROWS,
    ExactSearch,
    FaissSearch,
    Library,
    LibraryError,
    Matcher,
    build_library,
    calibrate_pair,
    choose_backend,
)
from lookfeel.index import build as build_module
from lookfeel.index.calibrate import (
    calibrate,
    fit_unknown_logit,
    threshold_for,
    unknown_probability,
)
from lookfeel.metrics import fit_temperature, pairwise_distances
from lookfeel.metrics._ranking import prepare
from lookfeel.metrics.cross_map import fit_cross_maps
from lookfeel.modality import Modality, Pair

from ._library import tiny_library


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "index", shard_size=8)


# ---- search --------------------------------------------------------------------------------


def test_exact_search_equals_brute_force():
    rng = np.random.default_rng(0)
    g, q = rng.normal(size=(50, 8)), rng.normal(size=(3, 8))
    truth = pairwise_distances(q, g)
    s = ExactSearch(g.astype(np.float32))
    d, idx = s.search(q, 5)
    assert idx.shape == (3, 5)
    np.testing.assert_array_equal(idx, np.argsort(truth, axis=1)[:, :5])
    np.testing.assert_allclose(d, np.sort(truth, axis=1)[:, :5], atol=1e-5)
    d_all, idx_all = s.search(q, 1000)  # k beyond G: every row, sorted
    assert idx_all.shape == (3, 50) and (np.diff(d_all, axis=1) >= 0).all()
    np.testing.assert_allclose(s.distances(q[0]), truth[:1], atol=1e-5)


def test_faiss_search_finds_the_exact_neighbours_and_round_trips():
    rng = np.random.default_rng(1)
    g = rng.normal(size=(400, 16)).astype(np.float32)
    q = g[:20] + 0.01 * rng.normal(size=(20, 16)).astype(np.float32)
    exact = ExactSearch(g)
    index = FaissSearch.from_bytes(FaissSearch.build(g).to_bytes())
    assert len(index) == 400 and not index.exact
    d, idx = index.search(q, 10)
    de, ie = exact.search(q, 10)
    recall = np.mean([len(set(a) & set(b)) / 10 for a, b in zip(idx, ie, strict=True)])
    assert recall >= 0.95
    np.testing.assert_array_equal(idx[:, 0], np.arange(20))  # each query's own point first
    np.testing.assert_allclose(d[:, 0], de[:, 0], atol=1e-4)


def test_choose_backend_by_size_and_override():
    assert choose_backend("auto", AUTO_FAISS_MIN_ROWS - 1) == "numpy"
    assert choose_backend("auto", AUTO_FAISS_MIN_ROWS) == "faiss"
    assert choose_backend("faiss", 10) == "faiss"
    assert choose_backend("numpy", 10**7) == "numpy"
    with pytest.raises(ValueError, match="'annoy' is not one of auto, numpy, faiss"):
        choose_backend("annoy", 10)


# ---- calibration ---------------------------------------------------------------------------


def test_threshold_accepts_at_most_the_target_share():
    scores = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.05])
    t = threshold_for(scores, 0.1)  # 1 of 10 may be accepted: only 0.9
    assert 0.8 < t <= 0.9 and (scores >= t).sum() == 1
    t = threshold_for(scores, 0.05)  # none may be accepted
    assert t > 0.9 and (scores >= t).sum() == 0
    assert threshold_for(scores, 0.35) == pytest.approx(0.6, abs=1e-12)  # 3 accepted
    assert threshold_for(np.zeros(0), 0.05) == 0.0


def test_threshold_lies_in_the_gap_to_the_known_matches():
    # Absent-fabric scores that all underflowed to 0 (fabrics far apart): the smallest
    # threshold would accept any query above 0, e.g. P = 1e-10 beside P(unknown) = 1.
    absent = np.zeros(20)
    known = np.array([0.97, 0.9, 0.8])
    t = threshold_for(absent, 0.05, known)
    assert t == pytest.approx(0.4) and t > 1e-10 and (known >= t).all()
    # Overlapping scores: the same known matches accepted, the threshold between the highest
    # rejected absent score (0.3) and the lowest accepted known one (0.5).
    absent = np.array([0.6, 0.3, 0.2, 0.1, 0.1, 0.05, 0.0, 0.0, 0.0, 0.0])
    known = np.array([0.9, 0.5, 0.25, 0.2])
    t = threshold_for(absent, 0.1, known)
    assert t == pytest.approx(0.4) and (absent >= t).sum() == 1
    assert (known >= t).sum() == (known >= threshold_for(absent, 0.1)).sum() == 2
    # No known match above the smallest threshold: it stays the smallest.
    assert threshold_for(absent, 0.1, np.array([0.25])) == threshold_for(absent, 0.1)


def test_unknown_logit_is_the_maximum_likelihood_split():
    # Symmetric evidence: known matches at L = +1, absent at L = -1, so a = 0 and P = 1/2 at 0.
    a = fit_unknown_logit(np.ones(10), -np.ones(10))
    assert a == pytest.approx(0.0, abs=1e-4)
    assert unknown_probability(1.0, a) < 0.5 < unknown_probability(-1.0, a)
    assert unknown_probability(0.0, 0.0) == pytest.approx(0.5)
    assert (
        float(unknown_probability(1e6, 0.0)) == 0.0 and float(unknown_probability(-1e6, 0.0)) == 1.0
    )


def _fit_temperature_before(dist, query_fabric, gallery_fabric, exclude_self=None) -> float:
    """`fit_temperature` as it was before session 55 made its likelihood cheaper (each call
    took exp over two dense (Q, G) matrices, one almost all infinity): the reference."""
    from scipy.optimize import minimize_scalar

    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    d2 = np.square(prep.dist)
    true = prep.gidx[None, :] == prep.qidx[:, None]
    if prep.excluded is not None:
        d2[prep.excluded] = np.inf
        true &= ~prep.excluded
    keep = true.any(axis=1)
    d2, true = d2[keep], true[keep]
    min_all = d2.min(axis=1, keepdims=True)
    min_true = np.where(true, d2, np.inf).min(axis=1, keepdims=True)
    rel_all = d2 - min_all
    rel_true = np.where(true, d2 - min_true, np.inf)

    def nll(log_c: float) -> float:
        c = np.exp(log_c)
        lse_all = -c * min_all[:, 0] + np.log(np.exp(-c * rel_all).sum(axis=1))
        lse_true = -c * min_true[:, 0] + np.log(np.exp(-c * rel_true).sum(axis=1))
        return float(-(lse_true - lse_all).mean())

    finite = d2[np.isfinite(d2)]
    scale = float(np.median(finite[finite > 0])) if (finite > 0).any() else 1.0
    grid = np.log(1.0 / scale) + np.linspace(np.log(1e-4), np.log(1e4), 33)
    vals = np.array([nll(x) for x in grid])
    i = int(np.argmin(vals))
    if i in (0, len(grid) - 1):
        return float(np.exp(grid[i]))
    res = minimize_scalar(
        nll, bounds=(grid[i - 1], grid[i + 1]), method="bounded", options={"xatol": 1e-6}
    )
    return float(np.exp(res.x))


# Seeds 1148, 1183, 1184 and 1197 include fabrics so well separated that the likelihood is flat
# to rounding: a sum over the true items alone, in another order, moved c there by up to 33%.
@pytest.mark.parametrize("seed", [0, 1, 2, 1148, 1183, 1184, 1197])
def test_fit_temperature_is_the_same_as_before_it_was_made_cheaper(seed: int):
    rng = np.random.default_rng(seed)
    fabrics, per = int(rng.integers(5, 60)), int(rng.integers(2, 15))
    gf = np.repeat(np.arange(fabrics), per)
    rng.shuffle(gf)
    centres = rng.normal(size=(fabrics, 8))
    gallery = centres[gf] + rng.uniform(0.3, 3.0) * rng.normal(size=(len(gf), 8))
    new = np.arange(min(40, len(gf)))  # new queries: other drapes of the first items' fabrics
    queries = centres[gf[new]] + rng.normal(size=(len(new), 8))
    # The gallery itself as queries (each its own item left out), and new queries.
    for dist, qf, own in (
        (pairwise_distances(gallery, gallery), gf, np.arange(len(gf))),
        (pairwise_distances(queries, gallery), gf[new], None),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an edge of c's range: both say so alike
            got = fit_temperature(dist, qf, gf, own)
        assert got == pytest.approx(_fit_temperature_before(dist, qf, gf, own), rel=1e-9, abs=0)


def test_calibration_on_separated_fabrics():
    # 6 fabrics, 4 items each, tight clusters far apart: every known query is right and far
    # from every other fabric, so an absent-fabric query is recognised as unknown.
    rng = np.random.default_rng(2)
    centres = 10.0 * np.eye(6, 8)
    emb = np.concatenate([c + 0.1 * rng.normal(size=(4, 8)) for c in centres])
    fab = np.repeat(np.arange(1, 7), 4)
    pc = calibrate_pair(
        emb, fab, emb, fab, Modality.DEPTH, Modality.DEPTH, target_false_accept=0.05, folds=3
    )
    assert pc is not None
    assert pc.top1 == 1.0 and pc.n_present == 24 and pc.n_absent == 24 and pc.fabrics == 6
    assert pc.c > 0 and pc.false_accept <= 0.05
    assert pc.true_accept == 1.0 and pc.accepted_top1 == 1.0
    # Overlapping fabrics (all items from one distribution) are not separable: few accepted.
    noise = rng.normal(size=(24, 8))
    pn = calibrate_pair(noise, fab, noise, fab, Modality.DEPTH, Modality.DEPTH, folds=3)
    assert pn is not None and pn.top1 < 0.7 and pn.true_accept < 0.5
    # One item per fabric: leave-self-out leaves no true item, nothing to calibrate.
    one = calibrate_pair(emb[::4], fab[::4], emb[::4], fab[::4], Modality.DEPTH, Modality.DEPTH)
    assert one is None


def test_calibration_matches_through_a_map_only_when_it_does_better():
    """Touch and depth embed the same fabrics in different spaces: through a map fitted on
    other fabrics they match, by their own distances they do not, so the map is chosen. Where
    they share one space, a useless map (fitted on shuffled fabrics) is not."""
    rng = np.random.default_rng(7)
    d, t = Modality.DEPTH, Modality.TOUCH
    mixes = {d: rng.standard_normal((3, 8)), t: rng.standard_normal((3, 8))}

    def items(latent: np.ndarray, first: int) -> dict[Modality, tuple[np.ndarray, np.ndarray]]:
        f = np.repeat(np.arange(len(latent)), 4)
        noise = {m: 0.05 * rng.standard_normal((len(f), 8)) for m in mixes}
        return {m: (latent[f] @ mixes[m] + noise[m], f + first) for m in mixes}

    train, library = (
        items(rng.standard_normal((30, 3)), 100),
        items(rng.standard_normal((12, 3)), 1),
    )
    both = [Pair(t, d), Pair(d, t)]
    cal = calibrate(library, folds=3, map_pairs=both, map_items=train)
    pc = cal.pairs["touch_to_depth"]
    assert pc.mapped and pc.top1 > 0.9 and pc.top1_unmapped < 0.5
    assert cal.pairs["depth_to_touch"].mapped and cal.default_gallery[t] in (t, d)
    no_folds = calibrate(library, folds=0, map_pairs=both, map_items=train)  # nothing held out
    assert not any(p.mapped for p in no_folds.pairs.values())
    assert not cal.pairs["depth_to_depth"].mapped
    # Fitted on the library's own fabrics, each fold is measured through a map without it.
    own = calibrate(library, folds=3, map_pairs=both, map_items=library).pairs["touch_to_depth"]
    assert own.mapped and own.top1 > 0.9
    assert math.isnan(cal.pairs["depth_to_depth"].top1_unmapped)  # no map tried
    mixes[t] = mixes[d]  # one space: their own distances match
    train, library = (
        items(rng.standard_normal((30, 3)), 100),
        items(rng.standard_normal((12, 3)), 1),
    )
    shuffled = {m: (e, rng.permutation(f)) for m, (e, f) in train.items()}
    pu = calibrate(library, folds=3, map_pairs=both, map_items=shuffled).pairs["touch_to_depth"]
    assert not pu.mapped and pu.top1 == pu.top1_unmapped > 0.9
    restored = type(pc).from_dict(json.loads(json.dumps(pc.to_dict())))
    assert restored == pc


def test_each_folds_queries_are_measured_by_a_distance_without_the_folds_fabrics():
    rng = np.random.default_rng(3)
    emb, fab = rng.normal(size=(24, 4)), np.repeat(np.arange(1, 7), 4)
    left_out: list[set[int]] = []

    def without(fabrics: np.ndarray):
        left_out.append(set(fabrics.tolist()))
        return pairwise_distances

    d = Modality.DEPTH
    pc = calibrate_pair(emb, fab, emb, fab, d, d, folds=3, distances_without=without)
    assert pc == calibrate_pair(emb, fab, emb, fab, d, d, folds=3)  # same distances, same result
    assert sorted(len(f) for f in left_out) == [2, 2, 2] and set().union(*left_out) == set(fab)


# ---- building and opening ------------------------------------------------------------------


def test_library_holds_every_item_embedded_as_training_does(run, library: Path):
    data, ckpt = run
    lib = Library.open(library)
    manifest = json.loads((library / "manifest.json").read_text(encoding="utf-8"))
    assert manifest["status"] == "complete" and manifest["backend"] == "numpy"
    assert sorted(p.name for p in (library / "shards").iterdir()) == [
        "color-00000.npz", "color-00001.npz", "color-00002.npz",
        "depth-00000.npz", "depth-00001.npz", "depth-00002.npz",
        "touch-00000.npz", "touch-00001.npz", "touch-00002.npz",
    ]  # fmt: skip
    loaded = load_model(ckpt)
    want = embed_catalog(loaded.model, scan(data), ImageLoader(loaded.config.data))
    assert lib.modalities == (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)
    for m, e in want.items():
        table = lib.table(m)
        np.testing.assert_allclose(table.embeddings, e.embeddings, atol=1e-5)
        np.testing.assert_array_equal(table.fabric_ids, e.fabric_ids)
        assert [table.item(i).path for i in range(len(table))] == [
            str(Path(p).resolve()) for p in e.paths
        ]
    touch = lib.item("touch:0")
    assert touch.kind == "fold" and touch.press == "100" and touch.fabric_id == 1
    assert touch.image.endswith("F0001_fold_02_100.png")  # the configured frame (-2) of 3
    assert lib.fabrics[3].labels == {
        "thickness_mm": 1.5, "density": 0.6, "stiffness": 3.0, "stretchiness": 1.0,
    }  # fmt: skip
    assert lib.fabrics[3].cluster == 2 and "density" not in lib.fabrics[2].labels
    cal = lib.calibration
    assert set(cal.pairs) == {f"{q.value}_to_{g.value}" for q in Modality for g in Modality}
    assert cal.default_gallery[Modality.DEPTH] is Modality.DEPTH
    for p in cal.pairs.values():
        assert p.c > 0 and p.n_absent > 0 and p.threshold >= 0.0
        assert p.false_accept <= cal.target_false_accept
    with pytest.raises(KeyError, match="item id 'smell:1' is not"):
        lib.item("smell:1")
    with pytest.raises(KeyError, match="depth has no item 99"):
        lib.item("depth:99")


class _Kill(Exception):
    pass


def test_killed_build_resumes_and_equals_an_unbroken_one(run, library: Path, tmp_path: Path):
    _, ckpt = run
    data = shutil.copytree(run[0], tmp_path / "data")
    out = tmp_path / "lib"
    written: list[str] = []

    def kill_after_two(name: str, rows: int) -> None:
        written.append(name)
        if len(written) == 2:
            raise _Kill

    with pytest.raises(_Kill):
        build_library(ckpt, data, out, shard_size=8, on_shard=kill_after_two)
    # A first build writes beside OUT until it is complete.
    work = tmp_path / "lib.building"
    assert not out.exists() and json.loads((work / "manifest.json").read_text(encoding="utf-8"))[
        "status"
    ] == ("building")
    with pytest.raises(LibraryError, match="did not finish; run `lookfeel index build` again"):
        Library.open(out)
    resumed = build_library(ckpt, data, out, shard_size=8, on_shard=lambda n, r: None)
    assert (resumed.shards_reused, resumed.shards_embedded) == (2, 7)
    a, b = Library.open(out), Library.open(library)
    for m in Modality:
        np.testing.assert_array_equal(a.table(m).embeddings, b.table(m).embeddings)
    assert a.calibration == b.calibration
    again = build_library(ckpt, data, out, shard_size=8)
    assert (again.shards_reused, again.shards_embedded) == (9, 0)
    # A removed file changes only the shard it was in (fabric 6's last depth: the last shard).
    (data / "depth/F0006_Depth_New_000002.png").unlink()
    changed = build_library(ckpt, data, out, shard_size=8)
    assert changed.shards_embedded == 1 and changed.items[Modality.DEPTH] == 17
    assert len(Library.open(out).table(Modality.DEPTH)) == 17


def test_a_library_matches_through_maps_fitted_on_its_own_fabrics(
    run, library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    data, ckpt = run
    assert any("no cross-modal maps" in n for n in Library.open(library).calibration.notes)
    monkeypatch.setattr(build_module, "MIN_MAP_FABRICS", 3)  # the tiny library has 6 fabrics
    out = tmp_path / "mapped"
    build_library(ckpt, data, out, shard_size=64)
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    assert manifest["version"] == 2 and (out / "cross_maps.npz").is_file()
    cross = {p for p in Pair.every(list(Modality)) if not p.same}
    assert set(manifest["cross_maps"]["pairs"]) == {str(p) for p in cross}
    lib = Library.open(out)
    fitted_on = {m: (t.embeddings, t.fabric_ids) for m, t in lib.tables.items()}
    want = fit_cross_maps(fitted_on, cross)
    assert set(lib.cross_maps) == cross
    for p, cmap in lib.cross_maps.items():
        np.testing.assert_allclose(cmap.forward.coef, want[p].forward.coef, rtol=1e-6, atol=1e-9)
        assert not math.isnan(lib.calibration.pairs[str(p)].top1_unmapped)  # both were tried
    # A pair matched through its map ranks fabrics by the map's distance to their items.
    t2d = Pair(Modality.TOUCH, Modality.DEPTH)
    lib.calibration.pairs[str(t2d)] = replace(lib.calibration.pairs[str(t2d)], mapped=True)
    r = Matcher(lib).match_item("touch:0", gallery=Modality.DEPTH, top=6)
    depth = lib.table(Modality.DEPTH)
    d = lib.cross_maps[t2d].distances(lib.table(Modality.TOUCH).embeddings[:1], depth.embeddings)
    for f in r.fabrics:
        assert f.distance == pytest.approx(d[0][depth.fabric_ids == f.fabric_id].min())
    assert "cross-modal map" in r.message and len(r.fabrics) == 6
    # Damaged maps: one line naming the file.
    (out / "cross_maps.npz").write_bytes(b"not a zip")
    with pytest.raises(LibraryError, match=r"maps missing or damaged \(not an \.npz archive\)"):
        Library.open(out)
    # --no-cross-map: no maps, no file, nothing mapped.
    build_library(ckpt, data, out, shard_size=64, cross_map=False)
    plain = Library.open(out)
    assert not plain.cross_maps and not (out / "cross_maps.npz").exists()
    assert not any(p.mapped for p in plain.calibration.pairs.values())


def test_faiss_library_matches_like_the_exact_one(run, library: Path, tmp_path: Path):
    data, ckpt = run
    out = tmp_path / "faiss"
    result = build_library(ckpt, data, out, backend="faiss", shard_size=64)
    assert result.backend == "faiss"
    assert sorted(p.name for p in out.glob("index-*.faiss")) == [
        "index-color.faiss", "index-depth.faiss", "index-touch.faiss",
    ]  # fmt: skip
    fast, exact = Matcher(Library.open(out)), Matcher(Library.open(library))
    assert fast.library.search(Modality.DEPTH).name == "faiss"
    for item in ("depth:4", "touch:7", "color:11"):
        a, b = fast.match_item(item, top=3), exact.match_item(item, top=3)
        assert [f.fabric_id for f in a.fabrics] == [f.fabric_id for f in b.fabrics]
        assert [f.probability for f in a.fabrics] == pytest.approx(
            [f.probability for f in b.fabrics], abs=1e-6
        )


def test_build_errors_are_clear(run, tmp_path: Path):
    data, ckpt = run
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine", encoding="utf-8")
    with pytest.raises(LibraryError, match="not a lookfeel library; choose a new or empty"):
        build_library(ckpt, data, foreign)
    with pytest.raises(LibraryError, match="search backend 'annoy'"):
        build_library(ckpt, data, tmp_path / "x", backend="annoy")
    broken = tmp_path / "broken"
    shutil.copytree(data, broken)
    (broken / "depth/F0001_Depth_New_000000.png").write_bytes(b"not a png")
    with pytest.raises(DatasetError, match="F0001_Depth_New_000000.png"):
        build_library(ckpt, broken, tmp_path / "y")
    with pytest.raises(LibraryError, match="no lookfeel library|not a lookfeel library"):
        Library.open(foreign)
    with pytest.raises(LibraryError, match="library folder not found"):
        Library.open(tmp_path / "absent")
    # Called from Python, an option is named as the CLI's flag and as the argument.
    for kwargs, message in [
        ({"folds": -1}, r"^--folds \(folds\) must be 0 or more"),
        ({"calibration_queries": 0}, r"^--calibration-queries \(calibration_queries\) must be"),
        ({"target_false_accept": 1.5}, r"^--false-accept \(target_false_accept\) must be"),
    ]:
        with pytest.raises(LibraryError, match=message):
            build_library(ckpt, data, tmp_path / "z", **kwargs)
        assert not (tmp_path / "z").exists()


def test_changed_or_moved_checkpoint(run, library: Path, tmp_path: Path):
    _, ckpt = run
    copy = tmp_path / "lib"
    shutil.copytree(library, copy)
    moved = tmp_path / "moved.pt"
    shutil.copy(ckpt, moved)
    assert Library.open(copy, checkpoint=moved).load_model().step == 20
    with pytest.raises(LibraryError, match=r"not there; .*\(--checkpoint, Library.open's checkpo"):
        Library.open(copy, checkpoint=tmp_path / "gone.pt").load_model()
    moved.write_bytes(moved.read_bytes() + b"\0")
    with pytest.raises(LibraryError, match="differs from the one the library was built with"):
        Library.open(copy, checkpoint=moved).load_model()
    (copy / "shards/depth-00001.npz").write_bytes(b"damaged")
    with pytest.raises(LibraryError, match="depth-00001.npz: shard missing or damaged"):
        Library.open(copy)


def test_cli_index_build_and_info(run, tmp_path: Path, capsys):
    data, ckpt = run
    out = tmp_path / "lib"
    argv = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    assert main([*argv, "--quiet", "--false-accept", "0.1"]) == 0
    printed = capsys.readouterr().out
    assert "18 depth, 18 color, 18 touch; 3 shard(s) embedded, 0 reused; search numpy" in printed
    assert "touch_to_depth" in printed
    legend = "(top1: how often a library item's best match, its own item left out, is its own"
    assert legend in printed  # what top1, c and the threshold are
    assert "(in-sample: fitted and scored on the library itself" in printed
    assert printed.count(" (chance 1/6 = 0.167)  c ") == 9  # beside each pair's top1
    assert main(["index", "info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "compact at 32 px, D = 16" in printed and "target false-accept 0.1" in printed
    assert legend in printed
    assert main(["index", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["items"] == {"depth": 18, "color": 18, "touch": 18} and info["fabrics"] == 6
    # what built it, as a run records it (session 54): the dataset's fingerprint, the software
    from lookfeel.data import scan
    from lookfeel.provenance import software_versions

    assert info["data_fingerprint"] == scan(data).fingerprint()
    assert info["software"] == software_versions()
    assert f"(fingerprint {info['data_fingerprint'][:12]})" in printed
    assert main(["index", "info", str(tmp_path / "nothing")]) == 1
    assert "library folder not found" in capsys.readouterr().err
    assert math.isclose(info["calibration"]["target_false_accept"], 0.1)
