"""`.ply` export and import in the layout the common 3DGS viewers read.

Properties per vertex: x y z, nx ny nz (zero), f_dc_0..2, f_rest_* (channel-major, as 3DGS),
opacity (logit), scale_0..2 (log), rot_0..3 (w, x, y, z). Viewers expect three colour channels: a
mono scene is written with its channel repeated and a `spikegs channels 1` comment, so that the
import gives back exactly one channel.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import torch
from plyfile import PlyData, PlyElement, PlyParseError

from .gaussians import GaussianModel


def save_ply(model: GaussianModel, path: str | Path) -> None:
    """Write `model` to `path`."""
    p = {k: v.detach().cpu().numpy() for k, v in model.params.items()}
    n, rest, channels = len(model), p["sh_rest"].shape[1], model.channels
    reps = 3 if channels == 1 else 1
    dc = np.repeat(p["sh_dc"][:, 0, :], reps, axis=1)  # [N, 3]
    f_rest = np.repeat(p["sh_rest"], reps, axis=2).transpose(0, 2, 1).reshape(n, -1)  # [N, 3 (K-1)]
    columns = {"x": p["means"][:, 0], "y": p["means"][:, 1], "z": p["means"][:, 2]}
    columns.update({f"n{a}": np.zeros(n, np.float32) for a in "xyz"})
    columns.update({f"f_dc_{i}": dc[:, i] for i in range(dc.shape[1])})
    columns.update({f"f_rest_{i}": f_rest[:, i] for i in range(f_rest.shape[1])})
    columns["opacity"] = p["opacity_logits"]
    columns.update({f"scale_{i}": p["log_scales"][:, i] for i in range(3)})
    columns.update({f"rot_{i}": p["quats"][:, i] for i in range(4)})
    vertex = np.empty(n, dtype=[(k, "f4") for k in columns])
    for k, v in columns.items():
        vertex[k] = v
    background = " ".join(f"{v:.9g}" for v in model.background.detach().tolist())
    comments = [
        f"spikegs channels {channels}",
        f"spikegs sh_degree {model.sh_degree}",
        f"spikegs sh_rest {rest}",
        f"spikegs background {background}",
    ]
    PlyData([PlyElement.describe(vertex, "vertex")], comments=comments).write(str(path))


def load_ply(path: str | Path) -> GaussianModel:
    """Read a 3DGS `.ply` (ours or another tool's) into a GaussianModel; ValueError naming the
    file where it is not a PLY or lacks a property of the layout."""
    try:
        ply = PlyData.read(str(path))
    except PlyParseError as err:
        raise ValueError(f"{path}: not a readable PLY file ({err})") from None
    if "vertex" not in [e.name for e in ply.elements]:
        raise ValueError(f"{path}: no 'vertex' element: not a Gaussian splat file")
    v = ply["vertex"].data
    names = v.dtype.names
    needed = ("x", "y", "z", "opacity", *(f"scale_{i}" for i in range(3)))
    missing = [k for k in (*needed, *(f"rot_{i}" for i in range(4))) if k not in names]
    if missing:
        raise ValueError(f"{path}: vertex properties {missing} missing: not a 3DGS splat file")
    tags = dict(c.split(" ", 2)[1:] for c in ply.comments if c.startswith("spikegs "))
    dc_names = sorted((k for k in names if re.fullmatch(r"f_dc_\d+", k)), key=lambda s: int(s[5:]))
    rest_names = sorted(
        (k for k in names if re.fullmatch(r"f_rest_\d+", k)), key=lambda s: int(s[7:])
    )
    stored = len(dc_names)
    if stored == 0 or len(rest_names) % stored:
        raise ValueError(f"{path}: expected f_dc_* and a multiple of {stored} f_rest_* properties")
    rest = len(rest_names) // stored
    channels = int(tags.get("channels", stored))
    sh_degree = int(tags.get("sh_degree", round((rest + 1) ** 0.5) - 1))
    if (sh_degree + 1) ** 2 != rest + 1:
        raise ValueError(f"{path}: {rest + 1} SH coefficients per channel is not a square")

    def col(keys):  # [N, len(keys)]
        if not keys:
            return torch.zeros(len(v), 0)
        return torch.from_numpy(np.stack([np.asarray(v[k], np.float32) for k in keys], axis=1))

    n = len(v)
    f_rest = col(rest_names).reshape(n, stored, rest).transpose(1, 2)  # [N, K-1, stored]
    params = {
        "means": col(["x", "y", "z"]),
        "log_scales": col([f"scale_{i}" for i in range(3)]),
        "quats": col([f"rot_{i}" for i in range(4)]),
        "opacity_logits": col(["opacity"])[:, 0],
        "sh_dc": col(dc_names)[:, None, :channels],
        "sh_rest": f_rest[:, :, :channels].contiguous(),
    }
    if "background" in tags:
        background = torch.tensor([float(x) for x in tags["background"].split()])
    else:
        background = torch.zeros(channels)
    return GaussianModel(params, background, sh_degree)
