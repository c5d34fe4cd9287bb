"""Fidelity of the synthetic GelSight presses (issue #17 point 4): synthetic flat presses of six
fabrics beside the real GelSight Mini presses of the same kinds of fabric
(``shared/reference/gelsight``: bath towel, blanket, carpet, denim, microfibre cloth, nylon
shirt), measured the same way on both.

Each press is measured against its own sensor's no-contact frame (the two sensors differ in
lights, markers and lens, so raw pixels are not comparable; what the contact changes is):

- ``change``: mean absolute colour change over the frame (grey levels, summed over RGB);
- ``contact``: share of the frame whose (lightly smoothed) change exceeds 10 grey levels;
- ``texture``: fine structure of the change (`lookfeel.synth.measure.touch_texture`),
  divided by the same measure of the sensor's own noise (how far above its floor it stands).

The synthetic fabric for each real one is drawn with its physics and material set by hand
(thickness, density and stiffness as such a fabric has; its material and weave), pressed flat
at its peak force. The output is the table and ``docs/images/synth_touch_vs_real.png``.

    python -m benchmarks --only synth_touch_fidelity
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image
from scipy import ndimage, stats

from lookfeel.modality import PressKind
from lookfeel.synth.fabric import make_fabric
from lookfeel.synth.gelsight import no_contact_frame, render_press, sensor
from lookfeel.synth.measure import touch_texture

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "gelsight"
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "images" / "synth_touch_vs_real.png"
PRESSES = 6

# Real reference -> (thickness mm, density (100 g/m^2), stiffness rating, material, weave).
FABRICS: dict[str, tuple[float, float, float, str, str]] = {
    "bath_towel_2": (5.0, 4.5, 2.5, "cotton", "pile"),
    "blanket_0": (6.0, 3.0, 2.0, "fleece", "pile"),
    "carpet_1": (9.0, 12.0, 4.5, "synthetic", "pile"),
    "denim_2": (1.0, 3.7, 4.0, "cotton", "twill"),
    "microfiber_cloth_0": (2.0, 3.0, 2.0, "synthetic", "pile"),
    "nylon_shirt_0": (0.3, 0.8, 1.5, "synthetic", "plain"),
}


def measure(press: NDArray[np.uint8], rest: NDArray[np.uint8]) -> dict[str, float]:
    """``change``, ``contact`` and ``texture`` of a press against its no-contact frame."""
    diff = np.abs(press.astype(np.float32) - rest.astype(np.float32)).sum(-1)
    smooth = ndimage.gaussian_filter(diff, 1.5)
    noise = rest.astype(np.float32) + np.random.default_rng(0).normal(0.0, 1.0, rest.shape)
    tex_floor = touch_texture(np.clip(np.rint(noise), 0, 255).astype(np.uint8), rest)
    return {
        "change": round(float(diff.mean()), 2),
        "contact": round(float((smooth > 10.0).mean()), 3),
        "texture": round(touch_texture(press, rest) / max(tex_floor, 1e-3), 2),
    }


def _synthetic(name: str) -> tuple[list[NDArray[np.uint8]], NDArray[np.uint8]]:
    t, d, s, material, weave = FABRICS[name]
    fabric = make_fabric(1, t, d, s, 0.0, seed=0, material=material, weave=weave)
    sen = sensor(320, 240)
    frames = [
        render_press(fabric, PressKind.FLAT, sen, np.random.default_rng([17, i]), 3)[-1]
        for i in range(PRESSES)
    ]
    return frames, no_contact_frame(sen)


def _figure(rows: list[tuple[str, NDArray[np.uint8], NDArray[np.uint8]]]) -> Path:
    from lookfeel.plots import save_figure
    from lookfeel.plots._figure import new_figure

    fig = new_figure(4.2, 1.62 * len(rows))
    fig.subplots_adjust(left=0.02, right=0.98, top=0.97, bottom=0.01, wspace=0.06, hspace=0.3)
    for i, (name, real, synth) in enumerate(rows):
        for j, (img, what) in enumerate(((real, "real GelSight Mini"), (synth, "synthetic"))):
            ax = fig.add_subplot(len(rows), 2, 2 * i + j + 1)
            ax.imshow(img)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{name.rsplit('_', 1)[0].replace('_', ' ')}: {what}", fontsize=7)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, FIGURE)


def run(data: Path | None) -> dict[str, Any]:
    if not REFERENCE.is_dir():
        return {"skipped": f"reference GelSight frames not found at {REFERENCE}"}
    rows, table = [], {}
    for name in FABRICS:
        rest = np.asarray(Image.open(REFERENCE / f"mini_{name}_nocontact.png").convert("RGB"))
        press = np.asarray(Image.open(REFERENCE / f"mini_{name}_press.png").convert("RGB"))
        frames, synth_rest = _synthetic(name)
        synth = [measure(f, synth_rest) for f in frames]
        table[name] = {
            "real": measure(press, rest),
            "synthetic": {k: round(float(np.median([m[k] for m in synth])), 3) for k in synth[0]},
        }
        rows.append((name, press, frames[0]))
    keys = ("change", "contact", "texture")
    rho = {
        k: round(
            float(
                stats.spearmanr(
                    [table[n]["real"][k] for n in FABRICS],
                    [table[n]["synthetic"][k] for n in FABRICS],
                )[0]
            ),
            3,
        )
        for k in keys
    }
    figure = _figure(rows)
    return {
        "what": "synthetic flat presses beside real GelSight Mini presses of the same kinds of "
        "fabric, each measured against its own sensor's no-contact frame",
        "fabrics": table,
        "spearman_real_vs_synthetic": rho,
        "figure": str(figure.relative_to(FIGURE.parents[2])),
        "note": "a measured comparison, not a target: the sensors differ (the synthetic one is "
        "GelFabric's kind, with markers; the reference presses are a GelSight Mini's)",
    }
