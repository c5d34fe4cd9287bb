"""A known-answer depth scene for registration tests: a drape over a post in a box-shaped room.

World frame (mm): floor ``z = 0``, back wall ``y = wall_y``, side panel ``x = panel_x``; the
cloth is a height field over the floor, a smooth mound ``peak_mm`` high around the post at the
origin. A pinhole camera at ``eye`` looks at ``target``. Rendering ray-marches the height field
and intersects the planes, so depth, room and cloth are exact (then noised and rounded to mm
like a Kinect's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lookfeel.data.register import Intrinsics


@dataclass(frozen=True)
class Scene:
    size: int = 64
    f: float = 90.0
    eye: tuple[float, float, float] = (0.0, -700.0, 560.0)
    target: tuple[float, float, float] = (0.0, 300.0, 80.0)
    roll_deg: float = 0.0
    wall_y: float = 550.0
    panel_x: float = 450.0
    peak_mm: float = 300.0
    spread_mm: float = 110.0
    cloth_offset: tuple[float, float] = (0.0, 0.0)
    noise_mm: float = 1.0
    seed: int = 0

    @property
    def intrinsics(self) -> Intrinsics:
        c = (self.size - 1) / 2.0
        return Intrinsics(self.f, c, c)

    def rotation(self) -> np.ndarray:
        """(3, 3) world -> camera rotation: rows are the camera's x (right), y (down), z."""
        fwd = np.subtract(self.target, self.eye).astype(np.float64)
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        t = np.radians(self.roll_deg)
        r2 = np.cos(t) * right + np.sin(t) * down
        d2 = -np.sin(t) * right + np.cos(t) * down
        return np.stack([r2, d2, fwd])

    def planes(self) -> dict[str, tuple[np.ndarray, float]]:
        """True room planes in the camera frame: label -> (unit normal, distance), n.X = d."""
        rot, eye = self.rotation(), np.asarray(self.eye)
        world = {
            "floor": (np.array([0.0, 0.0, -1.0]), 0.0),
            "wall": (np.array([0.0, 1.0, 0.0]), self.wall_y),
            "side": (np.array([1.0, 0.0, 0.0]), self.panel_x),
        }
        return {k: (rot @ n, d - n @ eye) for k, (n, d) in world.items()}

    def _height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        ox, oy = self.cloth_offset
        r2 = (x - ox) ** 2 + (y - oy) ** 2
        return self.peak_mm * np.exp(-r2 / (2.0 * self.spread_mm**2))

    def render(self) -> dict[str, np.ndarray]:
        """``depth`` (uint16 mm, noised), ``room`` and ``clean`` (float mm), ``clearance``."""
        n = self.size
        k = self.intrinsics
        v, u = np.mgrid[0:n, 0:n].astype(np.float64)
        rays = np.stack([(u - k.cx) / k.f, (v - k.cy) / k.f, np.ones_like(u)], -1)
        rot, eye = self.rotation(), np.asarray(self.eye, dtype=np.float64)
        dirs = rays @ rot  # camera z = 1 along each ray, so t is the depth
        ts = []
        for axis, level in ((2, 0.0), (1, self.wall_y), (0, self.panel_x)):
            dc = dirs[..., axis]
            t = (level - eye[axis]) / np.where(np.abs(dc) > 1e-9, dc, 1e-9)
            ts.append(np.where(t > 0, t, np.inf))
        room = np.min(ts, axis=0)
        # March along each ray to the first point under the height field, then bisect.
        lo = np.full((n, n), 50.0)
        hit = room.copy()
        steps = np.linspace(50.0, room.max(), 300)
        found = np.zeros((n, n), bool)
        for t in steps:
            p = eye + dirs * t
            inside = (p[..., 2] <= self._height(p[..., 0], p[..., 1])) & (t < room)
            new = inside & ~found
            hit = np.where(new, t, hit)
            found |= new
            lo = np.where(~found, t, lo)
        a, b = lo, np.where(found, hit, room)
        for _ in range(30):
            mid = 0.5 * (a + b)
            p = eye + dirs * mid[..., None]
            inside = p[..., 2] <= self._height(p[..., 0], p[..., 1])
            b = np.where(found & inside, mid, b)
            a = np.where(found & ~inside, mid, a)
        clean = np.where(found, b, room)
        pts = eye + dirs * clean[..., None]
        # Distance of the seen point in front of the nearest room plane (the true clearance).
        gaps = np.stack([pts[..., 2], self.wall_y - pts[..., 1], self.panel_x - pts[..., 0]])
        rng = np.random.default_rng(self.seed)
        noisy = clean + rng.normal(0.0, self.noise_mm, clean.shape)
        return {
            "depth": np.clip(np.rint(noisy), 1, 65535).astype(np.uint16),
            "clean": clean,
            "room": room,
            "clearance": gaps.min(axis=0),
            "height": pts[..., 2],
        }


def write_scene_dataset(
    root,
    fabrics: int = 6,
    drapes: int = 3,
    size: int = 48,
    shift_mm: float = 8.0,
    vary: float = 1.0,
):
    """A depth dataset of rendered drapes with a planted capture-session leak.

    Each fabric is its own session: its room (wall, side panel) and camera sit ``shift_mm``
    (times a few) differently from the next fabric's, as GelFabric's do by a few millimetres;
    with ``shift_mm=0`` every session shares one room. The cloth (height, spread, place) is
    drawn per drape (``vary`` scales how much drapes differ), independent of the fabric, so
    only the room tells fabrics apart. Writes ``depth/F{id}_Depth_New_*.png``
    and ``labels.csv``; returns ``root``.
    """
    from pathlib import Path

    from PIL import Image

    root = Path(root)
    (root / "depth").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    lines = ["fabric_id,cluster8,thickness_mm,density,stiffness,stretchiness,paper_split\n"]
    for f in range(1, fabrics + 1):
        shift = shift_mm * (f - (fabrics + 1) / 2)
        for k in range(drapes):
            scene = Scene(
                size=size,
                f=90.0 * size / 64,
                eye=(0.5 * shift, -700.0 + shift, 560.0),
                wall_y=550.0 + 1.5 * shift,
                panel_x=330.0 - shift,
                peak_mm=260.0 + vary * float(rng.uniform(-60.0, 60.0)),
                spread_mm=90.0 + vary * float(rng.uniform(-20.0, 20.0)),
                cloth_offset=(
                    vary * float(rng.uniform(-60, 60)),
                    vary * float(rng.uniform(-60, 60)),
                ),
                seed=100 * f + k,
            )
            name = f"F{f:04d}_Depth_New_{k:06d}.png"
            Image.fromarray(scene.render()["depth"]).save(root / "depth" / name)
        lines.append(f"{f},{(f - 1) % 3},{0.5 * f},{0.2 * f:.2f},{f % 5},{f % 2},train\n")
    (root / "labels.csv").write_text("".join(lines), encoding="utf-8")
    return root
