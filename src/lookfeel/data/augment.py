"""Seeded image augmentation on (C, H, W) tensors in [0, 1] (paper section 5.3 and the
authors' released code). Every random draw comes from the `torch.Generator` passed in."""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from lookfeel.config import AugmentConfig

__all__ = ["Augmenter", "add_noise", "apply_gamma", "hflip", "permute_channels", "square_crop"]


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


def _uniform(generator: torch.Generator) -> float:
    return float(torch.rand((), generator=generator))


class Augmenter:
    """Applies one modality's `AugmentConfig` to an image with a given generator.

    Order: crop, flip, gamma, channel order, noise. With a default config it returns the
    input unchanged and draws nothing.
    """

    def __init__(self, config: AugmentConfig) -> None:
        self.config = config

    @property
    def active(self) -> bool:
        c = self.config
        return bool(
            c.gamma is not None or c.permute_channels or c.crop_p or c.noise_std or c.hflip_p
        )

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
