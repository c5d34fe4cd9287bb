"""Write a synthetic world to disk in the one dataset layout (the README's "Data" section).

::

    OUT/labels.csv                        human-style labels and k-means clusters (or a copy)
    OUT/depth/F0001_Depth_Synth_01.png    16-bit PNG, millimetres, 0 = no reading
    OUT/color/F0001_1.jpg                 8-bit RGB photo of the same drape
    OUT/touch/F0001_flat_02_1001.jpg      frame 2 of flat press 1001
    OUT/touch/F0001_fold_02_2001.jpg      frame 2 of fold press 2001
    OUT/synth.json                        config, each fabric's true parameters, every file
    OUT/contact_sheet.png                 a few fabrics across all modalities

Work is spread over processes one fabric at a time; every random stream is keyed by
``(seed, fabric id, item)``, so the files do not depend on the number of workers or the order
in which they finish. Images are written to a hidden temporary name and renamed into place, so
a killed run never leaves a truncated image under a real name. Workers die with the process
that started them, even one killed by SIGKILL (Linux: ``PR_SET_PDEATHSIG``; everywhere: each
worker checks its parent every second). ``synth.json`` says ``"status": "running"`` until the
last file is written, so `lookfeel data check` (and every scan) refuses a half-rendered world.
"""

from __future__ import annotations

import io
import json
import math
import os
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from lookfeel.atomic import atomic_write_text
from lookfeel.locks import exclusive
from lookfeel.modality import REPRINTS, Modality, PressKind
from lookfeel.processes import available_cores, die_with_parent
from lookfeel.progress import bar as progress_bar
from lookfeel.synth.color import render_colors
from lookfeel.synth.config import SynthConfig, SynthSummary
from lookfeel.synth.depth import render_depth
from lookfeel.synth.drape import drape_surface, sample_drape
from lookfeel.synth.fabric import (
    LABEL_COLUMNS,
    Fabric,
    LabelFile,
    fabrics_from_labels,
    human_labels,
    kmeans,
    read_label_file,
    reprinted,
    sample_fabrics,
)
from lookfeel.synth.gelsight import render_press, sensor
from lookfeel.synth.scene import color_camera, depth_camera

__all__ = ["GENERATOR_VERSION", "MANIFEST", "generate", "render_fabric"]

MANIFEST = "synth.json"
_GENERATOR = "lookfeel.synth"
GENERATOR_VERSION = 3
"""Bumped whenever the same config renders different images (a world made by an earlier
version is not reused): 2 = touch carries the fold's mechanics and look the material (#17);
3 = a pressed surface shows its yarns' evenness and hairiness, which follow the material
(depth and colour render as in version 2)."""
_PRESS_BASE = {PressKind.FLAT: 1000, PressKind.FOLD: 2000}
_KIND_CODE = {PressKind.FLAT: 1, PressKind.FOLD: 2}


# ---------------------------------------------------------------------------------------------
# Names.


def _depth_name(fid: int, k: int) -> str:
    return f"depth/F{fid:04d}_Depth_Synth_{k + 1:02d}.png"


def _color_name(fid: int, k: int, ext: str) -> str:
    return f"color/F{fid:04d}_{k + 1}.{ext}"


def _reprint_name(fid: int, k: int, r: int, ext: str) -> str:
    return f"{REPRINTS}/F{fid:04d}_{k + 1}_r{r}.{ext}"


def _touch_name(fid: int, kind: PressKind, frame: int, press: int, ext: str) -> str:
    return f"touch/F{fid:04d}_{kind.value}_{frame + 1:02d}_{_PRESS_BASE[kind] + press + 1}.{ext}"


def _presses(cfg: SynthConfig) -> list[tuple[PressKind, int]]:
    return [(PressKind.FLAT, p) for p in range(cfg.presses_flat)] + [
        (PressKind.FOLD, p) for p in range(cfg.presses_fold)
    ]


