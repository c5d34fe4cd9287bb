"""Writes tiny datasets in the lookfeel layout with known content, for tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

LABELS_HEADER = "fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split\n"
QUICKTIME = b"\x00\x00\x00\x14ftypqt  \x00\x00\x02\x00" + bytes(64)
"""The first bytes of a QuickTime file: enough for the scan, which never decodes."""


def write_recordings(root: Path, presses: dict[str, int], labels: str) -> Path:
    """Recordings in the layout: ``videos/<object>_<n>.mov`` (QuickTime headers only, nothing
    to decode) for ``presses`` (object -> how many) and ``labels`` as labels.csv."""
    (root / "videos").mkdir(parents=True)
    (root / "labels.csv").write_text(labels, encoding="utf-8")
    for name, n in presses.items():
        for k in range(n):
            (root / "videos" / f"{name}_{k}.mov").write_bytes(QUICKTIME)
    return root


def write_depth(path: Path, fabric: int, k: int, size: int = 24, holes: bool = True) -> None:
    """A 16-bit depth PNG whose level encodes the fabric (so fabrics are distinguishable)."""
    rng = np.random.default_rng([fabric, k])
    d = (900 + 40 * fabric + rng.integers(0, 20, (size, size))).astype(np.uint16)
    if holes:
        d[0, :3] = 0
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(d).save(path)


def write_rgb(path: Path, fabric: int, k: int, size: tuple[int, int] = (24, 24)) -> None:
    """An 8-bit RGB image (PNG or JPEG by suffix) coloured by fabric."""
    rng = np.random.default_rng([fabric, k, 7])
    w, h = size
    a = np.zeros((h, w, 3), np.uint8)
    a[..., 0] = (20 * fabric) % 256
    a[..., 1] = rng.integers(0, 255, (h, w))
    a[..., 2] = (10 * k) % 256
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(a).save(path)


def write_tiny_dataset(
    root: Path,
    fabrics: int = 6,
    drapes: int = 3,
    fold_presses: int = 3,
    flat_presses: int = 2,
    frames: int = 3,
    labels: bool = True,
) -> Path:
    """Fabrics 1..n with depth and colour drapes, touch presses of 3 frames, and labels.csv.

    Clusters are ``(id - 1) % 3``; fabric 2 has an empty density cell (unknown label).
    """
    for f in range(1, fabrics + 1):
        for k in range(drapes):
            write_depth(root / "depth" / f"F{f:04d}_Depth_New_{k:06d}.png", f, k)
            write_rgb(root / "color" / f"F{f:04d}_{k + 1}.png", f, k)
        for kind, n in (("fold", fold_presses), ("flat", flat_presses)):
            for p in range(n):
                for fr in range(frames):
                    name = f"F{f:04d}_{kind}_{fr + 1:02d}_{100 * f + p}.png"
                    k = 10 * p + fr + (500 if kind == "flat" else 0)  # not a fold press's copy
                    write_rgb(root / "touch" / name, f, k, size=(32, 24))
    if labels:
        lines = [LABELS_HEADER]
        for f in range(1, fabrics + 1):
            density = "" if f == 2 else f"{0.2 * f:.2f}"
            lines.append(f"{f},{(f - 1) % 3},{0.5 * f},{density},{f % 5},{f % 2},train\n")
        (root / "labels.csv").write_text("".join(lines), encoding="utf-8")
    return root


def bomb_png(width: int, height: int) -> bytes:
    """A real greyscale PNG of ``width`` x ``height`` zeros: small on disk (zlib), huge decoded
    (13000 x 13000 is about 0.2 MB here and 169 MB as pixels, 507 MB as RGB)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    z = zlib.compressobj(1)
    row = bytes(width + 1)  # filter byte 0, then the row
    idat = b"".join(z.compress(row * 64) for _ in range(height // 64))
    idat += z.compress(row * (height % 64)) + z.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")
