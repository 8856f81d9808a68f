"""specholo: exact specular holograms from 3D models, verified by simulation.

The library works in millimetres and radians in the plate frame: x right, y up,
z out of the reflective face toward the viewer; a flat plate is z = 0.
"""

from specholo.errors import SpecholoError
from specholo.setup import Light, Machining, Setup, Tool, Viewer

__version__ = "0.1.0"

__all__ = ["Light", "Machining", "Setup", "SpecholoError", "Tool", "Viewer", "__version__"]
