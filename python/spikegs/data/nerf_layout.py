"""The NeRF / nerfstudio layout with one spike stream per frame (as USP-Gaussian's data).

DIR/transforms_train.json + transforms_test.json, or DIR/transforms.json or transforms_train.json
    alone (every 8th frame, or spikegs.json's test_views, held out)
    intrinsics fl_x, fl_y, cx, cy, w, h or camera_angle_x (and _y; radians), in the file or per
    frame (nerfstudio: a frame's keys override the file's; every frame must give the same camera,
    at the spikes' aspect ratio; distortion k1..k4, p1, p2 is not modelled: a warning if
    non-zero); frames with file_path and transform_matrix (camera-to-world, OpenGL unless
    "convention": "opencv"), converging on the scene unless spikegs.json gives scene_center and
    scene_radius
DIR/spike_data/...  a frame's spikes: its "spike_path" (relative to DIR) if it has one, else
    spike_data/<file_path without extension>.dat, else spike_data/<file name stem>.dat; an
    absolute file_path counts relative to DIR if it is inside DIR, else by its file name
DIR/<file_path>     optional sharp image (extension optional): a test frame's ground truth; a
    training frame's calibrates the intensity scale when spikegs.json gives no rate_at_one,
    checks the spikes' orientation (flip) and, where no test frame has one, sizes intrinsics in
    pixels given without w, h
DIR/spikegs.json    loader options (real_options.py), all optional

A test frame needs its spikes or its image; one with no image gets a pseudo ground truth (real.py).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..image_io import to_channels
from ..regular_file import is_given
from ..strict_json import json_text
from .dataset import POINTS, Dataset, repeated, warn_if_faint, warn_rows_out_of_line
from .real import ORIENTATION_VIEWS, camera_meta, held_out_mask, scene_sphere, views_dataset
from .real_options import ASPECT_FIX, OPTIONS_FILE, Options, open_spikes, read_options
from .trajectory import PathLike
from .transforms_file import (
    IMAGE_EXTENSIONS,
    TRANSFORMS,
    fitted,
    flat_frames,
    frame_columns,
    frame_files,
    is_opengl,
    one_camera_matrix,
    other_convention_fix,
    read_cameras,
    read_frame,
    read_transforms_doc,
    stated_size,
    transforms_viewmats,
    warn_unread_transforms,
    warn_upsampled_tests,
)
from .view_geometry import AXES_SPREAD_MIN, converging_centre, view_sphere

SPIKE_DIR = "spike_data"


def _relative(root: Path, file_path: str) -> Path:
    """A frame's file_path relative to DIR: an absolute one inside DIR relative to it, one outside
    DIR by its file name."""
    path = Path(file_path)
    if not path.is_absolute():
        return path
    try:
        return path.resolve().relative_to(root.resolve())
    except ValueError:
        return Path(path.name)


def _base(root: Path, file_path: str) -> Path:
    """A frame's file_path relative to DIR without its image extension (NeRF gives none)."""
    path = _relative(root, file_path)
    return path.with_suffix("") if path.suffix.lower() in IMAGE_EXTENSIONS else path


def _spike_candidates(root: Path, frame: dict, source) -> list[Path]:
    """Where a frame's spike file may be, in order (module docstring; a null spike_path: none)."""
    if "spike_path" in frame:
        path = frame["spike_path"]
        if path is not None and not isinstance(path, str):
            raise ValueError(
                f"{source}: frame '{frame['file_path']}' spike_path expected a path or null (no "
                f"spikes), found {json_text(path)}"
            )
        return [] if path is None else [root / path]
    base = _base(root, frame["file_path"])
    return list(
        dict.fromkeys([root / SPIKE_DIR / f"{base}.dat", root / SPIKE_DIR / f"{base.name}.dat"])
    )


def _find_spikes(root: Path, frames: list, sources: list) -> list[Path | None]:
    """Each frame's spike file [F], None where there is none; ValueError if two frames share one."""
    found, owner = [], {}
    for frame, source in zip(frames, sources):
        path = next((p for p in _spike_candidates(root, frame, source) if p.is_file()), None)
        if path is not None and path in owner:
            raise ValueError(
                f"{source}: frames '{owner[path]}' and '{frame['file_path']}' share the spike "
                f"file {path}; give each a spike_path"
            )
        if path is not None:
            owner[path] = frame["file_path"]
        found.append(path)
    return found


