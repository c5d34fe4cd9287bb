"""The synthetic world: config, layout and names, determinism, label-conditioned mode, the
output folder's safety, and physics read back from the rendered pixels."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage, stats

from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.config.recipes import recipe_path
from lookfeel.data import check_dataset, parse_touch_name, read_labels
from lookfeel.modality import REPRINTS, Modality, PressKind, reprint_path
from lookfeel.synth import MANIFEST, SIZE_PRESETS, SynthConfig, generate
from lookfeel.synth import world as world_module
from lookfeel.synth.color import render_color
from lookfeel.synth.depth import render_depth
from lookfeel.synth.drape import drape_surface, sample_drape
from lookfeel.synth.fabric import (
    MATERIALS,
    Fabric,
    fabrics_from_labels,
    make_fabric,
    read_label_file,
    reprinted,
    sample_fabrics,
)
from lookfeel.synth.gelsight import fold_gap_mm, no_contact_frame, render_press, sensor
from lookfeel.synth.measure import (
    drape_extent,
    fold_count,
    touch_contrast,
    touch_fold_width,
    touch_texture,
)
from lookfeel.synth.scene import background_depth, color_camera, depth_camera

REFERENCE = Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "gelsight"

TINY = SynthConfig(
    fabrics=3,
    drapes=2,
    presses_flat=1,
    presses_fold=2,
    frames=2,
    workers=1,
    **SIZE_PRESETS["tiny"],
)


def _digest(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.fixture(scope="module")
def tiny_world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("synth") / "world"
    generate(TINY, out, progress=False)
    return out


# ---- config ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"fabrics": 0}, "fabrics"),
        ({"frames": 0}, "frames"),
        ({"touch_size": (8, 8)}, "touch_size"),
        ({"image_format": "gif"}, "image_format"),
        ({"modalities": ("smell",)}, "modalities"),
        ({"seed": -1}, "seed"),
        ({"drapes": 0, "modalities": (Modality.DEPTH,)}, "drapes"),
    ],
)
def test_config_rejects_bad_values_naming_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"synth.{field}"):
        SynthConfig(**kwargs)


def test_config_accepts_modality_names_and_resolves_defaults() -> None:
    cfg = SynthConfig(modalities=("touch", "depth"))  # type: ignore[arg-type]
    assert cfg.modalities == (Modality.TOUCH, Modality.DEPTH)
    assert SynthConfig().resolved_modalities(label_mode=False) == tuple(Modality)
    assert SynthConfig().resolved_modalities(label_mode=True) == (Modality.COLOR, Modality.TOUCH)


# ---- layout, names, formats --------------------------------------------------------------------


def test_world_follows_the_dataset_layout(tiny_world: Path) -> None:
    depth = sorted((tiny_world / "depth").iterdir())
    color = sorted((tiny_world / "color").iterdir())
    touch = sorted((tiny_world / "touch").iterdir())
    assert [p.name for p in depth[:2]] == ["F0001_Depth_Synth_01.png", "F0001_Depth_Synth_02.png"]
    assert [p.name for p in color[:2]] == ["F0001_1.jpg", "F0001_2.jpg"]
    assert len(depth) == len(color) == 3 * 2
    assert len(touch) == 3 * (1 + 2) * 2
    names = {parse_touch_name(p.name) for p in touch}
    assert None not in names
    kinds = {(n.fabric_id, n.kind, n.press) for n in names if n is not None}
    assert (1, PressKind.FLAT, "1001") in kinds and (3, PressKind.FOLD, "2002") in kinds
    assert {n.frame for n in names if n is not None} == {1, 2}

    d = Image.open(depth[0])
    assert d.mode == "I;16" and d.size == (56, 56)
    arr = np.asarray(d)
    assert 600 < np.median(arr[arr > 0]) < 1600  # millimetres, like the real files
    for p in (color[0], touch[0]):
        im = Image.open(p)
        assert im.format == "JPEG" and im.mode == "RGB"
    assert Image.open(touch[0]).size == (80, 60)

    header = (tiny_world / "labels.csv").read_text(encoding="utf-8").splitlines()[0]
    assert header == "fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split"
    manifest = json.loads((tiny_world / MANIFEST).read_text(encoding="utf-8"))
    assert manifest["status"] == "complete"
    assert len(manifest["fabrics"]) == 3 and "bending_length_mm" in manifest["fabrics"][0]
    assert (tiny_world / "contact_sheet.png").is_file()


def test_world_passes_the_dataset_checker(tiny_world: Path) -> None:
    catalog = check_dataset(tiny_world, workers=1)
    assert [str(p) for p in catalog.errors] == []
    assert len(catalog.fabrics) == 3
    assert all(len(f.items[Modality.TOUCH]) == 3 for f in catalog.fabrics)


def test_same_seed_gives_byte_identical_files_whatever_the_workers(
    tiny_world: Path, tmp_path: Path
) -> None:
    again = tmp_path / "again"
    generate(dataclasses.replace(TINY, workers=2), again, progress=False)
    a, b = _digest(tiny_world), _digest(again)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
    other = tmp_path / "other"
    generate(dataclasses.replace(TINY, seed=1, fabrics=1), other, progress=False)
    assert (other / "color/F0001_1.jpg").read_bytes() != a["color/F0001_1.jpg"]


def test_a_rendering_process_imports_neither_torch_nor_the_data_layer() -> None:
    """Each of `generate`'s worker processes imports the world's module afresh (spawn): with
    torch in it, 16 workers took seconds to start (session 41)."""
    code = (
        "import sys, lookfeel.synth.world; print(sorted(m for m in sys.modules"
        " if m.split('.')[0] == 'torch' or m.startswith('lookfeel.data')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_each_photo_has_its_reprints_and_is_the_same_without_them(
    tiny_world: Path, tmp_path: Path
) -> None:
    photos = sorted((tiny_world / "color").iterdir())
    renders = sorted((tiny_world / REPRINTS).iterdir())
    n = TINY.reprints
    recipe = load_config(RunConfig, recipe_path("synth_cross.yaml"))
    assert n == recipe.data.color_reprints == 4  # a default world serves the recipe
    assert [p.name for p in renders] == sorted(
        f"{p.stem}_r{k}.jpg" for p in photos for k in range(1, n + 1)
    )
    assert all(reprint_path(p, k).is_file() for p in photos for k in range(1, n + 1))
    views = [reprint_path(photos[0], k).read_bytes() for k in range(1, n + 1)]
    assert len({photos[0].read_bytes(), *views}) == n + 1  # every render another print
    plain = tmp_path / "plain"
    generate(dataclasses.replace(TINY, reprints=0, fabrics=2), plain, progress=False)
    assert not (plain / REPRINTS).exists()
    for p in (plain / "color").iterdir():
        assert p.read_bytes() == (tiny_world / "color" / p.name).read_bytes()
    # A world with fewer renders writes the same first ones.
    one = tmp_path / "one"
    generate(dataclasses.replace(TINY, reprints=1, fabrics=2), one, progress=False)
    assert sorted(p.name for p in (one / REPRINTS).iterdir()) == sorted(
        reprint_path(p, 1).name for p in (one / "color").iterdir()
    )
    for p in (one / REPRINTS).iterdir():
        assert p.read_bytes() == (tiny_world / REPRINTS / p.name).read_bytes()


def test_a_reprint_is_the_same_drape_and_light_under_another_print() -> None:
    fabric = make_fabric(2, 1.5, 1.5, 3.0, 0.0, seed=0)
    surf = drape_surface(fabric, sample_drape(fabric, np.random.default_rng(3))).densify(4)
    cam = color_camera(128)
    other = reprinted(fabric, np.random.default_rng(7))
    assert (other.thickness_mm, other.material, other.sheen) == (
        fabric.thickness_mm,
        fabric.material,
        fabric.sheen,
    )
    assert other.base_rgb != fabric.base_rgb
    a, b = (render_color(f, surf, cam, np.random.default_rng(4)) for f in (fabric, other))
    changed = np.abs(a.astype(np.int16) - b.astype(np.int16)).max(-1) > 0
    # Only the cloth changes: the room, its light and the camera's noise are the photo's.
    assert 0.1 < changed.mean() < 0.9
    room = ~ndimage.binary_dilation(changed, iterations=2)
    assert np.array_equal(a[room], b[room])


# ---- label-conditioned mode --------------------------------------------------------------------


def test_label_mode_keeps_ids_and_columns_and_renders_only_what_is_asked(tmp_path: Path) -> None:
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split,roughness\n"
        "3,4,2.1,1.43,1.6,1,test,0.2\n"
        "42,0,2.0,1.5,3.5,0,train,\n"
        "107,0,,,,,excluded,\n",
        encoding="utf-8",
    )
    cfg = dataclasses.replace(TINY, fabrics=50, presses_flat=0, presses_fold=1, frames=1)
    out = generate(cfg, tmp_path / "out", labels=labels, progress=False)
    assert out.mode == "labels" and out.fabrics == 3 and out.depth_images == 0
    assert not (tmp_path / "out/depth").exists()
    ids = {int(p.name[1:5]) for p in (tmp_path / "out/color").iterdir()}
    assert ids == {3, 42, 107}
    assert sorted(p.name for p in (tmp_path / "out/touch").iterdir())[0] == "F0003_fold_01_2001.jpg"
    assert (tmp_path / "out/labels.csv").read_text(encoding="utf-8") == labels.read_text(
        encoding="utf-8"
    )

    with_depth = generate(
        dataclasses.replace(cfg, modalities=(Modality.DEPTH,)),
        tmp_path / "depth_only",
        labels=labels,
        progress=False,
    )
    assert with_depth.depth_images == 3 * cfg.drapes and with_depth.color_images == 0
    assert not (tmp_path / "depth_only/touch").exists()


def test_label_mode_reports_a_bad_labels_file(tmp_path: Path) -> None:
    bad = tmp_path / "labels.csv"
    bad.write_text("fabric_id,thickness_mm\n1,thick\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"labels\.csv:2: column 'thickness_mm'"):
        generate(TINY, tmp_path / "out", labels=bad, progress=False)
    bad.write_bytes("fabric_id\n1\n".encode("utf-16"))  # a spreadsheet's "Unicode text"
    with pytest.raises(ValueError, match=r"labels\.csv:1: saved as UTF-16 text \(a spreadsheet"):
        generate(TINY, tmp_path / "out", labels=bad, progress=False)


_LABELS_HEADER = "fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split\n"


@pytest.mark.parametrize(
    ("row", "said"),
    [
        ("2,2,2.7,1.3,3.3,1,bogus", ":3: column 'paper_split': 'bogus' is not one of train, "),
        ("2,-1,2.7,1.3,3.3,1,test", ":3: column 'cluster8': '-1' is not a cluster number"),
        ("2,2.5,2.7,1.3,3.3,1,test", ":3: column 'cluster8': '2.5' is not a cluster number"),
    ],
)
def test_label_mode_refuses_a_labels_file_the_dataset_reader_refuses(
    tmp_path: Path, row: str, said: str
) -> None:
    """synth copies the labels file as the world's labels.csv: one the dataset reader refuses
    (a paper_split of 'bogus', QA) made a world that `lookfeel data check` then refused. It is
    refused up front now, with the reader's own line, and nothing is written."""
    labels = tmp_path / "labels.csv"
    labels.write_text(_LABELS_HEADER + "1,0,5.3,3.9,2.8,0.5,train\n" + row + "\n", encoding="utf-8")
    assert [said in str(p) for p in read_labels(labels)[1]] == [True]  # the reader's words
    with pytest.raises(ValueError, match=re.escape(f"{labels}{said}")):
        generate(TINY, tmp_path / "out", labels=labels, progress=False)
    assert not (tmp_path / "out").exists()


