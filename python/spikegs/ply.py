"""`.ply` export and import in the layout the common 3DGS viewers read.

Properties per vertex: x y z, nx ny nz (zero), f_dc_0..2, f_rest_0..44 (channel-major, as 3DGS),
opacity (logit), scale_0..2 (log), rot_0..3 (w, x, y, z): the original 3DGS code's layout at SH
degree 3, which viewers that read a fixed record (SIBR's) need. A model of a lower degree is
written with its higher coefficients zero (it renders the same) and a `spikegs sh_degree` comment
that the import reads back. Viewers expect three colour channels: a mono scene is written with its
channel repeated and a `spikegs channels 1` comment, so that the import gives back exactly one.
Colours are the model's linear intensities (a viewer, which shows them as display values, shows
them darker than `spikegs render`); the background is a `spikegs background` comment. A model
with the 3D smoothing filter (`train.filter_3d`) adds Mip-Splatting's `filter_3D` property, its
widths (the scales and opacities stay the unfiltered ones, as Mip-Splatting writes them). The 2D
filter, where not 3DGS's, is a comment: `spikegs antialiased 1`, `spikegs dilation V` (px²).
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
import torch
from plyfile import PlyData, PlyElement, PlyParseError

from .atomic_save import write_atomically
from .gaussians import GaussianModel
from .rasterize import CONSTANTS, check_dilation
from .sh import MAX_DEGREE

FILE_SH_REST = 15  # SH coefficients per channel past the DC one that a file holds (degree 3)
FILTER_3D = "filter_3D"  # the 3D smoothing filter's widths: Mip-Splatting's name and meaning


def save_ply(model: GaussianModel, path: str | Path) -> None:
    """Write `model` to `path`, atomically: mono or colour (ValueError for other channel counts,
    which no viewer reads), the SH coefficients of its degree (`model.sh_degree`)."""
    channels = model.channels
    if channels not in (1, 3):
        raise ValueError(
            f"save_ply: a model of {channels} channels; a 3DGS .ply holds 1 (grey) or 3 (RGB)"
        )
    if model.background.shape != (channels,) or not model.background.isfinite().all():
        raise ValueError(  # load_ply would refuse the file
            f"save_ply: background {model.background.tolist()}: expected {channels} finite values"
        )
    p = {k: v.detach().cpu().numpy() for k, v in model.params.items()}
    n, used = len(model), (model.sh_degree + 1) ** 2 - 1  # the coefficients that render reads
    reps = 3 if channels == 1 else 1
    dc = np.repeat(p["sh_dc"][:, 0, :], reps, axis=1)  # [N, 3]
    rest = np.zeros((n, FILE_SH_REST, 3), np.float32)  # [N, 15, 3]
    rest[:, :used] = np.repeat(p["sh_rest"][:, :used], reps, axis=2)
    f_rest = rest.transpose(0, 2, 1).reshape(n, 3 * FILE_SH_REST)  # [N, 45] channel-major
    # the means of the model's frame: the world's, as every viewer reads it, or, about a far
    # origin (a scene over FAR_SCENE_RADII radii out), the origin's, given in a comment: world
    # positions would round in float32 (in a viewer's too), by pixels at 1e6 radii
    columns = {"x": p["means"][:, 0], "y": p["means"][:, 1], "z": p["means"][:, 2]}
    columns.update({f"n{a}": np.zeros(n, np.float32) for a in "xyz"})
    columns.update({f"f_dc_{i}": dc[:, i] for i in range(3)})
    columns.update({f"f_rest_{i}": f_rest[:, i] for i in range(3 * FILE_SH_REST)})
    columns["opacity"] = p["opacity_logits"]
    columns.update({f"scale_{i}": p["log_scales"][:, i] for i in range(3)})
    columns.update({f"rot_{i}": p["quats"][:, i] for i in range(4)})
    if model.filter_3d is not None:  # Mip-Splatting's property (a 3DGS viewer ignores it)
        columns[FILTER_3D] = model.filter_3d.detach().cpu().numpy()
    vertex = np.empty(n, dtype=[(k, "f4") for k in columns])
    for k, v in columns.items():
        vertex[k] = v
    background = " ".join(f"{v:.9g}" for v in model.background.detach().tolist())
    comments = [
        f"spikegs channels {channels}",
        f"spikegs sh_degree {model.sh_degree}",
        f"spikegs background {background}",
    ]
    if model.origin.any():
        comments.append("spikegs origin " + " ".join(f"{v!r}" for v in model.origin.tolist()))
    if model.antialiased:  # a 3DGS viewer draws it without (README, scene.ply in other tools)
        comments.append("spikegs antialiased 1")
    if model.dilation != CONSTANTS["dilation"]:  # a 3DGS viewer draws it with 0.3 px²
        comments.append(f"spikegs dilation {model.dilation!r}")
    # the comments go after 'element vertex N': SIBR's viewer (and its C++ kin) reads the count
    # from the header's third line, and read 0 Gaussians from a file comment there
    ply = PlyData([PlyElement.describe(vertex, "vertex", comments=comments)])
    write_atomically(Path(path), lambda tmp: ply.write(str(tmp)))  # never half a file at `path`


def _tags(ply: PlyData) -> dict[str, str]:
    """The `spikegs KEY VALUE` comments of a file, the vertex element's (save_ply's) or the
    file's (earlier files'); others ignored."""
    tags = {}
    for comment in [*ply.comments, *ply["vertex"].comments]:
        parts = comment.split(" ", 2)
        if parts[0] == "spikegs" and len(parts) == 3:
            tags[parts[1]] = parts[2]
    return tags


def _tag_int(path, tags: dict, key: str, default: int, lo: int, hi: int) -> int:
    """Integer tag `key` in [lo, hi] (`default` where absent); ValueError naming the file."""
    text = tags.get(key)
    if text is None:
        return default
    if not re.fullmatch(r"\d+", text.strip()) or not lo <= int(text) <= hi:
        raise ValueError(f"{path}: comment 'spikegs {key} {text}': expected {lo}..{hi}")
    return int(text)


def _tag_dilation(path, tags: dict) -> float:
    """The 2D filter's dilation a file states (`spikegs dilation V`, px²), else 3DGS's 0.3;
    ValueError naming the file for one out of the rasterizer's range."""
    text = tags.get("dilation")
    if text is None:
        return CONSTANTS["dilation"]
    try:
        dilation = float(text)
    except ValueError:
        dilation = text
    check_dilation(dilation, f"{path}: comment 'spikegs dilation {text}'")
    return dilation