def _image(root: Path, frame: dict, listings: dict) -> np.ndarray | None:
    """The frame's image, linear RGB [h, w, 3], or None when there is none (`listings`:
    `frame_files`')."""
    try:
        return read_frame(root / frame["file_path"], 1.0, listings)
    except FileNotFoundError:
        return None


def _readable(root: Path, frame: dict, listings: dict) -> np.ndarray | None:
    """`_image`, or None where the file cannot be read: for a training image only checked."""
    try:
        return _image(root, frame, listings)
    except ValueError:
        return None


PIXEL_KEYS = ("fl_x", "fl_y", "cx", "cy")  # intrinsics in the pixels of the frames' images


def _first_shape(images: Iterator) -> tuple[tuple, str] | None:
    """(h, w) of the first image of `images`, (file_path, image or None) pairs read as needed,
    that is not None, with its file_path; None where there is none."""
    return next(((im.shape[:2], name) for name, im in images if im is not None), None)


def _sizes(
    path: Path, camera: dict, tests: Iterator, training: Iterator, options: Options
) -> tuple[tuple, tuple, str]:
    """(h, w) the intrinsics are for, (h, w) of the spikes and what gives the first: the camera's
    w, h, else the first sharp test image's size (`tests`), else, for intrinsics in pixels or
    where spikegs.json does not give the spikes' size, the first readable training image's
    (`training`; an angle's focal scales with the spikes' width); the images, (file_path, image)
    pairs, read as needed; each of height, width from spikegs.json, else the first's."""
    src, what = stated_size(path, camera, "the first sharp image")
    if not src:
        pixels = any(k in camera for k in PIXEL_KEYS)
        found = _first_shape(tests) or (
            _first_shape(training) if pixels or not (options.height and options.width) else None
        )
        if found:
            src, what = found[0], f"the camera (sized as its first sharp image, {found[1]})"
    height = options.height or (src and src[0])
    width = options.width or (src and src[1])
    if not (height and width):
        raise ValueError(
            f"{path}: image size unknown (no w, h and no sharp image): set height and width in "
            f"{OPTIONS_FILE}"
        )
    size = (int(height), int(width))
    return tuple(map(int, src or size)), size, what


def _mono(
    image: np.ndarray | None, src: tuple, size: tuple, columns: slice, name: str, what: str
) -> np.ndarray | None:
    """Linear RGB [h, w, 3] -> luma [height, width, 1]: `fitted` to `size` (h, w) (ValueError
    naming the image, `name`, when its aspect ratio is not the camera's (h, w) `src`, which
    `what` gives), then its `columns` kept (a raw-row crop)."""
    if image is None:
        return None
    return to_channels(fitted(image, src, size, name, what)[:, columns], 1).astype(np.float32)


def _frames(root: Path, options: Options):
    """Frames [F], each frame's file [F] and its file's JSON [F], viewmats [F, 4, 4] and test
    mask [F]: transforms_train.json + transforms_test.json, else transforms.json or
    transforms_train.json alone with every 8th frame (or test_views) held out."""
    train, test, single = (root / name for name in TRANSFORMS)
    given = {path: is_given(path) for path in (train, test, single)}  # a folder named so: said
    if given[train] and given[test]:
        if options.test_views is not None:
            raise ValueError(
                f"{options.origin('test_views', root)} is for a single transforms file; "
                f"{test.name} lists the test frames here (remove one or the other)"
            )
        docs = [read_transforms_doc(train), read_transforms_doc(test)]
        paths = [train, test]
        if is_opengl(train, docs[0]) != is_opengl(test, docs[1]):
            stated = [doc.get("convention", "opengl (unstated)") for doc in docs]
            warnings.warn(  # each file is read in its own; one relabelled, not converted, is not
                f"{root}: {train.name} states convention {stated[0]}, {test.name} {stated[1]}: "
                f"each file's matrices are read in its own; a file whose matrices were converted "
                f"and its label not, or the reverse, reads as poses that do not converge",
                stacklevel=3,
            )
    else:
        if given[test] and not given[train] and not given[single]:
            raise FileNotFoundError(
                f"{root}: {test.name} without training frames: add {train.name} (or a "
                f"{single.name} whose every 8th frame is held out)"
            )
        path = train if given[train] else single
        docs, paths = [read_transforms_doc(path)], [path]
    warn_unread_transforms(root, paths)
    frames, sources, frame_docs = flat_frames(paths, docs)
    warn_unused_keys(root, paths, docs, frames)
    viewmats = np.concatenate(
        [transforms_viewmats(p, doc) for p, doc in zip(paths, docs)]
    )  # [F, 4, 4]
    if len(docs) == 2:
        mask = np.arange(len(frames)) >= len(docs[0]["frames"])
    else:
        mask = held_out_mask(len(frames), options, str(paths[0]))
    return frames, sources, frame_docs, viewmats, mask


