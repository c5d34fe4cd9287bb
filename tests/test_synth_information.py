"""The world's information table (`lookfeel.synth.information`): features from pixels, probes
that recover planted latents and nothing else, fabric-disjoint folds, matching from the probes,
and the command line's one-line errors."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from threadpoolctl import threadpool_limits

from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate
from lookfeel.synth import information as info

FOLDS = 3
N_FABRICS = 45  # 15 per fold: 9 others to pick among, chance 0.1
PER = 3  # images per fabric per stream


def _truth(rng: np.random.Generator, n: int) -> list[dict[str, Any]]:
    weaves = ["plain", "twill", "satin"]
    materials = ["cotton", "wool", "silk"]
    out = []
    for f in range(1, n + 1):
        out.append(
            {
                "fabric_id": f,
                "thickness_mm": float(np.exp(rng.uniform(-1.0, 1.5))),
                "density": float(np.exp(rng.uniform(-1.0, 1.0))),
                "stiffness": float(rng.uniform(0, 5)),
                "stretchiness": float(rng.choice([0.0, 0.5, 1.0])),
                "bending_length_mm": float(np.exp(rng.uniform(2, 3))),
                "weave": weaves[int(rng.integers(0, 3))],
                "material": materials[(f - 1) % 3],
            }
        )
    return out


def _image(
    rng: np.random.Generator, level: float, size: int, fingerprint: np.ndarray
) -> np.ndarray:
    """Noise texture plus a uniform ``level`` plus the fabric's fixed ``fingerprint``."""
    return level + 8.0 * rng.standard_normal((size, size)) + fingerprint


