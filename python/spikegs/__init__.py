"""SpikeGS: 3D Gaussian Splatting trained from spike-camera streams."""

from .rasterize import RasterizeResult, rasterize

__all__ = ["RasterizeResult", "rasterize"]
__version__ = "0.1.0"
