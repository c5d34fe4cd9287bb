"""The synthetic fabric world: fabrics with known physics, rendered as the paper's three
modalities (Kinect depth and colour photos of drapes over a post, GelSight presses flat and on a
fold) into the one dataset layout.

    >>> from lookfeel.synth import SynthConfig, generate
    >>> summary = generate(SynthConfig(fabrics=30), Path("out/world"))

Modules, one job each: `fabric` (parameters and labels), `drape` (shape over the post),
`scene` (room and cameras), `depth`, `color`, `gelsight` (renderers), `measure` (physics read
back from pixels), `world` (writing a world: `generate`), `contact_sheet`.
"""

from lookfeel.synth.config import SIZE_PRESETS, SynthConfig, SynthSummary
from lookfeel.synth.fabric import Fabric
from lookfeel.synth.world import MANIFEST, generate

__all__ = ["MANIFEST", "SIZE_PRESETS", "Fabric", "SynthConfig", "SynthSummary", "generate"]
