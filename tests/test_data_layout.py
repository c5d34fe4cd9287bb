"""The scanner: names, folder aliases, press grouping, labels and every kind of problem."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.data import DatasetError, parse_touch_name, scan
from lookfeel.modality import Modality, PressKind

from ._tiny import write_depth, write_rgb, write_tiny_dataset


def test_scan_counts_fabrics_items_and_presses(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    assert catalog.ids == [1, 2, 3, 4, 5, 6]
    assert catalog.modalities == (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)
    assert len(catalog.items(Modality.DEPTH)) == 18
    assert len(catalog.items(Modality.TOUCH)) == 30
    assert len(catalog.items(Modality.TOUCH, [PressKind.FOLD])) == 18
    press = catalog.items(Modality.TOUCH, [PressKind.FLAT])[0]
    assert (press.fabric_id, press.kind, press.press) == (1, PressKind.FLAT, "100")
    assert [p.name for p in press.frames] == [
        "F0001_flat_01_100.png",
        "F0001_flat_02_100.png",
        "F0001_flat_03_100.png",
    ]
    assert catalog.problems == ()
    s = catalog.summary()
    assert s["items"] == {"depth": 18, "color": 18, "touch": 30}
    assert s["touch_presses_by_kind"] == {"flat": 12, "fold": 18}
    assert s["touch_frames"] == 90
    assert s["clusters"] == {"0": 2, "1": 2, "2": 2}


def test_labels_keep_unknown_cells_absent(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    f2 = catalog.fabric(2)
    assert "density" not in f2.labels
    assert f2.labels["thickness_mm"] == 1.0
    assert f2.cluster == 1
    assert f2.paper_split == "train"
    assert np.isnan(catalog.label_matrix()[2][1])
    with pytest.raises(KeyError, match="fabric 99 is not in the dataset"):
        catalog.fabric(99)


def test_frames_are_ordered_by_integer_frame_number(tmp_path: Path):
    for frame in (10, 9, 2):
        write_rgb(tmp_path / "touch" / f"F3_fold_{frame}_7.jpg", 3, frame)
    (press,) = scan(tmp_path).items(Modality.TOUCH)
    assert [p.name for p in press.frames] == [
        "F3_fold_2_7.jpg",
        "F3_fold_9_7.jpg",
        "F3_fold_10_7.jpg",
    ]
    assert press.frame(-2).name == "F3_fold_9_7.jpg"  # the authors' "second-to-last"
    assert press.frame(-5).name == "F3_fold_2_7.jpg"  # clamped


@pytest.mark.parametrize(
    ("name", "parsed"),
    [
        ("F0012_fold_03_1502.jpg", (12, PressKind.FOLD, 3, "1502")),
        ("F7_FLAT_1_a-2.png", (7, PressKind.FLAT, 1, "a-2")),
        ("F0012_03_1502.jpg", (12, None, 3, "1502")),
        ("F12_fold_x.jpg", None),
        ("G12_fold_1_2.jpg", None),
    ],
)
def test_parse_touch_name(name, parsed):
    tn = parse_touch_name(name)
    assert (None if tn is None else (tn.fabric_id, tn.kind, tn.frame, tn.press)) == parsed


def test_authors_folder_aliases(tmp_path: Path):
    write_depth(tmp_path / "kinect_depth_new" / "F0001_Depth_New_1.png", 1, 0)
    write_depth(tmp_path / "kinect_depth" / "F0001_raw.png", 1, 1)
    write_rgb(tmp_path / "canon_resize" / "F0001_1.jpg", 1, 0)
    write_rgb(tmp_path / "image_fold" / "F0001_02_5.jpg", 1, 0)  # kind from the folder
    write_rgb(tmp_path / "image_flat" / "F0001_02_6.jpg", 1, 0)
    write_rgb(tmp_path / "image_rand2" / "F0001_01_9.jpg", 1, 0)
    catalog = scan(tmp_path)
    assert [it.path.parent.name for it in catalog.items(Modality.DEPTH)] == ["kinect_depth_new"]
    assert [str(p.path.name) for p in catalog.skipped] == ["kinect_depth"]
    assert len(catalog.items(Modality.COLOR)) == 1
    kinds = sorted(it.kind.value for it in catalog.items(Modality.TOUCH) if it.kind)
    assert kinds == ["flat", "fold", "rand"]
    assert catalog.problems == ()


def test_other_files_are_reported_skipped_not_read(tiny_dataset: Path):
    (tiny_dataset / "notes.txt").write_text("hello", encoding="utf-8")
    (tiny_dataset / "renders").mkdir()
    (tiny_dataset / "depth" / "Thumbs.db").write_bytes(b"x")
    (tiny_dataset / "depth" / "._F0001_Depth_New_1.png").write_bytes(b"x")  # macOS's copies
    catalog = scan(tiny_dataset)
    assert sorted(p.path.name for p in catalog.skipped if p.path) == [
        "._F0001_Depth_New_1.png",
        "Thumbs.db",
        "notes.txt",
        "renders",
    ]
    why = {p.path.name: p.message for p in catalog.skipped if p.path}
    assert why["._F0001_Depth_New_1.png"] == "a hidden file (its name begins with a dot)"
    assert why["Thumbs.db"] == "not an image (.png, .jpg, .jpeg)"
    [notes] = [p for p in catalog.skipped if p.path is not None and p.path.name == "notes.txt"]
    # The message lists every folder the layout reads, recordings' videos/ too.
    assert "(depth/, color/, touch/, videos/, labels.csv)" in str(notes)
    assert catalog.problems == ()


def test_a_synthetic_world_s_own_files_are_not_listed_as_skipped(tmp_path: Path):
    from lookfeel.synth import SynthConfig, generate

    out = tmp_path / "world"
    config = SynthConfig(fabrics=2, drapes=2, depth_size=32, modalities=(Modality.DEPTH,))
    generate(config, out, progress=False)
    assert {"synth.json", "contact_sheet.png"} <= {p.name for p in out.iterdir()}
    assert scan(out).skipped == ()
    # Outside a world, a file of that name is listed like any other.
    (tmp_path / "plain" / "depth").mkdir(parents=True)
    for p in (out / "depth").iterdir():
        (tmp_path / "plain" / "depth" / p.name).write_bytes(p.read_bytes())
    (tmp_path / "plain" / "contact_sheet.png").write_bytes(b"x")
    assert [p.path.name for p in scan(tmp_path / "plain").skipped if p.path] == [
        "contact_sheet.png"
    ]


def test_every_problem_is_reported_at_once(tiny_dataset: Path):
    depth = tiny_dataset / "depth"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(depth / "F0001_eight_bit.png")
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(depth / "F0001_rgb.png")
    (depth / "F0002_empty.png").write_bytes(b"")
    (depth / "drape_without_id.png").write_bytes(
        (depth / "F0001_Depth_New_000000.png").read_bytes()
    )
    write_rgb(tiny_dataset / "color" / "F0001_note.jpg", 1, 0)
    (tiny_dataset / "color" / "F0001_note.jpg").write_bytes(b"not an image at all")
    write_rgb(tiny_dataset / "touch" / "F12_fold_x.jpg", 12, 0)
    write_rgb(tiny_dataset / "touch" / "F0001_fold_01_100.jpg", 1, 0)  # frame 1 twice
    write_depth(depth / "F0042_Depth_New_1.png", 42, 0)  # not in labels.csv
    with open(tiny_dataset / "labels.csv", "a", encoding="utf-8") as f:
        f.write("77,1,1.0,1.0,1.0,0,test\n")  # labelled, no image: a warning
    catalog = scan(tiny_dataset)
    found = {(p.path.name if p.path else None, p.severity): p.message for p in catalog.problems}
    assert "8-bit greyscale" in found["F0001_eight_bit.png", "error"]
    assert found["F0001_rgb.png", "error"].startswith("depth PNG is 8-bit RGB; expected 16-bit")
    assert found["F0002_empty.png", "error"] == "file is empty"
    assert "must begin F<id>_" in found["drape_without_id.png", "error"]
    assert found["F0001_note.jpg", "error"] == "not a PNG or JPEG image"
    assert "does not parse" in found["F12_fold_x.jpg", "error"]
    assert found["F0001_fold_01_100.png", "error"].startswith(
        "frame 1 of fold press 100 of fabric 1 is also"
    )  # the .jpg sorts first and is kept
    assert (
        found["F0042_Depth_New_1.png", "error"] == "fabric 42 (1 item(s)) has no row in labels.csv"
    )
    assert found["color", "error"].startswith("fabric 42 has no color item")
    warn = [p for p in catalog.warnings]
    assert [(p.line, p.message) for p in warn] == [
        (8, "fabric 77 is in labels.csv but has no image (paper_split=test)")
    ]
    assert len(catalog.items(Modality.DEPTH)) == 18 + 1  # the bad files are left out
    with pytest.raises(DatasetError) as info:
        scan(tiny_dataset, strict=True)
    assert len(info.value.problems) == len(catalog.errors) >= 9
    assert "F12_fold_x.jpg" in str(info.value) and "F0002_empty.png" in str(info.value)


def test_required_modality_missing(tmp_path: Path):
    root = write_tiny_dataset(tmp_path / "d", fabrics=3, labels=False)
    for p in (root / "touch").glob("F0002_*"):
        p.unlink()
    msgs = [p.message for p in scan(root).errors]
    assert msgs == ["fabric 2 has no touch item (other fabrics have; a run that uses it cannot)"]
    assert scan(root, require=[Modality.DEPTH]).errors == ()
    with pytest.raises(DatasetError, match="fabric 2 has no touch"):
        scan(root).require([Modality.TOUCH])
    with pytest.raises(
        DatasetError, match=r"none of the 3 fabrics \(1, 2, 3\) has a touch \(rand presses\) item"
    ):
        scan(root, require=[]).require([Modality.TOUCH], [PressKind.RAND])


def test_a_sense_most_fabrics_lack_is_one_line_and_a_few_lacking_it_a_line_each(tmp_path: Path):
    # A dataset without a sense said so once per fabric: 12 fabrics, 12 lines.
    root = write_tiny_dataset(tmp_path / "d", fabrics=6, labels=False)
    for p in (root / "color").iterdir():
        p.unlink()
    for p in (root / "touch").glob("F000[23]_*"):
        p.unlink()
    errors = [p.message for p in scan(root, require=[Modality.COLOR, Modality.TOUCH]).errors]
    leave_out = (
        '; every fabric has depth: --set "train.views=[depth,depth]" trains without touch, or '
        "add its touch items"
    )  # a run's needs: the line says what trains (test_data_names.py)
    assert errors == [
        "none of the 6 fabrics (1, 2, 3 and 3 more) has a color item",
        "fabric 2 has no touch item" + leave_out,
        "fabric 3 has no touch item" + leave_out,
    ]
    for p in (root / "touch").glob("F000[45]_*"):
        p.unlink()
    said = [p.message for p in scan(root).problems if "touch" in p.message]
    assert said == [
        "4 of the 6 fabrics (2, 3, 4, 5) have no touch item (other fabrics have; a run that "
        "uses it cannot)"
    ]


def test_missing_root_is_a_clear_error(tmp_path: Path):
    with pytest.raises(DatasetError, match=r"^\S*nope: dataset folder does not exist$"):
        scan(tmp_path / "nope")
    (tmp_path / "file").write_text("x", encoding="utf-8")
    with pytest.raises(DatasetError, match=r"^\S*file: is not a folder \(a dataset is a folder"):
        scan(tmp_path / "file")


def test_subset_and_with_items(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    sub = catalog.subset([5, 2])
    assert sub.ids == [2, 5]
    with pytest.raises(DatasetError, match="fabric id.* 9 are not in the dataset"):
        catalog.subset([2, 9])
    keep = catalog.items(Modality.DEPTH)[:4]
    only = catalog.with_items(keep)
    assert only.ids == [1, 2] and only.modalities == (Modality.DEPTH,)


def test_files_in_subfolders_of_a_modality_folder_are_skipped_not_read(tiny_dataset: Path):
    # The layout is flat: depth/old/ (an old copy) and videos/sub/ used to be read recursively.
    write_depth(tiny_dataset / "depth" / "old" / "F0001_Depth_New_000099.png", 1, 99)
    write_depth(tiny_dataset / "depth" / "old" / "deeper" / "F0007_Depth_New_1.png", 7, 1)
    (tiny_dataset / "depth" / "empty").mkdir()
    (tiny_dataset / "videos" / "sub").mkdir(parents=True)
    (tiny_dataset / "videos" / "sub" / "bowl_0.mov").write_bytes(
        b"\x00\x00\x00\x14ftypqt  \x00\x00\x02\x00" + bytes(64)
    )
    catalog = scan(tiny_dataset)
    read = {
        p.name for f in catalog.fabrics for its in f.items.values() for it in its for p in it.frames
    }
    assert "F0001_Depth_New_000099.png" not in read and "bowl_0.mov" not in read
    assert catalog.ids == [1, 2, 3, 4, 5, 6]  # no fabric 7, no object "bowl"
    assert len(catalog.items(Modality.DEPTH)) == 18
    skipped = {str(p.path.relative_to(tiny_dataset)): p.message for p in catalog.skipped if p.path}
    assert skipped == {
        "depth/empty": "in a subfolder of depth/: not read (empty; the layout is flat)",
        "depth/old": "in a subfolder of depth/: not read (2 file(s), e.g. "
        "F0001_Depth_New_000099.png; the layout is flat)",
        "videos/sub": "in a subfolder of videos/: not read (1 file(s), e.g. bowl_0.mov; the "
        "layout is flat)",
    }
    assert catalog.problems == ()


def test_labels_csv_that_is_a_folder_is_an_error_not_skipped(tiny_dataset: Path):
    (tiny_dataset / "labels.csv").unlink()
    (tiny_dataset / "labels.csv").mkdir()
    catalog = scan(tiny_dataset)
    assert [str(p) for p in catalog.errors] == [
        f"{tiny_dataset / 'labels.csv'}: labels.csv is a folder, not a file"
    ]
    assert catalog.skipped == ()
    assert catalog.label_columns == () and catalog.ids == [1, 2, 3, 4, 5, 6]


def test_webm_and_m4v_presses_are_read_and_other_video_formats_say_so(tmp_path: Path):
    """WebM (a Matroska subset, VP8/VP9 inside) and .m4v (MP4) are videos as .mkv and .mp4
    are: scanned, and their press found. A video format lookfeel does not read (.wmv) is
    skipped with a reason that says so and names those it reads, not as "not a video"."""
    import av

    from lookfeel.data.video import read_press

    from ._video import PRESS, object_press, write_video

    vp = next((c for c in ("libvpx-vp9", "libvpx") if c in av.codecs_available), None)
    if vp is None:
        pytest.skip("this FFmpeg build has no VP8/VP9 encoder")
    videos = tmp_path / "rec" / "videos"
    videos.mkdir(parents=True)
    (tmp_path / "rec" / "labels.csv").write_text(
        "object,hardness\ncork,0\nfelt,1\n", encoding="utf-8"
    )
    frames = object_press(1, PRESS, 16)
    webm = write_video(videos / "cork_0.webm", frames, vp)
    m4v = write_video(videos / "felt_0.m4v", frames)
    (videos / "felt_1.wmv").write_bytes(b"0&\xb2u\x8ef\xcf\x11" + bytes(32))  # an ASF header
    catalog = scan(tmp_path / "rec")
    assert catalog.problems == ()
    assert sorted(it.path.name for it in catalog.items(Modality.TOUCH)) == [
        "cork_0.webm",
        "felt_0.m4v",
    ]
    for path in (webm, m4v):
        span = read_press(path).span
        assert (span.start, span.peak, span.end) == (5, 7, 10)
    [(name, why)] = [(p.path.name, p.message) for p in catalog.skipped if p.path]
    assert name == "felt_1.wmv"
    assert why == (
        "a video format lookfeel does not read (.wmv); convert it to one it reads "
        "(.mov, .mp4, .avi, .mkv, .webm, .m4v)"
    )


def test_a_missing_item_names_the_files_of_its_folder_that_were_skipped(tmp_path: Path):
    # Every depth map saved as .tif: "fabric 1 has no depth item" alone hid why.
    root = write_tiny_dataset(tmp_path / "d", fabrics=2, drapes=2)
    for png in (root / "depth").iterdir():
        png.rename(png.with_suffix(".tif"))
    (root / "depth" / ".DS_Store").write_bytes(b"")  # hidden files are no reason
    errors = [p.message for p in scan(root, require=[Modality.DEPTH]).errors]
    assert errors == [
        "none of the 2 fabrics (1, 2) has a depth item; 4 file(s) of its folder were skipped, "
        "e.g. F0001_Depth_New_000000.tif: not an image (.png, .jpg, .jpeg) (see `lookfeel data "
        "check`)"
    ]
    # A folder with nothing skipped says what it said.
    (root / "color" / "F0002_1.png").unlink()
    (root / "color" / "F0002_2.png").unlink()
    said = [p.message for p in scan(root).problems if "no color item" in p.message]
    assert said == ["fabric 2 has no color item (other fabrics have; a run that uses it cannot)"]


@pytest.mark.parametrize("file_form, labels_form", [("NFD", "NFC"), ("NFC", "NFD")])
def test_an_object_name_spelt_in_another_unicode_form_is_the_same_object(
    tmp_path: Path, file_form: str, labels_form: str
):
    """QA: macOS names a file ``crème_0.mp4`` with the é decomposed (e + a combining accent);
    a labels.csv typed elsewhere has it composed. The two look the same, yet the scan said
    "object 'crème' has no row in labels.csv" and "object 'crème' is in labels.csv but has no
    video". Both are now read in the composed form (NFC); the file keeps its own name."""
    import unicodedata

    forms = {
        "NFC": unicodedata.normalize("NFC", "crème"),
        "NFD": unicodedata.normalize("NFD", "crème"),
    }
    assert forms["NFC"] != forms["NFD"]  # e + a combining accent: they look alike

    def spelt(form: str) -> str:
        return forms[form]

    root = tmp_path / "rec"
    (root / "videos").mkdir(parents=True)
    (root / "labels.csv").write_text(
        f"object,hardness,material\n{spelt(labels_form)},1,{spelt(labels_form)}\nfelt,0,wool\n",
        encoding="utf-8",
    )
    mp4 = b"\x00\x00\x00\x18ftypmp42" + bytes(16)  # a header is all the scan reads
    video = root / "videos" / f"{spelt(file_form)}_0.mp4"
    video.write_bytes(mp4)
    (root / "videos" / "felt_0.mp4").write_bytes(mp4)
    catalog = scan(root)
    assert catalog.problems == ()
    creme = next(f for f in catalog.fabrics if f.name == spelt("NFC"))
    assert creme.labels == {"hardness": 1.0}
    assert creme.text_labels["material"] == spelt("NFC")
    [item] = creme.items[Modality.TOUCH]
    assert item.path == video  # opened by its real name
    assert item.path.name == f"{spelt(file_form)}_0.mp4"
