"""Data configuration: decoding, preprocessing, tuple sampling and augmentation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from lookfeel.config._core import ConfigError, check_choices
from lookfeel.modality import Modality, PressKind

__all__ = ["AugmentConfig", "DataConfig"]


@dataclass(frozen=True)
class AugmentConfig:
    """Training-time augmentation of one modality's images (all seeded).

    The paper (section 5.3) augments colour with a gamma in [0.5, 2.0] and a random order of
    the RGB channels; the authors' released code also crops a random square with probability
    0.2 (side 180-227 px of 227, resized back). Noise and flips "made little difference" there.
    """

    gamma: tuple[float, float] | None = None
    """Range of a random gamma ``x ** g`` (log-uniform); ``None`` disables it. Paper: (0.5, 2.0)."""
    permute_channels: bool = False
    """Shuffle the RGB channels (paper section 5.3). Ignored for one-channel depth."""
    crop_p: float = 0.0
    """Probability of a random square crop, resized back to the network size."""
    crop_scale: tuple[float, float] = (180 / 227, 1.0)
    """Crop side as a fraction of the image side (authors' code: 180-227 px of 227)."""
    noise_std: float = 0.0
    """Standard deviation of additive Gaussian noise on the [0, 1] image."""
    hflip_p: float = 0.0
    """Probability of a left-right flip."""
    level_shift: float = 0.0
    """Largest shift of the image's level, in [0, 1] input units: every pixel above 0 moves by
    one uniform draw in [-level_shift, level_shift], and 0 (masked: registered depth's room)
    stays 0. For registered depth, a floor fitted a few mm higher or lower (0.02 = 10 mm at
    ``depth_range_mm`` 500)."""
    level_tilt: float = 0.0
    """Largest tilt of the image's level: a plane through the image's centre, in a uniform
    direction, adds up to ``level_tilt`` at the image's edge midpoints to the pixels above 0
    (registered depth: a floor fitted slightly tilted)."""
    level_floor: float = 0.0
    """With a level shift or tilt, pixels moved below this level become 0 (registered depth:
    cloth that no longer stands ``depth_margin_mm`` above the moved floor is room; 0.03 = 15 mm
    of 500). 0: none is masked."""


MAX_TOUCH_FRAMES = 8
"""The most frames of a press `DataConfig.touch_frames` stacks."""


def _default_augment() -> dict[Modality, AugmentConfig]:
    return {}


@dataclass(frozen=True)
class DataConfig:
    """How images are decoded, preprocessed and grouped into training tuples."""

    image_size: int = 227
    """Side of the square network input in pixels (AlexNet: 227)."""
    color_size: int | None = None
    """Side of the colour photo's network input in pixels; ``None``: ``image_size``. On the
    synthetic world the photo at 96 px with depth and touch at 64 matched colour to touch
    better than every sense at 64 or at 96 (`configs/synth_cross.yaml`, docs/synth.md)."""
    depth_min_mm: float = 800.0
    """Depth mapped to 0; the authors' code maps ``clip((d - 800) / 500, 0, 1)``."""
    depth_range_mm: float = 500.0
    """Depth span mapped onto [0, 1]."""
    depth_holes: Literal["nearest", "clip"] = "nearest"
    """Pixels with no reading (0 mm): ``nearest`` fills each from the nearest valid pixel;
    ``clip`` keeps the authors' behaviour (0 mm is below the range, so it maps to 0)."""
    depth_input: Literal["raw", "registered"] = "raw"
    """``raw``: the depth image as the sensor saw it, room included (the authors' input; the
    room's few-mm shifts between capture sessions identify the session). ``registered``: per
    image, the room's planes are fitted and the cloth's height above the fitted floor is kept,
    everything else 0 (`lookfeel.data.register`), mapped as ``clip(height / depth_range_mm,
    0, 1)``; ``depth_min_mm`` is not used. Needs a drape in a room with a floor and a wall."""
    depth_margin_mm: float = 15.0
    """Registered input: cloth is every pixel more than this in front of the fitted room."""
    depth_focal_px: float | None = None
    """Registered input: the depth camera's focal length in pixels at the files' resolution
    (principal point at the image centre); ``None``: GelFabric's Kinect crop (373 px at
    224 px), scaled to the image. Only heights use it; room and cloth are found without it."""
    depth_cloth: Literal["all", "drape"] = "drape"
    """Registered input: ``drape`` keeps only the cloth region connected to the drape's top
    (where the post holds it), dropping separate objects that stand in the room;
    ``all`` keeps every region in front of the room."""
    depth_min_height_mm: float = 0.0
    """Registered input: cloth lower than this above the fitted floor is dropped (0). The cloth
    lying on the floor is where a floor fitted a few mm off changes the mask most (issue #12's
    background control); 0: every cloth pixel is kept."""
    depth_top_mm: float | None = None
    """Registered input: measure the cloth's heights down from the drape's top, which is set
    to this height (mm): ``height - top + depth_top_mm``, where ``top`` is the median height
    of the drape's top rows (where the post holds it), at least 1 mm on the cloth. The fitted
    floor's *distance* then plays no part, only its orientation (which way is up): that
    distance is the noisiest part of the fit (about 8 mm within one GelFabric session) and
    differs between sessions, so it tells sessions apart (docs/results/real-depth.md, "What the
    background swap still changes, and heights from the drape's top"). GelFabric's drape tops
    lie about 256 mm above the floor read from the first rows, 309 mm from the highest row
    (``depth_top_from``). ``None``: heights above the fitted floor."""
    depth_top_from: Literal["first_rows", "highest_row", "cloth_top"] = "first_rows"
    """Registered input with ``depth_top_mm``: where the drape's top is read
    (`lookfeel.data.register.drape_top`). ``first_rows``: the median of its first rows;
    ``highest_row``: the highest of the row medians over its top rows, the cloth over the
    post (GelFabric's first rows are often the sensor's mix of wall and cloth);
    ``cloth_top``: as ``highest_row``, and the rows of that mix above the cloth are dropped
    and the drape placed by the cloth's own top (`lookfeel.data.register.without_cap`; the
    real-depth recipe's choice since session 35, with ``depth_top_mm: 308``)."""
    depth_post_at: tuple[float, float] | None = None
    """Registered input: move the drape so that its top (where the post holds it,
    `lookfeel.data.register.Registration.post_uv`) lies at this (x, y), as fractions of the
    image's width and height (GelFabric's posts sit near (0.52, 0.06)). The camera moved a
    little between capture sessions, so where the drape lies in the image identifies the
    session (docs/results/real-depth.md, "The drape's position"); ``None`` leaves the drape
    where the camera saw it."""
    depth_wall_drop: float = 0.0
    """Registered input: the probability that a training draw of a drape drops the cloth near
    the room's walls, as a room fitted a few millimetres elsewhere drops it (another capture
    session's room: issue #12's background control, where that cloth is most of what the swap
    costs). The draw moves every fitted plane but the floor toward the cloth by a uniform
    shift of up to ``depth_wall_shift_mm``, tilted in a uniform direction by up to
    ``depth_wall_tilt_mm`` at the image's edges; the cloth left within ``depth_margin_mm`` of a
    moved plane is dropped, and the drape's largest piece kept, as registration keeps it
    (`lookfeel.data.tensors.ImageStore.drop_walls`, from each drape's gaps to its walls at
    the input's size: `lookfeel.data.register.wall_gap_input`). Evaluation and embedding read
    the image alone. 0: never."""
    depth_wall_shift_mm: float = 20.0
    """``depth_wall_drop``: the largest shift of a wall toward the cloth (mm)."""
    depth_wall_tilt_mm: float = 5.0
    """``depth_wall_drop``: the largest tilt of a moved wall, in mm at the image's edges."""
    depth_wall_band_mm: float = 0.0
    """Registered input: drop the cloth that lies within this of a fitted plane other than
    the floor, past ``depth_margin_mm``, from every registered image: evaluation, embedding,
    the background and room controls, and the training draws that ``depth_wall_drop`` does not
    take. Between capture sessions the walls sit a few millimetres elsewhere, so whether
    the cloth next to a wall counts as cloth depends on the session's room; without it, a
    drape registered in another fabric's room loses or gains that cloth. A training draw that
    ``depth_wall_drop`` takes drops the cloth near walls moved 0 to ``depth_wall_shift_mm``
    instead (the band is the drop's fixed middle, as a centre crop is a random crop's). The
    band comes before the drape is kept, placed and measured from its top
    (`lookfeel.data.register.kept_heights`); in the training draws ``depth_wall_drop`` leaves
    alone, it is dropped from the placed drape at the input's size. 0: none."""
    color_crop: Literal["none", "center"] = "none"
    """``none`` resizes the whole photo to a square; ``center`` first crops its central square."""
    touch_crop: Literal["auto", "center", "none"] = "auto"
    """``auto`` crops the central 720x720 of 960x720 GelSight frames (authors' code) and leaves
    other sizes (GelSight Mini, DIGIT) whole; ``center`` always crops the central square;
    ``none`` never crops."""
    touch_zoom: float = 1.0
    """The central fraction of the touch frame (after ``touch_crop``, in each direction) that
    is resized to ``image_size``: 1.0 the whole field; 0.5 its central half at twice the
    resolution. A 64 px view of an 18 mm GelSight field is 0.29 mm a pixel, coarser than the
    weave of most woven cloth (0.2-0.6 mm a period)."""
    touch_frame: int = -2
    """Which frame of a press is "the" image: an index into its ordered frames; negative
    counts from the end (authors' code: -2, the second-to-last). Clamped for short presses.
    Unused when ``touch_frames`` is set."""
    touch_frames: tuple[int, ...] | None = ()
    """Several frames of a press read together, stacked as channels in this order (3 per
    frame), e.g. ``[0, -1]``: the first frame, at the lightest force, and the last, at peak
    force, so the network sees how the contact changes as the force rises (a fold's
    flattening follows its stiffness and thickness). Indices as ``touch_frame``'s; empty
    (the default; ``null`` says the same and is stored as empty): the one frame
    ``touch_frame``. For presses stored as frame images (a video press has its own options,
    ``video_*``); the last index listed is the frame shown wherever one image of the press is
    displayed."""
    video_frame: float | None = None
    """Which frame of a press video (a touch item recorded as a video) is "the" image:
    ``None`` the deepest contact; a number in [0, 1] that position across the contact span
    (0 its first frame, 1 its last). The press is found automatically (`lookfeel.data.video`)."""
    video_frames: int = 1
    """How many frames of a press video make its image: 1 is one frame (``video_frame``); N > 1
    the mean of N frames spread evenly across the contact span, first to last (measured on
    PhysiCLeAR: pick 1 of 10 among objects from raw difference pixels rises from 0.40 top-1
    for the deepest frame to 0.50 for 5 frames and 0.53 for 9)."""
    video_reference: Literal["subtract", "none"] = "subtract"
    """``subtract``: a press video's frame becomes its difference from the no-contact frames
    before the press, ``128 + video_gain * (frame - reference)`` (removes the sensor's own
    light and drift); ``none``: the raw frame. Raw frames mostly identify the recording
    session: on PhysiCLeAR the no-contact frame alone picks the right object among 10 at 0.86
    top-1 (raw pixels), the deepest raw frame at 0.57, its difference at 0.40."""
    video_gain: float = 8.0
    """Gain of that difference (grey levels out per grey level of change): 8 saturates about 2%
    of a GelSight Mini press's pixels (`lookfeel.data.video.DEFAULT_GAIN`)."""
    video_rotate: Literal[0, 90, 180, 270] = 0
    """Turn every frame of every press video this many degrees clockwise as it is decoded
    (0, 90, 180 or 270), before anything else sees it: the press's detection, its reference
    and differences, the crops and the resize (`lookfeel.data.video.rotate_frame`). For videos
    recorded turned against what a model reads: a sensor mounted on its side, or a GelSight's
    landscape presses for a model of portrait DIGIT frames. Every video of a run is turned
    alike, and frame images of a press not at all: videos of two orientations stay two. A
    checkpoint keeps it, so ``predict``, ``match``, ``serve`` and the index turn their videos
    as training did."""
    video_views: int = 1
    """Training views of a press video: N > 1 lets each training draw of a press take one of
    its deepest frame and the frames of N spread across its contact span that are pressed at
    least ``video_views_min`` as deep (`lookfeel.data.video.deep_frames`), at random. Evaluation
    and embedding always use the one image ``video_frame`` names. Needs ``video_frames: 1``
    and ``video_frame: null``."""
    video_embed: Literal["image", "views"] = "image"
    """How evaluation, ``embed``, ``predict``, ``match`` and the index see a press video:
    ``image``, the one image ``video_frame`` / ``video_frames`` name; ``views``, its deepest
    frame and ``video_views`` frames spread across its contact span (`view_frames`), each
    embedded and the embeddings averaged (still one press; the raw-pixel baseline averages
    the same frames' pixels). Needs ``video_views`` > 1. Screened on PhysiCLeAR folds 0-1:
    touch to touch 0.766 against 0.693 for the deepest frame alone."""
    video_views_min: float = 0.0
    """Least contact depth of a training view, as a fraction of the deepest frame's (0-1); 0
    keeps every frame of the N. Screened on PhysiCLeAR folds 0-1 (12 views, 300 steps, width
    16): touch to touch 0.724 with 0, 0.693 with 0.6, 0.650 with the deepest frame alone."""
    color_reprints: int = 0
    """Train on re-printed renders of each colour photo instead of the photo: each training
    draw of a photo takes one of its first N renders in the dataset's ``reprints/`` folder
    (the same drape under another print and colours, `lookfeel.modality.reprint_path`; a
    synthetic world has them, ``lookfeel synth --reprints``), so that the net cannot name a
    fabric by its print and learns the drape and the material's look. Evaluation and
    embedding read the photos themselves. A dataset without ``reprints/`` trains on its photos
    (with a warning); a photo with fewer than N renders there is an error naming the file.
    0: the photos."""
    touch_kinds: tuple[PressKind, ...] = (PressKind.FOLD,)
    """Press kinds used for training and evaluation (the paper's 'Flat' model uses flat)."""
    presses: int = 1
    """Presses of one fabric per touch input, pooled by the Multi-input Net (paper: 3)."""
    same_fraction: float = 0.5
    """Fraction of training tuples drawn from one fabric (Y = 0); the rest are Y = 1."""
    augment: dict[Modality, AugmentConfig] = field(default_factory=_default_augment)
    """Augmentation per modality; modalities not listed are not augmented."""
    cache_dir: str | None = None
    """Optional on-disk cache of preprocessed images, keyed by file content and settings."""
    workers: int = 2
    """Images decoded and preprocessed at once (threads or processes: ``decode``)."""
    decode: Literal["auto", "threads", "processes"] = "auto"
    """How ``workers`` decode: ``threads`` in this process (Pillow and numpy release the GIL
    for about two thirds of the work, so threads stop scaling after two or three);
    ``processes``, worker processes (forked on Linux, spawned elsewhere at a few seconds'
    start); ``auto``, processes on Linux when at least 256 files wait, threads otherwise.
    The decoded images are the same either way (`lookfeel.data.decode_pool`)."""

    def __post_init__(self) -> None:
        if type(self.video_rotate) is not int or self.video_rotate not in (0, 90, 180, 270):
            raise ConfigError(
                f"data.video_rotate: {self.video_rotate!r} is not a turn of a press video; "
                "give 0, 90, 180 or 270 (degrees clockwise)"
            )
        check_choices(self, "data")
        if self.image_size < 8:
            raise ConfigError(f"data.image_size: must be >= 8, got {self.image_size}")
        if self.color_size is not None and self.color_size < 8:
            raise ConfigError(f"data.color_size: must be >= 8 or null, got {self.color_size}")
        if self.depth_range_mm <= 0:
            raise ConfigError(f"data.depth_range_mm: must be > 0, got {self.depth_range_mm}")
        if not 0.0 <= self.depth_wall_drop <= 1.0:
            raise ConfigError(
                f"data.depth_wall_drop: must be in [0, 1], got {self.depth_wall_drop}"
            )
        if self.depth_wall_drop and self.depth_input != "registered":
            raise ConfigError(
                "data.depth_wall_drop: drops cloth near the fitted room's walls, so it needs "
                f"data.depth_input: registered (got {self.depth_input!r})"
            )
        if self.depth_wall_shift_mm <= 0 or self.depth_wall_tilt_mm < 0:
            raise ConfigError(
                "data.depth_wall_shift_mm must be > 0 and data.depth_wall_tilt_mm >= 0, got "
                f"{self.depth_wall_shift_mm} and {self.depth_wall_tilt_mm}"
            )
        if self.depth_wall_band_mm < 0:
            raise ConfigError(
                f"data.depth_wall_band_mm: must be >= 0, got {self.depth_wall_band_mm}"
            )
        if self.depth_wall_band_mm and self.depth_input != "registered":
            raise ConfigError(
                "data.depth_wall_band_mm: drops cloth near the fitted room's walls, so it needs "
                f"data.depth_input: registered (got {self.depth_input!r})"
            )
        if self.depth_margin_mm <= 0:
            raise ConfigError(f"data.depth_margin_mm: must be > 0, got {self.depth_margin_mm}")
        if self.depth_focal_px is not None and self.depth_focal_px <= 0:
            raise ConfigError(f"data.depth_focal_px: must be > 0, got {self.depth_focal_px}")
        if self.presses < 1:
            raise ConfigError(f"data.presses: must be >= 1, got {self.presses}")
        if not 0.0 <= self.same_fraction <= 1.0:
            raise ConfigError(f"data.same_fraction: must be in [0, 1], got {self.same_fraction}")
        if not self.touch_kinds:
            raise ConfigError("data.touch_kinds: at least one press kind is needed")
        if self.video_frame is not None and not 0.0 <= self.video_frame <= 1.0:
            raise ConfigError(
                f"data.video_frame: must be null (deepest contact) or in [0, 1], got "
                f"{self.video_frame}"
            )
        if self.video_frames < 1:
            raise ConfigError(f"data.video_frames: must be >= 1, got {self.video_frames}")
        if self.video_frames > 1 and self.video_frame is not None:
            raise ConfigError(
                f"data.video_frame: a single frame's position ({self.video_frame}) and "
                f"data.video_frames = {self.video_frames} exclude each other; set one"
            )
        if not 0 <= self.color_reprints <= 99:
            raise ConfigError(f"data.color_reprints: must be in 0..99, got {self.color_reprints}")
        if self.video_views < 1:
            raise ConfigError(f"data.video_views: must be >= 1, got {self.video_views}")
        if self.video_views > 1 and (self.video_frames > 1 or self.video_frame is not None):
            raise ConfigError(
                f"data.video_views = {self.video_views} needs the deepest frame as the image "
                "(data.video_frames: 1 and data.video_frame: null)"
            )
        if self.video_embed == "views" and self.video_views < 2:
            raise ConfigError(
                "data.video_embed = views averages the embeddings of a press's deepest frame "
                f"and data.video_views frames across its span: needs video_views >= 2, got "
                f"{self.video_views}"
            )
        if not 0.0 <= self.video_views_min <= 1.0:
            raise ConfigError(
                f"data.video_views_min: must be in [0, 1], got {self.video_views_min}"
            )
        if not self.video_gain > 0:
            raise ConfigError(f"data.video_gain: must be > 0, got {self.video_gain}")
        if self.workers < 1:
            raise ConfigError(f"data.workers: must be >= 1, got {self.workers}")
        if self.depth_post_at is not None and not (
            len(self.depth_post_at) == 2 and all(0.0 <= f <= 1.0 for f in self.depth_post_at)
        ):
            raise ConfigError(
                f"data.depth_post_at: must be [x, y] fractions in [0, 1], got {self.depth_post_at}"
            )
        if self.touch_frames is None:  # null: none stacked, as the empty list says
            object.__setattr__(self, "touch_frames", ())
        frames = self.touch_frames or ()
        if len(frames) > MAX_TOUCH_FRAMES:
            raise ConfigError(
                f"data.touch_frames: at most {MAX_TOUCH_FRAMES} frames, got {len(frames)}"
            )
        touch_aug = [a for m, a in self.augment.items() if Modality(m) is Modality.TOUCH]
        if len(frames) > 1 and any(a.permute_channels for a in touch_aug):
            raise ConfigError(
                "data.augment.touch.permute_channels: would mix the frames that "
                "data.touch_frames stacks as channels; set one"
            )
        if not 0.0 < self.touch_zoom <= 1.0:
            raise ConfigError(f"data.touch_zoom: must be in (0, 1], got {self.touch_zoom}")
        if self.depth_top_mm is not None and not self.depth_top_mm > 0:
            raise ConfigError(f"data.depth_top_mm: must be > 0, got {self.depth_top_mm}")
        if not self.depth_min_height_mm >= 0:
            raise ConfigError(
                f"data.depth_min_height_mm: must be >= 0, got {self.depth_min_height_mm}"
            )
        for modality, aug in self.augment.items():
            key = f"data.augment.{Modality(modality).value}"
            for name in ("crop_p", "hflip_p"):
                if not 0.0 <= getattr(aug, name) <= 1.0:
                    raise ConfigError(f"{key}.{name}: must be in [0, 1], got {getattr(aug, name)}")
            for name in ("noise_std", "level_shift", "level_tilt", "level_floor"):
                if not 0.0 <= getattr(aug, name) < 1.0:
                    raise ConfigError(f"{key}.{name}: must be in [0, 1), got {getattr(aug, name)}")

    @property
    def touch_frame_indices(self) -> tuple[int, ...]:
        """The frames of a press the network reads, in channel order: ``touch_frames``, or
        ``(touch_frame,)``."""
        return self.touch_frames or (self.touch_frame,)

    @property
    def stacks_touch_frames(self) -> bool:
        """Whether a touch input is several frames of a press stacked as channels."""
        return len(self.touch_frame_indices) > 1

    def size_of(self, modality: Modality | str) -> int:
        """Side in pixels of ``modality``'s network input (a `Modality` or its name):
        ``color_size`` for colour when set, else ``image_size``.

        Raises:
            ModalityError: ``modality`` names no modality.
        """
        if Modality.of(modality) is Modality.COLOR and self.color_size is not None:
            return self.color_size
        return self.image_size

    @property
    def touch_channels(self) -> int:
        """Channels of a touch input: 3 per frame read (`touch_frame_indices`)."""
        return 3 * len(self.touch_frame_indices)