def warn_unused_keys(root: Path, paths: list[Path], docs: list[dict], frames: list) -> None:
    """UserWarnings for what nerfstudio's files state and this layout does not read, which would
    change a training: a `ply_file_path` (its sparse points, where DATASET/points3d.ply would start
    the Gaussians there; without it they start at random) and frames' `mask_path` (every pixel
    trains and is scored)."""
    for path, doc in zip(paths, docs):
        cloud = doc.get("ply_file_path")
        if isinstance(cloud, str) and not (root / POINTS).exists():
            warnings.warn(
                f"{path}: ply_file_path '{cloud}' is not read; copy it to {root / POINTS} for the "
                f"Gaussians to start at its points (they start at random points in the scene "
                f"bounds)",
                stacklevel=4,
            )
    masked = sum("mask_path" in frame for frame in frames)
    if masked:
        warnings.warn(
            f"{root}: {masked} frame(s) state a mask_path, which is not read: every pixel of each "
            f"view trains and is scored",
            stacklevel=4,
        )


def _view_names(root: Path, frames: list, sources: list) -> list[str]:
    """Each frame's view name [F], its file path without extension and '/' as '_'; ValueError
    where a frame is listed twice, naming the files that list it, or two become one name."""
    bases = [_base(root, f["file_path"]).as_posix() for f in frames]
    names = [b.replace("/", "_") for b in bases]  # a view's name names its files: no folders
    for name in repeated(names):
        listed = [(f, b, s) for f, b, n, s in zip(frames, bases, names, sources) if n == name]
        clash = sorted({b for _, b, _ in listed})
        # the files that list them (the first file alone was named until 2026-12-06)
        files = " and ".join(dict.fromkeys(str(s) for *_, s in listed))
        if len(clash) > 1:
            raise ValueError(
                f"frames {clash} (in {files}) both become view '{name}' ('/' turns into '_'); "
                f"rename one of them"
            )
        raise ValueError(
            f"frame {json_text(listed[0][0]['file_path'])} listed {len(listed)} times (in "
            f"{files}): a view is listed once"
        )
    return names


def _check_test_files_converge(viewmats: np.ndarray, test, sources: list[Path], path: Path):
    """ValueError naming a test file (of `sources` [F], where `test` [F] marks the test frames)
    whose poses keep the cameras' optical axes (viewmats [F, 4, 4]) from converging where the
    training file's (`path`) alone converge: the error named the training file, which was right
    (a transforms_test.json in OpenCV axes, the real-layout trial). Called where the scene
    sphere failed, so that a loading whose views converge finds their centre once."""
    test = np.asarray(test, bool)
    others = sorted({str(s) for s, is_test in zip(sources, test) if is_test and s != path})
    if (
        others
        and converging_centre(viewmats, AXES_SPREAD_MIN) is None
        and converging_centre(viewmats[~test], AXES_SPREAD_MIN) is not None
    ):
        raise ValueError(
            f"{others[0]}: its poses keep the cameras' optical axes from converging in front of "
            f"them, where {path.name}'s alone converge: matrices in another convention than the "
            f"file states (OpenCV's where OpenGL's are read), or world-to-camera ones; state "
            f'theirs ("convention": "opencv" or "opengl") or mend them'
        )