def _fabric_files(fid: int, cfg: SynthConfig, mods: Sequence[Modality]) -> list[str]:
    ext = cfg.image_format
    files = []
    if Modality.DEPTH in mods:
        files += [_depth_name(fid, k) for k in range(cfg.drapes)]
    if Modality.COLOR in mods:
        files += [_color_name(fid, k, ext) for k in range(cfg.drapes)]
        files += [
            _reprint_name(fid, k, r, ext)
            for k in range(cfg.drapes)
            for r in range(1, cfg.reprints + 1)
        ]
    if Modality.TOUCH in mods:
        files += [
            _touch_name(fid, kind, f, p, ext)
            for kind, p in _presses(cfg)
            for f in range(cfg.frames)
        ]
    return files


# ---------------------------------------------------------------------------------------------
# Writing.


def _encode(img: NDArray[np.generic], fmt: str, quality: int) -> bytes:
    buf = io.BytesIO()
    pil = Image.fromarray(img)
    if fmt == "png":
        pil.save(buf, format="PNG", compress_level=3)
    else:
        pil.save(buf, format="JPEG", quality=quality, subsampling=2, optimize=False)
    return buf.getvalue()


def _write(root: Path, rel: str, data: bytes) -> None:
    """Write to a hidden temporary name beside the target, then rename it into place."""
    path = root / rel
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as e:  # a full disk: name the file, leave no temp behind
        tmp.unlink(missing_ok=True)
        raise OSError(e.errno, e.strerror, str(path)) from None


def _densify_factor(cfg: SynthConfig) -> int:
    # ~4 surface samples per 8 mm grid step suffice at 224-256 px; more for bigger images.
    scale = max(cfg.depth_size / 224, cfg.color_size / 256)
    return int(min(12, max(2, math.ceil(4 * scale))))


@dataclass(frozen=True)
class _Task:
    fabric: Fabric
    cfg: SynthConfig
    modalities: tuple[Modality, ...]
    out: Path


def render_fabric(
    fabric: Fabric, cfg: SynthConfig, modalities: Sequence[Modality], out: Path
) -> dict[str, int]:
    """Render and write every image of one fabric; returns counts by kind of item.

    Each drape, and each press, has its own random stream keyed by ``(seed, id, item)``.
    """
    fid, seed, ext = fabric.fabric_id, cfg.seed, cfg.image_format
    counts = {"depth": 0, "color": 0, "reprints": 0, "presses": 0, "frames": 0}
    if Modality.DEPTH in modalities or Modality.COLOR in modalities:
        k_dense = _densify_factor(cfg)
        dcam, ccam = depth_camera(cfg.depth_size), color_camera(cfg.color_size)
        for k in range(cfg.drapes):
            params = sample_drape(fabric, np.random.default_rng([seed, 20, fid, k]))
            surf = drape_surface(fabric, params).densify(k_dense)
            if Modality.DEPTH in modalities:
                d = render_depth(surf, dcam, np.random.default_rng([seed, 21, fid, k]))
                _write(out, _depth_name(fid, k), _encode(d, "png", 0))
                counts["depth"] += 1
            if Modality.COLOR in modalities:
                # The photo, then the same drape, light and camera under other prints.
                prints = [fabric] + [
                    reprinted(fabric, np.random.default_rng([seed, 23, fid, k, r]))
                    for r in range(1, cfg.reprints + 1)
                ]
                photos = render_colors(
                    prints, surf, ccam, np.random.default_rng([seed, 22, fid, k])
                )
                _write(out, _color_name(fid, k, ext), _encode(photos[0], ext, cfg.jpeg_quality))
                counts["color"] += 1
                for r, c in enumerate(photos[1:], start=1):
                    _write(out, _reprint_name(fid, k, r, ext), _encode(c, ext, cfg.jpeg_quality))
                    counts["reprints"] += 1
    if Modality.TOUCH in modalities:
        s = sensor(*cfg.touch_size)
        for kind, p in _presses(cfg):
            rng = np.random.default_rng([seed, 30, fid, _KIND_CODE[kind], p])
            for f, frame in enumerate(render_press(fabric, kind, s, rng, cfg.frames)):
                _write(
                    out, _touch_name(fid, kind, f, p, ext), _encode(frame, ext, cfg.jpeg_quality)
                )
                counts["frames"] += 1
            counts["presses"] += 1
    return counts


def _run_task(task: _Task) -> dict[str, int]:
    return render_fabric(task.fabric, task.cfg, task.modalities, task.out)


