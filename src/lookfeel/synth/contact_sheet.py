"""``contact_sheet.png``: a few fabrics of a generated world across all its modalities.

Rows are fabrics chosen evenly from the stiffest to the most flexible (by bending length), so
the sheet shows the physics at a glance: depth (false colour, near = bright), colour photos,
and the second-to-last frame of a flat press and of two fold presses. Images are read back
from the files written, so the sheet shows exactly what is on disk.

With ``beside`` (another dataset folder, e.g. the real GelFabric data in label-conditioned mode)
each row starts with that dataset's depth images of the same fabric id, outlined in red, so the
synthetic renders stand beside real ones; only fabrics the other dataset has are shown then.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from lookfeel.atomic import atomic_write_bytes
from lookfeel.modality import Modality
from lookfeel.synth.config import SynthConfig
from lookfeel.synth.fabric import Fabric

__all__ = ["depth_beside", "write_contact_sheet"]

_TILE = 128
_LABEL_W = 150
_HEAD = 18  # a row of column titles
# A perceptual ramp (dark blue -> teal -> yellow) for depth, near = bright.
_RAMP = np.array([[20, 20, 70], [40, 90, 140], [40, 160, 130], [170, 210, 70], [250, 240, 80]])


def _depth_tile(path: Path) -> NDArray[np.uint8]:
    d = np.asarray(Image.open(path), dtype=np.float32)
    v = np.clip((1300.0 - d) / 550.0, 0.0, 1.0)  # the paper's 800-1300 mm window, near bright
    x = np.linspace(0, 1, len(_RAMP))
    rgb = np.stack([np.interp(v, x, _RAMP[:, k]) for k in range(3)], -1)
    rgb[d == 0] = 0
    return rgb.astype(np.uint8)


def _fit(img: NDArray[np.uint8]) -> Image.Image:
    pil = Image.fromarray(img).convert("RGB")
    w, h = pil.size
    s = _TILE / h
    return pil.resize((max(1, round(w * s)), _TILE), Image.Resampling.BILINEAR)


def _first(out: Path, pattern: str) -> Path | None:
    hits = sorted(out.glob(pattern))
    return hits[0] if hits else None


def depth_beside(root: Path, fabric_ids: Iterable[int]) -> tuple[str, dict[int, list[Path]]]:
    """Up to two depth images per fabric of ``fabric_ids`` from the dataset at ``root``, to
    open the contact sheet's rows (checked before anything is rendered).

    Raises:
        ValueError: ``root`` is not a folder, or holds no depth image of any of the fabrics.
    """
    from lookfeel.data import scan

    if not Path(root).is_dir():
        raise ValueError(f"beside {root}: not a folder")
    wanted = set(fabric_ids)
    found = {
        f.id: sorted(it.path for it in f.items_of(Modality.DEPTH))[:2]
        for f in scan(root).fabrics
        if f.id in wanted and f.items_of(Modality.DEPTH)
    }
    if not found:
        raise ValueError(f"beside {root}: no depth image of any fabric id of this world")
    return Path(root).name, found


def write_contact_sheet(
    out: Path,
    fabrics: Sequence[Fabric],
    cfg: SynthConfig,
    modalities: Sequence[Modality],
    rows: int = 6,
    beside: tuple[str, Mapping[int, Sequence[Path]]] | None = None,
) -> Path:
    """Compose and write ``out/contact_sheet.png``; returns its path.

    Args:
        beside: (a name, fabric id -> depth images) from `depth_beside`: these open each row,
            and only the fabrics they cover are shown.
    """
    name, other = beside if beside is not None else ("", {})
    if beside is not None:
        fabrics = [f for f in fabrics if f.fabric_id in other]
    order = sorted(fabrics, key=lambda f: f.bending_length_mm)
    idx = np.unique(np.linspace(0, len(order) - 1, min(rows, len(order))).round().astype(int))
    picked = [order[i] for i in idx]
    ext = cfg.image_format
    mid = f"{max(1, cfg.frames - 1):02d}"  # the authors' "second-to-last" frame
    strips = []
    heads: list[list[str]] = []
    for f in picked:
        fid = f"F{f.fabric_id:04d}"
        tiles: list[Image.Image] = []
        titles: list[str] = []
        for p in other.get(f.fabric_id, []):
            tile = _fit(_depth_tile(p))
            ImageDraw.Draw(tile).rectangle(
                (0, 0, tile.size[0] - 1, _TILE - 1), outline=(220, 30, 30), width=3
            )
            tiles.append(tile)
            titles.append(f"depth: {name}")
        if Modality.DEPTH in modalities:
            for p in sorted((out / "depth").glob(f"{fid}_*.png"))[:2]:
                tiles.append(_fit(_depth_tile(p)))
                titles.append("depth (synthetic)")
        if Modality.COLOR in modalities:
            for p in sorted((out / "color").glob(f"{fid}_*.{ext}"))[:2]:
                tiles.append(_fit(np.asarray(Image.open(p).convert("RGB"))))
                titles.append("colour (synthetic)")
        if Modality.TOUCH in modalities:
            for kind, n in (("flat", 1), ("fold", 2)):
                presses = sorted(
                    {
                        p.stem.rsplit("_", 1)[1]
                        for p in (out / "touch").glob(f"{fid}_{kind}_*.{ext}")
                    }
                )
                for press in presses[:n]:
                    frame = _first(out, f"touch/{fid}_{kind}_{mid}_{press}.{ext}")
                    if frame is not None:
                        tiles.append(_fit(np.asarray(Image.open(frame).convert("RGB"))))
                        titles.append(f"touch, {kind} (synthetic)")
        label = Image.new("RGB", (_LABEL_W, _TILE), (255, 255, 255))
        draw = ImageDraw.Draw(label)
        text = (
            f"{fid}\nbend length {f.bending_length_mm:.0f} mm\nthick {f.thickness_mm:.1f} mm\n"
            f"density {f.density:.2f}\nstiff {f.stiffness:.1f}\n"
            f"{f.material} {f.weave}, {f.print_kind}"
        )
        draw.multiline_text((6, 8), text, fill=(0, 0, 0), spacing=4)
        strips.append([label, *tiles])
        heads.append(titles)
    width = max(sum(t.size[0] + 2 for t in s) for s in strips)
    sheet = Image.new("RGB", (width, _HEAD + len(strips) * (_TILE + 2)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    longest = max(range(len(strips)), key=lambda r: len(heads[r]))
    x = _LABEL_W + 2
    for t, title in zip(strips[longest][1:], heads[longest], strict=True):
        draw.text((x + 4, 4), title, fill=(0, 0, 0))
        x += t.size[0] + 2
    for r, strip in enumerate(strips):
        x = 0
        for t in strip:
            sheet.paste(t, (x, _HEAD + r * (_TILE + 2)))
            x += t.size[0] + 2
    buf = io.BytesIO()
    sheet.save(buf, format="PNG", compress_level=6)
    path = out / "contact_sheet.png"
    atomic_write_bytes(path, buf.getvalue())
    return path
