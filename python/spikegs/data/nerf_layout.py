"""The NeRF / nerfstudio layout with one spike stream per frame (as USP-Gaussian's data).

DIR/transforms_train.json + transforms_test.json, or DIR/transforms.json (every 8th frame held out)
    intrinsics fl_x, fl_y, cx, cy, w, h or camera_angle_x; frames with file_path and
    transform_matrix (camera-to-world, OpenGL unless "convention": "opencv")
DIR/spike_data/...  a frame's spikes: its "spike_path" (relative to DIR) if it has one, else
    spike_data/<file_path without extension>.dat, else spike_data/<file name stem>.dat
DIR/<file_path>     optional sharp image (extension optional): a test frame's ground truth
DIR/spikegs.json    loader options (real_options.py), all optional

A test frame needs its spikes or its image; one with no image gets a pseudo ground truth (real.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import skimage.transform

from .dataset import Dataset
from .real import camera_meta, held_out, scene_sphere, views_dataset
from .real_options import Options, open_spikes, read_options
from .sources import OPENGL_TO_OPENCV, centre_of_view, read_frame, to_channels
from .trajectory import PathLike

SPIKE_DIR = "spike_data"
TRANSFORMS = ("transforms_train.json", "transforms_test.json", "transforms.json")
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".exr")


def _read_doc(path: Path) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"transforms file not found: {path}")
    doc = json.loads(path.read_text())
    for frame in doc.get("frames") or []:
        if "file_path" not in frame or "transform_matrix" not in frame:
            raise ValueError(f"{path}: every frame needs a file_path and a transform_matrix")
    if not doc.get("frames"):
        raise ValueError(f"{path}: no frames")
    return doc


def _viewmats(path: Path, doc: dict) -> np.ndarray:
    """OpenCV world-to-camera viewmats [F, 4, 4] of a transforms file's frames."""
    c2w = np.array([f["transform_matrix"] for f in doc["frames"]], np.float64)  # [F, 4, 4]
    if c2w.shape[1:] != (4, 4):
        raise ValueError(f"{path}: transform_matrix expected 4x4, found {list(c2w.shape[1:])}")
    bad = np.flatnonzero(~np.isfinite(c2w).all(axis=(1, 2)))
    if bad.size:
        raise ValueError(f"{path}: non-finite (NaN/inf) transform_matrix in frames {bad.tolist()}")
    if doc.get("convention", "opengl").lower() != "opencv":
        c2w = c2w @ OPENGL_TO_OPENCV
    return np.linalg.inv(c2w)


def _base(file_path: str) -> Path:
    """A frame's file_path without its image extension (NeRF synthetic gives none)."""
    path = Path(file_path)
    return path.with_suffix("") if path.suffix.lower() in IMAGE_EXTENSIONS else path


def _spike_candidates(root: Path, frame: dict) -> list[Path]:
    """Where a frame's spike file may be, in order (module docstring)."""
    if "spike_path" in frame:
        return [root / frame["spike_path"]]
    base = _base(frame["file_path"])
    return [root / SPIKE_DIR / f"{base}.dat", root / SPIKE_DIR / f"{base.name}.dat"]


def _find_spikes(root: Path, frames: list, sources: list) -> list[Path | None]:
    """Each frame's spike file [F], None where there is none; ValueError if two frames share one."""
    found, owner = [], {}
    for frame, source in zip(frames, sources):
        path = next((p for p in _spike_candidates(root, frame) if p.is_file()), None)
        if path is not None and path in owner:
            raise ValueError(
                f"{source}: frames '{owner[path]}' and '{frame['file_path']}' share the spike "
                f"file {path}; give each a spike_path"
            )
        if path is not None:
            owner[path] = frame["file_path"]
        found.append(path)
    return found


def _image(root: Path, frame: dict) -> np.ndarray | None:
    """The frame's image, linear RGB [h, w, 3], or None when there is none."""
    try:
        return read_frame(root / frame["file_path"], background=1.0)
    except FileNotFoundError:
        return None


