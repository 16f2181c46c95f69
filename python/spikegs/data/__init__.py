"""Spike datasets: synthetic ones (trajectories, ground-truth sources, the layout on disk) and the
real-data layouts (LLFF, NeRF/nerfstudio with spike_data/), all opened by `load_dataset`."""

from .dataset import Dataset, TestView, load_dataset
from .llff import load_llff
from .nerf_layout import load_nerf_layout
from .scenes import SCENES, GaussianScene
from .simulate import make_source, simulate_dataset
from .sources import FrameSequenceSource, MitsubaSource, ProceduralSource, Source
from .trajectory import Trajectory

__all__ = [
    "Dataset",
    "FrameSequenceSource",
    "GaussianScene",
    "MitsubaSource",
    "ProceduralSource",
    "SCENES",
    "Source",
    "TestView",
    "Trajectory",
    "load_dataset",
    "load_llff",
    "load_nerf_layout",
    "make_source",
    "simulate_dataset",
]
