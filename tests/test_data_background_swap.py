"""The background control: cloth kept, background from another fabric's image, reproducibly."""

import warnings

import numpy as np
import pytest

from lookfeel.data.background_swap import pair_other_fabric, swap_backgrounds
from lookfeel.errors import LookfeelError


def _batch(n_fabrics: int = 5, per: int = 3, size: int = 8):
    """Image i is filled with 1000 * (i + 1); its cloth is a square whose place varies."""
    n = n_fabrics * per
    fab = np.repeat(np.arange(10, 10 + n_fabrics), per)
    images = (1000.0 * (np.arange(n) + 1))[:, None, None] * np.ones((n, size, size))
    cloth = np.zeros((n, size, size), bool)
    for i in range(n):
        r = i % (size - 3)
        cloth[i, r : r + 3, 2:5] = True
        images[i][cloth[i]] += 1.0  # cloth pixels: 1000 (i + 1) + 1
    return images, cloth, fab


def test_pairs_are_other_fabrics_deterministic_and_uniform():
    fab = np.repeat([1, 2, 3, 4], [1, 2, 3, 4])
    p = pair_other_fabric(fab, seed=5)
    assert np.array_equal(p, pair_other_fabric(fab, seed=5))
    assert not np.array_equal(p, pair_other_fabric(fab, seed=6))
    assert (fab[p] != fab).all()
    # Uniform over the other fabrics' items: the lone fabric-1 item draws each of the 9 others.
    draws = np.array([pair_other_fabric(fab, seed=s)[0] for s in range(1800)])
    counts = np.bincount(draws, minlength=10)[1:]
    assert counts.min() > 120 and counts.max() < 280  # 200 expected each


def test_swap_keeps_cloth_and_takes_background_from_the_partner():
    images, cloth, fab = _batch()
    out = swap_backgrounds(images, cloth, fab, seed=1)
    assert out.images.shape == images.shape
    for i, j in enumerate(out.partner):
        assert fab[j] != fab[i]
        assert np.array_equal(out.images[i][cloth[i]], images[i][cloth[i]])
        back = ~cloth[i]
        # Every background pixel is the partner's background: 1000 (j + 1), never its cloth
        # (1000 (j + 1) + 1) and never image i's own background.
        assert (out.images[i][back] == 1000.0 * (j + 1)).all()


def test_partner_cloth_hole_is_filled_from_its_room_when_given():
    images, cloth, fab = _batch()
    rooms = np.full(images.shape, 7.0)
    out = swap_backgrounds(images, cloth, fab, seed=2, rooms=rooms)
    for i, j in enumerate(out.partner):
        hole = cloth[j] & ~cloth[i]
        assert (out.images[i][hole] == 7.0).all()
        rest = ~cloth[j] & ~cloth[i]
        assert (out.images[i][rest] == images[j][rest]).all()


def test_swap_is_deterministic_and_keeps_dtype():
    images, cloth, fab = _batch()
    a = swap_backgrounds(images.astype(np.uint16), cloth, fab, seed=3)
    b = swap_backgrounds(images.astype(np.uint16), cloth, fab, seed=3)
    assert a.images.dtype == np.uint16 and np.array_equal(a.images, b.images)


def test_swap_rejects_bad_input():
    images, cloth, fab = _batch()
    with pytest.raises(LookfeelError, match="must agree"):
        swap_backgrounds(images, cloth[:, :4], fab)
    with pytest.raises(LookfeelError, match="two or more fabrics"):
        swap_backgrounds(images, cloth, np.zeros(len(fab)))
    with pytest.raises(LookfeelError, match="rooms"):
        swap_backgrounds(images, cloth, fab, rooms=images[:2])