def _intrinsics(path: Path, doc: dict, src: tuple, size: tuple) -> np.ndarray:
    """K [3, 3] of the file's intrinsics for images of `src` (h, w), scaled to `size` (h, w)."""
    (src_h, src_w), (height, width) = src, size
    if "fl_x" in doc:
        fx, fy = float(doc["fl_x"]), float(doc.get("fl_y", doc["fl_x"]))
    elif "camera_angle_x" in doc:
        fx = fy = src_w / 2 / np.tan(float(doc["camera_angle_x"]) / 2)
    else:
        raise ValueError(f"{path}: intrinsics expected (camera_angle_x, or fl_x/fl_y/cx/cy)")
    cx, cy = float(doc.get("cx", src_w / 2)), float(doc.get("cy", src_h / 2))
    sx, sy = width / src_w, height / src_h
    return np.array([[fx * sx, 0.0, cx * sx], [0.0, fy * sy, cy * sy], [0.0, 0.0, 1.0]])


def _sizes(path: Path, doc: dict, images: list, options: Options) -> tuple[tuple, tuple]:
    """(h, w) the intrinsics are for and (h, w) of the spikes: from spikegs.json, the transforms
    file's w, h, or the first sharp image."""
    shapes = [im.shape[:2] for im in images if im is not None]
    src = (doc["h"], doc["w"]) if "w" in doc and "h" in doc else (shapes[0] if shapes else None)
    size = (options.height, options.width) if options.height and options.width else src
    if size is None:
        raise ValueError(
            f"{path}: image size unknown (no w, h and no sharp image): set height and width in "
            f"spikegs.json"
        )
    return tuple(map(int, src or size)), tuple(map(int, size))


def _mono(image: np.ndarray | None, height: int, width: int) -> np.ndarray | None:
    """Linear RGB [h, w, 3] -> luma [height, width, 1], resized if need be."""
    if image is None:
        return None
    if image.shape[:2] != (height, width):
        image = skimage.transform.resize(image, (height, width), anti_aliasing=True)
    return to_channels(image, 1).astype(np.float32)


def _frames(root: Path, options: Options):
    """The file with the intrinsics, its JSON, frames [F], each frame's file [F], viewmats
    [F, 4, 4] and test mask [F]."""
    train, test, single = (root / name for name in TRANSFORMS)
    if single.is_file() and not train.is_file():
        doc = _read_doc(single)
        count = len(doc["frames"])
        mask = held_out(count, options.test_views, str(single))
        return single, doc, doc["frames"], [single] * count, _viewmats(single, doc), mask
    doc, test_doc = _read_doc(train), _read_doc(test)
    frames = doc["frames"] + test_doc["frames"]
    sources = [train] * len(doc["frames"]) + [test] * len(test_doc["frames"])
    viewmats = np.concatenate([_viewmats(train, doc), _viewmats(test, test_doc)])  # [F, 4, 4]
    return train, doc, frames, sources, viewmats, np.arange(len(frames)) >= len(doc["frames"])


def load_nerf_layout(path: PathLike, **overrides) -> Dataset:
    """Open a NeRF/nerfstudio-layout directory with spikes per frame (module docstring);
    `overrides` are spikegs.json options. Every file is checked before any spike is read."""
    root = Path(path)
    options = read_options(root, overrides)
    path, doc, frames, sources, viewmats, test = _frames(root, options)
    spikes = _find_spikes(root, frames, sources)
    images = [_image(root, f) if t else None for f, t in zip(frames, test)]
    for frame, source, found, image, is_test in zip(frames, sources, spikes, images, test):
        if found is None and image is None:
            tried = ", ".join(str(p) for p in _spike_candidates(root, frame))
            raise FileNotFoundError(
                f"{source}: spike file of frame '{frame['file_path']}' not found (tried {tried})"
                + (", and no sharp image either" if is_test else "")
            )
    src, (height, width) = _sizes(path, doc, images, options)
    K = _intrinsics(path, doc, src, (height, width))
    sphere = scene_sphere(options, *centre_of_view(viewmats))
    meta = camera_meta("nerf", root, K, height, width, options, **sphere)
    streams = [None if p is None else open_spikes(p, height, width, options) for p in spikes]
    names = [_base(f["file_path"]).as_posix().replace("/", "_") for f in frames]
    images = [_mono(im, height, width) for im in images]  # [H, W, 1] intensity
    return views_dataset(
        root, meta, names, viewmats, streams, images, test, options.pseudo_gt_window, str(path)
    )
