import torch

from lookfeel.config import AugmentConfig
from lookfeel.data import Augmenter
from lookfeel.data.augment import add_noise, apply_gamma, hflip, permute_channels, square_crop


def test_functions_on_known_values():
    x = torch.tensor([[[0.25, 1.0]], [[0.5, 0.0]], [[0.0, 0.04]]])  # (3, 1, 2)
    torch.testing.assert_close(apply_gamma(x, 0.5)[0], torch.tensor([[0.5, 1.0]]))
    assert torch.equal(permute_channels(x, [2, 0, 1])[0], x[2])
    assert torch.equal(hflip(x)[0], torch.tensor([[1.0, 0.25]]))
    img = torch.arange(16.0).reshape(1, 4, 4)
    crop = square_crop(img, 1, 1, 2)
    assert crop.shape == (1, 4, 4)
    assert crop.min() >= 5 and crop.max() <= 10  # only the central 2x2 (5, 6, 9, 10)
    noisy = add_noise(torch.full((1, 8, 8), 0.5), 0.1, torch.Generator().manual_seed(0))
    assert noisy.min() >= 0.0 and noisy.max() <= 1.0 and noisy.std() > 0.05


def test_default_config_is_identity_and_draws_nothing():
    aug = Augmenter(AugmentConfig())
    g = torch.Generator().manual_seed(0)
    x = torch.rand(3, 8, 8)
    assert aug(x, g) is x
    assert torch.equal(
        torch.rand(1, generator=g), torch.rand(1, generator=torch.Generator().manual_seed(0))
    )


def test_paper_colour_augmentation_is_seeded_and_in_range():
    aug = Augmenter(AugmentConfig(gamma=(0.5, 2.0), permute_channels=True, crop_p=1.0, hflip_p=0.5))
    x = torch.rand(3, 16, 16)
    a = aug(x, torch.Generator().manual_seed(1))
    b = aug(x, torch.Generator().manual_seed(1))
    c = aug(x, torch.Generator().manual_seed(2))
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert a.shape == x.shape and a.min() >= 0.0 and a.max() <= 1.0
    depth = torch.rand(1, 16, 16)  # one channel: channel order is left alone
    assert aug(depth, torch.Generator().manual_seed(1)).shape == (1, 16, 16)


def test_batched_augmentation_matches_one_image_at_a_time_and_is_seeded():
    import numpy as np

    from lookfeel.data.augment import AugmentDraw

    aug = Augmenter(AugmentConfig(gamma=(0.5, 2.0), permute_channels=True, crop_p=0.7, hflip_p=0.5))
    x = torch.rand(12, 3, 20, 20)
    d = aug.draw_batch(np.random.default_rng(3), 12, 3, 20, 20)
    assert len(d) == 12 and (d.crop[:, 2] > 0).any() and (d.crop[:, 2] == 0).any()
    assert d.flip.any() and not d.flip.all()
    again = aug.draw_batch(np.random.default_rng(3), 12, 3, 20, 20)
    assert np.array_equal(d.crop, again.crop) and np.array_equal(d.order, again.order)
    y = aug.apply_batch(x, d)
    assert y.shape == x.shape and y.min() >= 0.0 and y.max() <= 1.0
    for i in range(12):  # the reference, image by image: square_crop, hflip, gamma, order
        ref = x[i]
        top, left, side = (int(v) for v in d.crop[i])
        if side:
            ref = square_crop(ref, top, left, side)
        if d.flip[i]:
            ref = hflip(ref)
        assert d.gamma is not None and d.order is not None
        ref = permute_channels(apply_gamma(ref, float(d.gamma[i])), d.order[i].tolist())
        torch.testing.assert_close(y[i], ref, atol=2e-5, rtol=0)
    assert torch.equal(aug.apply_batch(x[3:5], d[3:5]), y[3:5])  # a share is the same images
    off = Augmenter(AugmentConfig())
    assert off.apply_batch(x, off.draw_batch(np.random.default_rng(0), 12, 3, 20, 20)) is x
    assert isinstance(d[[0, 2]], AugmentDraw) and len(d[[0, 2]]) == 2


def test_level_shift_and_tilt_move_the_foreground_by_a_plane_and_keep_the_mask():
    # Registered depth: the room is 0; a floor fitted a few mm off moves the cloth's level by
    # a plane. The augmentation must do exactly that, and never unmask or mask a pixel.
    import numpy as np

    from lookfeel.data.augment import shift_level

    x = torch.zeros(2, 1, 4, 4)
    x[:, :, 1:3, :] = 0.5
    level = torch.tensor([[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])
    y = shift_level(x, level)
    assert torch.equal(y[x == 0], x[x == 0])  # the room stays 0
    torch.testing.assert_close(y[0, 0, 1], torch.full((4,), 0.6))  # shifted by 0.1
    # tilt along x: u = -0.75, -0.25, 0.25, 0.75 at the pixel centres
    torch.testing.assert_close(y[1, 0, 2], 0.5 + 0.2 * torch.tensor([-0.75, -0.25, 0.25, 0.75]))
    low = shift_level(x, torch.tensor([[-0.9, 0.0, 0.0]]).expand(2, 3))
    assert (low[x > 0] > 0).all()  # a foreground pixel is never pushed into the mask
    # ... unless it falls below the floor: cloth no longer above the margin is room
    sunk = shift_level(x, torch.tensor([[0.0, 0.2, 0.0]]).expand(2, 3), floor=0.4)
    assert torch.equal(sunk[0, 0, 1], torch.tensor([0.0, 0.45, 0.55, 0.65]))
    assert torch.equal(sunk[x == 0], x[x == 0])

    aug = Augmenter(AugmentConfig(level_shift=0.02, level_tilt=0.03))
    d = aug.draw_batch(np.random.default_rng(0), 64, 1, 4, 4)
    assert d.level is not None and d.level.shape == (64, 3)
    assert np.abs(d.level[:, 0]).max() <= 0.02 and np.hypot(*d.level[:, 1:].T).max() <= 0.03
    assert np.abs(d.level[:, 0]).max() > 0.01  # the range is used, not a constant
    batch = x[:1].expand(64, 1, 4, 4)
    y = aug.apply_batch(batch, d)
    assert torch.equal(y[batch == 0], batch[batch == 0])
    assert (y - batch).abs().max() <= 0.02 + 0.03 + 1e-6 and (y != batch).any()
    one = aug(x[0], torch.Generator().manual_seed(5))  # the one-image path does the same kind
    assert torch.equal(one[x[0] == 0], x[0][x[0] == 0]) and not torch.equal(one, x[0])


def test_augmentation_amounts_out_of_range_name_their_key():
    import re

    import pytest

    from lookfeel.config import ConfigError, RunConfig, load_config

    for override, message in [
        ("data.augment.depth.level_tilt=-0.1", "data.augment.depth.level_tilt: must be in [0, 1)"),
        ("data.augment.color.hflip_p=1.5", "data.augment.color.hflip_p: must be in [0, 1]"),
    ]:
        with pytest.raises(ConfigError, match=re.escape(message)):
            load_config(RunConfig, overrides=[override])
