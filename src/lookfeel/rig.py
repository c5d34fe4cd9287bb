"""GelFabric's depth camera: the crop's size, focal length and principal point.

Depth registration (`lookfeel.data.register`) reads real drapes with them, and the synthetic
world's camera (`lookfeel.synth.scene`) renders with them. They live here, apart from both,
so that the world's rendering processes import neither torch nor the data layer: a process
that renders fabrics starts in a fraction of the time, and many of them fit in less memory.
"""

from __future__ import annotations

__all__ = ["GELFABRIC_CENTRE", "GELFABRIC_FOCAL", "GELFABRIC_SIZE"]

GELFABRIC_SIZE = 224
"""Side in pixels of GelFabric's cropped Kinect depth images."""
GELFABRIC_FOCAL = 373.0
"""Focal length in pixels of that crop (the synthetic world's camera uses it too)."""
GELFABRIC_CENTRE = 111.5
"""Principal point (both axes) in pixels of that crop."""