def read_vertices(path: str | Path) -> PlyData:
    """A PLY file with a 'vertex' element; ValueError naming the file where it is not one (a
    header declaring more elements than memory holds too: an ASCII file's are allocated before
    they are read, and numpy's "Unable to allocate 10.7 PiB" named no file)."""
    try:
        ply = PlyData.read(str(path))
    except (PlyParseError, UnicodeDecodeError, ValueError) as err:
        raise ValueError(f"{path}: not a readable PLY file ({err})") from None
    except MemoryError as err:
        raise ValueError(
            f"{path}: not a readable PLY file: its header declares more than memory holds ({err})"
        ) from None
    if "vertex" not in [e.name for e in ply.elements]:
        raise ValueError(f"{path}: no 'vertex' element")
    return ply


def load_ply(path: str | Path) -> GaussianModel:
    """Read a 3DGS `.ply` (ours or another tool's) into a GaussianModel; ValueError naming the
    file where it is not a PLY or lacks a property of the layout."""
    ply = read_vertices(path)
    v = ply["vertex"].data
    names = v.dtype.names
    if "packed_position" in names:  # a splat file still, quantised in chunks of 256
        raise ValueError(
            f"{path}: a compressed .ply (PlayCanvas / SuperSplat: chunk element, packed_* vertex "
            f"properties), which spikegs does not read; export it uncompressed (3DGS's "
            f"x, y, z, f_dc_*, opacity, scale_*, rot_* floats) and load that"
        )
    needed = ("x", "y", "z", "opacity", *(f"scale_{i}" for i in range(3)))
    missing = [k for k in (*needed, *(f"rot_{i}" for i in range(4))) if k not in names]
    if missing:
        raise ValueError(f"{path}: vertex properties {missing} missing: not a 3DGS splat file")
    tags = _tags(ply)
    dc_names = sorted((k for k in names if re.fullmatch(r"f_dc_\d+", k)), key=lambda s: int(s[5:]))
    rest_names = sorted(
        (k for k in names if re.fullmatch(r"f_rest_\d+", k)), key=lambda s: int(s[7:])
    )
    stored = len(dc_names)
    if stored == 0:
        raise ValueError(f"{path}: no f_dc_* colour properties: not a 3DGS splat file")
    for kind, found in (("f_dc", dc_names), ("f_rest", rest_names)):
        if found != [f"{kind}_{i}" for i in range(len(found))]:  # f_dc_0, f_dc_1, f_dc_3
            raise ValueError(f"{path}: {kind}_* properties {found}: expected {kind}_0 onwards")
    if stored not in (1, 3):  # (f_dc_2 missing was "expected a multiple of 2 f_rest_*")
        raise ValueError(
            f"{path}: f_dc_* properties {dc_names}: expected f_dc_0 (grey) or f_dc_0..f_dc_2 (RGB)"
        )
    if len(rest_names) % stored:
        raise ValueError(f"{path}: expected a multiple of {stored} f_rest_* properties")
    rest = len(rest_names) // stored  # per channel
    channels = _tag_int(path, tags, "channels", stored, 1, stored)
    if channels not in (1, 3):  # as save_ply writes: the renderer would draw 2, a video refuse
        raise ValueError(
            f"{path}: {channels} colour channels (its f_dc_* or comment 'spikegs channels'): a "
            f"3DGS .ply holds 1 (grey) or 3 (RGB)"
        )
    inferred = math.isqrt(rest + 1) - 1  # the highest degree whose coefficients the file holds
    if "sh_degree" not in tags and (inferred + 1) ** 2 != rest + 1:
        raise ValueError(
            f"{path}: {rest + 1} SH coefficients per channel, which no SH degree has (1, 4, 9, 16)"
        )
    if "sh_degree" not in tags and inferred > MAX_DEGREE:
        raise ValueError(
            f"{path}: SH degree {inferred} ({rest + 1} coefficients per channel); spikegs renders "
            f"degrees 0..{MAX_DEGREE}"
        )
    sh_degree = _tag_int(path, tags, "sh_degree", inferred, 0, min(inferred, MAX_DEGREE))
    used = (sh_degree + 1) ** 2 - 1

    def col(keys):  # [N, len(keys)]
        if not keys:
            return torch.zeros(len(v), 0, dtype=torch.float32)
        return torch.from_numpy(np.stack([np.asarray(v[k], np.float32) for k in keys], axis=1))

    n = len(v)
    f_rest = col(rest_names).reshape(n, stored, rest).transpose(1, 2)  # [N, rest, stored]
    if channels < stored:  # a mono file (save_ply's grey in R, G and B): colour is dropped
        dc = col(dc_names)  # [N, stored]
        spread = float(torch.nan_to_num((dc - dc[:, :1]).abs().amax(), nan=0.0)) if n else 0.0
        if spread > 0:  # (unsaid until 2026-12-06: a tool's colour edit kept the comment)
            warnings.warn(
                f"{path}: comment 'spikegs channels {channels}', but its f_dc_* differ by up to "
                f"{spread:.3g} across R, G and B: read as grey, f_dc_0 alone (remove the comment "
                f"to read the colour)",
                stacklevel=2,
            )
    params = {
        "means": col(["x", "y", "z"]),
        "log_scales": col([f"scale_{i}" for i in range(3)]),
        "quats": col([f"rot_{i}" for i in range(4)]),
        "opacity_logits": col(["opacity"])[:, 0],
        "sh_dc": col(dc_names)[:, None, :channels],
        "sh_rest": f_rest[:, :used, :channels].contiguous(),
    }
    if "background" in tags:
        try:
            background = torch.tensor(
                [float(x) for x in tags["background"].split()], dtype=torch.float32
            )
        except ValueError:
            background = None
        if background is None or background.shape != (channels,) or not background.isfinite().all():
            raise ValueError(
                f"{path}: comment 'spikegs background {tags['background']}': expected "
                f"{channels} finite numbers"
            )
    else:  # another tool's file, or ours re-saved by one: 3DGS's black (dB lost unsaid)
        background = torch.zeros(channels, dtype=torch.float32)
        warnings.warn(
            f"{path}: no 'spikegs background' comment (another tool's file, or re-saved by one): "
            f"rendered over black; add 'comment spikegs background V' (a value per channel, as "
            f"the run's own scene.ply has it) after 'element vertex N' to restore a trained "
            f"background",
            stacklevel=2,
        )
    activated = dict(params, log_scales=params["log_scales"].exp())
    activated["opacity_logits"] = params["opacity_logits"].sigmoid()
    not_finite, culled_mask = _not_finite(params.values()), _not_finite(activated.values())  # [N]
    broken, culled = int(not_finite.sum()), int((culled_mask & not_finite).sum())
    overflowing = int((culled_mask & ~not_finite).sum())  # a finite log-scale past ~88.7
    if overflowing:
        warnings.warn(
            f"{path}: {overflowing} of its {n} Gaussians have a log-scale past "
            f"{math.log(torch.finfo(torch.float32).max):.4g}, an infinite scale once activated "
            f"(exp, in float32): kept, and culled by the renderer",
            stacklevel=2,
        )
    if broken:  # (an infinite opacity logit or a log-scale of -inf activates to a finite value)
        finite = (  # (-inf's opacity 0 is culled as any too faint, a dot antialiased too)
            f"; {broken - culled} activate to finite values, drawn or culled as any (an opacity "
            f"logit of +inf is opacity 1, -inf 0; a log-scale of -inf a scale of 0)"
        )
        warnings.warn(
            f"{path}: {broken} of its {n} Gaussians hold a NaN or infinite property: kept; the "
            f"renderer culls {culled} (not finite once activated)"
            + (finite if culled < broken else ""),
            stacklevel=2,
        )
    unrotated = int((params["quats"] == 0).all(1).sum())
    if unrotated:
        warnings.warn(
            f"{path}: {unrotated} of its {n} Gaussians have the rotation quaternion (0, 0, 0, 0), "
            f"no orientation: kept, and culled by the renderer",
            stacklevel=2,
        )
    if not n:
        warnings.warn(f"{path}: no Gaussians: it renders the background alone", stacklevel=2)
    origin = None
    if "origin" in tags:  # x, y, z are about it (save_ply, a scene far from the world's origin)
        try:
            origin = [float(x) for x in tags["origin"].split()]
        except ValueError:
            origin = []
        if len(origin) != 3 or not np.isfinite(origin).all():
            raise ValueError(
                f"{path}: comment 'spikegs origin {tags['origin']}': expected 3 finite numbers"
            )
    antialiased = bool(_tag_int(path, tags, "antialiased", 0, 0, 1))
    dilation = _tag_dilation(path, tags)
    widths = col([FILTER_3D])[:, 0] if FILTER_3D in names else None
    if widths is not None and not (widths.isfinite() & (widths >= 0)).all():
        raise ValueError(f"{path}: vertex property {FILTER_3D}: expected finite widths >= 0")
    return GaussianModel(params, background, sh_degree, origin, antialiased, widths, dilation)


def declares_channels(path: str | Path) -> bool:
    """Whether a .ply states its channel count (`comment spikegs channels N`, which save_ply writes
    and another tool's re-save drops)."""
    return "channels" in _tags(read_vertices(path))


def _not_finite(params) -> torch.Tensor:
    """[N] bool: the Gaussians holding a NaN or infinite value in any of `params` [N, ...]."""
    rows = [p.flatten(1) if p.dim() > 1 else p[:, None] for p in params]  # [N, *]
    return (~torch.cat(rows, 1).isfinite()).any(1)
