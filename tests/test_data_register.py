"""Scene registration on rendered rooms with a known answer: planes, cloth, invariance."""

import dataclasses

import numpy as np
import pytest

from lookfeel.config import ConfigError
from lookfeel.data.background_swap import register_items
from lookfeel.data.holes import unseen_regions
from lookfeel.data.register import (
    Intrinsics,
    RegistrationError,
    _counts,
    _post,
    _residual,
    register_depth,
    register_in_room,
)

from ._scene import Scene

BASE = Scene(spread_mm=90.0, panel_x=330.0)
# Another rig: camera higher, further, yawed and rolled, a longer lens, a bigger image.
OTHER = Scene(
    eye=(150.0, -800.0, 700.0),
    target=(-50.0, 250.0, 50.0),
    roll_deg=6.0,
    f=110.0,
    wall_y=620.0,
    panel_x=300.0,
    size=80,
    spread_mm=90.0,
)


def _angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(float(np.dot(a, b)))))))


@pytest.mark.parametrize("scene", [BASE, OTHER], ids=["base", "other-rig"])
def test_fitted_room_matches_the_truth(scene: Scene):
    r = scene.render()
    reg = register_depth(r["depth"], scene.intrinsics)
    truth = scene.planes()
    assert sorted(p.label for p in reg.planes) == ["floor", "side", "wall"]
    for p in reg.planes:
        normal, _ = truth[p.label]
        assert _angle_deg(p.normal, normal) < 1.0, p
    seen_room = r["clearance"] < 3.0  # pixels that show the room itself
    err = np.abs(reg.room - r["room"])[seen_room]
    assert np.median(err) < 1.0 and np.percentile(err, 99) < 6.0
    assert reg.residual_mm < 2.0  # noise is 1 mm


@pytest.mark.parametrize("scene", [BASE, OTHER], ids=["base", "other-rig"])
def test_cloth_mask_and_height_match_the_truth(scene: Scene):
    r = scene.render()
    reg = register_depth(r["depth"], scene.intrinsics, margin_mm=15.0)
    clear = r["clearance"]
    assert ((clear > 20.0) & ~reg.cloth).mean() < 0.002  # cloth missed
    assert ((clear < 10.0) & reg.cloth).mean() < 0.002  # room taken for cloth
    assert 0.15 < reg.cloth.mean() < 0.5
    on = reg.cloth & (clear > 20.0)
    assert np.median(np.abs(reg.height - r["height"])[on]) < 5.0  # mm above the floor
    assert (reg.height[~reg.cloth] == 0).all() and (reg.clearance[~reg.cloth] == 0).all()
    u, v = reg.post_uv or (np.nan, np.nan)
    rows, cols = np.nonzero(clear > 15.0)
    top = rows.min()
    assert abs(v - top) <= 2.0 and abs(u - cols[rows == top].mean()) <= 2.0


def test_unknown_intrinsics_still_find_room_and_cloth():
    """Planes and cloth are fitted in image space: a wrong focal length changes neither."""
    r = OTHER.render()
    right = register_depth(r["depth"], OTHER.intrinsics)
    default = register_depth(r["depth"])  # GelFabric's intrinsics, wrong for this rig
    assert np.array_equal(right.cloth, default.cloth)
    assert np.allclose(right.room, default.room)
    assert {p.label for p in default.planes} == {"floor", "wall", "side"}


def test_registered_image_ignores_a_moved_wall():
    a = BASE.render()
    b = dataclasses.replace(BASE, wall_y=BASE.wall_y + 6.0).render()
    raw_change = np.abs(a["depth"].astype(float) - b["depth"].astype(float))
    assert raw_change.max() >= 5.0  # the session fingerprint is in the raw depth
    ra, rb = (
        register_depth(a["depth"], BASE.intrinsics),
        register_depth(b["depth"], BASE.intrinsics),
    )
    assert (ra.cloth != rb.cloth).mean() < 0.003  # a few pixels at the margin's edge
    both = ra.cloth & rb.cloth
    assert np.abs(ra.height - rb.height)[both].max() < 1.5
    assert (ra.height[~ra.cloth & ~rb.cloth] == rb.height[~ra.cloth & ~rb.cloth]).all()


def test_registered_image_ignores_a_moved_camera():
    """The camera a few mm off (another session): raw depth changes everywhere, the
    registered image hardly (only the cloth's sub-pixel resampling)."""
    moved = dataclasses.replace(BASE, eye=(3.0, -704.0, 562.0))
    a, b = BASE.render(), moved.render()
    raw = np.abs(a["depth"].astype(float) - b["depth"].astype(float))
    ra, rb = (
        register_depth(a["depth"], BASE.intrinsics),
        register_depth(b["depth"], BASE.intrinsics),
    )
    reg = np.abs(ra.height - rb.height)
    back = ~ra.cloth & ~rb.cloth
    assert np.median(raw[back]) >= 2.0 and reg[back].max() == 0.0
    assert reg.mean() < 0.5 * raw.mean()