def test_label_mode_takes_the_clusters_and_unknown_cells_the_dataset_reader_takes(
    tmp_path: Path,
) -> None:
    """A cluster is any integer >= 0 for the reader, whatever the column is called (9 in
    ``cluster8``), and "nan" is an unknown cell: synth takes both, as the reader does."""
    labels = tmp_path / "labels.csv"
    labels.write_text(
        _LABELS_HEADER + "1,9,5.3,nan,2.8,0.5,train\n2,2,2.7,1.3,3.3,1,test\n2007,2,,,,,\n",
        encoding="utf-8",
    )
    assert read_labels(labels)[1] == []
    assert read_label_file(labels).ids == (1, 2, 2007)


@pytest.mark.parametrize("value", ["inf", "-inf", "1e999", "+nan"])
def test_label_mode_says_an_infinite_label_is_not_finite(tmp_path: Path, value: str) -> None:
    """'inf' was refused with "must be >= 0" (QA), which is not what is wrong with it."""
    labels = tmp_path / "labels.csv"
    labels.write_text(_LABELS_HEADER + f"1,0,5.3,{value},2.8,0.5,train\n", encoding="utf-8")
    with pytest.raises(
        ValueError, match=rf":2: column 'density': '{re.escape(value)}' is not finite$"
    ):
        read_label_file(labels)
    labels.write_text(
        _LABELS_HEADER + "1,0,-5.3,3.9,2.8,0.5,train\n", encoding="utf-8"
    )  # negative: its own words
    with pytest.raises(ValueError, match=r":2: column 'thickness_mm': '-5.3' must be >= 0$"):
        read_label_file(labels)


