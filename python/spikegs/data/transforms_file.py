"""The NeRF / nerfstudio transforms files: their documents, cameras (intrinsics checked, one
camera across frames), camera-to-world matrices as OpenCV viewmats, and frame images."""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np
import skimage.transform

from ..image_io import read_stored_image, srgb_to_linear, to_channels
from ..number_checks import is_number, number_array
from ..strict_json import json_text, read_json
from .dataset import check_intrinsics, intrinsics_keys
from .trajectory import rigid_c2w

IMAGE_EXTENSIONS = (
    ".png",
    ".exr",
    ".jpg",
    ".jpeg",
    ".tif",
    ".tiff",
)  # tried in turn after an extensionless path
OPENGL_TO_OPENCV = np.diag([1.0, -1.0, -1.0, 1.0])  # camera axes: y up, z back -> y down, z forward
SIMULATE_ASPECT_FIX = "simulate spikes of that aspect ratio (height, width; --height, --width)"
CAMERA_KEYS = ("camera_angle_x", "camera_angle_y", "fl_x", "fl_y", "cx", "cy", "w", "h")
DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2")  # FULL_OPENCV: k1..k6
# nerfstudio's camera models that are a pinhole (with distortion, warned of where not zero); the
# others (fisheye, equirectangular, ...) a pinhole rasterizer cannot render
PINHOLE_MODELS = ("PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "FULL_OPENCV", "SIMPLE_RADIAL", "RADIAL")
CAMERA_RANGES = {  # key: (in range, what is expected)
    "camera_angle_x": (lambda v: 0 < v < math.pi, "in (0, pi) radians"),
    "camera_angle_y": (lambda v: 0 < v < math.pi, "in (0, pi) radians"),
    "fl_x": (lambda v: v > 0, "> 0 (pixels)"),
    "fl_y": (lambda v: v > 0, "> 0 (pixels)"),
    "w": (lambda v: v > 0 and v.is_integer(), "a positive integer (pixels)"),
    "h": (lambda v: v > 0 and v.is_integer(), "a positive integer (pixels)"),
}


TRANSFORMS = ("transforms_train.json", "transforms_test.json", "transforms.json")  # NeRF layout


def warn_unread_transforms(root: Path, read: list[Path]) -> None:
    """A UserWarning naming the TRANSFORMS files in `root` that are not among `read` (the files
    taken: transforms_train.json + transforms_test.json, else one file)."""
    unread = [name for name in TRANSFORMS if (root / name).is_file() and root / name not in read]
    if unread:
        taken = ", ".join(p.name for p in read if p.is_file())
        warnings.warn(
            f"{root}: reading {taken}; {', '.join(unread)} not read (the layout takes "
            f"transforms_train.json + transforms_test.json, else one file)",
            stacklevel=3,
        )


def read_transforms_doc(path: Path) -> dict:
    """A transforms JSON (NeRF / nerfstudio); FileNotFoundError, or ValueError naming `path`
    unless it is an object with a non-empty list of frames, each with a file_path (text) and a
    transform_matrix. A backslash in a frame's file_path or spike_path is read as a separator
    (a Windows tool's `.\\images\\r_0.png` was a file name, not found)."""
    if not path.is_file():
        raise FileNotFoundError(f"transforms file not found: {path}")
    doc = read_json(path)
    if not isinstance(doc.get("frames", []), list):
        raise ValueError(f"{path}: expected a JSON object with a list of frames")
    for i, frame in enumerate(doc.get("frames") or []):
        if not (
            isinstance(frame, dict)
            and isinstance(frame.get("file_path"), str)
            and "transform_matrix" in frame
        ):
            raise ValueError(f"{path}: frame {i} needs a file_path (text) and a transform_matrix")
    if not doc.get("frames"):
        raise ValueError(f"{path}: no frames")
    for frame in doc["frames"]:
        for key in ("file_path", "spike_path"):
            if isinstance(frame.get(key), str):
                frame[key] = frame[key].replace("\\", "/")
    return doc


def _transform_matrix(path: Path, i: int, frame: dict) -> np.ndarray:
    """Frame i's transform_matrix [4, 4]; ValueError naming the frame if it is not 4x4 numbers."""
    try:
        matrix = number_array(frame["transform_matrix"])
    except (ValueError, TypeError):
        matrix = None
    if matrix is None or matrix.shape != (4, 4):
        raise ValueError(
            f"{path}: frame {i} ('{frame['file_path']}'): transform_matrix expected 4 rows of 4 "
            f"numbers, found {json_text(frame['transform_matrix'])}"[:300]
        )
    return matrix


def transforms_viewmats(path: Path, doc: dict) -> np.ndarray:
    """OpenCV world-to-camera viewmats [F, 4, 4] of a transforms document's frames (`path` names
    it in errors); rounded rotations made exactly rigid, other ones refused."""
    c2w = np.stack([_transform_matrix(path, i, f) for i, f in enumerate(doc["frames"])])
    bad = np.flatnonzero(~np.isfinite(c2w).all(axis=(1, 2)))  # c2w [F, 4, 4]
    if bad.size:
        raise ValueError(f"{path}: non-finite (NaN/inf) transform_matrix in frames {bad.tolist()}")
    if is_opengl(path, doc):
        c2w = c2w @ OPENGL_TO_OPENCV
    return np.linalg.inv(rigid_c2w(c2w, str(path), "frame"))


def intrinsics_text(K: np.ndarray) -> str:
    """fx, fy, cx, cy of a camera matrix [3, 3] to 9 significant digits (two cameras 1e-6 apart
    told apart), for a message."""
    return ", ".join(f"{v:.9g}" for v in intrinsics_keys(K).values())


def _camera_text(camera: dict) -> str:
    """A transforms file's camera keys and their numbers, for a message: 'w 48, fl_x 40.5'."""
    return ", ".join(f"{key} {value:.6g}" for key, value in camera.items())


def flat_frames(paths: list[Path], docs: list[dict]) -> tuple[list, list, list]:
    """The frames [F] of transforms documents `docs` (read from `paths`) in order, each frame's
    file [F] and its file's document [F]."""
    rows = [(frame, path, doc) for path, doc in zip(paths, docs) for frame in doc["frames"]]
    return [r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows]


def read_transforms(paths: list[Path], width: int, height: int, channels: int, background: float):
    """Frames [F_i, height, width, C] and OpenCV viewmats [F_i, 4, 4] of each of the transforms
    JSONs `paths` (training, then test frames), the K [3, 3] of their one camera and the first
    file's document. The files' cameras are checked as one (`one_camera_matrix`) once each file's
    first frame is read, before any other."""
    docs = [read_transforms_doc(path) for path in paths]
    viewmats = [transforms_viewmats(path, doc) for path, doc in zip(paths, docs)]  # [F_i, 4, 4]
    _warn_of_shared_images(paths[0], docs[0])
    frames, sources, frame_docs = flat_frames(paths, docs)
    cameras = read_cameras(frame_docs, frames, sources)
    listings: dict = {}  # each folder listed once (`frame_files`)
    firsts = [
        read_frame(p.parent / d["frames"][0]["file_path"], background, listings)
        for p, d in zip(paths, docs)
    ]
    # the aspect ratio and the frames' cameras as one (no crop here), before another frame is
    # read: a camera without w, h is for its file's images (their first one's size)
    sizes = {path: first.shape[:2] for path, first in zip(paths, firsts)}
    src, what = stated_size(paths[0], cameras[0], "its first frame")
    src = src or sizes[paths[0]]
    frame_columns(paths[0], what, src, (height, width), SIMULATE_ASPECT_FIX)
    K = one_camera_matrix(cameras, frames, sources, src, (height, width), sizes=sizes)
    images = []
    for i, (path, doc, first) in enumerate(zip(paths, docs, firsts)):
        # each frame into its place as it is read: a list of the resized frames in float64 and
        # their stack held 4 times the frames' float32 at once (200 frames, 400x400 colour: 2.2 GB
        # peak, 0.6 GB now)
        stack = np.empty((len(doc["frames"]), height, width, channels), np.float32)
        negative = []  # (file, values below 0, the lowest) a frame
        upsampled = []  # test frames smaller than the dataset's: (file, width, height)
        below = []  # frames upsampled to the dataset's size: (file, width, height)
        largest = (0, 0)  # the file's largest frame (height, width)
        for j, f in enumerate(doc["frames"]):
            image = read_frame(path.parent / f["file_path"], background, listings) if j else first
            h, w = image.shape[:2]
            largest = max(largest, (h, w))
            if h < height or w < width:
                (upsampled if i else below).append((f["file_path"], w, h))
            if (image < 0).any():  # a renderer's or denoiser's round-off in float images (EXR)
                negative.append((f["file_path"], int((image < 0).sum()), float(image.min())))
                image = np.maximum(image, 0.0)
            image = fitted(image, src, (height, width), f"{path.parent / f['file_path']}", what)
            stack[j] = to_channels(image, channels)
        if negative:
            warnings.warn(
                f"{path}: {len(negative)} frame(s) hold {sum(n for _, n, _ in negative)} values "
                f"below 0 (the lowest {min(low for *_, low in negative):.3g}, first in "
                f"{negative[0][0]}), set to 0: light is not negative",
                stacklevel=3,
            )
        warn_upsampled_tests(path, upsampled, width, height, "or simulate at theirs")
        # (a training frame's light, and the on-path truth from it, blurred unsaid, where the
        # others are not: frames all upsampled alike are the scene as given)
        smaller = [(n, w, h) for n, w, h in below if h < largest[0] or w < largest[1]]
        if smaller:
            name, w, h = smaller[0]
            warnings.warn(
                f"{path}: {len(smaller)} frame(s) smaller than its largest, {largest[1]}x"
                f"{largest[0]}, and than the dataset's {width}x{height} (first {name}, {w}x{h}) "
                f"are upsampled to it: their light, and the ground truth of a view made from it, "
                f"blurred; give the frames at one size",
                stacklevel=3,
            )
        images.append(stack)
    return images, viewmats, K, docs[0]


def _warn_of_shared_images(path: Path, doc: dict) -> None:
    """A UserWarning where two of a frame sequence's frames name one image file: the light at
    both poses is that one view's (a frame list copied, its file names left; taken unsaid)."""
    seen: dict[str, int] = {}
    for i, frame in enumerate(doc["frames"]):
        name = os.path.normpath(frame["file_path"])
        if name in seen:
            warnings.warn(
                f"{path}: frames {seen[name]} and {i} name one image ({frame['file_path']}): the "
                f"light at both poses is that one view's (a frame list copied, its file names "
                f"left?)",
                stacklevel=4,
            )
            return
        seen[name] = i


def warn_upsampled_tests(path, upsampled: list, width: int, height: int, fix: str) -> None:
    """A UserWarning where test images (file, w, h) of `path`'s are smaller than the dataset's
    width x height: upsampled to it as ground truth, a blurred truth scores renders higher than
    a sharp one; `fix` names the other way out."""
    if upsampled:
        name, w, h = upsampled[0]
        warnings.warn(
            f"{path}: {len(upsampled)} test image(s) smaller than the dataset's {width}x{height} "
            f"(first {name}, {w}x{h}) are upsampled to it as ground truth: a blurred truth "
            f"scores renders higher than a sharp one (+2.3 dB in a trial of 32x32 test frames "
            f"at 64x64); give test images at the dataset's size or larger, {fix}",
            stacklevel=4,
        )


def camera_number(path: Path, key: str, value) -> float:
    """A transforms file's camera value as a finite float, in CAMERA_RANGES for its key;
    ValueError naming `key` otherwise (a camera angle over pi: degrees, not radians?)."""
    number = float(value) if is_number(value) else math.nan  # "0.4" is text, true no number
    if not math.isfinite(number):
        raise ValueError(f"{path}: {key} expected a finite number, found {json_text(value)}")
    in_range, expected = CAMERA_RANGES.get(key, (lambda v: True, ""))
    if not in_range(number):
        degrees = key.startswith("camera_angle") and number >= math.pi
        hint = f" ({number:g} degrees would be {math.radians(number):.6g})" if degrees else ""
        raise ValueError(f"{path}: {key} expected {expected}, found {json_text(value)}{hint}")
    return number


def other_convention_fix(path: Path) -> str:
    """What `view_sphere` adds where a transforms file's cameras do not converge: its matrices
    may be in the other convention than it states (OpenCV ones unlabelled were told to give a
    scene sphere alone, which simulated them and left train to refuse)."""
    return (
        f", or, where its matrices are in the other convention than {path.name} states, state "
        f'theirs ("convention": "opencv" or "opengl")'
    )


def is_opengl(path: Path, doc: dict) -> bool:
    """Whether a transforms file's camera-to-world matrices are OpenGL's (y up, z back: the
    default) or OpenCV's ("convention": "opencv"); ValueError naming the file for another value."""
    convention = doc.get("convention", "opengl")
    if not isinstance(convention, str) or convention.lower() not in ("opengl", "opencv"):
        raise ValueError(
            f'{path}: convention {json_text(convention)}, expected "opengl" or "opencv"'
        )
    return convention.lower() == "opengl"


def fitted(
    image: np.ndarray, src: tuple, size: tuple, name: str, what: str = "the camera"
) -> np.ndarray:
    """`image` [h, w, C] resized to (h, w) `size` if need be; ValueError naming it (`name`) unless
    it has the aspect ratio of the camera's (h, w) `src` (its width within a pixel or 1 % of the
    camera's aspect at its height), `what` giving that size: another aspect ratio is another
    crop of the view, which resizing would stretch."""
    (h, w), (src_h, src_w) = image.shape[:2], src
    if abs(w - h * src_w / src_h) > max(1.0, 0.01 * w):
        raise ValueError(
            f"{name}: image {w}x{h} (aspect {w / h:.3f}), {what} is for {src_w}x{src_h} images "
            f"(aspect {src_w / src_h:.3f}): an image of another aspect ratio shows another crop "
            f"of the view; crop or pad it to the camera's"
        )
    if (h, w) == tuple(size):
        return image
    return skimage.transform.resize(image, size, anti_aliasing=True)


def read_cameras(docs: list, frames: list, sources: list) -> dict[int, dict]:
    """The cameras {key: number} of frames [F] (CAMERA_KEYS, DISTORTION_KEYS), each under the index
    of the first frame stating it, the first frame's first: the frame's own file's keys (docs [F],
    each frame's file's JSON; sources [F], its path), then the frame's (nerfstudio), else, where
    these state no intrinsics (or no distortion), the first frame's file's; each checked
    (`camera_number`); ValueError for a camera_model that is not a pinhole, or an is_fisheye
    (instant-ngp's); a warning for the first camera's non-zero distortion, which the pinhole
    rasterizer does not model. Cameras stated with other keys may still be one
    (`one_camera_matrix`)."""
    for doc, frame, source in zip(docs, frames, sources):
        stated = {**docs[0], **doc, **frame}
        model = stated.get("camera_model", "PINHOLE")
        # instant-ngp's colmap2nerf says fisheye so, without a camera_model: its k1..k4 are then
        # a fisheye's, and even at 0 the projection is not a pinhole's
        fisheye = stated.get("is_fisheye", False) not in (False, None)
        if model not in PINHOLE_MODELS or fisheye:
            key = "is_fisheye" if fisheye else "camera_model"  # the one stated: PINHOLE passes
            raise ValueError(
                f"{source}: {key} {json_text(stated[key])} of frame '{frame['file_path']}': the "
                f"rasterizer renders pinhole cameras ({', '.join(PINHOLE_MODELS)}); rectify the "
                f"frames to one"
            )
    cameras = {}
    for i, (doc, frame, source) in enumerate(zip(docs, frames, sources)):
        merged = {}
        for keys in (CAMERA_KEYS, DISTORTION_KEYS):  # the first file's where these state none
            own = {k: v for d in (doc, frame) for k, v in d.items() if k in keys}
            merged |= own or {k: v for k, v in docs[0].items() if k in keys}
        camera = {k: camera_number(source, k, v) for k, v in merged.items()}
        if camera not in cameras.values():
            cameras[i] = camera
    distortion = {k: cameras[0][k] for k in DISTORTION_KEYS if cameras[0].get(k, 0) != 0}
    if distortion:
        warnings.warn(
            f"{sources[0]}: distortion {distortion} ignored: the rasterizer assumes a pinhole "
            f"camera (undistort the spikes' frames to model it)",
            stacklevel=3,
        )
    return cameras


def _same_distortion(a: dict, b: dict) -> bool:
    """Whether cameras `a` and `b` state the same distortion (within 1e-6 relative, 1e-9 absolute;
    absent is 0)."""
    return np.allclose(
        [a.get(k, 0) for k in DISTORTION_KEYS],
        [b.get(k, 0) for k in DISTORTION_KEYS],
        rtol=1e-6,
        atol=1e-9,
    )


def one_camera_matrix(
    cameras: dict[int, dict],
    frames: list,
    sources: list,
    src: tuple,
    size: tuple,
    shift: float = 0,
    sizes: dict | None = None,
) -> np.ndarray:
    """K [3, 3] of the first of `cameras` (`read_cameras`) at `camera_matrix`'s `src`, `size` and
    `shift`, each other camera's at its own w, h where it states them, else at `sizes`' (h, w) of
    its file's images (default `src`); ValueError naming two frames whose cameras differ in K or
    in distortion (within 1e-6): one camera expected. Keys one file states and another leaves to
    their defaults (camera_angle_y, cx, w, h, ...) are one camera where they give the same K."""

    def matrix(i: int, camera: dict) -> np.ndarray:
        own = stated_size(sources[i], camera, "")[0] or (sizes or {}).get(sources[i], src)
        return camera_matrix(sources[i], camera, own, size, shift)

    (first, camera), *others = cameras.items()
    K = matrix(first, camera)
    for i, other in others:
        K_i = matrix(i, other)
        same_K = np.allclose(K_i, K, rtol=1e-6, atol=0)
        if not (same_K and _same_distortion(other, camera)):
            differ = "their distortion differs" if same_K else "their fx, fy, cx, cy differ"
            raise ValueError(
                f"{sources[i]}: frame '{frames[i]['file_path']}' has intrinsics "
                f"{_camera_text(other)} (fx, fy, cx, cy {intrinsics_text(K_i)}), frame "
                f"'{frames[first]['file_path']}' of {sources[first]} {_camera_text(camera)} "
                f"({intrinsics_text(K)}): {differ}; one camera expected"
            )
    return K


def stated_size(path: Path, camera: dict, image: str) -> tuple[tuple[int, int] | None, str]:
    """(h, w) of the images a camera's intrinsics are for, from its w and h (None without them,
    the size of `image` then), and what gives it (for `frame_columns`); ValueError naming `path`
    when the camera gives one of w, h alone."""
    if ("w" in camera) != ("h" in camera):
        raise ValueError(f"{path}: w and h expected together (the intrinsics' image size)")
    if "w" not in camera:
        return None, f"the camera (sized as {image})"
    return (int(camera["h"]), int(camera["w"])), "the camera (its w, h)"


def frame_columns(
    source, what: str, src: tuple, size: tuple, fix: str, raw_width=None, col_offset: int = 0
) -> tuple[int, int]:
    """(width, first column) of frames of `size` (h, w) within images of `src` (h, w) resized to
    their height: (w, 0), or (raw_width, col_offset) for a raw-row crop (src's width at that height
    within a pixel of raw_width's, not of w's); a crop keeps the focal. ValueError naming `source`
    and `what` src is, saying how to `fix` it, when neither is within a pixel: another aspect
    ratio, the focal would differ in x and y (non-square pixels)."""
    (src_h, src_w), (height, width) = src, size
    scaled = src_w * height / src_h  # the images' width at the frames' height
    crop = raw_width is not None and raw_width != width and abs(scaled - raw_width) <= 1
    frame, shift = (raw_width, col_offset) if crop else (width, 0)
    if abs(scaled - frame) > 1:
        stored = f" (or the {raw_width} stored pixels of a row, raw_width)" if raw_width else ""
        # sizes in the other order said (an LLFF hwf written w, h, f was told to set the size
        # already set: the real-layout trial); LLFF's order named for an hwf alone
        swapped = (
            f"; {what} gives the spikes' height and width in the other order: one of the two "
            f"transposed?" + (" (LLFF's hwf is height, width, focal)" if what == "hwf" else "")
            if (src_h, src_w) == (width, height)
            else ""
        )
        raise ValueError(
            f"{source}: {what} is for {src_h:g}x{src_w:g} images (height x width), of another "
            f"aspect ratio than the {height}x{width} spikes{stored}: {src_w / src_h:.4g} vs "
            f"{width / height:.4g}, the focal would differ in x and y (non-square pixels); {fix}"
            f"{swapped}"
        )
    return frame, shift


def camera_matrix(
    path: Path, camera: dict, src: tuple, size: tuple, shift: float = 0
) -> np.ndarray:
    """K [3, 3] of a transforms file's `camera` (`read_cameras`' keys: fl_x, fl_y, cx, cy, or
    camera_angle_x and camera_angle_y as instant-ngp writes them) for images of `src` (h, w),
    scaled to `size` (h, w) and moved `shift` columns left (a crop, `frame_columns`); cx, cy
    default to the image centre."""
    (src_h, src_w), (height, width) = src, size
    get = lambda key, default: camera_number(path, key, camera.get(key, default))  # noqa: E731
    sides = {"x": ("width", src_w), "y": ("height", src_h)}  # the image side an angle spans
    angles = {  # axis: the focal (px) of camera_angle_<axis> at the images' width or height
        axis: size / 2 / np.tan(get(f"camera_angle_{axis}", None) / 2)
        for axis, (_, size) in sides.items()
        if f"camera_angle_{axis}" in camera
    }
    if "fl_x" in camera or "fl_y" in camera:  # one focal given: square pixels
        fx = get("fl_x", camera.get("fl_y"))
        fy = get("fl_y", fx)
        for axis, focal in (("x", fx), ("y", fy)):
            if axis in angles and abs(angles[axis] - focal) > 0.01 * focal:
                warnings.warn(
                    f"{path}: fl_{axis} {focal:g} and camera_angle_{axis} (a focal of "
                    f"{angles[axis]:.6g} px at {sides[axis][0]} {sides[axis][1]:g}) "
                    f"disagree; fl_{axis} is used",
                    stacklevel=2,
                )
    elif "x" in angles:  # camera_angle_y (instant-ngp's), where given, the focal in y
        fx = fy = angles["x"]
        if "y" in angles and abs(angles["y"] - fx) > 0.01 * fx:
            warnings.warn(
                f"{path}: camera_angle_x and camera_angle_y give focals of {fx:.6g} and "
                f"{angles['y']:.6g} px: non-square pixels, taken as given (Blender's angle_y "
                f"follows its sensor's height whatever the render's aspect: where it came from "
                f"there, remove camera_angle_y)",
                stacklevel=2,
            )
        fy = angles.get("y", fx)
    else:
        raise ValueError(
            f"{path}: intrinsics expected (camera_angle_x, or fl_x/fl_y/cx/cy, in the file or "
            f"in every frame)"
        )
    cx, cy = get("cx", src_w / 2), get("cy", src_h / 2)
    sx, sy = width / src_w, height / src_h
    K = np.array([[fx * sx, 0.0, cx * sx - shift], [0.0, fy * sy, cy * sy], [0.0, 0.0, 1.0]])
    check_intrinsics(K, height, width, path)
    return K


def frame_files(base: Path, listings: dict | None = None) -> list[Path]:
    """The image files a frame's file_path `base` names: itself, or with an extension of
    IMAGE_EXTENSIONS added, or, where it ends in one, in place of it, in that order, in any
    case (a camera's r_0.PNG was passed over unsaid, the view then held out without its
    image). `listings`: {folder: its names (`_names_by_lower_case`)}, filled as folders are
    listed: one dict across a load's frames lists each folder once."""
    listings = {} if listings is None else listings
    if base.parent not in listings:
        listings[base.parent] = _names_by_lower_case(base.parent)
    names = listings[base.parent]
    # a path with an image's extension, as its stem too (r_0.png listed, r_0.jpg written:
    # every view was held out without its image, unsaid)
    stems = [base.name] + [base.stem] * (base.suffix.lower() in IMAGE_EXTENSIONS)
    found = [n for s in stems for ext in IMAGE_EXTENSIONS for n in names.get((s + ext).lower(), [])]
    return [p for p in dict.fromkeys([base, *(base.parent / n for n in found)]) if p.is_file()]


def _names_by_lower_case(folder: Path) -> dict[str, list[str]]:
    """The names in `folder` under their lower-case form, each list sorted; {} where there is no
    such folder."""
    names: dict[str, list[str]] = {}
    try:
        listed = sorted(os.listdir(folder))
    except OSError:  # no such folder: no image
        listed = []
    for name in listed:
        names.setdefault(name.lower(), []).append(name)
    return names


def frame_file(base: Path, listings: dict | None = None) -> Path:
    """The image file a frame's file_path `base` names, the first of `frame_files` (`listings`:
    theirs); FileNotFoundError where there is none, a warning where there are several."""
    files = frame_files(base, listings)
    if not files:
        raise FileNotFoundError(
            f"frame image not found: {base} (tried {', '.join(IMAGE_EXTENSIONS)})"
        )
    found = files[0]
    if found != base and found.stem == base.stem and base.suffix.lower() in IMAGE_EXTENSIONS:
        warnings.warn(  # one message per folder, not per frame
            f"{base.parent}: frame images named {base.suffix} (file_path), found as "
            f"{found.suffix}: read",
            stacklevel=2,  # one place for every frame: read_frame has two callers
        )
    elif len(files) > 1 and found != base:  # one message per folder, not per frame
        warnings.warn(
            f"{base.parent}: frame images in several formats "
            f"({', '.join(p.suffix for p in files)}): {found.suffix} is read, the first of "
            f"{', '.join(IMAGE_EXTENSIONS)}",
            stacklevel=2,
        )
    return found


def read_frame(base: Path, background: float, listings: dict | None = None) -> np.ndarray:
    """Linear RGB [h, w, 3] of an image file (`frame_file`: extension optional, as in NeRF
    synthetic; `listings` its), an alpha channel composited over `background` in linear light,
    colour read as the file's metadata says: sRGB or linear, associated with alpha (EXR) or not
    (PNG)."""
    stored = read_stored_image(frame_file(base, listings))
    colour = np.broadcast_to(stored.colour, (*stored.colour.shape[:2], 3)).astype(np.float64)
    alpha = None if stored.alpha is None else stored.alpha.astype(np.float64)  # [h, w, 1]
    if stored.srgb:
        if stored.premultiplied and alpha is not None:  # sRGB units of colour * alpha
            colour = np.divide(colour, alpha, out=np.zeros_like(colour), where=alpha > 0)
        colour = srgb_to_linear(colour)
    if alpha is not None:
        associated = stored.premultiplied and not stored.srgb
        colour = (colour if associated else colour * alpha) + background * (1 - alpha)
    return colour  # [h, w, 3]