# ---------------------------------------------------------------------------------------------
# The output folder.


def _read_manifest(out: Path) -> dict[str, object] | None:
    path = out / MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("generator") != _GENERATOR:
        return None
    return data


def _prepare_out(out: Path, planned: Iterable[str]) -> None:
    """Check that ``out`` may be written, and remove what an earlier synth run left there.

    Only files an earlier run listed in its manifest (and its temporary files) are removed;
    anything else in the folder is left alone.

    Raises:
        FileExistsError: ``out`` is a file, or a non-empty folder that is not synth output.
    """
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"output {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()):
        old = _read_manifest(out)
        if old is None:
            raise FileExistsError(
                f"output folder {out} is not empty and holds no {MANIFEST} from an earlier "
                "`lookfeel synth` run; choose an empty or new folder (nothing was changed)"
            )
        # here, not at the top: `lookfeel.data` imports torch, which render workers need not
        from lookfeel.data.paths import lies_within

        keep = set(planned)
        old_files = old.get("files", [])
        inside = out.resolve()
        for rel in old_files if isinstance(old_files, list) else []:
            if not isinstance(rel, str) or rel in keep:
                continue
            target = out / rel
            # Only a file of this folder: never an absolute path, one up through "..", or one
            # through a symlinked folder (a real depth/ linked in beside the synthetic senses).
            if Path(rel).is_absolute() or ".." in Path(rel).parts:
                continue
            if not lies_within(target.parent, inside):  # by identity too (`lies_within`)
                continue
            target.unlink(missing_ok=True)
        for sub in ("depth", "color", REPRINTS, "touch"):
            folder = out / sub
            if folder.is_dir():
                for tmp in folder.glob(".F*.tmp"):
                    tmp.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)


def _labels_text(fabrics: Sequence[Fabric], seed: int, n_test: int | None = None) -> str:
    """labels.csv of a sampled world: human-style labels, k-means clusters, a split holding
    out ``n_test`` fabrics (``None``: the paper's share)."""
    rows = [human_labels(f, seed) for f in fabrics]
    x = np.array([[r[c] for c in LABEL_COLUMNS] for r in rows], dtype=np.float64)
    clusters = kmeans(x, 8, seed)
    n = len(fabrics)
    if n_test is None:
        # The paper holds out 18 of 118 fabrics; keep that share (at least one when n >= 4).
        n_test = max(1 if n >= 4 else 0, round(n * 18 / 118))
    test = set(np.random.default_rng([seed, 16]).permutation(n)[:n_test].tolist())
    lines = ["fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split"]
    for i, (f, r) in enumerate(zip(fabrics, rows, strict=True)):
        lines.append(
            f"{f.fabric_id},{clusters[i]},{r['thickness_mm']:.1f},{r['density']:.4f},"
            f"{r['stiffness']:.1f},{r['stretchiness']:g},{'test' if i in test else 'train'}"
        )
    return "\n".join(lines) + "\n"


def _workers(cfg: SynthConfig, n_tasks: int) -> int:
    if cfg.workers:
        return max(1, min(cfg.workers, n_tasks))
    return max(1, min(available_cores(), n_tasks))


def generate(
    config: SynthConfig,
    out: Path,
    labels: Path | None = None,
    progress: bool = True,
    beside: Path | None = None,
) -> SynthSummary:
    """Generate a synthetic visuo-tactile fabric world into ``out``.

    Args:
        config: what to generate.
        out: output folder: new, empty, or an earlier synth output (whose files are replaced;
            files it did not write are kept).
        labels: a labels.csv (e.g. GelFabric's): label-conditioned mode. Exactly the fabrics in
            the file are rendered, ids kept, their physics read from the labels (missing labels
            filled from the fabric's cluster); its rows are copied to ``out/labels.csv``.
        progress: show a progress bar (tqdm) on stderr.
        beside: a dataset folder (e.g. the real GelFabric data) whose depth images of the same
            fabric ids open each row of the contact sheet, beside the synthetic renders.

    Returns:
        Counts and paths of what was written.

    With more than one worker, processes are *spawned* (safe beside torch's threads): a script
    that calls this at import time must do so under ``if __name__ == "__main__":``.

    Raises:
        FileExistsError: ``out`` is not empty and not an earlier synth output.
        ValueError: the labels file is unreadable or malformed (the message names the line),
            or given with ``config.test_fabrics``.
    """
    with exclusive(out, "synth", "this world"):  # a second synth into ``out`` is refused
        return _generate(config, out, labels, progress, beside)