def test_drape_moved_to_a_fixed_place_undoes_a_camera_that_moved_sideways():
    """Another session's camera, 40 mm to the side: the drape lies elsewhere in the image
    (a session cue); ``data.depth_post_at`` puts its top at one place in every image."""
    from lookfeel.config import DataConfig
    from lookfeel.data.register import registered_input

    moved = dataclasses.replace(BASE, eye=(40.0, -700.0, 560.0), target=(40.0, 300.0, 80.0))
    a, b = BASE.render()["depth"], moved.render()["depth"]
    plain = DataConfig(depth_input="registered", depth_focal_px=BASE.f)
    at = dataclasses.replace(plain, depth_post_at=(0.5, 0.1))
    ua = (register_depth(a, BASE.intrinsics).post_uv or (0.0, 0.0))[0]
    ub = (register_depth(b, BASE.intrinsics).post_uv or (0.0, 0.0))[0]
    assert abs(ua - ub) >= 2.0  # the drape moved in the image
    for d in (a, b):  # the drape's top (as registration finds it) lies at the place asked
        u, v = _post(registered_input(d, at) > 0) or (0.0, 0.0)
        assert abs(u - 0.5 * 63) <= 1.0 and abs(v - 0.1 * 63) <= 1.0
    before = np.abs(registered_input(a, plain) - registered_input(b, plain)).mean()
    after = np.abs(registered_input(a, at) - registered_input(b, at)).mean()
    assert after < 0.5 * before
    with pytest.raises(ConfigError, match="depth_post_at: must be"):
        dataclasses.replace(plain, depth_post_at=(0.5, 1.5))


def test_ransac_counts_are_those_of_the_residuals():
    """The hot loop's counts (one buffer, in place) equal those read from `_residual`, including
    hypotheses whose plane the rays miss (residual -inf)."""
    rng = np.random.default_rng(3)
    n = 500
    u, v = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    z = rng.uniform(700, 1300, n)
    free = rng.random(n) > 0.3
    coefs = np.column_stack([rng.normal(0, 2e-4, 40), rng.normal(0, 2e-4, 40), 1 / z[:40]])
    coefs[:5, 2] = -1e-3  # behind the camera: every ray misses
    r = _residual(coefs, u, v, z)
    inl, behind = _counts(coefs, u, v, z, free, 8.0, 30.0)
    np.testing.assert_array_equal(inl, ((np.abs(r) < 8.0) & free).sum(axis=1))
    np.testing.assert_array_equal(behind, (r > 30.0).sum(axis=1))
    assert (inl[:5] == 0).all() and inl[5:].sum() > 0


def test_deterministic_and_errors():
    d = BASE.render()["depth"]
    a, b = register_depth(d, seed=3), register_depth(d, seed=3)
    assert np.array_equal(a.height, b.height) and a.planes == b.planes
    with pytest.raises(RegistrationError, match="no valid pixel"):
        register_depth(np.zeros((16, 16), np.uint16))
    with pytest.raises(RegistrationError, match="2-D"):
        register_depth(np.ones((2, 16, 16), np.uint16))


@pytest.mark.parametrize("blind", ["bottom", "frame"])
def test_a_region_without_reading_is_left_out_of_the_fit_and_the_cloth(blind: str):
    # Another camera leaves a band without reading (0) along its image's edge. Filled from its
    # rim it would be a flat strip behind the floor, which then no longer looks like a room.
    scene = dataclasses.replace(BASE, size=96)
    r = scene.render()
    d = r["depth"].copy()
    band = np.zeros(d.shape, bool)
    if blind == "bottom":
        band[-12:] = True
    else:
        band[:8], band[-8:], band[:, :8], band[:, -8:] = True, True, True, True
    d[band] = 0
    reg = register_depth(d, scene.intrinsics)
    truth = scene.planes()
    assert sorted(p.label for p in reg.planes) == ["floor", "side", "wall"]
    for p in reg.planes:
        assert _angle_deg(p.normal, truth[p.label][0]) < 1.0, p
    whole = register_depth(r["depth"], scene.intrinsics)
    assert not (reg.cloth & band).any()
    agree = (reg.cloth == whole.cloth)[~band].mean()
    assert agree > 0.995, agree
    # The small holes a depth camera leaves are filled as before: the same registration.
    holes = d.copy()
    holes[::9, ::7] = 0
    holes[band] = r["depth"][band]
    assert holes.size * 0.002 < (holes == 0).sum() < holes.size * 0.02
    assert unseen_regions(holes) is None and unseen_regions(d) is not None
    assert sorted(p.label for p in register_depth(holes, scene.intrinsics).planes) == [
        "floor", "side", "wall"
    ]  # fmt: skip


def test_an_image_with_nothing_in_front_of_the_room_is_refused():
    from lookfeel.config import DataConfig
    from lookfeel.data.register import registered_input

    r = BASE.render()
    empty = np.round(r["room"]).astype(np.uint16)  # the room alone, no cloth
    config = DataConfig(depth_input="registered")
    with pytest.raises(RegistrationError, match=r"no cloth found: nothing stands more than "):
        registered_input(empty, config)
    assert (registered_input(r["depth"], config) > 0).any()


