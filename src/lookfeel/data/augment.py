"""Seeded image augmentation on (C, H, W) tensors in [0, 1] (paper section 5.3 and the
authors' released code). Every random draw comes from the `torch.Generator` passed in.

Two ways to apply one draw: `Augmenter.__call__` augments one image on the CPU;
`Augmenter.draw_batch` draws the choices for a whole batch at once from a numpy generator (the
same distributions) and `Augmenter.apply_batch` applies them on whatever device the images are
on (crops as one ``grid_sample``). Training augments that way: the draws are a few vectorised
numpy calls on the CPU, the pixels never leave the accelerator."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from lookfeel.config import AugmentConfig

__all__ = [
    "AugmentDraw",
    "Augmenter",
    "add_noise",
    "apply_gamma",
    "hflip",
    "permute_channels",
    "shift_level",
    "square_crop",
]


def apply_gamma(x: torch.Tensor, gamma: float) -> torch.Tensor:
    """Gamma correction ``x ** gamma`` (changes exposure and, per channel, hue)."""
    return x.clamp(0.0, 1.0).pow(gamma)


def permute_channels(x: torch.Tensor, order: list[int]) -> torch.Tensor:
    """Reorder the channels of a (C, H, W) image."""
    return x[order]


def square_crop(x: torch.Tensor, top: int, left: int, side: int) -> torch.Tensor:
    """Crop a square of ``side`` pixels and resize it back to the input size (bilinear)."""
    h, w = x.shape[-2:]
    patch = x[..., top : top + side, left : left + side]
    return F.interpolate(
        patch.unsqueeze(0), size=(h, w), mode="bilinear", align_corners=False, antialias=False
    ).squeeze(0)


def add_noise(x: torch.Tensor, std: float, generator: torch.Generator) -> torch.Tensor:
    """Add Gaussian noise of ``std`` and clip to [0, 1]."""
    noise = torch.randn(x.shape, generator=generator, dtype=x.dtype) * std
    return (x + noise).clamp_(0.0, 1.0)


def hflip(x: torch.Tensor) -> torch.Tensor:
    """Mirror left-right."""
    return x.flip(-1)


def shift_level(x: torch.Tensor, level: torch.Tensor, floor: float = 0.0) -> torch.Tensor:
    """Move the level of every pixel above 0 of a batch (N, C, H, W) by a plane per image.

    ``level`` (N, 3) holds each image's (shift, tilt along x, tilt along y): the plane is
    ``shift + tx * u + ty * v`` with u, v from -1 to 1 across the image (pixel centres).
    Pixels at 0 (registered depth's masked room) stay 0; the others stay in (0, 1], except
    that those moved below ``floor`` become 0."""
    h, w = x.shape[-2:]
    u = (torch.arange(w, device=x.device, dtype=x.dtype) + 0.5) * (2.0 / w) - 1.0
    v = (torch.arange(h, device=x.device, dtype=x.dtype) + 0.5) * (2.0 / h) - 1.0
    s, tx, ty = (level[:, k].view(-1, 1, 1, 1) for k in range(3))
    plane = s + tx * u.view(1, 1, 1, w) + ty * v.view(1, 1, h, 1)  # (N, 1, H, W)
    moved = (x + plane).clamp(1e-3, 1.0)
    if floor > 0:
        moved = torch.where(moved < floor, torch.zeros_like(moved), moved)
    return torch.where(x > 0, moved, x)


def _level_plane(
    c: AugmentConfig, a: np.ndarray, b: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(shift, tilt along x, tilt along y) of `shift_level` from uniform draws in [0, 1): the
    shift from ``a``, the tilt's direction from ``b`` and its size from ``t``."""
    angle = 2.0 * math.pi * b
    tilt = c.level_tilt * t
    return c.level_shift * (2.0 * a - 1.0), tilt * np.cos(angle), tilt * np.sin(angle)


def _uniform(generator: torch.Generator) -> float:
    return float(torch.rand((), generator=generator))


@dataclass(frozen=True)
class AugmentDraw:
    """The random choices of a batch of N augmentations (see `Augmenter.draw_batch`)."""

    crop: np.ndarray
    """(N, 3) int (top, left, side) of each square crop; side 0: no crop."""
    flip: np.ndarray
    """(N,) bool."""
    gamma: np.ndarray | None
    """(N,) float gamma per image, or none."""
    order: np.ndarray | None
    """(N, C) channel order per image, or none."""
    noise_seed: np.ndarray | None
    """(N,) seeds of each image's Gaussian noise, or none."""
    level: np.ndarray | None = None
    """(N, 3) float (shift, tilt along x, tilt along y) of each image's level, or none."""

    def __len__(self) -> int:
        return len(self.flip)

    def __getitem__(self, index: slice | np.ndarray | list[int]) -> AugmentDraw:
        """The draws of some images."""

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[index]

        return AugmentDraw(
            self.crop[index], self.flip[index], pick(self.gamma), pick(self.order),
            pick(self.noise_seed), pick(self.level),
        )  # fmt: skip


def _crop_grids(
    draws: Sequence[tuple[int, int, int]], h: int, w: int, device: torch.device
) -> torch.Tensor:
    """Sampling grids that crop square (top, left, side) and resize to (h, w) like
    `square_crop`: output pixel i samples source (i + 0.5) * side / size - 0.5 + offset,
    clamped to the crop (bilinear, half-pixel centres), in ``grid_sample``'s units."""
    t = torch.tensor(draws, dtype=torch.float64)
    top, left, side = t[:, 0:1], t[:, 1:2], t[:, 2:3]
    i = torch.arange(h, dtype=torch.float64)[None]
    j = torch.arange(w, dtype=torch.float64)[None]
    sy = torch.minimum(((i + 0.5) * side / h - 0.5).clamp_min(0) + top, top + side - 1)
    sx = torch.minimum(((j + 0.5) * side / w - 0.5).clamp_min(0) + left, left + side - 1)
    gy, gx = (2 * sy + 1) / h - 1, (2 * sx + 1) / w - 1  # (N, h), (N, w)
    # Only the (N, h) and (N, w) coordinates cross to the device; the (N, h, w, 2) grid is
    # built there (for 384 touch crops at 227 px it is 160 MB: building it on the host and
    # copying it cost ~12 ms a step on an H100 machine).
    gx = gx.to(device=device, dtype=torch.float32, non_blocking=True)
    gy = gy.to(device=device, dtype=torch.float32, non_blocking=True)
    grid = torch.stack(torch.broadcast_tensors(gx[:, None, :], gy[:, :, None]), dim=-1)
    return grid  # (N, h, w, 2) as (x, y)


class Augmenter:
    """Applies one modality's `AugmentConfig` to an image with a given generator.

    Order: crop, flip, level, gamma, channel order, noise. With a default config it returns the
    input unchanged and draws nothing.
    """

    def __init__(self, config: AugmentConfig) -> None:
        self.config = config

    @property
    def active(self) -> bool:
        c = self.config
        return bool(
            c.gamma is not None
            or c.permute_channels
            or c.crop_p
            or c.noise_std
            or c.hflip_p
            or c.level_shift
            or c.level_tilt
        )

    def draw_batch(
        self, rng: np.random.Generator, n: int, channels: int, height: int, width: int
    ) -> AugmentDraw:
        """The random choices for ``n`` images of (channels, height, width), drawn at once
        from ``rng`` (the same distributions as `__call__`)."""
        c = self.config
        crop = np.zeros((n, 3), np.int64)
        if c.crop_p:
            chosen = rng.random(n) < c.crop_p
            lo, hi = c.crop_scale
            side = np.rint((lo + (hi - lo) * rng.random(n)) * min(height, width)).astype(np.int64)
            side = np.clip(side, 1, min(height, width))
            top = (rng.random(n) * (height - side + 1)).astype(np.int64)
            left = (rng.random(n) * (width - side + 1)).astype(np.int64)
            crop = np.where(chosen[:, None], np.stack([top, left, side], axis=1), 0)
        flip = rng.random(n) < c.hflip_p if c.hflip_p else np.zeros(n, bool)
        gamma = None
        if c.gamma is not None:
            lo, hi = c.gamma  # log-uniform, so gamma and 1/gamma are equally likely
            gamma = np.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * rng.random(n))
        order = None
        if c.permute_channels and channels > 1:
            order = np.argsort(rng.random((n, channels)), axis=1)
        noise_seed = rng.integers(0, 2**62, n) if c.noise_std else None
        level = None
        if c.level_shift or c.level_tilt:
            level = np.stack(_level_plane(c, *rng.random((3, n))), axis=1)
        return AugmentDraw(crop, flip, gamma, order, noise_seed, level)

    def apply_batch(self, x: torch.Tensor, draws: AugmentDraw) -> torch.Tensor:
        """Apply one draw per image to a batch (N, C, H, W) in [0, 1], on ``x``'s device.

        Crops resample with one ``grid_sample`` (bilinear, half-pixel centres, edges clamped:
        `square_crop`'s resampling up to float rounding); no per-image Python.
        """
        if len(draws) != len(x):
            raise ValueError(f"{len(draws)} draws for a batch of {len(x)} images")
        if not self.active or len(draws) == 0:
            return x
        n, ch, h, w = x.shape
        dev = x.device
        cropped = np.flatnonzero(draws.crop[:, 2] > 0)
        if len(cropped):
            x = x.clone()
            grid = _crop_grids(draws.crop[cropped].tolist(), h, w, dev)
            idx = torch.from_numpy(cropped).to(dev)
            x[idx] = F.grid_sample(
                x[idx], grid, mode="bilinear", padding_mode="border", align_corners=False
            )
        if draws.flip.any():
            mask = torch.from_numpy(draws.flip).to(dev).view(n, 1, 1, 1)
            x = torch.where(mask, x.flip(-1), x)
        if draws.level is not None:
            x = shift_level(
                x, torch.from_numpy(draws.level).to(dev, x.dtype), self.config.level_floor
            )
        if draws.gamma is not None:
            g = torch.from_numpy(draws.gamma).to(dev, x.dtype).view(n, 1, 1, 1)
            x = x.clamp(0.0, 1.0).pow(g)
        if draws.order is not None and ch > 1:
            index = torch.from_numpy(draws.order).to(dev).view(n, ch, 1, 1).expand(n, ch, h, w)
            x = x.gather(1, index)
        if draws.noise_seed is not None and self.config.noise_std:
            noise = torch.stack(
                [
                    torch.randn((ch, h, w), generator=torch.Generator().manual_seed(int(s)))
                    for s in draws.noise_seed
                ]
            ).to(dev, x.dtype)
            x = (x + noise * self.config.noise_std).clamp_(0.0, 1.0)
        return x

    def __call__(self, x: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Augment a (C, H, W) image in [0, 1]; returns a new tensor of the same shape."""
        c = self.config
        if not self.active:
            return x
        if c.crop_p and _uniform(generator) < c.crop_p:
            h, w = x.shape[-2:]
            lo, hi = c.crop_scale
            side = round((lo + (hi - lo) * _uniform(generator)) * min(h, w))
            side = max(1, min(side, h, w))
            top = int(torch.randint(0, h - side + 1, (), generator=generator))
            left = int(torch.randint(0, w - side + 1, (), generator=generator))
            x = square_crop(x, top, left, side)
        if c.hflip_p and _uniform(generator) < c.hflip_p:
            x = hflip(x)
        if c.level_shift or c.level_tilt:
            draws = [_uniform(generator) for _ in range(3)]
            level = torch.tensor([_level_plane(c, *np.array(draws))], dtype=x.dtype)
            x = shift_level(x[None], level, c.level_floor)[0]
        if c.gamma is not None:
            lo, hi = c.gamma  # log-uniform, so gamma and 1/gamma are equally likely
            g = math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * _uniform(generator))
            x = apply_gamma(x, g)
        if c.permute_channels and x.shape[0] > 1:
            order = torch.randperm(x.shape[0], generator=generator).tolist()
            x = permute_channels(x, order)
        if c.noise_std:
            x = add_noise(x, c.noise_std, generator)
        return x