def write_fake_world(root: Path, n: int = N_FABRICS, status: str = "complete") -> Path:
    """A hand-made world whose pixels encode known things:

    - depth and colour brightness: the fabric's log thickness (a shared planted latent);
    - colour's red channel: its material (a planted class);
    - touch brightness: the log thickness of *another* fabric (shuffled: no shared latent);
    - touch: also a fixed random pattern per fabric (a fingerprint a leaky probe would
      memorise to predict the unplanted density);
    - density, stiffness, stretchiness, bending length and weave: not in the pixels at all.
    """
    rng = np.random.default_rng(7)
    fabrics = _truth(rng, n)
    shuffled = rng.permutation(n)
    for sub in ("depth", "color", "touch"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    for i, f in enumerate(fabrics):
        fid = f["fabric_id"]
        z = math.log(f["thickness_mm"])
        z_other = math.log(fabrics[int(shuffled[i])]["thickness_mm"])
        mat = ["cotton", "wool", "silk"].index(f["material"])
        none = np.zeros((32, 32))
        finger = 40.0 * np.random.default_rng([99, fid]).standard_normal((32, 32))
        for k in range(PER):
            d = _image(rng, 1000.0 + 120.0 * z, 32, none)
            d[0, :2] = 0  # holes
            Image.fromarray(np.clip(d, 0, 65535).astype(np.uint16)).save(
                root / "depth" / f"F{fid:04d}_Depth_Synth_{k + 1:02d}.png"
            )
            g = _image(rng, 110.0 + 40.0 * z, 32, none)
            rgb = np.stack([g + 30.0 * mat, g, g], axis=2)
            Image.fromarray(np.clip(rgb, 0, 255).astype(np.uint8)).save(
                root / "color" / f"F{fid:04d}_{k + 1}.png"
            )
            for kind, base in (("flat", 1001), ("fold", 2001)):
                t = _image(rng, 110.0 + 40.0 * z_other, 32, finger)
                Image.fromarray(np.clip(np.stack([t] * 3, axis=2), 0, 255).astype(np.uint8)).save(
                    root / "touch" / f"F{fid:04d}_{kind}_02_{base + k}.png"
                )
    manifest = {"generator": "lookfeel.synth", "status": status, "fabrics": fabrics}
    (root / "synth.json").write_text(json.dumps(manifest), encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def fake_world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_fake_world(tmp_path_factory.mktemp("info") / "fake")


@pytest.fixture(scope="module")
def fake_table(fake_world: Path) -> dict[str, Any]:
    return info.information_table(fake_world, folds=FOLDS, seed=0, workers=1)


# ---- features -----------------------------------------------------------------------------


def test_features_have_a_fixed_documented_length_and_are_finite() -> None:
    rng = np.random.default_rng(0)
    for modality, shapes in (
        ("depth", [(40, 40), (112, 112)]),
        ("color", [(40, 40, 3), (128, 128, 3)]),
        ("touch", [(30, 40, 3), (120, 160, 3)]),
    ):
        lengths = set()
        for shape in shapes:
            img = rng.uniform(1, 255, shape).astype(np.float32)
            v = info.image_features(img, modality)
            assert np.isfinite(v).all()
            lengths.add(len(v))
        assert lengths == {len(info.feature_names(modality))}
    holes = np.zeros((40, 40), np.float32)
    holes[10:20, 10:20] = 900.0
    v = info.image_features(holes, "depth")
    thumb = v[: info.THUMB**2]
    assert np.isfinite(v).all() and thumb.min() == pytest.approx(900.0)  # holes filled


def test_features_are_rotation_invariant_statistics_beside_the_thumbnail() -> None:
    rng = np.random.default_rng(1)
    img = rng.uniform(0, 255, (64, 64, 3)).astype(np.float32)
    a = info.image_features(img, "color")
    b = info.image_features(np.rot90(img).copy(), "color")
    n_thumb = 3 * info.THUMB**2
    np.testing.assert_allclose(a[n_thumb:], b[n_thumb:], rtol=1e-4, atol=1e-3)


def test_reading_decodes_small(tmp_path: Path) -> None:
    # (The features' cost is measured in benchmarks/bench_synth_information.py, not here.)
    rng = np.random.default_rng(2)
    p = tmp_path / "F0001_flat_02_1001.jpg"
    Image.fromarray(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)).save(p, quality=90)
    img = info.read_image(p, "touch")
    assert img.shape == (120, 160, 3)  # JPEG draft at 1/2 keeps the short side >= 96
    d = tmp_path / "F0001_Depth_Synth_01.png"
    depth = (900 + rng.integers(0, 50, (224, 224))).astype(np.uint16)
    depth[:5, :5] = 0
    Image.fromarray(depth).save(d)
    dd = info.read_image(d, "depth")
    assert dd.shape == (112, 112) and dd[:2, :2].max() == 0 and dd[3:, 3:].min() >= 900
    assert info.file_features(p, "touch").shape == (len(info.feature_names("touch")),)


# ---- probes -------------------------------------------------------------------------------


def test_probe_recovers_a_planted_latent_and_not_an_unplanted_one(
    fake_table: dict[str, Any],
) -> None:
    probe = fake_table["probe"]
    for stream in ("depth", "color"):
        assert probe[stream]["log_thickness_mm"]["r2_fabric"] > 0.8
        assert probe[stream]["log_thickness_mm"]["r2_image"] > 0.7
        for unplanted in ("log_density", "stiffness", "log_bending_length_mm"):
            assert -0.35 < probe[stream][unplanted]["r2_fabric"] < 0.2, (stream, unplanted)
    # Touch carries a shuffled copy: nothing about its own fabric's thickness.
    assert probe["touch"]["log_thickness_mm"]["r2_fabric"] < 0.2
    # Material is planted in colour only; weave nowhere.
    assert probe["color"]["material"]["acc_fabric"] > 0.9
    assert probe["depth"]["material"]["acc_fabric"] < 0.6
    assert probe["color"]["weave"]["acc_fabric"] < 0.6
    assert probe["color"]["material"]["majority_fabric"] == pytest.approx(1 / 3, abs=0.01)


def test_folds_are_fabric_disjoint_and_nothing_is_fitted_on_held_out_fabrics(
    fake_world: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: list[set[int]] = []
    real_ridge, real_logistic = info._fit_ridge, info._fit_logistic

    def ridge(x: np.ndarray, y: np.ndarray, groups: np.ndarray) -> Any:
        seen.append(set(groups.tolist()))
        return real_ridge(x, y, groups)

    def logistic(x: np.ndarray, labels: np.ndarray, n: int, groups: np.ndarray) -> Any:
        seen.append(set(groups.tolist()))
        return real_logistic(x, labels, n, groups)

    monkeypatch.setattr(info, "_fit_ridge", ridge)
    monkeypatch.setattr(info, "_fit_logistic", logistic)
    fabrics, images = info.read_world(fake_world)
    lat = info._latents(fabrics)
    fold_of = info.fabric_folds(lat.ids, FOLDS, seed=0)
    ims = [im for im in images if im.modality == "depth"]
    x = info.extract_features(ims, workers=1)["depth"].astype(np.float64)
    fab = np.array([im.fabric for im in ims])
    with threadpool_limits(limits=1):
        info._probe_stream(x, fab, [im.group for im in ims], lat, fold_of, FOLDS)
    assert len(seen) == FOLDS * (1 + len(lat.classes))
    folds = [{f for f, k in fold_of.items() if k == j} for j in range(FOLDS)]
    for fitted in seen:
        held = [j for j in range(FOLDS) if not (folds[j] & fitted)]
        assert len(held) == 1  # exactly one fold unseen ...
        assert fitted == set(fold_of) - folds[held[0]]  # ... and all the others seen


def test_a_leaky_probe_would_memorise_fingerprints_the_honest_one_does_not(
    fake_world: Path, fake_table: dict[str, Any]
) -> None:
    # Touch images carry a per-fabric fingerprint but no density: fitted on all fabrics (as a
    # leaky split would), the probe "predicts" density; held out, it cannot.
    fabrics, images = info.read_world(fake_world)
    ims = [im for im in images if im.modality == "touch"]
    x = info.extract_features(ims, workers=1)["touch"].astype(np.float64)
    fab = np.array([im.fabric for im in ims])
    y = np.log([{f["fabric_id"]: f["density"] for f in fabrics}[i] for i in fab])[:, None]
    with threadpool_limits(limits=1):
        reducer = info._Reducer(x)
        z = reducer(x)
        alphas = info._RIDGE_ALPHAS[:1] * len(z)
        w, xm, ym = info._ridge_path(z, y, alphas)
    leaky = (z - xm) @ w[0] + ym
    assert 1 - ((leaky - y) ** 2).sum() / ((y - y.mean()) ** 2).sum() > 0.8
    assert fake_table["probe"]["touch"]["log_density"]["r2_fabric"] < 0.2


# ---- matching -----------------------------------------------------------------------------


def test_matching_finds_a_shared_planted_latent_and_not_a_shuffled_one(
    fake_table: dict[str, Any],
) -> None:
    m = fake_table["matching"]
    assert set(m) == {f"{a}->{b}" for a in info.MODALITIES for b in info.MODALITIES}
    for pair in ("depth->color", "color->depth", "depth->depth", "color->color"):
        assert m[pair]["chance"] == pytest.approx(0.1)
        assert m[pair]["top1"] > 0.35, pair
        lo, hi = m[pair]["ci95"]
        assert lo <= m[pair]["top1"] <= hi and lo > 0.1
    for pair in ("depth->touch", "touch->depth", "color->touch", "touch->color"):
        assert m[pair]["top1"] < 0.3 and m[pair]["ci95"][0] < 0.12, pair  # about chance
    assert m["depth->depth"]["queries"] == N_FABRICS * PER


def test_within_modality_matching_leaves_the_query_out(tmp_path: Path) -> None:
    # One image per fabric: with the query left out, its fabric has nothing left to match.
    fabrics = [{"fabric_id": f, "thickness_mm": float(f)} for f in range(1, 7)]
    p = info._StreamPredictions(
        fabric=np.arange(1, 7),
        group=[f"d{i}" for i in range(6)],
        continuous=np.arange(6, dtype=float)[:, None],
        probs={},
        vector=np.arange(6, dtype=float)[:, None],
    )
    fold_of = dict.fromkeys(range(1, 7), 0)
    assert info._match(p, p, fold_of, True, 0, 1)["queries"] == 0
    assert info._match(p, p, fold_of, False, 0, 1)["top1"] == 1.0
    assert len(fabrics) == 6


# ---- the table on a generated world ---------------------------------------------------------


def test_table_on_a_tiny_generated_world_is_complete_json_and_deterministic(
    tmp_path: Path,
) -> None:
    cfg = SynthConfig(
        fabrics=8,
        drapes=2,
        presses_flat=1,
        presses_fold=2,
        frames=2,
        workers=1,
        contact_sheet=False,
        **SIZE_PRESETS["tiny"],
    )
    world = tmp_path / "world"
    generate(cfg, world, progress=False)
    a = info.information_table(world, folds=2, seed=3, workers=1, max_images_per_fabric=2)
    b = info.information_table(world, folds=2, seed=3, workers=1, max_images_per_fabric=2)
    a.pop("seconds"), b.pop("seconds")
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    assert list(a["probe"]) == list(info.STREAMS)
    assert a["images"] == {
        "depth": 16,
        "color": 16,
        "touch": 32,
        "touch_flat": 16,
        "touch_fold": 16,
    }
    truth = json.loads((world / "synth.json").read_text(encoding="utf-8"))["fabrics"][0]
    assert a["latents"]["continuous"] == list(info.CONTINUOUS_LATENTS)
    assert ("material" in a["latents"]["classes"]) == ("material" in truth)
    assert "weave" in a["latents"]["classes"]
    text = info.format_information_table({**a, "seconds": {}})
    assert "| log_thickness_mm R² |" in text and "| touch |" in text and "touch-fold" in text


# ---- command line -------------------------------------------------------------------------


@pytest.mark.parametrize("case", ["missing", "no_manifest", "running", "file"])
def test_cli_bad_world_is_one_line_naming_the_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    world = tmp_path / "w"
    if case == "no_manifest":
        world.mkdir()
    elif case == "running":
        write_fake_world(world, n=4, status="running")
    elif case == "file":
        world.write_text("x", encoding="utf-8")
    assert info.main([str(world)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(world) in err and "Traceback" not in err


def test_cli_runs_as_a_module_and_fails_cleanly(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere"
    r = subprocess.run(
        [sys.executable, "-m", "lookfeel.synth.information", str(missing)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and str(missing) in r.stderr