def test_registered_in_its_own_room_is_the_registration_and_in_another_is_measured_from_it():
    """`register_in_room`: with the image's own fitted planes it is `register_depth`; with the
    planes fitted in another session whose camera stood 5 mm higher, the cloth stays cloth
    (but for what lies within the margin and 5 mm of the floor) and every height is measured
    from that session's floor, 5 mm further from this camera."""
    d = BASE.render()["depth"]
    own = register_depth(d, BASE.intrinsics)
    again = register_in_room(d, own.planes, BASE.intrinsics)
    for field in ("room", "cloth", "height", "clearance"):
        assert np.array_equal(getattr(own, field), getattr(again, field)), field
    assert again.post_uv == own.post_uv and again.residual_mm == own.residual_mm
    higher = dataclasses.replace(BASE, eye=(0.0, -700.0, 565.0), target=(0.0, 300.0, 85.0))
    higher = higher.render()["depth"]
    other = register_depth(higher, BASE.intrinsics)
    moved = register_in_room(d, other.planes, BASE.intrinsics)
    changed = moved.cloth != own.cloth  # only cloth lying within the margin + 5 mm of the floor
    assert changed.mean() < 0.05
    assert (np.maximum(moved.height, own.height)[changed] < 15.0 + 5.0 + 3.0).all()
    both = moved.cloth & own.cloth
    assert np.median((moved.height - own.height)[both]) == pytest.approx(5.0, abs=1.0)
    with pytest.raises(RegistrationError, match="no room plane"):
        register_in_room(d, (), BASE.intrinsics)
    with pytest.raises(RegistrationError, match="2-D"):
        register_in_room(d[None], own.planes)


def test_gelfabric_intrinsics_scale_with_the_image():
    k = Intrinsics.gelfabric()
    assert (k.f, k.cx, k.cy) == (373.0, 111.5, 111.5)
    half = Intrinsics.gelfabric(112, 112)
    assert half.f == pytest.approx(186.5) and half.cx == pytest.approx(55.5)


def test_real_depth_registration(real_data):
    from lookfeel.data.images import decode_depth

    paths = sorted((real_data / "depth").glob("F00*_Depth_New_*.png"))[::300][:2]
    for p in paths:
        reg = register_depth(decode_depth(p))
        assert {"floor", "wall"} <= {pl.label for pl in reg.planes}
        assert 0.15 < reg.cloth.mean() < 0.7
        assert reg.residual_mm < 5.0
        assert reg.post_uv is not None and reg.post_uv[1] < 30  # the drape hangs from the top


def test_register_items_reads_files_and_names_the_bad_one(tmp_path):
    from PIL import Image

    from lookfeel.data.catalog import Item
    from lookfeel.modality import Modality

    items = []
    for k, scene in enumerate([BASE, dataclasses.replace(BASE, wall_y=560.0)]):
        path = tmp_path / f"F{k + 1:04d}_Depth_New_000000.png"
        Image.fromarray(scene.render()["depth"]).save(path)
        items.append(Item(Modality.DEPTH, k + 1, (path,)))
    batch = register_items(items, BASE.intrinsics)
    assert batch.cloth.shape == batch.height.shape == (2, BASE.size, BASE.size)
    one = register_depth(BASE.render()["depth"], BASE.intrinsics)
    assert np.array_equal(batch.cloth[0], one.cloth) and np.array_equal(batch.height[0], one.height)
    flat = tmp_path / "F0003_Depth_New_000000.png"
    Image.fromarray(np.full((BASE.size, BASE.size), 0, np.uint16)).save(flat)
    with pytest.raises(RegistrationError, match="F0003_Depth_New_000000.png: depth image has no"):
        register_items([*items, Item(Modality.DEPTH, 3, (flat,))])


def _write(path, depth):
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(depth).save(path)
    return path


def test_registered_loader_input_is_the_height_and_ignores_the_moved_room(tmp_path):
    """`data.depth_input: registered` through the loader: the cloth's height above the floor
    (known answer), the same whether the session moved the wall and camera or not."""
    from lookfeel.config import DataConfig
    from lookfeel.data.images import ImageLoader, PreprocessSettings
    from lookfeel.modality import Modality

    moved = dataclasses.replace(BASE, wall_y=BASE.wall_y + 6.0, eye=(3.0, -704.0, 562.0))
    truth = BASE.render()
    a = _write(tmp_path / "F0001_Depth_New_000000.png", truth["depth"])
    b = _write(tmp_path / "F0002_Depth_New_000000.png", moved.render()["depth"])
    reg = DataConfig(image_size=BASE.size, depth_input="registered", depth_focal_px=BASE.f)
    raw = DataConfig(image_size=BASE.size)
    rl, ll = ImageLoader(reg), ImageLoader(raw)
    ra, rb = rl.array(a, Modality.DEPTH), rl.array(b, Modality.DEPTH)
    la, lb = ll.array(a, Modality.DEPTH), ll.array(b, Modality.DEPTH)
    assert np.abs(la - lb).mean() > 4 * np.abs(ra - rb).mean()  # the room moved, not the cloth
    assert np.abs(ra - rb).mean() < 0.003  # 1.5 mm of the 500 mm range
    cloth = truth["clearance"] > 25.0
    height_mm = ra * reg.depth_range_mm
    assert np.median(np.abs(height_mm - truth["height"])[cloth]) < 5.0
    assert (ra[truth["clearance"] < 5.0] == 0).mean() > 0.99  # the room is masked
    # The settings are part of every cache key.
    assert PreprocessSettings.of(reg).digest() != PreprocessSettings.of(raw).digest()
    other = DataConfig(image_size=BASE.size, depth_input="registered", depth_margin_mm=30.0)
    assert PreprocessSettings.of(other).digest() != PreprocessSettings.of(reg).digest()
    other = dataclasses.replace(reg, depth_margin_mm=25.0)
    assert PreprocessSettings.of(other).digest() != PreprocessSettings.of(reg).digest()


