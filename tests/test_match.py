"""Matching queries against a library: preprocessing, ranking, pooling, unknowns, errors, CLI."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from lookfeel.cli import main
from lookfeel.data import ImageError, ImageLoader, scan
from lookfeel.index import (
    Library,
    LibraryError,
    Matcher,
    MatchFailure,
    MatchResult,
    build_library,
    load_query_image,
)
from lookfeel.index import match as match_module
from lookfeel.modality import Modality

from ._library import tiny_library
from ._tiny import write_depth, write_rgb


@pytest.fixture(scope="module")
def matcher(tmp_path_factory: pytest.TempPathFactory) -> Matcher:
    return Matcher(Library.open(tiny_library(tmp_path_factory, "match", shard_size=64)))


def test_query_images_are_preprocessed_exactly_as_training(run, matcher: Matcher):
    data, _ = run
    catalog = scan(data)
    loader = ImageLoader(matcher.data_config)
    for m in Modality:
        item = catalog.items(m)[4]
        got = load_query_image(loader.frame_path(item), m, matcher.data_config)
        assert got.dtype == torch.float32
        assert torch.equal(got, loader.load(item))


def test_a_new_depth_image_of_a_known_fabric_ranks_it_first(matcher: Matcher, tmp_path: Path):
    query = tmp_path / "new_drape.png"
    write_depth(query, fabric=3, k=99)  # a drape of fabric 3 the library has not seen
    [r] = matcher.match_files([query], Modality.DEPTH, top=6)
    assert r.query_modality is Modality.DEPTH and r.gallery_modality is Modality.DEPTH
    assert r.path == str(query) and r.paths == [str(query)] == r.query  # `query`: as before
    assert r.presses == 1 and r.backend == "numpy"
    assert r.fabrics[0].fabric_id == 3 and r.known and r.message.startswith("fabric 3 (P = ")
    probs = [f.probability for f in r.fabrics]
    assert [f.rank for f in r.fabrics] == [1, 2, 3, 4, 5, 6]
    assert probs == sorted(probs, reverse=True)
    assert sum(probs) + r.unknown_probability == pytest.approx(1.0)  # all 6 fabrics shown
    lib = matcher.library
    e = matcher.embed(matcher.load([query], Modality.DEPTH), Modality.DEPTH)[0]
    for f in r.fabrics:
        assert set(f.nearest) == {"depth", "color", "touch"}
        for m, refs in f.nearest.items():
            table = lib.table(Modality(m))
            rows = table.rows_of(f.fabric_id)
            want = np.linalg.norm(table.embeddings[rows] - e, axis=1)
            assert [ref.distance for ref in refs] == pytest.approx(sorted(want)[:2], abs=1e-5)
            for ref in refs:
                item = lib.item(ref.id)
                assert item.fabric_id == f.fabric_id and ref.path == item.image
        assert f.distance == pytest.approx(f.nearest["depth"][0].distance, abs=1e-5)
        assert f.labels == lib.fabrics[f.fabric_id].labels
    # Properties: the top 5 fabrics weighted by probability, among those with the label, by
    # label column as `predict` gives them; a number's mean is its value, a rank's (stiffness,
    # stretchiness: classes) the number behind the likeliest rank.
    by_name = r.properties
    assert list(by_name) == ["thickness_mm", "density", "stiffness", "stretchiness"]
    top5 = r.fabrics[:5]
    for name, est in by_name.items():
        known = [(f.labels[name], f.probability) for f in top5 if name in f.labels]
        v = np.array([x for x, _ in known])
        w = np.array([p for _, p in known]) / sum(p for _, p in known)
        assert est.fabrics == len(known)
        ranks = name in ("stiffness", "stretchiness")
        mean = est.number if ranks else est.value
        assert (est.probability is not None) == ranks and (est.number is not None) == ranks
        assert isinstance(mean, float)
        # rounded to 4 significant digits of the column's largest label (at most 4.0 here)
        assert mean == pytest.approx(float((w * v).sum()), abs=5e-4)
        spread = math.sqrt(float((w * (v - (w * v).sum()) ** 2).sum()))
        assert est.std == pytest.approx(spread, abs=5e-4)
    assert by_name["density"].fabrics == (4 if 2 in [f.fabric_id for f in top5] else 5)


def test_touch_presses_are_pooled_into_one_query(run, matcher: Matcher):
    data, _ = run
    presses = [data / "touch/F0004_fold_02_400.png", data / "touch/F0004_fold_02_401.png"]
    [r] = matcher.match_files(presses, Modality.TOUCH, top=3)
    assert r.presses == 2 and r.paths == [str(p) for p in presses] and r.path == str(presses[0])
    x = matcher.load(presses, Modality.TOUCH)
    assert x.shape == (1, 2, 3, 32, 32)
    with torch.inference_mode():
        branch = matcher.model.branch("touch")
        per_press = branch.backbone(x[0])  # (P, D0): each press alone, before pooling
        want = branch.project(per_press.amax(dim=0, keepdim=True))  # max over presses
    np.testing.assert_allclose(matcher.embed(x, Modality.TOUCH), want.numpy(), atol=1e-6)
    single = matcher.embed(matcher.load(presses[:1], Modality.TOUCH), Modality.TOUCH)
    assert not np.allclose(single, want.numpy())
    drapes = sorted((data / "color").glob("F0002_*.png"))
    results = matcher.match_files(drapes, Modality.COLOR, top=2)
    assert [res.paths for res in results] == [[str(p)] for p in drapes]  # one result each
    assert all(res.presses == 1 and len(res.fabrics) == 2 for res in results)


def test_many_files_are_embedded_in_batches_with_the_same_answers(
    run, matcher: Matcher, monkeypatch: pytest.MonkeyPatch
):
    data, _ = run
    drapes = sorted((data / "color").glob("*.png"))[:7]
    presses = sorted((data / "touch").glob("F0004_fold_*.png"))[:5]
    forward = matcher.model.forward
    batches: list[int] = []

    def counted(inputs: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        batches.extend(len(x) for x in inputs.values())
        return forward(inputs)

    monkeypatch.setattr(matcher.model, "forward", counted)
    monkeypatch.setattr(match_module, "EMBED_BATCH", 1000, raising=False)
    whole = matcher.match_files(drapes, Modality.COLOR, top=6)
    pooled = matcher.match_files(presses, Modality.TOUCH, top=6)
    assert batches == [7, 1]
    batches.clear()
    monkeypatch.setattr(match_module, "EMBED_BATCH", 3, raising=False)
    split = matcher.match_files(drapes, Modality.COLOR, top=6)
    assert batches == [3, 3, 1]  # 7 separate queries, 3 at a time
    batches.clear()
    x = matcher.load(drapes, Modality.COLOR)
    every = matcher.embed(x, Modality.COLOR)  # a batch given to embed is split alike
    assert batches == [3, 3, 1]
    batches.clear()
    assert matcher.match_files(presses, Modality.TOUCH, top=6)[0].fabrics == pooled[0].fabrics
    assert batches == [1]  # a pooled query's 5 presses still go through the model together
    one_pass = np.concatenate([matcher.embed(x[i : i + 1], Modality.COLOR) for i in range(7)])
    np.testing.assert_allclose(every, one_pass, atol=1e-6)
    assert [r.paths for r in split] == [r.paths for r in whole] == [[str(p)] for p in drapes]
    for a, b in zip(split, whole, strict=True):
        assert a.message == b.message and a.known == b.known
        assert [f.fabric_id for f in a.fabrics] == [f.fabric_id for f in b.fabrics]
        assert [f.probability for f in a.fabrics] == pytest.approx(
            [f.probability for f in b.fabrics], abs=1e-6
        )


def test_far_from_every_fabric_is_no_known_fabric(matcher: Matcher):
    table = matcher.library.table(Modality.DEPTH)
    far = table.embeddings.mean(axis=0) + 100.0  # far beyond every library item
    r = matcher.match_embedding(far, Modality.DEPTH, ["far"], top=3)
    assert not r.known and r.unknown_probability > 0.999
    assert r.message.startswith("no known fabric: the best match, fabric ")
    assert r.message.endswith(  # QA: it said "on held-out fabrics", and `index build` in-sample
        f"below the threshold {r.threshold:.3f} chosen for a 5% false-accept rate in-sample (on "
        "the library's own fabrics, each left out of the gallery in turn: not a rate measured "
        "on new ones)"
    )
    assert r.best_probability < r.threshold
    near = matcher.match_embedding(table.embeddings[7], Modality.DEPTH, ["item"], top=3)
    assert near.known and near.fabrics[0].fabric_id == int(table.fabric_ids[7])
    assert near.unknown_probability < 0.5


def test_no_known_object_says_objects_in_its_calibration_too(
    matcher: Matcher, monkeypatch: pytest.MonkeyPatch
):
    """A library of named objects (recordings: ``videos/<object>_<n>.mov``) says objects
    throughout: the threshold was chosen on its own objects, not on held-out fabrics."""
    import dataclasses

    lib = matcher.library
    named = {i: dataclasses.replace(r, name=f"thing{i}") for i, r in lib.fabrics.items()}
    monkeypatch.setattr(lib, "fabrics", named)
    far = lib.table(Modality.DEPTH).embeddings.mean(axis=0) + 100.0
    r = matcher.match_embedding(far, Modality.DEPTH, ["far"], top=3)
    assert r.message.startswith("no known object: the best match, thing")
    assert "in-sample (on the library's own objects, each left out" in r.message
    assert "fabric" not in r.message


def test_a_library_item_as_query_leaves_itself_out(matcher: Matcher):
    r = matcher.match_item("depth:7", top=6)
    ids = [ref.id for f in r.fabrics for refs in f.nearest.values() for ref in refs]
    assert "depth:7" not in ids and r.fabrics[0].fabric_id == 3
    assert min(f.distance for f in r.fabrics) > 0.0  # its own zero distance is gone
    with pytest.raises(KeyError, match="depth has no item 500"):
        matcher.match_item("depth:500")


def test_wrong_files_are_named(run, matcher: Matcher, tmp_path: Path):
    data, _ = run
    eight_bit = tmp_path / "eight_bit.png"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(eight_bit)
    text = tmp_path / "notes.png"
    text.write_text("not an image", encoding="utf-8")
    Image.open(data / "color/F0003_2.png").save(tmp_path / "photo.webp")  # PIL reads it; not we
    cases = [
        (tmp_path / "missing.png", Modality.DEPTH, "missing.png: file not found"),
        (eight_bit, Modality.DEPTH, "eight_bit.png: depth image is mode L; expected 16-bit"),
        (text, Modality.COLOR, r"notes.png: not a PNG or JPEG image \(.png, .jpg, .jpeg\): it"),
        (tmp_path / "photo.webp", Modality.COLOR, "photo.webp: is a WebP image, not a PNG or JP"),
        (tmp_path, Modality.COLOR, "is a folder, not an image file"),
        (data / "touch", Modality.TOUCH, "touch: is a folder, not a press: give a press's video"),
        (data / "depth/F0001_Depth_New_000000.png", Modality.TOUCH, "16-bit or float"),
    ]
    for path, modality, message in cases:
        with pytest.raises(ImageError, match=message):
            matcher.match_files([path], modality)
    with pytest.raises(LibraryError, match="top must be >= 1"):
        matcher.match_files([data / "depth/F0001_Depth_New_000000.png"], Modality.DEPTH, top=0)


def test_a_library_without_a_modality_says_so(run, tmp_path: Path, capsys):
    data, ckpt = run
    no_color = shutil.copytree(data, tmp_path / "data")
    shutil.rmtree(no_color / "color")
    build_library(ckpt, no_color, tmp_path / "lib")
    m = Matcher(Library.open(tmp_path / "lib"))
    query = tmp_path / "photo.png"
    write_rgb(query, fabric=2, k=5)
    with pytest.raises(LibraryError, match="no calibrated gallery for color queries"):
        m.match_files([query], Modality.COLOR)
    with pytest.raises(LibraryError, match="has no color items"):
        m.match_files([data / "depth/F0001_Depth_New_000000.png"], Modality.DEPTH,
                      gallery=Modality.COLOR)  # fmt: skip
    with pytest.raises(LibraryError, match=r"no calibration for color_to_touch \(calibrated: dep"):
        m.match_files([query], Modality.COLOR, gallery=Modality.TOUCH)  # no colour to calibrate
    [r] = m.match_files([data / "touch/F0002_fold_02_200.png"], Modality.TOUCH, top=2)
    assert set(r.fabrics[0].nearest) == {"depth", "touch"}
    # `lookfeel match` without --modality: a photo's folder says colour, which it lacks (it
    # used to ask which modality the photo shows, or take it for the only other sense).
    photo = str(data / "color/F0003_2.png")
    assert main(["match", "--index", str(tmp_path / "lib"), photo]) == 1
    assert capsys.readouterr().err.strip() == (
        f"lookfeel: {photo}: an image in a color/ folder shows color, which the library does "
        "not take (it takes depth, touch); give --modality depth or touch to read it as one of "
        "those anyway"
    )


def test_cli_match(run, matcher: Matcher, tmp_path: Path, capsys):
    data, _ = run
    lib = str(matcher.library.root)
    presses = [str(data / f"touch/F0005_fold_02_50{i}.png") for i in range(3)]
    assert main(["match", "--index", lib, "--modality", "touch", *presses, "--top", "2"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Query touch (3 presses: F0005_fold_02_500.png, F0005_fold_02_501")
    assert "rank  fabric       P        D  depth" in out
    assert "properties (the 5 likeliest fabrics weighted by P" in out  # 5, not --top's 2
    depth = str(data / "depth/F0004_Depth_New_000001.png")
    args = ["match", "--index", lib, "--modality", "depth", depth, "--top", "3"]
    assert main([*args, "--property-fabrics", "1", "--json"]) == 0
    [r] = json.loads(capsys.readouterr().out)
    assert len(r["fabrics"]) == 3 and r["property_fabrics"] == 1
    best = r["fabrics"][0]["fabric_id"]  # one fabric: its own labels, no spread
    labels = {f["id"]: f["labels"] for f in matcher.library.manifest["fabrics"]}[best]
    # As `predict --json`: label -> its value, probability ..., the spread and count beside.
    assert list(r["properties"]) == ["thickness_mm", "density", "stiffness", "stretchiness"]
    thickness = r["properties"]["thickness_mm"]
    assert thickness == {
        "value": pytest.approx(labels["thickness_mm"]),
        "probability": None,
        "probabilities": {},
        "number": None,
        "std": 0.0,
        "fabrics": 1,
    }
    stiffness = r["properties"]["stiffness"]  # a rank: the class, the mean rank behind it
    assert stiffness["value"] == int(labels["stiffness"]) and stiffness["probability"] == 1.0
    assert stiffness["number"] == pytest.approx(labels["stiffness"])
    assert r["path"] == depth and r["paths"] == [depth] and r["error"] is None
    assert "query" not in r
    assert main([*args, "--property-fabrics", "1"]) == 0
    assert "properties (the likeliest fabric weighted by P)" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main([*args, "--property-fabrics", "0"])
    assert "--property-fabrics: must be >= 1, got 0" in capsys.readouterr().err
    depth = str(data / "depth/F0004_Depth_New_000001.png")
    assert main(["match", "--index", lib, "--modality", "depth", depth, "--json"]) == 0
    [r] = json.loads(capsys.readouterr().out)
    assert r["fabrics"][0]["fabric_id"] == 4 and r["query_modality"] == "depth"
    assert len(r["fabrics"]) == 5 and set(r["fabrics"][0]["nearest"]) == {"depth", "color", "touch"}
    assert main(["match", "--index", lib, "--modality", "depth", str(tmp_path / "x.png")]) == 1
    assert "x.png: file not found" in capsys.readouterr().err
    assert main(["match", "--index", str(tmp_path), "--modality", "depth", depth]) == 1
    assert "not a lookfeel library" in capsys.readouterr().err


def test_each_query_is_matched_or_answered_with_its_error(
    run, matcher: Matcher, tmp_path: Path, capsys
):
    """QA: `match --json good.png missing.png other.png` exited 1 with no JSON at all, where
    `predict` answers each query: a file that cannot be used is now its own query's `error`
    and the others are matched; the exit status is 1 only when nothing was."""
    data, _ = run
    lib = str(matcher.library.root)
    good = [str(data / f"depth/F000{f}_Depth_New_000001.png") for f in (4, 3)]
    missing = str(tmp_path / "missing.png")
    notes = tmp_path / "notes.png"
    notes.write_text("not an image", encoding="utf-8")
    answers = matcher.match_each([good[0], missing, notes, good[1]], "depth", top=2)
    gone = MatchFailure(missing, [missing], Modality.DEPTH, f"{missing}: file not found")
    assert answers[1] == gone
    bad = answers[2]
    assert isinstance(bad, MatchFailure) and bad.paths == [str(notes)]
    assert bad.error.startswith(f"{notes}: not a PNG or JPEG image")
    alone = matcher.match_files(good, "depth", top=2)
    for a, r in zip(alone, (answers[0], answers[3]), strict=True):  # the others: as alone
        assert isinstance(r, MatchResult) and (r.paths, r.fabrics) == (a.paths, a.fabrics)
        assert r.properties == a.properties
    with pytest.raises(ImageError, match="missing.png: file not found"):
        matcher.match_files([good[0], missing], "depth")  # the Python API's one call: raised

    for modality in (["--modality", "depth"], []):  # guessed: the others' modality
        argv = ["match", "--index", lib, *modality, good[0], missing, good[1], "--top", "2"]
        assert main([*argv, "--json"]) == 0
        out = capsys.readouterr()
        entries = json.loads(out.out)
        assert [e["error"] for e in entries] == [None, f"{missing}: file not found", None]
        assert out.err.splitlines() == [
            f"lookfeel: warning: {missing}: file not found; nothing matched for it"
        ]
        entry = entries[1]
        assert list(entry) == list(entries[0])  # every key, as each of predict's entries
        assert (entry["path"], entry["paths"], entry["query_modality"]) == (
            missing,
            [missing],
            "depth",
        )
        assert (entry["fabrics"], entry["properties"], entry["known"]) == ([], {}, None)
        assert [e["fabrics"][0]["fabric_id"] for e in (entries[0], entries[2])] == [4, 3]
    # Without --json: each result printed, the failed one in its place, as predict prints it.
    assert main(["match", "--index", lib, "--modality", "depth", good[0], missing]) == 0
    blocks = capsys.readouterr().out.strip().split("\n\n")
    assert blocks[0].startswith("Query depth (1 image: F0004_Depth_New_000001.png) against")
    assert blocks[1] == f"{missing}: file not found (nothing matched)"
    # Nothing matched: exit 1, each query's error said; --json still answers each.
    argv = ["match", "--index", lib, "--modality", "depth", missing, str(notes), "--json"]
    assert main(argv) == 1
    out = capsys.readouterr()
    assert [(e["path"], e["error"] is not None) for e in json.loads(out.out)] == [
        (missing, True),
        (str(notes), True),
    ]
    assert out.err.splitlines()[0] == f"lookfeel: {missing}: file not found"
    # Touch presses are one query, which a missing press fails (as `predict --together`).
    for modality in (["--modality", "touch"], []):
        presses = [str(data / "touch/F0005_fold_02_500.png"), missing]
        assert main(["match", "--index", lib, *modality, *presses, "--json"]) == 1
        [entry] = json.loads(capsys.readouterr().out)
        assert (entry["path"], entry["paths"]) == (presses[0], presses)
        assert (entry["query_modality"], entry["error"]) == ("touch", f"{missing}: file not found")


def test_property_estimates_drop_the_weights_rounding_noise_and_name_classes(
    matcher: Matcher, tmp_path: Path
):
    from dataclasses import replace

    from lookfeel.index import format_match

    lib = shutil.copytree(matcher.library.root, tmp_path / "lib")
    manifest = json.loads((lib / "manifest.json").read_text(encoding="utf-8"))
    for f in manifest["fabrics"]:
        if f["id"] == 2:
            f["labels"]["thickness_mm"] = 0.0  # a label of 0 beside 0.5 ... 3.0
    (lib / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    m = Matcher(Library.open(lib))
    # stiffness (f % 5) and stretchiness (f % 2) are ranks (whole numbers, repeated): classes
    assert m.library.classes == {"stiffness": ("0", "1", "2", "3", "4"), "stretchiness": ("0", "1")}

    # Fabric 2 all but certain, fabric 1 at 1e-20: its labels must not show as 5e-21.
    by_name = m._properties([(2, 1.0), (1, 1e-20)])
    thickness = by_name["thickness_mm"]
    assert (thickness.value, thickness.std, thickness.probability) == (0.0, 0.0, None)
    assert str(thickness.value) == "0.0"  # not -0.0
    stretch = by_name["stretchiness"]
    assert (stretch.value, stretch.probability) == (0, 1.0)
    assert stretch.probabilities == {"0": 1.0, "1": 0.0}
    assert by_name["density"].fabrics == 1  # fabric 2's density is unknown: fabric 1's, 0.2

    # The most likely class is the one whose fabrics carry the most weight, as a share.
    split = m._properties([(1, 0.6), (2, 0.3), (3, 0.1)])
    assert (split["stretchiness"].value, split["stretchiness"].probability) == (1, 0.7)
    assert split["stiffness"].probabilities == {"0": 0.0, "1": 0.6, "2": 0.3, "3": 0.1, "4": 0.0}
    assert split["stretchiness"].number == pytest.approx(0.7)  # the numbers are kept as well

    query = tmp_path / "q.png"
    write_depth(query, fabric=2, k=50)
    [r] = m.match_files([query], Modality.DEPTH)
    line = format_match(replace(r, properties=by_name)).splitlines()[-1]
    assert line == (
        "  properties (the 5 likeliest fabrics weighted by P): thickness_mm 0 ± 0, "
        "density 0.2 ± 0, stiffness 2 (100%), stretchiness 0 (100%)"
    )
    # No known fabric: the shares are of the nearest fabrics, not a finding (QA: "100%" beside
    # P = 0.000 read as certainty).
    unknown = format_match(replace(r, known=False, properties=by_name))
    assert unknown.splitlines()[-1].startswith(
        "  properties (the 5 likeliest fabrics weighted by P; no known fabric: the nearest "
        "ones', a guess): thickness_mm 0 ± 0"
    )


def test_a_model_trained_on_still_frames_takes_frames_and_videos(
    run, matcher: Matcher, tmp_path: Path
):
    from lookfeel.checkpoint import TOUCH_FRAMES, read_checkpoint

    from ._video import PRESS, object_press, write_video

    data, ckpt = run
    assert read_checkpoint(ckpt)["touch_input"] == TOUCH_FRAMES
    assert matcher.touch_input == TOUCH_FRAMES
    [r] = matcher.match_files([data / "touch/F0003_fold_02_300.png"], Modality.TOUCH, top=2)
    assert len(r.fabrics) == 2 and r.fabrics[0].name is None  # a numbered fabric: no name
    pytest.importorskip("av")
    video = write_video(tmp_path / "press.mov", object_press(1, PRESS, t=14))
    with pytest.warns(UserWarning, match=r"press.mov: this model was trained on still GelSight"):
        [r] = matcher.match_files([video], Modality.TOUCH, top=2)  # read as a press video is read
    assert r.paths == [str(video)] and len(r.fabrics) == 2


def test_a_modality_by_name_and_a_single_path_are_taken_as_meant(run, matcher: Matcher):
    from lookfeel.errors import LookfeelError
    from lookfeel.modality import ModalityError

    data, _ = run
    photo = data / "color/F0002_1.png"
    cfg = matcher.data_config
    assert torch.equal(
        load_query_image(photo, "color", cfg), load_query_image(photo, Modality.COLOR, cfg)
    )
    [want] = matcher.match_files([photo], Modality.COLOR, gallery=Modality.DEPTH)
    for paths in (str(photo), photo):  # one file, not one per character of its name
        [r] = matcher.match_files(paths, "color", gallery="depth")
        assert r.paths == [str(photo)] and r.query_modality is Modality.COLOR
        assert r.gallery_modality is Modality.DEPTH and r.fabrics == want.fabrics
    assert matcher.match_item("depth:7", gallery="color").gallery_modality is Modality.COLOR
    press = data / "touch/F0004_fold_02_400.png"
    assert matcher.match_files(str(press), "touch")[0].query_modality is Modality.TOUCH
    with pytest.raises(ModalityError, match="unknown modality 'colour'; expected one of"):
        matcher.match_files([photo], "colour")
    with pytest.raises(ModalityError, match="unknown modality 'deep'"):
        matcher.match_files([photo], Modality.COLOR, gallery="deep")
    with pytest.raises(ModalityError, match="'colour'"):
        load_query_image(photo, "colour", cfg)
    with pytest.raises(LookfeelError, match="no query file given"):
        matcher.match_files([], Modality.COLOR)


def test_a_query_embedding_must_be_one_finite_vector_of_the_library_s_width(matcher: Matcher):
    e = matcher.library.table(Modality.DEPTH).embeddings[7]
    r = matcher.match_embedding(torch.from_numpy(e), "depth", "q.png")
    assert r.known and r.paths == ["q.png"] and r.path == "q.png"
    for bad in (np.full_like(e, np.nan), np.where(np.arange(len(e)) == 0, np.inf, e)):
        with pytest.raises(LibraryError, match="embedding of q.png holds non-finite values"):
            matcher.match_embedding(bad, Modality.DEPTH, ["q.png"])  # not "library item" itself
    dim = matcher.library.embed_dim
    for shape in [(dim // 2,), (2, dim)]:
        with pytest.raises(LibraryError, match=rf"has shape \({shape[0]}, ?.*expected \({dim},\)"):
            matcher.match_embedding(np.zeros(shape, np.float32), Modality.DEPTH, ["q"])


def test_a_device_this_machine_lacks_is_one_line(matcher: Matcher):
    from lookfeel.devices import DeviceError

    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        Matcher(matcher.library, device="tpu")


def _press_videos(folder: Path) -> dict[str, Path]:
    """One press as colour, as a single grey channel, as grey stored in colour (red, green and
    blue equal), and as colour after a black first frame (a camera starting up)."""
    from ._video import grey_and_colour_presses

    return grey_and_colour_presses(folder, dark=True)


def test_a_video_is_grey_by_its_pixel_format_or_equal_channels_in_every_frame(tmp_path: Path):
    pytest.importorskip("av")
    from lookfeel.data.video import is_grey_video

    v = _press_videos(tmp_path)
    broken = tmp_path / "broken.mov"
    broken.write_bytes(b"not a video")
    assert {name: is_grey_video(p) for name, p in v.items()} == {
        "colour": False,
        "grey": True,
        "stored": True,
        "dark": False,
    }
    assert not is_grey_video(broken)  # its query's own error says why


def test_a_grey_press_video_is_matched_with_one_warning_naming_it(matcher: Matcher, tmp_path: Path):
    """QA: a grey press video was matched silently, though a model reads a press's colours.
    It is still matched, with one line naming it (the first, counting the others, of a query of
    several presses); a colour video gets none."""
    pytest.importorskip("av")
    import warnings

    v = _press_videos(tmp_path)
    grey = (
        "the video has no colour (grey); lookfeel reads a press's colours, and a model trained "
        "on colour presses reads a grey one unlike them"
    )

    def grey_lines(paths: list[Path]) -> list[str]:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            [r] = matcher.match_files(paths, Modality.TOUCH, top=2)
        assert r.paths == [str(p) for p in paths] and len(r.fabrics) == 2  # still matched
        return [str(w.message) for w in said if "no colour" in str(w.message)]

    assert grey_lines([v["grey"]]) == [f"{v['grey']}: {grey}"]
    assert grey_lines([v["colour"], v["stored"], v["grey"]]) == [
        f"{v['stored']} (and 1 other grey video): {grey}"
    ]
    assert grey_lines([v["colour"], v["dark"]]) == []


def test_a_query_video_is_decoded_once_whether_grey_or_not(
    matcher: Matcher, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Whether a press video is grey is known from the decoding that reads its press: asking
    again decoded one more frame of a colour or one-channel video, and the whole of a grey one
    stored as colour."""
    import warnings

    pytest.importorskip("av")
    from ._video import count_decoded_frames

    v = _press_videos(tmp_path)
    decoded = count_decoded_frames(monkeypatch)  # frames decoded, by file
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        matcher.match_files([v["colour"], v["grey"], v["stored"]], Modality.TOUCH, top=2)
    assert [str(w.message) for w in said if "no colour" in str(w.message)] == [
        f"{v['grey']} (and 1 other grey video): {match_module.GREY_VIDEO}"
    ]
    assert decoded == {"colour.mov": 14, "grey.mkv": 14, "stored.mov": 14}  # each frame once


def test_a_property_estimate_is_given_by_name():
    # Its fields were (name, mean, ...) before session 57: a call by position would misread.
    from lookfeel.index import PropertyEstimate

    with pytest.raises(TypeError):
        PropertyEstimate("stiffness", 0.5)  # type: ignore[misc]
    assert PropertyEstimate(value=0.5, std=0.1, fabrics=3).number is None
