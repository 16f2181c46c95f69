"""Synthetic spike datasets: camera trajectories, ground-truth sources, the layout on disk."""

from .dataset import Dataset, TestView, load_dataset
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
    "make_source",
    "simulate_dataset",
]