def test_drape_rule_drops_objects_apart_from_the_cloth():
    from lookfeel.data.register import drape_mask

    cloth = np.zeros((20, 20), bool)
    cloth[2:15, 6:14] = True  # the drape
    cloth[5:18, 0:2] = True  # a strip standing apart, at the image's edge
    kept = drape_mask(cloth)
    assert kept[2:15, 6:14].all() and not kept[:, 0:2].any()
    assert np.array_equal(drape_mask(np.zeros((4, 4), bool)), np.zeros((4, 4), bool))


def test_registered_loader_input_names_the_file_it_cannot_register(tmp_path):
    from lookfeel.config import ConfigError, DataConfig
    from lookfeel.data.images import ImageLoader
    from lookfeel.modality import Modality

    bad = _write(tmp_path / "F0003_Depth_New_000000.png", np.zeros((16, 16), np.uint16))
    loader = ImageLoader(DataConfig(image_size=16, depth_input="registered"))
    with pytest.raises(RegistrationError) as e:
        loader.array(bad, Modality.DEPTH)
    msg = str(e.value)
    assert msg.startswith(f"{bad}: cannot register depth") and "no valid pixel" in msg
    assert "\n" not in msg
    with pytest.raises(ConfigError, match="data.depth_input: 'flat' is not one of"):
        DataConfig(depth_input="flat")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="data.depth_margin_mm: must be > 0"):
        DataConfig(depth_margin_mm=0.0)


def test_lowest_cloth_is_dropped_above_a_minimum_height():
    """`data.depth_min_height_mm`: cloth lying lower than it above the fitted floor is room
    (0), the rest keeps its height; 0 keeps everything and the cache key of before."""
    from lookfeel.config import DataConfig
    from lookfeel.data.images import PreprocessSettings
    from lookfeel.data.register import registered_input

    depth = BASE.render()["depth"]
    config = DataConfig(image_size=BASE.size, depth_input="registered", depth_focal_px=BASE.f)
    every = registered_input(depth, config)
    high = registered_input(depth, dataclasses.replace(config, depth_min_height_mm=40.0))
    low = (every > 0) & (every < 40.0)
    assert low.sum() > 20 and (every >= 40.0).sum() > 20  # the scene has both
    assert (high[low] == 0).all() and (high[~low] == every[~low]).all()
    digest = PreprocessSettings.of(config).digest()
    assert (
        digest
        == PreprocessSettings.of(dataclasses.replace(config, depth_min_height_mm=0.0)).digest()
    )
    assert (
        digest
        != PreprocessSettings.of(dataclasses.replace(config, depth_min_height_mm=40.0)).digest()
    )


def test_heights_from_the_drape_top_ignore_where_the_floor_was_fitted():
    """``data.depth_top_mm``: a floor fitted 8 mm off (noise within a session, an offset
    between sessions) shifts every height above the floor, and nothing measured from the
    drape's top; that top lands at the height asked, and the drape's shape is kept."""
    from lookfeel.config import DataConfig
    from lookfeel.data.register import heights_from_top, registered_heights

    d = BASE.render()["depth"]
    plain = DataConfig(depth_input="registered", depth_focal_px=BASE.f)
    h, _ = registered_heights(d, plain)
    cloth = h > 0
    off = np.where(cloth, h - 8.0, 0.0).astype(np.float32)  # the same cloth, floor 8 mm higher
    assert np.abs(off - h)[cloth].min() == pytest.approx(8.0, abs=1e-3)
    a, b = heights_from_top(h, 250.0), heights_from_top(off, 250.0)
    assert np.abs(a - b).max() < 1e-3
    assert ((a > 0) == cloth).all() and a[cloth].min() >= 1.0
    rows = np.flatnonzero(cloth.any(axis=1))
    band = a[rows[0] : rows[0] + 2][cloth[rows[0] : rows[0] + 2]]
    assert np.median(band) == pytest.approx(250.0, abs=1e-3)
    keep = cloth & (a > 1.0)  # above the 1 mm floor: differences are the registered ones
    diff = (a - h)[keep]
    assert diff.max() - diff.min() < 1e-3
    top = dataclasses.replace(plain, depth_top_mm=250.0)
    assert np.array_equal(registered_heights(d, top)[0], a)
    from lookfeel.data.images import PreprocessSettings

    assert PreprocessSettings.of(top).digest() != PreprocessSettings.of(plain).digest()
    assert np.array_equal(heights_from_top(np.zeros_like(h), 250.0), np.zeros_like(h))
    with pytest.raises(ConfigError, match="depth_top_mm: must be > 0"):
        dataclasses.replace(plain, depth_top_mm=0.0)


