"""Configuration and summary of a synthetic world (`lookfeel.synth.generate`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lookfeel.config import ConfigError
from lookfeel.modality import Modality, parse_modalities

__all__ = ["IMAGE_FORMATS", "SIZE_PRESETS", "SynthConfig", "SynthSummary"]

SIZE_PRESETS: dict[str, dict[str, Any]] = {
    "tiny": {"depth_size": 56, "color_size": 64, "touch_size": (80, 60)},
    "net": {"depth_size": 224, "color_size": 256, "touch_size": (320, 240)},
    "full": {"depth_size": 224, "color_size": 512, "touch_size": (960, 720)},
}
"""Image sizes by name. ``net`` (the default) is what the networks read: depth 224 like the
real files, colour 256 (room for 227 crops), touch 320x240 (the sensor's 4:3 field, the size of a
GelSight Mini or DIGIT frame). ``full`` renders touch at the authors' 960x720. ``tiny`` is for
tests and CI."""

IMAGE_FORMATS = ("jpg", "png")
"""File formats of the colour and touch images (depth is always 16-bit PNG)."""


@dataclass(frozen=True)
class SynthConfig:
    """What world to generate (paper section 3 sets the defaults: 118 fabrics, 10 drapes,
    10 flat and 15 fold presses)."""

    fabrics: int = 118
    """Number of fabrics (ids 1..n). Ignored in label-conditioned mode (the file decides)."""
    drapes: int = 10
    """Drapes per fabric: one depth image and one colour photo each."""
    presses_flat: int = 10
    """GelSight presses per fabric on one flat layer."""
    presses_fold: int = 15
    """GelSight presses per fabric on a fold."""
    frames: int = 3
    """Frames per press, force rising (the authors' code uses the second-to-last)."""
    depth_size: int = 224
    """Side of the square depth image in pixels (the real files are 224)."""
    color_size: int = 256
    """Side of the square colour photo in pixels."""
    touch_size: tuple[int, int] = (320, 240)
    """GelSight frame (width, height) in pixels; the field is always 18.4 x 13.8 mm."""
    image_format: str = "jpg"
    """File format of colour and touch images: ``jpg`` (as in GelFabric; fixed quality, so
    still byte-identical for one seed) or ``png``. Depth is always 16-bit PNG."""
    jpeg_quality: int = 90
    """JPEG quality (50-100) when ``image_format`` is ``jpg``."""
    seed: int = 0
    """Seed of the world: the same seed gives byte-identical files."""
    workers: int = 0
    """Processes rendering fabrics in parallel; 0 = one per available core; 1 = in-process."""
    modalities: tuple[Modality, ...] | None = None
    """Modalities to render; ``None``: all three, or colour and touch in label-conditioned mode
    (where real depth images exist). Strings are accepted and converted."""
    contact_sheet: bool = True
    """Write ``contact_sheet.png`` (a few fabrics across all modalities) beside the data."""
    reprints: int = 4
    """Re-printed renders of every colour photo, written to ``reprints/`` (``F0001_1_r1.jpg``
    beside ``color/F0001_1.jpg``): the same drape, light and camera under a print and colours
    drawn afresh for each. Training reads them in place of the photos
    (``data.color_reprints``), so that a network cannot name a fabric by its print and learns
    the drape and the material's look instead (domain randomisation). The photos themselves
    are the same with or without them, and a world's first N renders are the same whatever
    more it writes. 4 (the default) are what ``configs/synth_cross.yaml`` reads; 0 writes none."""
    test_fabrics: int | None = None
    """Fabrics held out as ``paper_split`` ``test`` in labels.csv, drawn at random; ``None``:
    the paper's share, 18 of every 118 (at least one from 4 fabrics). `make demo` holds out 50
    of 150 so that its intervals are narrower than 18 allow. Not in label-conditioned mode,
    where the labels file decides."""

    def __post_init__(self) -> None:
        def need(name: str, ok: bool, what: str) -> None:
            if not ok:
                raise ConfigError(f"synth.{name}: {what}, got {getattr(self, name)!r}")

        for name, lo, hi in (
            ("fabrics", 1, 9999),
            ("drapes", 0, 999),
            ("presses_flat", 0, 999),
            ("presses_fold", 0, 999),
            ("frames", 1, 99),
            ("depth_size", 16, 2048),
            ("color_size", 16, 4096),
            ("jpeg_quality", 50, 100),
            ("workers", 0, 256),
            ("reprints", 0, 99),
        ):
            v = getattr(self, name)
            need(name, isinstance(v, int) and not isinstance(v, bool), "must be an integer")
            need(name, lo <= v <= hi, f"must be in [{lo}, {hi}]")
        need("seed", isinstance(self.seed, int) and self.seed >= 0, "must be an integer >= 0")
        if self.test_fabrics is not None:
            t = self.test_fabrics
            is_int = isinstance(t, int) and not isinstance(t, bool)
            need("test_fabrics", is_int, "must be an integer")
            need(
                "test_fabrics",
                0 <= t < self.fabrics,
                f"must be in [0, fabrics - 1] = [0, {self.fabrics - 1}]",
            )
        ts = self.touch_size
        need(
            "touch_size",
            isinstance(ts, (tuple, list))
            and len(ts) == 2
            and all(isinstance(v, int) and 16 <= v <= 4096 for v in ts),
            "must be (width, height), each an integer in [16, 4096]",
        )
        object.__setattr__(self, "touch_size", (int(ts[0]), int(ts[1])))
        need("image_format", self.image_format in IMAGE_FORMATS, f"must be one of {IMAGE_FORMATS}")
        need("contact_sheet", isinstance(self.contact_sheet, bool), "must be true or false")
        if self.modalities is not None:
            try:
                mods = parse_modalities(
                    self.modalities
                    if isinstance(self.modalities, str)
                    else [str(m) for m in self.modalities]
                )
            except ValueError as e:
                raise ConfigError(f"synth.modalities: {e}") from None
            object.__setattr__(self, "modalities", mods)
            if Modality.TOUCH in mods:
                need(
                    "presses_fold",
                    self.presses_flat + self.presses_fold > 0,
                    "touch needs at least one press (presses_flat + presses_fold > 0)",
                )
            if Modality.DEPTH in mods or Modality.COLOR in mods:
                need("drapes", self.drapes > 0, "depth and colour need at least one drape")

    def resolved_modalities(self, label_mode: bool) -> tuple[Modality, ...]:
        """The modalities this run renders (see ``modalities``)."""
        if self.modalities is not None:
            return self.modalities
        if label_mode:
            return (Modality.COLOR, Modality.TOUCH)
        return (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)

    def to_dict(self) -> dict[str, Any]:
        """Plain values (JSON/YAML-able)."""
        return {
            "fabrics": self.fabrics,
            "drapes": self.drapes,
            "presses_flat": self.presses_flat,
            "presses_fold": self.presses_fold,
            "frames": self.frames,
            "depth_size": self.depth_size,
            "color_size": self.color_size,
            "touch_size": list(self.touch_size),
            "image_format": self.image_format,
            "jpeg_quality": self.jpeg_quality,
            "seed": self.seed,
            "workers": self.workers,
            "modalities": None if self.modalities is None else [m.value for m in self.modalities],
            "contact_sheet": self.contact_sheet,
            "reprints": self.reprints,
            # Only when set: a world made before the field existed keeps its manifest's config.
            **({} if self.test_fabrics is None else {"test_fabrics": self.test_fabrics}),
        }


@dataclass(frozen=True)
class SynthSummary:
    """What `generate` wrote."""

    out: Path
    mode: str
    """``sampled`` (fabrics drawn by the generator) or ``labels`` (from a labels.csv)."""
    modalities: tuple[Modality, ...]
    fabrics: int
    depth_images: int
    color_images: int
    touch_presses: int
    touch_frames: int
    labels_path: Path
    manifest_path: Path
    """``synth.json``: the config, each fabric's true parameters and every file written."""
    contact_sheet: Path | None
    seconds: float
    files: tuple[str, ...] = field(default=(), repr=False)
    """Every file written, relative to ``out``."""
    reprints: int = 0
    """Re-printed renders of the colour photos written (`SynthConfig.reprints`)."""