def test_label_mode_says_a_non_ascii_digit_is_not_a_fabric_id(tmp_path: Path) -> None:
    """A "²" is a digit to str.isdigit but not to int(), which said "invalid literal"."""
    labels = tmp_path / "labels.csv"
    labels.write_text("fabric_id,density\n\u00b2,1\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r":2: fabric_id '\u00b2' is not an integer id \("):
        read_label_file(labels)


def test_label_mode_reads_the_file_once_with_the_dataset_reader(tmp_path: Path) -> None:
    """synth parsed the file itself, then again with the dataset reader: its own first error
    came alone and in its own words ("FILE, line 2: ..."), and a "nan" cell was a NaN label.
    Now the reader parses it: the first problem in the reader's words with how many more, and
    "nan" is an unknown cell, filled from the fabric's cluster as an empty one is."""
    labels = tmp_path / "labels.csv"
    labels.write_text(
        _LABELS_HEADER + "1,0,-5.3,3.9,2.8,0.5,train\n2,0,2.7,1.3,3.3,1,bogus\n", encoding="utf-8"
    )
    with pytest.raises(ValueError) as raised:
        read_label_file(labels)
    assert str(raised.value) == (
        f"{labels}:2: column 'thickness_mm': '-5.3' must be >= 0 (and 1 more problem(s) in "
        "this file)"
    )
    labels.write_text("object,hardness\nsponge,0\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r":1: no 'fabric_id' column in the header: synth "):
        read_label_file(labels)

    rows = "1,0,5.3,{},2.8,0.5,train\n2,0,2.7,1.3,3.3,1,test\n3,0,2.9,1.5,3.1,1,test\n"
    labels.write_text(_LABELS_HEADER + rows.format("nan"), encoding="utf-8")
    with_nan = read_label_file(labels)
    assert with_nan.values[0] == {"thickness_mm": 5.3, "stiffness": 2.8, "stretchiness": 0.5}
    labels.write_text(_LABELS_HEADER + rows.format(""), encoding="utf-8")
    assert fabrics_from_labels(with_nan, 0) == fabrics_from_labels(read_label_file(labels), 0)


def test_test_fabrics_sets_how_many_are_held_out_and_nothing_else(tmp_path: Path) -> None:
    """`test_fabrics` holds out exactly that many; labels and clusters are those of the paper's
    share, so a world with more held out differs only in its split."""
    base = dataclasses.replace(
        TINY, fabrics=6, drapes=1, modalities=(Modality.DEPTH,), contact_sheet=False
    )
    generate(base, tmp_path / "paper", progress=False)
    generate(dataclasses.replace(base, test_fabrics=4), tmp_path / "four", progress=False)

    def rows(name: str) -> list[list[str]]:
        lines = (tmp_path / name / "labels.csv").read_text(encoding="utf-8").splitlines()[1:]
        return [line.split(",") for line in lines]

    paper, four = rows("paper"), rows("four")
    assert [r[-1] for r in paper].count("test") == 1  # round(6 * 18 / 118)
    assert [r[-1] for r in four].count("test") == 4
    assert [r[:-1] for r in four] == [r[:-1] for r in paper]
    assert _digest(tmp_path / "four" / "depth") == _digest(tmp_path / "paper" / "depth")
    # Recorded only when set, so a world made before the field existed keeps its config.
    assert "test_fabrics" not in base.to_dict()
    manifest = json.loads((tmp_path / "four" / MANIFEST).read_text(encoding="utf-8"))
    assert manifest["config"]["test_fabrics"] == 4


def test_test_fabrics_refuses_what_cannot_be_held_out(tmp_path: Path) -> None:
    for bad in (6, -1, True):
        with pytest.raises(ConfigError, match="synth.test_fabrics"):
            dataclasses.replace(TINY, fabrics=6, test_fabrics=bad)
    labels = tmp_path / "labels.csv"
    labels.write_text("fabric_id\n1\n2\n", encoding="utf-8")
    with pytest.raises(ValueError, match="test_fabrics: not with a labels file"):
        generate(
            dataclasses.replace(TINY, test_fabrics=1),
            tmp_path / "out",
            labels=labels,
            progress=False,
        )
    assert not (tmp_path / "out").exists()


# ---- the output folder -------------------------------------------------------------------------


def test_refuses_a_folder_that_is_not_synth_output(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("keep me", encoding="utf-8")
    with pytest.raises(FileExistsError, match="not empty"):
        generate(TINY, tmp_path, progress=False)
    assert [p.name for p in tmp_path.iterdir()] == ["mine.txt"]


def test_rerun_replaces_its_own_files_and_keeps_the_users(tmp_path: Path) -> None:
    one = dataclasses.replace(TINY, fabrics=2, contact_sheet=False)
    generate(one, tmp_path, progress=False)
    (tmp_path / "notes.txt").write_text("mine", encoding="utf-8")
    (tmp_path / "color" / "mine.png").write_bytes(b"x")
    generate(dataclasses.replace(one, fabrics=1), tmp_path, progress=False)
    assert (tmp_path / "notes.txt").read_text(encoding="utf-8") == "mine"
    assert (tmp_path / "color" / "mine.png").exists()
    assert not list(tmp_path.rglob("F0002_*"))
    assert (tmp_path / "color" / "F0001_1.jpg").exists()


def test_a_killed_run_leaves_no_truncated_image_and_can_be_rerun(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    real_replace = os.replace

    def dying_replace(src: str, dst: str) -> None:
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt  # killed between writing a temp file and renaming it
        real_replace(src, dst)

    monkeypatch.setattr(world_module.os, "replace", dying_replace)
    cfg = dataclasses.replace(TINY, fabrics=1, contact_sheet=False)
    with pytest.raises(KeyboardInterrupt):
        generate(cfg, tmp_path, progress=False)
    monkeypatch.setattr(world_module.os, "replace", real_replace)
    images = [p for p in tmp_path.rglob("F*") if p.suffix in (".png", ".jpg")]
    assert images  # some were written before the kill ...
    for p in images:  # ... and every one under a real name decodes completely
        Image.open(p).load()
    assert json.loads((tmp_path / MANIFEST).read_text(encoding="utf-8"))["status"] == "running"
    generate(cfg, tmp_path, progress=False)
    assert not list(tmp_path.rglob("*.tmp"))
    assert json.loads((tmp_path / MANIFEST).read_text(encoding="utf-8"))["status"] == "complete"


# ---- physics shows in the pixels ---------------------------------------------------------------


def test_drape_extent_and_fold_count_follow_the_bending_length() -> None:
    fabrics = sample_fabrics(16, seed=7)
    cam = depth_camera(224)
    room = background_depth(cam)
    extent, folds, bend = [], [], []
    for f in fabrics:
        e, k = [], []
        for d in range(3):
            p = sample_drape(f, np.random.default_rng([7, f.fabric_id, d]))
            img = render_depth(
                drape_surface(f, p).densify(4), cam, np.random.default_rng([8, f.fabric_id, d])
            )
            e.append(drape_extent(img, room))
            k.append(fold_count(img, room))
        extent.append(np.mean(e))
        folds.append(np.mean(k))
        bend.append(f.bending_length_mm)
    # Stiffer, lighter fabrics stand out further with fewer folds (measured from pixels).
    assert stats.spearmanr(bend, extent)[0] > 0.85
    assert stats.spearmanr(bend, folds)[0] < -0.7


def test_fold_presses_show_a_band_flat_ones_texture() -> None:
    s = sensor(320, 240)
    bg = no_contact_frame(s)
    fabrics = sample_fabrics(14, seed=3)
    fold_elong, flat_elong, flat_tex = [], [], []
    for f in fabrics:
        for i in range(4):
            rng = np.random.default_rng([3, f.fabric_id, i])
            fold = render_press(f, PressKind.FOLD, s, rng, 3)[-2]
            fold_elong.append(touch_fold_width(fold, bg)[1])
        flat = render_press(f, PressKind.FLAT, s, np.random.default_rng([4, f.fabric_id]), 3)
        flat_elong.append(touch_fold_width(flat[-2], bg)[1])
        flat_tex.append(touch_texture(flat[-1], bg))
    # A fold makes a long band; a flat press a round patch.
    assert np.median(fold_elong) > 1.4 * np.median(flat_elong)
    # Flat presses show texture above the sensor's noise floor.
    noisy = bg + np.random.default_rng(1).normal(0.0, 1.2, bg.shape)
    floor = touch_texture(np.clip(np.rint(noisy), 0, 255).astype(np.uint8), bg)
    assert np.median(flat_tex) > 1.5 * floor


def test_colour_and_print_are_independent_of_physics_the_material_is_not() -> None:
    # Same id and seed, very different physics: same colour and print (a network must look
    # past the print to match colour with touch).
    a = make_fabric(5, 0.6, 0.4, 1.0, 0.0, seed=0)
    b = make_fabric(5, 9.0, 4.0, 5.0, 1.0, seed=0)
    assert (a.base_rgb, a.print_kind, a.print_rgb, a.print_scale_mm) == (
        b.base_rgb,
        b.print_kind,
        b.print_rgb,
        b.print_scale_mm,
    )
    assert a.bending_length_mm != b.bending_length_mm
    fabrics = sample_fabrics(300, seed=0)
    kinds = [f.print_kind for f in fabrics]
    assert 0.5 < kinds.count("solid") / len(kinds) < 0.7  # paper: about 60% single colour
    # The material comes as real fabrics do: fleece is thick and fluffy, silk thin and shiny.
    by = {m: [f for f in fabrics if f.material == m] for m in MATERIALS}
    assert all(len(v) >= 5 for v in by.values()), {m: len(v) for m, v in by.items()}
    others = [f for f in fabrics if f.material not in ("fleece", "silk")]
    assert np.median([f.bulk_density for f in by["fleece"]]) < 0.6 * np.median(
        [f.bulk_density for f in others]
    )
    assert np.median([f.thickness_mm for f in by["silk"]]) < np.median(
        [f.thickness_mm for f in others]
    )
    assert min(f.sheen for f in by["silk"]) > max(f.sheen for f in by["wool"] + by["fleece"])
    assert all(f.weave == "pile" for f in by["fleece"])


def test_a_stiff_fold_stands_as_a_ridge_under_the_sensor_a_limp_one_is_pressed_flat() -> None:
    s = sensor(320, 240)
    bg = no_contact_frame(s)
    # The same cloth but for its bending stiffness (rating 1 vs 5: 37x the flexural rigidity),
    # thin and thick.
    for t in (1.0, 3.0):
        limp, stiff = (make_fabric(3, t, 1.5, r, 0.0, seed=0) for r in (1.0, 5.0))
        assert limp.material == stiff.material and limp.weave == stiff.weave
        width, peak = [], []
        for i in range(8):  # the same poses and forces for both
            last = [
                render_press(f, PressKind.FOLD, s, np.random.default_rng([9, i]), 3)[-1]
                for f in (limp, stiff)
            ]
            widths = [touch_fold_width(frame, bg)[0] for frame in last]
            peaks = [np.percentile(touch_contrast(frame, bg), 99.5) for frame in last]
            width.append(widths[1] / widths[0])
            peak.append(peaks[1] / peaks[0])
        # Pressed hard, the limp fold's loop closes and the gel spreads over both layers; the
        # stiff loop still holds its edge up, a narrow ridge that takes the force.
        assert np.median(width) < 0.8, t
        assert np.median(peak) > 1.05, t
    # The gap closes as the force rises, ~ F^(-1/2) once pressed (q = 4 B / gap^2).
    gaps = [fold_gap_mm(stiff, force) for force in (0.5, 2.0, 8.0)]
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[1] / gaps[2] == pytest.approx(2.0, rel=0.05)
    assert fold_gap_mm(stiff, 2.0) > 5 * fold_gap_mm(limp, 2.0)
    # Unloaded, the loop stands open to about the bending length.
    assert fold_gap_mm(stiff, 0.0) == pytest.approx(stiff.bending_length_mm)


def test_an_uneven_spun_yarn_feels_coarser_than_an_even_filament_at_network_size() -> None:
    # The same cloth but for its fibre: flax's slub yarns against silk's even filament. Markers
    # removed so that the measure reads the cloth; frames shrunk to the recipe's 64 px.
    s = sensor(320, 240)
    s = dataclasses.replace(
        s, markers=np.zeros_like(s.markers), marker_centres=s.marker_centres[:0]
    )
    bg = no_contact_frame(s)

    def small(a: np.ndarray) -> np.ndarray:
        return np.asarray(Image.fromarray(a).resize((64, 48), Image.Resampling.BILINEAR))

    cloth = make_fabric(3, 1.5, 1.5, 3.0, 0.0, seed=0, material="cotton", weave="plain")
    linen, silk = (dataclasses.replace(cloth, material=m) for m in ("linen", "silk"))
    assert linen.yarn_irregularity > 5 * silk.yarn_irregularity
    ratio = []
    for i in range(6):  # the same poses and forces for both
        frames = [
            render_press(f, PressKind.FLAT, s, np.random.default_rng([9, i]), 3)[-1]
            for f in (linen, silk)
        ]
        ratio.append(
            touch_texture(small(frames[0]), small(bg)) / touch_texture(small(frames[1]), small(bg))
        )
    assert np.median(ratio) > 1.08


def _cloth_photo(fabric: Fabric) -> tuple[np.ndarray, np.ndarray]:
    """Luminance of one colour photo of ``fabric`` on a fixed drape and light, and where the
    cloth is (the pixels that change when the cloth's colour does)."""
    shape = make_fabric(2, 1.5, 1.5, 3.0, 0.0, seed=0)
    surf = drape_surface(shape, sample_drape(shape, np.random.default_rng(3))).densify(4)
    cam = color_camera(256)

    def photo(f: Fabric) -> np.ndarray:
        return render_color(f, surf, cam, np.random.default_rng(4)).astype(np.float32).mean(-1)

    dark = photo(dataclasses.replace(fabric, base_rgb=(0.02, 0.02, 0.02)))
    bright = photo(dataclasses.replace(fabric, base_rgb=(0.8, 0.8, 0.8)))
    return photo(fabric), (bright - dark) > 20


def _grey(level: float, **changes: object) -> Fabric:
    """A plain fabric of one grey, its other properties changed as given."""
    return dataclasses.replace(
        make_fabric(2, 1.5, 1.5, 3.0, 0.0, seed=0),
        base_rgb=(level, level, level),
        print_kind="solid",
        print_rgb=(),
        **changes,
    )


def test_a_shinier_material_shows_more_specular_highlight() -> None:
    grey = _grey(0.2)
    matte = dataclasses.replace(grey, material="wool", sheen=0.0, gloss=5.0, fuzz=0.0)
    shiny = dataclasses.replace(grey, material="silk", sheen=0.6, gloss=40.0, fuzz=0.0)
    lum_m, cloth = _cloth_photo(matte)
    lum_s, _ = _cloth_photo(shiny)
    # The highlight: bright spots on the cloth that the matte one lacks.
    assert np.percentile(lum_s[cloth], 99) > np.percentile(lum_m[cloth], 99) + 20
    assert np.median(lum_s[cloth]) == pytest.approx(np.median(lum_m[cloth]), abs=12)


def test_hairy_and_thin_cloth_shade_softer() -> None:
    grey = _grey(0.3, sheen=0.0, fuzz=0.0, material="wool")
    lum, cloth = _cloth_photo(grey)
    fuzzy, _ = _cloth_photo(dataclasses.replace(grey, fuzz=1.0))
    sheer, _ = _cloth_photo(dataclasses.replace(grey, material="silk", density=0.2))
    assert sheer.shape == lum.shape
    spread = float(np.std(lum[cloth]))
    # Fibres scatter light round the folds; a thin cloth glows with light let through.
    assert np.std(fuzzy[cloth]) < 0.85 * spread
    assert np.std(sheer[cloth]) < 0.85 * spread


# ---- held against the real data (skipped without ../shared) ----------------------------------


@pytest.mark.real_data
def test_room_matches_the_real_depth_images(real_data: Path) -> None:
    files = sorted((real_data / "depth").glob("*.png"))[::20]
    real = np.stack([np.asarray(Image.open(p), dtype=np.float32) for p in files])
    real[real == 0] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pixels that are holes in every image
        far = np.nanpercentile(real, 90, axis=0)  # mostly the empty room
    room = background_depth(depth_camera(224))
    wall = np.s_[0:55, 20:85]
    floor = np.s_[190:224, 30:200]
    assert np.nanmedian(np.abs(room[wall] - far[wall])) < 15
    assert np.nanmedian(np.abs(room[floor] - far[floor])) < 15


@pytest.mark.real_data
def test_label_mode_renders_touch_and_colour_for_the_real_fabrics(
    real_data: Path, tmp_path: Path
) -> None:
    cfg = dataclasses.replace(TINY, drapes=1, presses_flat=0, presses_fold=1, frames=1)
    summary = generate(cfg, tmp_path, labels=real_data / "labels.csv", progress=False)
    lines = (real_data / "labels.csv").read_text(encoding="utf-8").splitlines()[1:]
    real_ids = [int(line.split(",")[0]) for line in lines]
    assert summary.fabrics == len(real_ids) == 119
    assert sorted(int(p.name[1:5]) for p in (tmp_path / "color").iterdir()) == real_ids
    assert (tmp_path / "labels.csv").read_text(encoding="utf-8") == (
        real_data / "labels.csv"
    ).read_text(encoding="utf-8")
    assert check_dataset(tmp_path, workers=1).errors == ()


@pytest.mark.real_data
def test_sensor_matches_the_reference_gelsight_frame() -> None:
    ref_path = REFERENCE / "markers_nocontact.jpg"
    if not ref_path.is_file():
        pytest.skip(f"reference GelSight frames not found at {REFERENCE}")
    ref = np.asarray(Image.open(ref_path).convert("RGB").resize((320, 240)), dtype=np.float32)
    ours = no_contact_frame(sensor(320, 240)).astype(np.float32)
    # Same illumination layout (red lower right, green left, blue top) within ~25 grey levels.
    assert np.abs(ref - ours).mean() < 25
    assert np.abs(ref.mean((0, 1)) - ours.mean((0, 1))).max() < 15


def test_contact_sheet_beside_another_datasets_depth(tmp_path: Path) -> None:
    from ._tiny import write_tiny_dataset

    real = write_tiny_dataset(tmp_path / "real", fabrics=3, drapes=2)
    labels = real / "labels.csv"
    cfg = dataclasses.replace(TINY, presses_flat=1, presses_fold=1, frames=2)
    alone = generate(cfg, tmp_path / "alone", labels=labels, progress=False)
    beside = generate(cfg, tmp_path / "beside", labels=labels, progress=False, beside=real)
    assert alone.contact_sheet is not None and beside.contact_sheet is not None
    w_alone, h_alone = Image.open(alone.contact_sheet).size
    w_beside, h_beside = Image.open(beside.contact_sheet).size
    assert h_beside == h_alone and w_beside > w_alone  # the same rows, two real tiles more
    with pytest.raises(ValueError, match="no depth image of any fabric id"):
        generate(cfg, tmp_path / "none", labels=labels, progress=False, beside=tmp_path / "alone")
    assert not (tmp_path / "none").exists()  # refused before anything was rendered
    with pytest.raises(ValueError, match="not a folder"):
        generate(cfg, tmp_path / "x", labels=labels, progress=False, beside=tmp_path / "nope")


def test_a_rerun_removes_only_files_of_its_own_folder(tmp_path: Path) -> None:
    """QA: an earlier run's manifest lists what a rerun removes; a listed absolute path (a
    hand-edited or foreign synth.json) deleted a file outside the folder. Now only files of
    the folder go: never an absolute path, one through "..", or one through a symlinked
    folder (a real depth/ linked in beside the synthetic senses)."""
    out = tmp_path / "world"
    (out / "touch").mkdir(parents=True)
    real = tmp_path / "real_depth"
    real.mkdir()
    (out / "depth").symlink_to(real)
    victim, theirs = tmp_path / "victim.txt", real / "F0001_Depth_New_000001.png"
    old_touch = out / "touch" / "F0001_fold_01_1000.jpg"
    for f in (victim, theirs, old_touch):
        f.write_text("keep" if f != old_touch else "old", encoding="utf-8")
    listed = [
        str(victim),
        "../victim.txt",
        "depth/F0001_Depth_New_000001.png",
        str(old_touch.relative_to(out)),
    ]
    manifest = {"generator": world_module._GENERATOR, "files": listed}
    (out / MANIFEST).write_text(json.dumps(manifest), encoding="utf-8")
    world_module._prepare_out(out, planned=[])
    assert (
        victim.read_text(encoding="utf-8") == "keep"
        and theirs.read_text(encoding="utf-8") == "keep"
    )
    assert not old_touch.exists()  # the earlier run's own file, not planned again


def test_a_failed_write_names_the_file_and_leaves_no_temp(tmp_path: Path, monkeypatch) -> None:
    """QA: on a full disk synth ended in a traceback naming nothing, and left
    ``.NAME.PID.tmp`` behind."""
    import builtins
    import errno

    real_open = builtins.open

    class Full:
        def __init__(self, f):
            self.f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, data):
            self.f.write(data[:3])
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(builtins, "open", lambda p, *a, **k: Full(real_open(p, *a, **k)))
    (tmp_path / "touch").mkdir()
    with pytest.raises(OSError) as e:
        world_module._write(tmp_path, "touch/F0001_fold_01_1000.jpg", b"jpeg bytes")
    monkeypatch.undo()
    assert e.value.filename == str(tmp_path / "touch" / "F0001_fold_01_1000.jpg")
    assert list((tmp_path / "touch").iterdir()) == []