def _generate(
    config: SynthConfig,
    out: Path,
    labels: Path | None,
    progress: bool,
    beside: Path | None,
) -> SynthSummary:
    """`generate`'s work, while it holds ``out``'s lock."""
    started = time.perf_counter()
    out = Path(out)
    if labels is not None and config.test_fabrics is not None:
        raise ValueError(
            f"synth.test_fabrics: not with a labels file ({labels}): its rows decide the split"
        )
    if labels is not None:
        lf: LabelFile | None = read_label_file(Path(labels))
        assert lf is not None
        fabrics = fabrics_from_labels(lf, config.seed)
    else:
        lf = None
        fabrics = sample_fabrics(config.fabrics, config.seed)
    mods = config.resolved_modalities(label_mode=lf is not None)
    real = None
    if beside is not None and config.contact_sheet:  # a bad folder fails before rendering
        from lookfeel.synth.contact_sheet import depth_beside

        real = depth_beside(Path(beside), [f.fabric_id for f in fabrics])
    files = [rel for f in fabrics for rel in _fabric_files(f.fabric_id, config, mods)]
    _prepare_out(out, files)
    for sub, m in (("depth", Modality.DEPTH), ("color", Modality.COLOR), ("touch", Modality.TOUCH)):
        if m in mods:
            (out / sub).mkdir(exist_ok=True)
    if Modality.COLOR in mods and config.reprints:
        (out / REPRINTS).mkdir(exist_ok=True)

    manifest: dict[str, object] = {
        "generator": _GENERATOR,
        "version": GENERATOR_VERSION,
        "status": "running",
        "mode": "labels" if lf is not None else "sampled",
        "labels_source": None if lf is None else str(lf.path),
        # Without ``workers``: it changes nothing in the files, and the manifest is one of them.
        "config": {k: v for k, v in config.to_dict().items() if k != "workers"},
        "modalities": [m.value for m in mods],
        "fabrics": [f.truth() for f in fabrics],
        "files": files + ["labels.csv"] + (["contact_sheet.png"] if config.contact_sheet else []),
    }
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1) + "\n")
    labels_path = out / "labels.csv"
    text = lf.text if lf is not None else _labels_text(fabrics, config.seed, config.test_fabrics)
    atomic_write_text(labels_path, text)

    tasks = [_Task(f, config, mods, out) for f in fabrics]
    totals = {"depth": 0, "color": 0, "reprints": 0, "presses": 0, "frames": 0}
    bar = progress_bar(total=len(tasks), desc="synth", unit="fabric", show=progress)
    n_workers = _workers(config, len(tasks))
    try:
        if n_workers == 1:
            results: Iterable[dict[str, int]] = map(_run_task, tasks)
            for r in results:
                _add(totals, r)
                bar.update(1)
        else:
            ctx = get_context("spawn")
            with ProcessPoolExecutor(
                n_workers, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),)
            ) as pool:
                for r in pool.map(_run_task, tasks, chunksize=1):
                    _add(totals, r)
                    bar.update(1)
    finally:
        bar.close()

    sheet = None
    if config.contact_sheet:
        from lookfeel.synth.contact_sheet import write_contact_sheet

        sheet = write_contact_sheet(out, fabrics, config, mods, beside=real)
    manifest["status"] = "complete"
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1) + "\n")
    return SynthSummary(
        out=out,
        mode=str(manifest["mode"]),
        modalities=mods,
        fabrics=len(fabrics),
        depth_images=totals["depth"],
        color_images=totals["color"],
        reprints=totals["reprints"],
        touch_presses=totals["presses"],
        touch_frames=totals["frames"],
        labels_path=labels_path,
        manifest_path=out / MANIFEST,
        contact_sheet=sheet,
        seconds=time.perf_counter() - started,
        files=tuple(files),
    )


def _add(totals: dict[str, int], r: dict[str, int]) -> None:
    for k, v in r.items():
        totals[k] += v
