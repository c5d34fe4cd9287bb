"""Scanning a dataset folder in the one on-disk layout (README, "Data") into a `Catalog`.

::

    <root>/labels.csv                      optional; one row per fabric
    <root>/depth/F0001_Depth_New_204300.png one drape; 16-bit PNG, millimetres, 0 = no reading
    <root>/color/F0001_1.jpg                one drape; 8-bit RGB
    <root>/touch/F0001_fold_03_1502.jpg     frame 3 of press 1502, a fold press
    <root>/touch/F0001_fold_1502.mp4        press 1502 as a video (GelSight Mini, DIGIT ...)
    <root>/videos/sponge_0.mov              press 0 of the object ``sponge`` (labels.csv keyed
                                            by ``object``; each name becomes a fabric id)

The authors' folder names are aliases (``kinect_depth``, ``kinect_depth_new``; ``canon``,
``canon_resize``; ``image_fold``, ``image_flat``, ``image_rand*``, whose kind the names may then
omit). Anything else, a subfolder of these folders included (the layout is flat), is reported
as skipped, never silently read. The scan reads only names and the first bytes of each file
(cheap); `lookfeel.data.check_dataset` decodes every pixel.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import unicodedata
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from lookfeel.data.catalog import Catalog, Fabric, Item
from lookfeel.data.files import file_kind
from lookfeel.data.labels import LabelTable, read_labels
from lookfeel.data.paths import lies_within
from lookfeel.data.problems import DatasetError, Problem, lacking_lines, leave_out
from lookfeel.data.video import VIDEO_SUFFIXES
from lookfeel.modality import REPRINTS, Modality, PressKind

__all__ = [
    "FOLDER_ALIASES",
    "IMAGE_SUFFIXES",
    "NOT_A_VIDEO_CONTAINER",
    "VIDEO_SUFFIXES",
    "duplicate_files",
    "folder_modality",
    "parse_touch_name",
    "press_frame_files",
    "press_kind",
    "scan",
    "sniff_video",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")

_OTHER_VIDEO_SUFFIXES = frozenset(
    {".wmv", ".asf", ".flv", ".f4v", ".3gp", ".3g2", ".mpg", ".mpeg", ".m2v", ".ogv", ".mts"}
    | {".m2ts", ".ts", ".vob", ".mxf", ".dv", ".qt", ".rm", ".rmvb", ".divx", ".y4m", ".h264"}
    | {".264", ".h265", ".hevc", ".mjpeg", ".mjpg"}
)
"""Suffixes of videos that lookfeel does not read (not `VIDEO_SUFFIXES`): skipped with a reason
that says so and names the ones it reads, so a press recorded as ``.wmv`` is converted, not
wondered about."""

FOLDER_ALIASES: dict[Modality, tuple[str, ...]] = {
    Modality.DEPTH: ("depth", "kinect_depth_new", "kinect_depth"),
    Modality.COLOR: ("color", "canon_resize", "canon"),
    Modality.TOUCH: ("touch", "videos", "image_fold", "image_flat", "image_rand"),
}
"""Folder names per modality, canonical first. For depth and colour the first folder present is
read and the others are skipped (the authors' tree keeps raw and cropped copies side by side)."""

_FIXED_KIND = {"image_fold": PressKind.FOLD, "image_flat": PressKind.FLAT}
_FABRIC = re.compile(r"^[Ff]0*(\d+)_(.+)$")
"""A depth or colour file's name: ``F0012_1``, or ``f0012_1`` (as labels.csv reads ``f0012`` and
a touch file's name is read in any case)."""
_TOUCH = re.compile(
    r"^F0*(?P<fabric>\d+)_(?:(?P<kind>fold|flat|rand)_)?(?P<frame>\d+)_(?P<press>[A-Za-z0-9-]+)$",
    re.IGNORECASE,
)
_TOUCH_VIDEO = re.compile(
    r"^F0*(?P<fabric>\d+)_(?:(?P<kind>fold|flat|rand)_)?(?P<press>[A-Za-z0-9-]+)$", re.IGNORECASE
)
_OBJECT_VIDEO = re.compile(r"^(?P<object>.+)_(?P<press>\d+)$")
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def sniff_video(head: bytes) -> bool:
    """Whether a file's first 16 bytes begin a video container FFmpeg reads: QuickTime/MP4
    (an atom such as ``ftyp`` at byte 4), AVI (``RIFF....AVI ``) or Matroska/WebM."""
    if head[4:8] in (b"ftyp", b"moov", b"mdat", b"wide", b"free", b"skip", b"pnot"):
        return True
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return True
    return head[:4] == b"\x1a\x45\xdf\xa3"


NOT_A_VIDEO_CONTAINER = "not a video container (QuickTime .mov, MP4, AVI or Matroska)"
"""Why the scan refuses a video file by its first bytes (`sniff_video`); ``lookfeel data
check``, which decodes, says what the file is instead (an image renamed ``.mp4``)."""


def _video_header_problem(path: Path) -> str | None:
    """A cheap check that a video file is a container FFmpeg reads (QuickTime/MP4, AVI,
    Matroska/WebM)."""
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as e:
        return f"cannot read file: {e.strerror}"
    if not head:
        return "file is empty"
    if sniff_video(head):
        return None
    return NOT_A_VIDEO_CONTAINER


@dataclass(frozen=True)
class TouchName:
    """The parts of a touch frame's file name."""

    fabric_id: int
    kind: PressKind | None
    frame: int
    press: str


def parse_touch_name(name: str) -> TouchName | None:
    """Parse ``F<id>_<kind>_<frame>_<press>.<ext>`` (kind optional); None when it does not fit."""
    m = _TOUCH.match(Path(name).stem)
    if m is None:
        return None
    kind = PressKind(m["kind"].lower()) if m["kind"] else None
    fabric = _fabric_id(m["fabric"].lstrip("0") or "0")
    frame = int(m["frame"]) if len(m["frame"]) <= 9 else None
    if frame is None:
        return None
    return TouchName(MAX_FABRIC_ID + 1 if fabric is None else fabric, kind, frame, m["press"])


def press_frame_files(path: Path) -> tuple[Path, ...] | None:
    """Every frame of the press that touch frame ``path`` belongs to, in frame order: the
    image files beside it whose names give the same fabric, kind and press
    (``F<id>_<kind>_<frame>_<press>.<ext>``); ``None`` when ``path``'s name does not parse.
    For a press given as one of its files (a query) rather than found by `scan`."""
    own = parse_touch_name(path.name)
    if own is None:
        return None
    frames = []
    for p in path.parent.iterdir():
        if p.suffix.lower() not in IMAGE_SUFFIXES:
            continue
        tn = parse_touch_name(p.name)
        if tn is not None and (tn.fabric_id, tn.kind, tn.press) == (
            own.fabric_id,
            own.kind,
            own.press,
        ):
            frames.append((tn.frame, p.name, p))
    return tuple(p for _, _, p in sorted(frames))


def press_kind(path: str | os.PathLike[str]) -> PressKind | None:
    """The kind of press a touch file shows, as `scan` reads it: from its name, a frame's
    (``F0001_fold_02_101.png``, `parse_touch_name`) or a video's (``F0001_flat_1000.mp4``),
    else from its folder (``image_flat/``, `folder_modality`); None where neither says
    (``press.mp4``, an object's ``sponge_0.mov``). For a query file, which no scan has read."""
    p = Path(path)
    if p.suffix.lower() in VIDEO_SUFFIXES:
        m = _TOUCH_VIDEO.match(p.stem)
        kind = PressKind(m["kind"].lower()) if m is not None and m["kind"] else None
    else:
        tn = parse_touch_name(p.name)
        kind = None if tn is None else tn.kind
    if kind is None:
        folder = folder_modality(p.parent.name)
        kind = None if folder is None else folder[1]
    return kind


def folder_modality(name: str) -> tuple[Modality, PressKind | None] | None:
    low = name.lower()
    for modality, names in FOLDER_ALIASES.items():
        if low in names:
            return modality, _FIXED_KIND.get(low)
    if low.startswith("image_rand"):
        return Modality.TOUCH, PressKind.RAND
    return None


def _header_problem(path: Path, modality: Modality) -> str | None:
    """A cheap check of the file's first bytes: format, and 16-bit greyscale for depth."""
    try:
        with path.open("rb") as f:
            head = f.read(32)
    except OSError as e:
        return f"cannot read file: {e.strerror}"
    if not head:
        return "file is empty"
    is_png = head.startswith(_PNG_MAGIC)
    is_jpeg = head.startswith(b"\xff\xd8\xff")
    if modality is Modality.DEPTH:
        if not is_png:
            return "depth must be a 16-bit greyscale PNG (millimetres); this is not a PNG"
        if len(head) < 26 or head[12:16] != b"IHDR":
            return "PNG header is truncated or damaged"
        bit_depth, colour_type = head[24], head[25]
        if bit_depth != 16 or colour_type != 0:
            kind = {0: "greyscale", 2: "RGB", 3: "palette", 4: "grey+alpha", 6: "RGBA"}.get(
                colour_type, f"colour type {colour_type}"
            )
            return (
                f"depth PNG is {bit_depth}-bit {kind}; expected 16-bit greyscale in millimetres "
                "(an 8-bit depth map has lost its scale)"
            )
        return None
    if not (is_png or is_jpeg):
        return "not a PNG or JPEG image"
    if is_png and (len(head) < 26 or head[12:16] != b"IHDR"):
        return "PNG header is truncated or damaged"
    return None


MAX_FABRIC_ID = 2**31 - 1
"""Largest fabric id a file name may carry (ids are stored as 64-bit integers everywhere; a
name like ``F99999999999999999999999_1.jpg`` is reported, not overflowed)."""
SYNTH_MANIFEST = "synth.json"
_SYNTH_FILES = (SYNTH_MANIFEST, "contact_sheet.png")
"""What `lookfeel synth` writes beside a world's data: not items, and not listed as skipped."""


def _id_message(path: Path) -> str:
    return f"fabric id in the file name is larger than {MAX_FABRIC_ID}; expected F<id>_..."


def _walk(folder: Path) -> tuple[list[Path], list[Path]]:
    """(entries to read, subfolders) of a modality folder, each sorted by name.

    The layout is flat (README, "Data"): a folder inside ``depth/`` or ``videos/`` (an
    ``old/`` copy, a camera's session folder) is listed as skipped, never read, so that no file
    enters a run unseen. A symbolic link is an entry even when it leads to a folder (the file
    policy then reports it)."""
    entries: list[Path] = []
    subfolders: list[Path] = []
    for p in sorted(folder.iterdir()):
        (subfolders if p.is_dir() and not p.is_symlink() else entries).append(p)
    return entries, subfolders


def _subfolder_skip(path: Path, folder: Path) -> Problem:
    """The skip entry of a subfolder of a modality folder: what it holds, which is not read."""
    files = sorted(p for p in path.rglob("*") if not p.is_dir())
    holds = f"{len(files)} file(s), e.g. {files[0].name}" if files else "empty"
    return Problem(
        path, f"in a subfolder of {folder.name}/: not read ({holds}; the layout is flat)", "skip"
    )


def _file_problem(path: Path, real_root: Path) -> str | None:
    """A file the image policy refuses: a special file, or a link leaving the dataset folder."""
    try:
        st = path.stat()  # follows links
    except FileNotFoundError:
        return f"symbolic link to {os.readlink(path)}, which does not exist"
    except OSError as e:
        return f"cannot read file: {e.strerror}"
    if not stat.S_ISREG(st.st_mode):
        return f"is {file_kind(st.st_mode)}, not a regular image file"
    if path.is_symlink():
        target = path.resolve()
        if not lies_within(target, real_root):  # by identity too: another case of its name
            return (
                f"symbolic link to {target}, outside the dataset folder {real_root}; copy the "
                "file in, or link the whole dataset folder instead"
            )
    return None


def _labels_file_problem(path: Path) -> str | None:
    """Why ``labels.csv`` cannot be read as a file (a folder, a FIFO, a dangling link), if so."""
    try:
        mode = path.stat().st_mode  # follows links
    except FileNotFoundError:
        return f"labels.csv is a symbolic link to {os.readlink(path)}, which does not exist"
    except OSError as e:
        return f"cannot read labels file: {e.strerror}"
    if stat.S_ISREG(mode):
        return None
    return f"labels.csv is {file_kind(mode)}, not a file"


def _fabric_id(text: str) -> int | None:
    """A file name's fabric id, or None when it is out of range."""
    if len(text) > 10:
        return None
    fid = int(text)
    return fid if fid <= MAX_FABRIC_ID else None


def _synth_problem(root: Path) -> Problem | None:
    """An unfinished ``lookfeel synth`` world (its manifest's status is not ``complete``)."""
    path = root / SYNTH_MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return Problem(path, "synthetic-world manifest is unreadable; run `lookfeel synth` again")
    if not isinstance(data, dict) or data.get("generator") != "lookfeel.synth":
        return None
    if data.get("status") != "complete":
        return Problem(
            path,
            f"this synthetic world was not finished (status {data.get('status')!r}: `lookfeel "
            "synth` was stopped while rendering); run the same `lookfeel synth` command again",
        )
    return None


def _video_key(
    path: Path, folder: Path, folder_kind: PressKind | None, objects: frozenset[str] = frozenset()
) -> tuple[tuple[int | str, PressKind | None, str] | None, str | None]:
    """(owner, kind, press) of a video: ``F<id>_[<kind>_]<press>`` names a fabric (in any touch
    folder); in ``videos/``, ``<object>_<n>`` names an object, and always does for one of
    ``objects`` (those a labels file keyed by ``object`` names: ``F0001_0.mp4`` is object
    ``F0001``'s press there, not fabric 1's). Or a message saying why not.

    An object's name is taken in Unicode's composed form (NFC), as `read_labels` takes the
    names in labels.csv: macOS writes ``crème`` in a file name decomposed (``e`` and a combining
    accent), which looks the same but compares unequal. The path itself is kept as it is."""
    stem = unicodedata.normalize("NFC", path.stem)
    in_videos = folder.name.lower() == "videos"
    named = _OBJECT_VIDEO.match(stem) if in_videos else None
    if named is not None and named["object"] in objects:
        return (named["object"], None, named["press"]), None
    m = _TOUCH_VIDEO.match(stem)
    if m is not None:
        fid = _fabric_id(m["fabric"].lstrip("0") or "0")
        if fid is None:
            return None, _id_message(path)
        kind = PressKind(m["kind"].lower()) if m["kind"] else folder_kind
        if m["kind"] and folder_kind is not None and kind != folder_kind:
            return (
                None,
                f"name says a {m['kind'].lower()} press but folder {folder.name}/ holds "
                f"{folder_kind.value} presses",
            )
        if kind is None and folder.name.lower() != "videos":
            return None, (
                "touch video name has no press kind (fold, flat, rand) and its folder "
                f"{folder.name}/ does not give one; expected F<id>_<kind>_<press>{path.suffix}"
            )
        return (fid, kind, m["press"]), None
    if in_videos:
        if named is not None:
            return (named["object"], None, named["press"]), None
        return None, (
            f"video name does not parse; expected <object>_<n>{path.suffix} "
            f"(e.g. sponge_0{path.suffix}) or F<id>_<press>{path.suffix}"
        )
    return None, (
        f"touch video name does not parse; expected F<id>_<fold|flat|rand>_<press>{path.suffix}, "
        f"e.g. F0012_fold_1502{path.suffix}"
    )


def _folded(names: Iterable[str]) -> dict[str, list[str]]:
    """Names by their case-folded spelling (``egg`` -> ``["EGG", "Egg", "egg"]``), sorted."""
    out: dict[str, list[str]] = defaultdict(list)
    for n in sorted(names):
        out[n.casefold()].append(n)
    return out


def _case_hint(name: str | None, folded: dict[str, list[str]], where: str) -> str:
    """``" (labels.csv has row 'Egg': names are case-sensitive ...)"``: the names in
    ``folded`` that differ from ``name`` in case alone, after ``where``; empty when none
    does."""
    if name is None:
        return ""
    near = [repr(n) for n in folded.get(name.casefold(), ()) if n != name]
    if not near:
        return ""
    return (
        f" ({where} {' and '.join(near)}: names are case-sensitive; write them alike if they "
        "are one)"
    )


def _case_problems(owners: dict[str, Path]) -> list[Problem]:
    """A warning per group of object names (each with its first file) that differ only in
    case (``egg``, ``Egg``, ``EGG``): each is an object of its own, so one physical object may
    sit on both sides of a held-out split."""
    out = []
    for names in _folded(owners).values():
        if len(names) < 2:
            continue
        listed = ", ".join(repr(n) for n in names[:-1]) + f" and {names[-1]!r}"
        first = min(owners[n] for n in names)
        out.append(
            Problem(
                first.parent,
                f"objects {listed} differ only in case, so they are {len(names)} objects (a "
                "split may train on one and hold out another); rename their files alike if "
                "they are one",
                "warning",
            )
        )
    return out


def _clash_problems(folder: Path, names: Iterable[str]) -> list[Problem]:
    """A warning per group of names in one ``folder`` that differ only in case, or only in how
    an accented letter is written (composed or not): Linux keeps them as two files
    (``F0001_1.png`` and ``f0001_1.png``, two items), but macOS and Windows cannot hold both
    in one folder, so a copy of the dataset there keeps one and silently has other items and
    another fingerprint."""
    groups: dict[str, list[str]] = defaultdict(list)
    for n in sorted(names):
        groups[unicodedata.normalize("NFC", n).casefold()].append(n)
    out = []
    for same in groups.values():
        if len(same) < 2:
            continue
        listed = ", ".join(repr(n) for n in same[:-1]) + f" and {same[-1]!r}"
        how = (
            "in case"
            if len({n.casefold() for n in same}) == 1
            else "in how an accented letter is written (composed or not)"
        )
        out.append(
            Problem(
                folder,
                f"{listed} differ only {how}: they cannot both exist on macOS or Windows, "
                "where a copy of this folder keeps one; rename one if they are different",
                "warning",
            )
        )
    return out


def scan(
    root: str | Path,
    require: Iterable[Modality] | None = None,
    *,
    strict: bool = False,
    check_headers: bool = True,
) -> Catalog:
    """Scan a dataset folder into a `Catalog`, collecting every problem at once.

    Files with problems are left out of the catalog's items; each problem names its path.

    Args:
        root: the dataset folder.
        require: modalities every fabric must have (a run's needs). ``None`` requires each
            modality that any fabric has, so a fabric missing one is reported.
        strict: raise `DatasetError` listing all errors instead of returning them.
        check_headers: read each file's first bytes to check its format (cheap).

    Raises:
        DatasetError: ``root`` is not a folder; or, with ``strict``, any error.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(
            "dataset folder does not exist"
            if not root.exists()
            else "is not a folder (a dataset is a folder: depth/, color/, touch/, videos/)",
            root,
        )
    problems: list[Problem] = []
    skipped: list[Problem] = []
    real_root = root.resolve()
    if (unfinished := _synth_problem(root)) is not None:
        problems.append(unfinished)

    # ---- which folders hold which modality -------------------------------------------------
    folders: list[tuple[Path, Modality, PressKind | None]] = []
    used_single: dict[Modality, Path] = {}
    labels_path: Path | None = None
    top = sorted(root.iterdir())
    problems.extend(_clash_problems(root, (p.name for p in top)))
    for entry in top:
        if entry.name == "labels.csv":
            if msg := _labels_file_problem(entry):
                problems.append(Problem(entry, msg))  # not skipped: the labels would be lost
            else:
                labels_path = entry
            continue
        if entry.is_dir() and entry.name == REPRINTS:
            continue  # training views of the colour photos (`reprint_path`), not items
        if entry.name in _SYNTH_FILES and (root / SYNTH_MANIFEST).is_file():
            continue  # a `lookfeel synth` world's own record and picture (read above)
        fm = folder_modality(entry.name) if entry.is_dir() else None
        if fm is None:
            skipped.append(
                Problem(
                    entry,
                    "not part of the layout (depth/, color/, touch/, videos/, labels.csv)",
                    "skip",
                )
            )
            continue
        folders.append((entry, fm[0], fm[1]))
    rank = {m: {n: i for i, n in enumerate(names)} for m, names in FOLDER_ALIASES.items()}
    for path, modality, _ in sorted(folders, key=lambda x: rank[x[1]].get(x[0].name.lower(), 99)):
        if modality is not Modality.TOUCH and modality not in used_single:
            used_single[modality] = path
    # labels.csv before the files: one keyed by `object` says which videos name objects (its
    # problems are reported after the files', where they always were)
    table: LabelTable | None = None
    label_problems: list[Problem] = []
    if labels_path is not None:
        table, label_problems = read_labels(labels_path)
    objects = frozenset(table.named) if table is not None and table.key == "object" else frozenset()
    kept = []
    for path, modality, kind in folders:
        if modality is not Modality.TOUCH and used_single[modality] != path:
            skipped.append(
                Problem(
                    path,
                    f"another {modality.value} folder is read: {used_single[modality]}",
                    "skip",
                )
            )
        else:
            kept.append((path, modality, kind))

    # ---- files -------------------------------------------------------------------------------
    singles: dict[int, dict[Modality, list[Path]]] = defaultdict(lambda: defaultdict(list))
    presses: dict[tuple[int, PressKind, str], dict[int, Path]] = {}
    videos: dict[tuple[int | str, PressKind | None, str], Path] = {}
    for folder, modality, folder_kind in kept:
        in_videos = folder.name.lower() == "videos"
        entries, subfolders = _walk(folder)
        skipped.extend(_subfolder_skip(sub, folder) for sub in subfolders)
        problems.extend(_clash_problems(folder, (p.name for p in (*entries, *subfolders))))
        for path in entries:
            suffix = path.suffix.lower()
            is_video = modality is Modality.TOUCH and suffix in VIDEO_SUFFIXES
            if path.name.startswith(".") or not (
                is_video or (suffix in IMAGE_SUFFIXES and not in_videos)
            ):
                reads = ", ".join(VIDEO_SUFFIXES)
                what = (
                    "a hidden file (its name begins with a dot)"
                    if path.name.startswith(".")
                    else f"a video format lookfeel does not read ({suffix}); convert it to one "
                    f"it reads ({reads})"
                    if modality is Modality.TOUCH and suffix in _OTHER_VIDEO_SUFFIXES
                    else f"not a video ({reads})"
                    if in_videos
                    else "not an image (.png, .jpg, .jpeg)"
                    + (f" or a video ({reads})" if modality is Modality.TOUCH else "")
                )
                skipped.append(Problem(path, what, "skip"))
                continue
            if msg := _file_problem(path, real_root):
                problems.append(Problem(path, msg))
                continue
            if is_video:
                key, msg = _video_key(path, folder, folder_kind, objects)
                if msg is None and check_headers:
                    msg = _video_header_problem(path)
                if msg is not None or key is None:
                    problems.append(Problem(path, msg or "unusable video name"))
                    continue
                if key in videos:
                    problems.append(Problem(path, f"same press as {videos[key]}"))
                    continue
                videos[key] = path
                continue
            if modality is Modality.TOUCH:
                tn = parse_touch_name(path.name)
                if tn is not None and tn.fabric_id > MAX_FABRIC_ID:
                    problems.append(Problem(path, _id_message(path)))
                    continue
                if tn is None:
                    problems.append(
                        Problem(
                            path,
                            "touch frame name does not parse; expected F<id>_<fold|flat|rand>_"
                            "<frame>_<press>.<ext>, e.g. F0012_fold_03_1502.jpg",
                        )
                    )
                    continue
                kind = tn.kind or folder_kind
                if kind is None:
                    problems.append(
                        Problem(
                            path,
                            "touch frame name has no press kind (fold, flat, rand) and its folder "
                            f"{folder.name}/ does not give one",
                        )
                    )
                    continue
                if tn.kind is not None and folder_kind is not None and tn.kind != folder_kind:
                    problems.append(
                        Problem(
                            path,
                            f"name says a {tn.kind.value} press but folder {folder.name}/ holds "
                            f"{folder_kind.value} presses",
                        )
                    )
                    continue
                if check_headers and (msg := _header_problem(path, modality)):
                    problems.append(Problem(path, msg))
                    continue
                frames = presses.setdefault((tn.fabric_id, kind, tn.press), {})
                if tn.frame in frames:
                    problems.append(
                        Problem(
                            path,
                            f"frame {tn.frame} of {kind.value} press {tn.press} of fabric "
                            f"{tn.fabric_id} is also {frames[tn.frame]}",
                        )
                    )
                    continue
                frames[tn.frame] = path
            else:
                name_match = _FABRIC.match(path.stem)
                if name_match is None:
                    problems.append(
                        Problem(
                            path,
                            f"{modality.value} file name must begin F<id>_ (e.g. F0012_1.png)",
                        )
                    )
                    continue
                fid = _fabric_id(name_match.group(1))
                if fid is None:
                    problems.append(Problem(path, _id_message(path)))
                    continue
                if check_headers and (msg := _header_problem(path, modality)):
                    problems.append(Problem(path, msg))
                    continue
                singles[fid][modality].append(path)

    # ---- the labels' problems, and ids for the named objects -----------------------------------
    problems.extend(label_problems)
    names = sorted(
        {k[0] for k in videos if isinstance(k[0], str)} | set(table.named if table else ())
    )
    first_named = max([*singles, *(k[0] for k in presses), 0]) + 1
    first_named = max(
        [first_named, *(k[0] + 1 for k in videos if isinstance(k[0], int))], default=first_named
    )
    name_ids = {n: first_named + i for i, n in enumerate(names)}
    if table is not None and table.key == "object":
        table = table.with_ids(name_ids)

    items: dict[int, dict[Modality, list[Item]]] = defaultdict(lambda: defaultdict(list))
    for (owner, kind, press), path in sorted(videos.items(), key=lambda kv: str(kv[1])):
        fid = name_ids[owner] if isinstance(owner, str) else owner
        items[fid][Modality.TOUCH].append(Item(Modality.TOUCH, fid, (path,), kind, press))
    for fid, by_mod in singles.items():
        for modality, paths in by_mod.items():
            items[fid][modality] = [Item(modality, fid, (p,)) for p in sorted(paths)]
    for (fid, kind, press), frames in sorted(
        presses.items(), key=lambda kv: (kv[0][0], kv[0][1].value, kv[0][2])
    ):
        ordered = tuple(frames[k] for k in sorted(frames))
        items[fid][Modality.TOUCH].append(Item(Modality.TOUCH, fid, ordered, kind, press))

    id_names = {i: n for n, i in name_ids.items()}
    owned: dict[str, Path] = {}  # each object's first video
    for (owner, _, _), path in sorted(videos.items(), key=lambda kv: str(kv[1])):
        if isinstance(owner, str):
            owned.setdefault(owner, path)
    problems.extend(_case_problems(owned))
    rows_folded = _folded(table.named if table is not None else ())
    files_folded = _folded(owned)
    if table is not None and table.keyed:  # else its one error says why no row is read
        for fid in sorted(items):
            if fid not in table.rows:
                first = min(p for its in items[fid].values() for it in its for p in it.frames)
                n = sum(len(its) for its in items[fid].values())
                who = f"object {id_names[fid]!r}" if fid in id_names else f"fabric {fid}"
                near = _case_hint(id_names.get(fid), rows_folded, f"{table.path.name} has row")
                problems.append(
                    Problem(first, f"{who} ({n} item(s)) has no row in {table.path.name}{near}")
                )

    present = {m for by_mod in items.values() for m, its in by_mod.items() if its}
    needed = [m for m in Modality if m in present] if require is None else list(require)
    for m in needed:
        folder = used_single.get(m) or root / m.value
        # Files of this modality's folders that were skipped (a .tif depth map, a subfolder
        # of frames) are the likely reason an item is missing: name them.
        its_folders = {f for f, mod, _ in kept if mod is m}
        passed = [
            (q.path, q.message)
            for q in skipped
            if q.path is not None
            and q.path.parent in its_folders
            and not q.path.name.startswith(".")
        ]
        why = (
            f"; {len(passed)} file(s) of its folder were skipped, e.g. {passed[0][0].name}: "
            f"{passed[0][1]} (see `lookfeel data check`)"
            if passed
            else ""
        )
        lacking = [fid for fid in sorted(items) if not items[fid].get(m)]
        if not lacking:
            continue
        noun = "object" if id_names else "fabric"
        names = [repr(id_names[f]) if f in id_names else str(f) for f in lacking]
        heads, grouped = lacking_lines(names, len(items), noun, m.value)
        others = f" (other {noun}s have; a run that uses it cannot)" if require is None else ""
        # A run's needs (``require``): the --set that trains on what every fabric has; a sense
        # no fabric has is the run's own line (`lookfeel.train.loop.views_problem`).
        fix = ""
        if require is not None and len(lacking) < len(items):
            everyone = [s.value for s in Modality if all(items[f].get(s) for f in items)]
            fix = leave_out(m.value, everyone, noun, not grouped)
        problems += [Problem(folder, head + others + fix + why) for head in heads]
    if require is not None and not items:
        problems.append(
            Problem(root, "no image or video found in the layout (depth/, color/, touch/, videos/)")
        )

    fabrics = []
    for fid in sorted(items):
        row = table.rows.get(fid) if table is not None else None
        fabrics.append(
            Fabric(
                id=fid,
                labels=dict(row.values) if row else {},
                cluster=row.cluster if row else None,
                paper_split=row.paper_split if row else None,
                items={m: tuple(its) for m, its in items[fid].items() if its},
                name=id_names.get(fid),
                text_labels=dict(row.text) if row else {},
            )
        )
    labelled_only: dict[int, Fabric] = {}
    if table is not None:
        for fid, row in sorted(table.rows.items()):
            if fid not in items:
                labelled_only[fid] = Fabric(
                    fid,
                    dict(row.values),
                    row.cluster,
                    row.paper_split,
                    name=row.name,
                    text_labels=dict(row.text),
                )
                held = f" (paper_split={row.paper_split})" if row.paper_split else ""
                who = (
                    f"object {row.name!r} is in {table.path.name} but has no video"
                    + _case_hint(row.name, files_folded, "the videos name")
                    if row.name
                    else f"fabric {fid} is in {table.path.name} but has no image"
                )
                problems.append(
                    Problem(
                        table.path,
                        f"{who}{held}",
                        "warning",
                        row.line,
                    )
                )

    catalog = Catalog(
        root=root,
        fabrics=tuple(fabrics),
        label_columns=table.columns if table else (),
        text_columns=table.text_columns if table else (),
        rank_columns=table.rank_columns if table else (),
        cluster_column=table.cluster_column if table else None,
        labelled_only=labelled_only,
        problems=tuple(problems),
        skipped=tuple(skipped),
    )
    if strict and catalog.errors:
        raise DatasetError(catalog.errors, root)
    return catalog


def duplicate_files(fabrics: Iterable[Fabric]) -> list[Problem]:
    """A warning per item whose file holds the same bytes as another item's (a press: every
    frame), naming both: Finder's ``F0002_2 copy.jpg``, a press saved as ``egg_0.mov`` and
    ``egg_3.mp4``. Each copy counts as an item of its own, so a query can find its own copy,
    and a split can hold one out while training on the other. Of a group of copies the one of
    the shortest name (then the first by path) is taken as the original and the others warned
    of. For ``lookfeel data check`` (the scan itself reads no file whole).

    Only files of equal size are read (and hashed, SHA-256), so a dataset without copies costs
    one ``stat`` per file (GelFabric's 1,104 depth maps, 376 of which share a size: 20-40 ms)."""
    by_size: dict[tuple[int, ...], list[tuple[Item, Fabric]]] = defaultdict(list)
    for f in fabrics:
        for its in f.items.values():
            for it in its:
                try:
                    sizes = tuple(p.stat().st_size for p in it.frames)
                except OSError:
                    continue  # unreadable: reported where it is decoded
                by_size[sizes].append((it, f))
    out: list[Problem] = []
    for same_size in by_size.values():
        if len(same_size) < 2:
            continue
        by_bytes: dict[tuple[str, ...], list[tuple[Item, Fabric]]] = defaultdict(list)
        for it, f in same_size:
            try:
                by_bytes[tuple(_sha256(p) for p in it.frames)].append((it, f))
            except OSError:
                continue
        for copies in by_bytes.values():
            # The original first: the shorter name (``F0002_2.jpg``, not ``F0002_2 copy.jpg``).
            copies.sort(key=lambda c: (len(c[0].path.name), str(c[0].path)))
            (first, owner), *rest = copies
            for it, f in rest:
                out.append(_duplicate_problem(first, owner, it, f))
    return sorted(out, key=lambda p: str(p.path))


def _sha256(path: Path) -> str:
    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _duplicate_problem(first: Item, owner: Fabric, copy: Item, fabric: Fabric) -> Problem:
    """The warning of `duplicate_files` for ``copy`` (of ``fabric``), the same bytes as
    ``first`` (of ``owner``)."""
    other = f"{first.path.parent.name}/{first.path.name}"
    if len(copy.frames) > 1:
        what, same = "press", f"the same frames, byte for byte, as the press of {other}"
    else:
        what = "video" if copy.path.suffix.lower() in VIDEO_SUFFIXES else "image"
        same = f"the same bytes as {other}"
    if owner.id == fabric.id:
        return Problem(
            copy.path,
            f"{same}, also of {_who(fabric)}: one {what} counted twice, so a query can find its "
            "own copy; delete one",
            "warning",
        )
    return Problem(
        copy.path,
        f"{same}, of {_who(owner)}, but named as {_who(fabric)}'s here: one {what} counted "
        "twice, under two names; delete the wrong one",
        "warning",
    )


def _who(fabric: Fabric) -> str:
    return f"object {fabric.name!r}" if fabric.name is not None else f"fabric {fabric.id}"