def test_drape_top_from_the_highest_row_ignores_a_cap_of_wall_pixels():
    """``data.depth_top_from``: on Kinect images a few rows where the drape's rim meets the
    wall often count as cloth, at heights well below the cloth over the post. The first rows'
    median reads that cap; the highest row median reads the cloth over the post, so heights
    measured from it do not move when a cap is there."""
    from lookfeel.config import DataConfig
    from lookfeel.data.images import PreprocessSettings
    from lookfeel.data.register import drape_top, heights_from_top, registered_heights

    d = BASE.render()["depth"]
    plain = DataConfig(depth_input="registered", depth_focal_px=BASE.f)
    h, _ = registered_heights(d, plain)
    cloth = h > 0
    rows = np.flatnonzero(cloth.any(axis=1))
    top_rows = drape_top(h, "first_rows")
    top_high = drape_top(h, "highest_row")
    assert top_rows is not None and top_high is not None
    # Without a cap both rules read the cloth over the post (within a few mm).
    assert abs(top_high - top_rows) < 0.05 * top_high
    capped = h.copy()
    cols = np.flatnonzero(cloth[rows[0]])
    cap = top_high - 50.0  # wall pixels mixed in: 50 mm below the cloth over the post
    band = max(2, round(4 * h.shape[0] / 224))
    capped[rows[0] - band : rows[0], cols[0] : cols[-1] + 1] = cap
    assert drape_top(capped, "first_rows") == pytest.approx(cap, abs=1e-3)
    assert drape_top(capped, "highest_row") == pytest.approx(top_high, abs=1e-3)
    a = heights_from_top(h, 300.0, "highest_row")
    b = heights_from_top(capped, 300.0, "highest_row")
    assert np.abs(a - b)[cloth].max() < 1e-3
    assert np.abs(heights_from_top(h, 300.0) - heights_from_top(capped, 300.0))[cloth].max() > 20
    assert drape_top(np.zeros_like(h), "highest_row") is None
    high = dataclasses.replace(plain, depth_top_mm=300.0, depth_top_from="highest_row")
    assert np.array_equal(registered_heights(d, high)[0], a)
    rows_cfg = dataclasses.replace(high, depth_top_from="first_rows")
    assert PreprocessSettings.of(high).digest() != PreprocessSettings.of(rows_cfg).digest()
    with pytest.raises(ValueError, match="unknown drape-top rule"):
        drape_top(h, "middle")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="depth_top_from"):
        dataclasses.replace(plain, depth_top_from="middle")


def test_cloth_top_drops_a_cap_of_wall_pixels_and_places_the_drape_by_its_cloth():
    """``data.depth_top_from: cloth_top``: a cap of the sensor's wall-and-cloth mix planted
    above the drape in the depth image itself (30 mm in front of the wall, so cloth by the
    15 mm margin) is dropped: the heights and the drape's top are those of the image without
    it. ``highest_row`` keeps the cap as cloth and places the drape by the cap's top."""
    from lookfeel.config import DataConfig
    from lookfeel.data.images import PreprocessSettings
    from lookfeel.data.register import register_depth, registered_heights, without_cap

    d = BASE.render()["depth"].astype(np.float64)
    cfg = DataConfig(
        depth_input="registered",
        depth_focal_px=BASE.f,
        depth_top_mm=300.0,
        depth_top_from="cloth_top",
    )
    h0, post0 = registered_heights(d, cfg)
    cloth = h0 > 0
    rows = np.flatnonzero(cloth.any(axis=1))
    cols = np.flatnonzero(cloth[rows[0] + 2])
    assert post0 is not None and rows[0] > 8
    room = register_depth(d, BASE.intrinsics).room
    capped = d.copy()
    n = max(2, round(6 * d.shape[0] / 224))  # 6 rows at 224 px, as on GelFabric
    cap = (slice(rows[0] - n, rows[0]), slice(cols[0], cols[-1] + 1))
    capped[cap] = room[cap] - 30.0
    h1, post1 = registered_heights(capped, cfg)
    # The room is fitted again on the capped image (RANSAC): the same to a hundredth of a
    # mm, and a pixel or so at the drape's foot may change sides of the margin.
    both = (h0 > 0) & (h1 > 0)
    assert (h1[cap] == 0).all() and ((h0 > 0) != (h1 > 0)).sum() <= 2
    assert np.abs(h1 - h0)[both].max() < 0.05
    assert post1 == pytest.approx(post0, abs=0.05)
    high = dataclasses.replace(cfg, depth_top_from="highest_row")
    h2, post2 = registered_heights(capped, high)
    assert (h2[cap] > 0).mean() > 0.5  # the cap stays cloth by the highest-row rule
    assert post2 is not None and post2[1] < post0[1] - n + 0.5  # and the drape is placed by it
    assert np.array_equal(without_cap(h0), h0)  # nothing to drop on a drape with no cap
    assert np.array_equal(without_cap(np.zeros_like(h0)), np.zeros_like(h0))
    assert PreprocessSettings.of(cfg).digest() != PreprocessSettings.of(high).digest()


