"""Small press videos for tests, written with PyAV: a sensor's light pattern, then an object's
texture pressed in and out over a known span."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

W, H = 64, 48


def sensor() -> np.ndarray:
    """(H, W, 3) float32: the untouched sensor's light pattern (smooth colour gradients)."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    return np.stack([90 + 60 * x / W, 100 + 50 * y / H, 150 - 40 * x / W], axis=-1)


def object_press(
    texture: int,
    depth: dict[int, float],
    t: int,
    seed: int = 0,
    light: dict[int, float] | None = None,
) -> np.ndarray:
    """(t, H, W, 3) uint8: a press of object ``texture`` (stripes of its own period and angle
    under a round contact), pressed to ``depth[i]`` at frame i (others: no contact), the
    sensor's light times ``light[i]`` at frame i (others: 1; a camera's exposure)."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    rng = np.random.default_rng(seed)
    cx, cy = 32 + rng.uniform(-3, 3), 24 + rng.uniform(-3, 3)
    contact = np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 12.0**2))
    angle = 0.5 * texture
    period = 4.0 + 2.0 * (texture % 3)
    stripes = 0.5 + 0.5 * np.sin(2 * np.pi * (x * np.cos(angle) + y * np.sin(angle)) / period)
    tint = np.array([70.0, 40.0, 20.0], dtype=np.float32)  # brighter where pressed (luma)
    out = []
    for i in range(t):
        f = sensor() + depth.get(i, 0.0) * (contact * (0.4 + 0.6 * stripes))[..., None] * tint
        f = f * (light or {}).get(i, 1.0)
        f = f + rng.normal(0, 0.7, (H, W, 1))
        out.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    return np.stack(out)


PRESS = {5: 0.4, 6: 0.7, 7: 1.0, 8: 0.8, 9: 0.5}
"""A press from frame 5 to 9, deepest at 7."""


def write_video(
    path: Path, frames: np.ndarray, codec: str = "mpeg4", pix_fmt: str = "yuv420p"
) -> Path:
    """Encode (T, H, W, 3) uint8 RGB frames into ``path`` (container from its suffix)."""
    import av

    with av.open(str(path), mode="w") as c:
        s = c.add_stream(codec, rate=10)
        s.width, s.height = frames.shape[2], frames.shape[1]
        s.pix_fmt = pix_fmt
        s.bit_rate = 4_000_000
        for f in frames:
            for packet in s.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                c.mux(packet)
        for packet in s.encode():
            c.mux(packet)
    return path


TWO_PRESSES = {**PRESS, 15: 0.5, 16: 0.8, 17: 0.9, 18: 0.6}
"""Two presses: frames 5-9 (deepest at 7), then, the gel released, 15-18 (use ``t`` >= 22)."""

PRESSED_START = {**{i: 0.8 for i in range(14)}, 7: 1.0, 8: 1.0, 9: 1.0}
"""A recording begun mid-press: the gel held pressed (0.8 deep) from its first frame, pressed
deeper at frames 7-9 (use ``t=14``). Its first frames move no more than an untouched gel's."""


def another_session(frames: np.ndarray) -> np.ndarray:
    """(T, H, W, 3) uint8 ``frames`` as another recording session's sensor shows them: its light
    falls off towards the corners (no gain and offset of `sensor`'s), the presses unchanged."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    fall = 40.0 * ((x - W / 2) ** 2 + (y - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
    return np.clip(frames.astype(np.float32) - fall[..., None], 0, 255).astype(np.uint8)


def cut_in_half(path: Path) -> Path:
    """Drop the second half of the file's bytes (a copy interrupted): a Matroska file still
    declares the whole duration (`lookfeel.data.video.TruncatedVideoWarning`)."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def grey_and_colour_presses(
    folder: Path, stored_suffix: str = ".mov", dark: bool = False
) -> dict[str, Path]:
    """One press as colour (``colour``), as a single grey channel (``grey``, FFV1 ``gray``)
    and as grey stored in colour, red, green and blue equal (``stored``, its suffix
    ``stored_suffix``); with ``dark``, also as colour after a black first frame (``dark``: a
    camera starting up)."""
    frames = object_press(1, PRESS, t=14)
    equal = np.repeat(frames.mean(axis=-1, keepdims=True).astype(np.uint8), 3, axis=-1)
    videos = {
        "colour": write_video(folder / "colour.mov", frames),
        "grey": write_video(folder / "grey.mkv", frames, "ffv1", "gray"),
        "stored": write_video(folder / f"stored{stored_suffix}", equal),
    }
    if dark:
        frames[0] = 0
        videos["dark"] = write_video(folder / "dark.mov", frames)
    return videos


def count_decoded_frames(monkeypatch: Any, by: str = "name") -> Counter[str]:
    """Count every frame `lookfeel.data.video` decodes from now on (monkeypatched for the test),
    by the file's ``name`` or ``suffix``: what a check that decodes a video again would add."""
    from lookfeel.data import video

    decoded: Counter[str] = Counter()
    real = video._decode

    def counting(path: Path, *args: Any, **kwargs: Any) -> Iterator[Any]:
        for frame in real(path, *args, **kwargs):
            decoded[getattr(Path(path), by)] += 1
            yield frame

    monkeypatch.setattr(video, "_decode", counting)
    return decoded


def write_objects(
    root: Path, objects: dict[str, tuple[str, str]], presses: int, grey: bool = False
) -> Path:
    """A recordings folder (``videos/<object>_<n>`` + ``labels.csv`` keyed by ``object``) of
    ``objects`` (name -> (hardness, material)), ``presses`` press videos each, object ``k``'s
    press ``n`` seeded ``10 * k + n``: colour ``.mov``, or with ``grey`` one-channel FFV1
    ``.mkv`` (a camera set to greyscale)."""
    (root / "videos").mkdir(parents=True, exist_ok=True)
    rows = ["object,hardness,material"]
    for k, (name, (hardness, material)) in enumerate(objects.items()):
        rows.append(f"{name},{hardness},{material}")
        for n in range(presses):
            frames = object_press(k, PRESS, t=14, seed=10 * k + n)
            if grey:
                write_video(root / "videos" / f"{name}_{n}.mkv", frames, "ffv1", "gray")
            else:
                write_video(root / "videos" / f"{name}_{n}.mov", frames)
    (root / "labels.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    return root