def _top1(x: np.ndarray, fab: np.ndarray) -> float:
    """Exact pick-1 top-1 of pixels z-scored over the images (as the leak check scores)."""
    from lookfeel.metrics import EXACT_PICK, score_pairs
    from lookfeel.modality import Modality, Pair

    sd = x.std(axis=0)
    x = (x[:, sd > 1e-6] - x[:, sd > 1e-6].mean(axis=0)) / sd[sd > 1e-6]
    d = Modality.DEPTH
    pair = Pair(d, d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # 5 fabrics: pick 1 of 5
        return float(score_pairs({d: x}, {d: fab}, EXACT_PICK, [pair])[pair].pick.mean[0])


def test_background_control_exposes_the_planted_room_leak_and_not_registered_depth(leaky_depth):
    """The room identifies the fabric, the cloth does not (`leaky_depth`)."""
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader, scan
    from lookfeel.data.background_swap import BackgroundControl
    from lookfeel.modality import Modality

    items = scan(leaky_depth).items(Modality.DEPTH)
    fab = np.array([it.fabric_id for it in items])
    arrays = {}
    for kind in ("raw", "registered"):
        config = DataConfig(image_size=32, depth_input=kind)
        loader = ImageLoader(config)
        control = BackgroundControl(config, seed=0)
        swapped = control.loader(items)
        assert control.arrays(items) is control.arrays(items)  # kept, not redone
        x = np.stack([loader.array(it.path, Modality.DEPTH) for it in items])
        y = np.stack([swapped.array(it.path, Modality.DEPTH) for it in items])
        arrays[kind] = (x.reshape(len(x), -1), y.reshape(len(y), -1))
    raw, swapped_raw = arrays["raw"]
    # Raw depth: the room alone picks the fabric; swapping the background takes that away
    # (chance: 1/6).
    assert _top1(raw, fab) > 0.8 and _top1(swapped_raw, fab) < 0.4
    reg, swapped_reg = arrays["registered"]
    # Registered depth: the room is gone (near chance), and the swap changes little: the cloth
    # is kept in its own camera's pixels but measured from the partner's floor, so a session
    # that moved the camera by tens of mm (here) moves the heights by that much, a few mm on
    # GelFabric.
    assert np.abs(reg - swapped_reg).mean() < 0.2 * np.abs(raw - swapped_raw).mean()
    assert _top1(reg, fab) < 0.4 and _top1(swapped_reg, fab) < 0.4


def _two_sessions(root, size: int = 48):
    """Fabric 1's drapes taken with the camera 5 mm lower than fabric 2's (two sessions of
    one room); each fabric's drapes differ in where the cloth lies."""
    import dataclasses

    from PIL import Image

    from ._scene import Scene

    (root / "depth").mkdir(parents=True)
    base = Scene(size=size, f=90.0 * size / 64, spread_mm=90.0, panel_x=330.0)
    for fabric, lift in ((1, 0.0), (2, 5.0)):
        for k in range(2):
            scene = dataclasses.replace(
                base,
                eye=(0.0, -700.0, 560.0 + lift),
                target=(0.0, 300.0, 80.0 + lift),
                cloth_offset=(30.0 * k - 15.0, 0.0),
                seed=10 * fabric + k,
            )
            name = f"F{fabric:04d}_Depth_New_{k:06d}.png"
            Image.fromarray(scene.render()["depth"]).save(root / "depth" / name)
    (root / "labels.csv").write_text("fabric_id,thickness_mm\n1,0.5\n2,1.0\n", encoding="utf-8")
    return root, base.f


def test_room_control_measures_the_cloth_from_the_partners_floor(tmp_path):
    """Registered depth: each image registered in its partner's fitted room (the other
    session's, 5 mm further from this camera's floor) keeps its cloth and is 5 mm higher, or
    lower; heights measured from the drape's top do not move; raw depth has no room control."""
    import dataclasses

    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader, scan
    from lookfeel.data.background_swap import BackgroundControl
    from lookfeel.modality import Modality

    root, focal = _two_sessions(tmp_path / "data")
    items = scan(root).items(Modality.DEPTH)
    config = DataConfig(image_size=48, depth_input="registered", depth_focal_px=focal)
    for top, expected in ((None, 5.0), (250.0, 0.0)):
        cfg = dataclasses.replace(config, depth_top_mm=top)
        control = BackgroundControl(cfg, seed=0)
        assert control.has_room_control
        rooms = control.room_arrays(items)
        assert control.room_arrays(items) is rooms  # kept, not redone
        loader = ImageLoader(cfg)
        for it in items:
            own, moved = loader.array(it.path, Modality.DEPTH), rooms[it.path]
            both = (own > 0.05) & (moved > 0.05)  # cloth in both, off its rim
            assert both.sum() > 0.9 * (own > 0.05).sum()
            sign = 1.0 if it.fabric_id == 1 else -1.0  # fabric 2's floor is 5 mm nearer
            shift_mm = float(np.median((moved - own)[both])) * cfg.depth_range_mm
            assert shift_mm == pytest.approx(sign * expected, abs=1.0), (it.path.name, top)
    raw = BackgroundControl(DataConfig(image_size=48), seed=0)
    assert not raw.has_room_control
    with pytest.raises(LookfeelError, match="not registered"):
        raw.room_arrays(items)