# A drape hanging near the back wall: the top of its silhouette stands 15-35 mm in front of it.
NEAR_WALL = Scene(size=96, f=135.0, cloth_offset=(0.0, 520.0), spread_mm=150.0)


def test_drop_near_walls_drops_the_cloth_a_moved_wall_reaches():
    """`drop_near_walls` on a known answer: a wall whose gap grows 5 mm a column drops the
    columns its shifted (and tilted) plane passes, then only the largest piece is kept."""
    from lookfeel.data.register import drop_near_walls

    cloth = np.ones((1, 8, 8), bool)
    cloth[0, 0, 7] = False
    gaps = np.broadcast_to(np.arange(8, dtype=np.float32) * 5.0, (1, 1, 8, 8)).copy()
    no_move = drop_near_walls(cloth, gaps, np.zeros((1, 1, 3)), 20.0, 5.0)
    assert np.array_equal(no_move, cloth)
    shifted = drop_near_walls(cloth, gaps, np.array([[[0.5, 0.0, 0.0]]]), 20.0, 5.0)
    assert np.array_equal(shifted[0], cloth[0] & (np.arange(8) >= 2)[None, :])  # gap < 10 mm
    # Tilted along x by 5 mm at the edges (u = -7/8 .. 7/8): column 2 (gap 10, u = -3/8) now
    # stands in front of the moved wall (10 - 3/8 * 5 < 10), column 3 (15) still does.
    tilted = drop_near_walls(cloth, gaps, np.array([[[0.5, 0.0, 1.0]]]), 20.0, 5.0)
    assert np.array_equal(tilted[0], cloth[0] & (np.arange(8) >= 2)[None, :])
    tilted_back = drop_near_walls(cloth, gaps, np.array([[[0.5, 0.5, 1.0]]]), 20.0, 5.0)
    assert np.array_equal(tilted_back[0], cloth[0] & (np.arange(8) >= 3)[None, :])
    # A piece cut off from the drape by the dropped band goes too, as registration drops it.
    island = cloth.copy()
    island[0, :, 3] = False
    gaps2 = gaps.copy()
    gaps2[0, 0, :, :3] = 100.0  # columns 0-2 far from the wall: a piece left of the gap
    kept = drop_near_walls(island, gaps2, np.array([[[0.5, 0.0, 0.0]]]), 20.0, 5.0)
    assert np.array_equal(kept[0], island[0] & (np.arange(8) >= 4)[None, :])
    # A second wall (padding: no wall) changes nothing.
    padded = np.concatenate([gaps, np.full_like(gaps, 1e4)], axis=1)
    again = drop_near_walls(
        cloth, padded, np.array([[[0.5, 0.0, 0.0], [1.0, 0.0, 1.0]]]), 20.0, 5.0
    )
    assert np.array_equal(again, shifted)