def load_nerf_layout(path: PathLike, **overrides) -> Dataset:
    """Open a NeRF/nerfstudio-layout directory with spikes per frame (module docstring);
    `overrides` are spikegs.json options. Every file is checked before any spike is read."""
    root = Path(path)
    options = read_options(root, overrides)
    frames, sources, docs, viewmats, test = _frames(root, options)
    names = _view_names(root, frames, sources)  # before any file is read
    path, cameras = sources[0], read_cameras(docs, frames, sources)
    camera = cameras[0]
    spikes = _find_spikes(root, frames, sources)
    listings: dict = {}  # each image folder listed once (`frame_files`)
    for frame, source, found, is_test in zip(frames, sources, spikes, test):
        if found is None and not (is_test and frame_files(root / frame["file_path"], listings)):
            tried = [str(p) for p in _spike_candidates(root, frame, source)]
            where = f"tried {', '.join(tried)}" if tried else "its spike_path is null"
            raise FileNotFoundError(
                f"{source}: spike file of frame '{frame['file_path']}' not found ({where})"
                + (", and no sharp image either" if is_test else "")
            )
    # sharp images read one at a time (a test set's, full size, would fill the memory at once);
    # the one that gives the size (none where w, h are stated) kept for its view, not read again
    sized: dict[int, np.ndarray] = {}

    def keep(i: int, image: np.ndarray | None) -> np.ndarray | None:
        if image is not None:
            sized[i] = image
        return image

    tests = (
        (f["file_path"], keep(i, _image(root, f, listings)))
        for i, (f, is_test) in enumerate(zip(frames, test))
        if is_test
    )
    training = (
        (f["file_path"], keep(i, _readable(root, f, listings)))
        for i, (f, is_test) in enumerate(zip(frames, test))
        if not is_test
    )
    src, (height, width), what = _sizes(path, camera, tests, training, options)
    row, shift = frame_columns(  # the resized images' width, the spikes' first column in it
        path, what, src, (height, width), ASPECT_FIX, options.raw_width, options.col_offset
    )
    # the frames' cameras checked as one before the training images are read
    K = one_camera_matrix(cameras, frames, sources, src, (height, row), shift)
    fix = f"set scene_center and scene_radius in {root / OPTIONS_FILE}"
    try:
        center, radius = view_sphere(
            viewmats,
            path,
            fix,
            center=options.scene_center,
            radius=options.scene_radius,
            axes_fix=other_convention_fix(path),
        )
    except ValueError:  # (the test file named where its poses, not the training file's, fail)
        _check_test_files_converge(viewmats, test, sources, path)
        raise
    # [H, W, 1] intensity or None; a training frame's image (read one at a time) calibrates the
    # intensity scale where spikegs.json gives none, and checks the spikes' orientation: the first
    # ORIENTATION_VIEWS training frames' images where it gives one (the check was skipped then;
    # the first frames', images or not, checked none where only later frames had images), those
    # that cannot be read or fitted left out (nothing else needs them)
    calibrate = options.rate_at_one is None
    checked = 0  # training images read for the orientation check alone

    # test images smaller than the spikes' frames, by the transforms file listing them: {file:
    # [(image, w, h)]} (transforms_test.json's were warned of as the training file's)
    upsampled = {}

    def mono(i: int, frame: dict, is_test: bool = False) -> np.ndarray | None:
        image = sized.pop(i) if i in sized else _image(root, frame, listings)
        if is_test and image is not None and (image.shape[0] < height or image.shape[1] < row):
            small = (frame["file_path"], image.shape[1], image.shape[0])
            upsampled.setdefault(sources[i], []).append(small)
        name = f"{root / frame['file_path']}"
        return _mono(image, src, (height, row), slice(shift, shift + width), name, what)

    def training_image(i: int, frame: dict) -> np.ndarray | None:
        nonlocal checked
        if calibrate:
            return mono(i, frame)
        if checked >= ORIENTATION_VIEWS:
            return None
        try:
            image = mono(i, frame)
        except ValueError:  # unreadable, or of another aspect ratio
            return None
        checked += image is not None
        return image

    images = [
        mono(i, frame, True) if is_test else training_image(i, frame)
        for i, (frame, is_test) in enumerate(zip(frames, test))
    ]
    for listed_in, small in upsampled.items():
        warn_upsampled_tests(
            listed_in, small, row, height, "or set height and width in spikegs.json"
        )
    sized.clear()  # a training image that gave the size but is not checked
    sphere = scene_sphere(options, center, radius)
    meta = camera_meta("nerf", root, K, height, width, options, **sphere)
    sized_by = f"{what} in {path}"
    opened = [
        None if p is None else open_spikes(p, height, width, options, sized_by) for p in spikes
    ]
    streams = [None if o is None else o[0] for o in opened]  # (stream, rates) each
    first = next((o for o in opened if o is not None), None)
    if first is not None:
        warn_rows_out_of_line(first[0], options.frame_settings())  # (the views share a frame size)
        warn_if_faint([first[1]], len(first[0]), first[0].path, OPTIONS_FILE)  # (a light)
    return views_dataset(root, meta, names, viewmats, streams, images, test, options, str(path))