def test_wall_gaps_of_a_drape_near_the_wall_through_the_loader_and_the_store(tmp_path, monkeypatch):
    """`data.depth_wall_drop`: the loader reads a drape's image and its gaps to the walls at the
    input's size (cached on disk under their own key; the image unchanged, registered once for
    both whichever is asked first); a training store holds the image alone as its row and
    drops the cloth near the walls in a drawn share of the images, each process's share as the
    whole batch's."""
    import torch

    from lookfeel.config import DataConfig
    from lookfeel.data.catalog import Item
    from lookfeel.data.images import WALL_GAP_NONE, ImageLoader, PreprocessSettings
    from lookfeel.data.register import register_configured, wall_gap_input, wall_gaps
    from lookfeel.data.tensors import ImageStore
    from lookfeel.modality import Modality

    depth = NEAR_WALL.render()["depth"]
    path = _write(tmp_path / "F0001_Depth_New_000000.png", depth)
    plain = DataConfig(
        image_size=32, depth_input="registered", depth_focal_px=NEAR_WALL.f,
        depth_post_at=(0.5, 0.1), cache_dir=str(tmp_path / "cache"),
    )  # fmt: skip
    config = dataclasses.replace(plain, depth_wall_drop=1.0)
    assert PreprocessSettings.of(config) == PreprocessSettings.of(plain)
    # At full size, unmoved, the gaps are registration's own: cloth where every gap is > 0.
    unmoved = dataclasses.replace(config, depth_post_at=None)
    heights, share, full = wall_gap_input(depth, unmoved)
    reg = register_configured(depth, unmoved)
    assert np.array_equal(share, (heights > 0).astype(np.float32))
    assert np.allclose(full, wall_gaps(depth, reg, unmoved) * share)
    assert (full.min(axis=0)[heights > 0] > 0).all()
    assert ((full.min(axis=0) < 20.0) & (heights > 0)).sum() > 30  # cloth near the wall

    item = Item(Modality.DEPTH, 1, (path,))
    loader = ImageLoader(config)
    assert loader.has_views(item) and not ImageLoader(plain).has_views(item)
    views = loader.views(item)
    assert views.shape[0] == 1 + len(full) and views.shape[1:] == (32, 32)
    image = ImageLoader(plain).array(path, Modality.DEPTH)
    assert np.array_equal(views[0], image)
    on = image > 0
    assert (views[1:, ~on] == WALL_GAP_NONE).all()
    assert (views[1:, on] > 0).all() and (views[1:, on] < 1000).all()
    assert len(list((tmp_path / "cache").rglob("*_wallgaps.npy"))) == 1
    assert np.array_equal(ImageLoader(config).views(item), views)  # read back from disk
    import lookfeel.data.register as register

    calls: list[int] = []
    registering = register.register_configured
    monkeypatch.setattr(
        register, "register_configured", lambda *a: calls.append(1) or registering(*a)
    )
    fresh = ImageLoader(dataclasses.replace(config, cache_dir=None))
    assert np.array_equal(fresh.array(path, Modality.DEPTH), image)  # training preloads it
    assert np.array_equal(fresh.views(item), views)  # then its store reads the gaps
    assert len(calls) == 1
    monkeypatch.undo()

    store = ImageStore(ImageLoader(config), [item], views=True)
    assert store.shape(Modality.DEPTH) == (1, 32, 32)
    rows = torch.tensor(store.rows(Modality.DEPTH, [item]) * 16)
    assert torch.equal(store.draw_views(Modality.DEPTH, rows, np.random.default_rng(0)), rows)
    x = store.batch(Modality.DEPTH, rows)
    whole = slice(0, 16)
    out = store.drop_walls(Modality.DEPTH, rows, x, np.random.default_rng(5), whole)
    kept = out[:, 0] > 0
    assert not (kept & (x[:, 0] == 0)).any()
    assert torch.equal(out[:, 0][kept], x[:, 0][kept])  # the cloth left keeps its heights
    gone = (x[:, 0] > 0) & ~kept
    assert 0 < int(gone.sum()) < int((x[:, 0] > 0).sum()) // 2
    assert len({tuple(g.flatten().tolist()) for g in gone}) > 4  # a new draw per image
    nearest = torch.from_numpy(views[1:].min(axis=0))
    assert (nearest.expand_as(gone)[gone] <= 20.0 + 5.0 * np.sqrt(2)).all()
    halves = [
        store.drop_walls(Modality.DEPTH, rows, x[s], np.random.default_rng(5), s)
        for s in (slice(0, 7), slice(7, 16))
    ]
    assert torch.equal(torch.cat(halves), out)  # processes draw alike
    rarely = ImageStore(ImageLoader(dataclasses.replace(config, depth_wall_drop=0.25)), [item],
                        views=True)  # fmt: skip
    some = rarely.drop_walls(Modality.DEPTH, rows, x, np.random.default_rng(5), whole)
    untouched = (some == x).flatten(1).all(dim=1)
    assert 0 < int(untouched.sum()) < 16
    evaluation = ImageStore(ImageLoader(config), [item])
    assert evaluation.drop_walls(Modality.DEPTH, rows, x, np.random.default_rng(5), whole) is x


def test_wall_drop_needs_registered_depth():
    from lookfeel.config import ConfigError, DataConfig

    with pytest.raises(ConfigError, match="data.depth_wall_drop: drops cloth near the fitted"):
        DataConfig(depth_wall_drop=1.0)
    with pytest.raises(ConfigError, match=r"data.depth_wall_drop: must be in \[0, 1\]"):
        DataConfig(depth_input="registered", depth_wall_drop=2.0)
    with pytest.raises(ConfigError, match="data.depth_wall_shift_mm must be > 0"):
        DataConfig(depth_input="registered", depth_wall_shift_mm=0.0)


def test_wall_band_drops_the_cloth_near_the_walls_before_the_drape_is_kept():
    """``data.depth_wall_band_mm``: registration records each pixel's clearance from the walls
    (not the floor); the band keeps only the cloth more than the margin plus the band in front
    of them, before the drape's piece, top and heights are taken, in the training input and
    in the room control alike. The cache key follows it; 0 is the input as before."""
    from lookfeel.config import DataConfig
    from lookfeel.data.images import PreprocessSettings
    from lookfeel.data.register import (
        kept_heights,
        placed_heights,
        register_configured,
        registered_input,
        wall_gaps,
    )

    depth = NEAR_WALL.render()["depth"]
    plain = DataConfig(
        image_size=32, depth_input="registered", depth_focal_px=NEAR_WALL.f,
        depth_top_mm=300.0, depth_top_from="cloth_top",
    )  # fmt: skip
    reg = register_configured(depth, plain)
    walls = wall_gaps(depth, reg, plain).min(axis=0) + plain.depth_margin_mm
    assert reg.wall_clearance is not None
    np.testing.assert_allclose(reg.wall_clearance, walls, rtol=1e-5, atol=1e-3)
    assert (reg.wall_clearance[reg.cloth] > plain.depth_margin_mm).all()

    before = registered_input(depth, plain)
    assert np.array_equal(registered_input(depth, dataclasses.replace(plain)), before)
    cloth = before > 0
    for band in (10.0, 25.0):
        banded = dataclasses.replace(plain, depth_wall_band_mm=band)
        kept = kept_heights(reg, banded) > 0
        assert 0 < kept.sum() < cloth.sum()
        assert (reg.wall_clearance[kept] > plain.depth_margin_mm + band).all()
        # What is dropped is the cloth within the band (the drape's piece aside).
        near = cloth & (reg.wall_clearance <= plain.depth_margin_mm + band)
        assert near.any() and not (kept & near).any()
        # The heights are measured from the top of the cloth left: this drape's top stands
        # 15-35 mm in front of the wall, so a 25 mm band lowers it and the cloth kept is
        # re-measured from there (every pixel by one level), a 10 mm band leaves it.
        shift = kept_heights(reg, banded)[kept] - kept_heights(reg, plain)[kept]
        assert np.ptp(shift) < 1e-3
        assert float(shift[0]) == (pytest.approx(4.47, abs=0.05) if band == 25.0 else 0.0)
        assert np.array_equal(placed_heights(reg, banded), registered_input(depth, banded))
        assert PreprocessSettings.of(banded) != PreprocessSettings.of(plain)
        # The image a training draw of depth_wall_drop drops from keeps the band's cloth.
        assert (kept_heights(reg, banded, band=False) > 0).sum() == cloth.sum()
    wider = kept_heights(reg, dataclasses.replace(plain, depth_wall_band_mm=25.0)) > 0
    narrower = kept_heights(reg, dataclasses.replace(plain, depth_wall_band_mm=10.0)) > 0
    assert wider.sum() < narrower.sum()

    with pytest.raises(ConfigError, match="data.depth_wall_band_mm: must be >= 0"):
        DataConfig(depth_input="registered", depth_wall_band_mm=-1.0)
    with pytest.raises(ConfigError, match="data.depth_wall_band_mm: drops cloth near the"):
        DataConfig(depth_wall_band_mm=10.0)


def test_wall_band_through_the_loader_and_the_store(tmp_path):
    """With ``depth_wall_drop`` and a band, the loader's image (evaluation's) is the banded
    input and its training views start from the unbanded one; a store drops near randomly
    moved walls in the draws ``depth_wall_drop`` takes and the band (walls moved that far, no
    tilt) in the others, which without a band it leaves alone."""
    import torch

    from lookfeel.config import DataConfig
    from lookfeel.data.catalog import Item
    from lookfeel.data.images import ImageLoader
    from lookfeel.data.tensors import ImageStore
    from lookfeel.modality import Modality

    depth = NEAR_WALL.render()["depth"]
    path = _write(tmp_path / "F0001_Depth_New_000000.png", depth)
    plain = DataConfig(
        image_size=32, depth_input="registered", depth_focal_px=NEAR_WALL.f,
        depth_post_at=(0.5, 0.1), depth_wall_drop=0.25,
    )  # fmt: skip
    band = dataclasses.replace(plain, depth_wall_band_mm=15.0)
    item = Item(Modality.DEPTH, 1, (path,))
    unbanded = ImageLoader(plain).array(path, Modality.DEPTH)
    loader = ImageLoader(band)
    image = loader.array(path, Modality.DEPTH)
    views = loader.views(item)
    assert np.array_equal(views[0], unbanded)  # a training draw starts from all the cloth
    assert 0 < (image > 0).sum() < (unbanded > 0).sum()
    assert np.array_equal(ImageLoader(band).array(path, Modality.DEPTH), image)  # views first

    rows = torch.tensor(ImageStore(loader, [item], views=True).rows(Modality.DEPTH, [item]) * 32)
    whole = slice(0, 32)
    gaps = torch.from_numpy(views[1:].min(axis=0))
    rarely = 1e-9  # (nearly) no draw taken by depth_wall_drop
    for cfg in (plain, band):
        store = ImageStore(ImageLoader(dataclasses.replace(cfg, depth_wall_drop=rarely)),
                           [item], views=True)  # fmt: skip
        x = store.batch(Modality.DEPTH, rows)
        out = store.drop_walls(Modality.DEPTH, rows, x, np.random.default_rng(3), whole)
        within = (x[:, 0] > 0) & (gaps < 15.0)  # the cloth the band drops (gaps past the margin)
        assert bool(within.any())
        if cfg is plain:  # left alone
            assert torch.equal(out, x)
        else:  # every draw without its band's cloth, and nothing else lost but stray pieces
            kept = out[:, 0] > 0
            assert not bool(kept[within].any())
            assert int(((x[:, 0] > 0) & ~within & ~kept).sum()) < int(within.sum())
