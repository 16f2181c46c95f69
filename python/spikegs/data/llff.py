"""The LLFF layout (SpikeNeRF's real scenes): poses_bounds.npy with spikes per view or one stream.

DIR/poses_bounds.npy            [N, 17]: per view a 3x5 matrix, row-major, [R | t | hwf] (R's
                                columns: the camera's down, right, backwards axes in the world;
                                t: its centre; hwf: height, width, focal in pixels), then the near
                                and far depth bounds
DIR/spikes/*.dat                one stream per view, in pose order by file name (LLFF's tools sort
                                names as strings: names whose numbers are not zero-padded, view_2
                                and view_10, are refused as ambiguous); or
DIR/spikes.dat + readouts.txt   one stream and the readout of each pose, one number a line
DIR/spikegs.json                loader options (real_options.py), all optional

Poses become OpenCV world-to-camera viewmats here (rotations within 1e-3 of one re-orthonormalised).
The scene sphere (`llff_sphere`) does not trust the far bounds, which may be loose.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from .dataset import (
    Dataset,
    check_intrinsics,
    microseconds_hint,
    read_column,
    spike_files,
    warn_if_faint,
    warn_rows_out_of_line,
)
from .real import (
    camera_meta,
    first_of,
    held_out_mask,
    light_span,
    scene_sphere,
    stream_dataset,
    views_dataset,
)
from .real_options import ASPECT_FIX, OPTIONS_FILE, Options, open_spikes, read_options
from .trajectory import PathLike, pixel_rays, readout_number, rigid_c2w
from .transforms_file import frame_columns
from .view_geometry import CONVERGING, axes_meeting, converging_centre, optical_axes

POSES_BOUNDS, SPIKES_DIR, STREAM, READOUTS = (
    "poses_bounds.npy",
    "spikes",
    "spikes.dat",
    "readouts.txt",
)
# camera axes [down, right, backwards] <-> [right, down, forward]; the matrix is its own inverse
LLFF_TO_OPENCV = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
# near bounds this many times the cameras' distance to where their axes meet: in other units
# (x10 lost 9 dB unsaid); nearer, axes that cross in front of the scene keep the frustum sphere
OFF_SCALE = 2.0
LOOSE_SPHERE = 20.0  # warn when the sphere is this many times the cameras' spread and near bound
# _warn_if_looking_away: view directions spread (CONVERGING) whose optical axes' nearest point
# lies behind every camera, within 60° of straight behind (cos < BEHIND_COS), and as far from them
# as the scene's near bounds or further: an inward orbit with its z axes reversed (OpenGL's axes
# written as LLFF's columns) trained 18.7 dB where its right poses gave 25.4, unsaid (the
# frustum sphere lies ahead of any cameras). A pan about a point just behind the lens (a tripod,
# a hand) has its axes meet there, nearer than the scene: not warned of
BEHIND_COS = -0.5


def natural_key(name: str) -> list:
    """Sort key comparing runs of digits as numbers: view_2 < view_10."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def viewmats_from_llff(poses: np.ndarray, source: str = POSES_BOUNDS) -> np.ndarray:
    """LLFF poses [N, 3, 5] -> OpenCV world-to-camera viewmats [N, 4, 4] (rotations
    re-orthonormalised; ValueError naming the view if one is not nearly a rotation)."""
    c2w = np.tile(np.eye(4), (len(poses), 1, 1))  # [N, 4, 4]
    c2w[:, :3, :3] = poses[:, :, :3] @ LLFF_TO_OPENCV
    c2w[:, :3, 3] = poses[:, :, 3]
    return np.linalg.inv(rigid_c2w(c2w, source))


def to_poses_bounds(viewmats: np.ndarray, hwf, bounds: np.ndarray) -> np.ndarray:
    """OpenCV viewmats [N, 4, 4], hwf (height, width, focal), bounds [N, 2] -> [N, 17] rows.
    ValueError naming the argument of another shape or with values not finite (one viewmat
    [4, 4], or one bounds pair for all views, failed inside numpy)."""
    viewmats = np.asarray(viewmats, np.float64)
    bounds, hwf = np.asarray(bounds, np.float64), np.asarray(hwf, np.float64)
    if viewmats.ndim != 3 or viewmats.shape[1:] != (4, 4):
        raise ValueError(f"viewmats: expected [N, 4, 4], found {list(viewmats.shape)}")
    if bounds.shape != (len(viewmats), 2):
        raise ValueError(
            f"bounds: expected [{len(viewmats)}, 2] (near, far a view), found {list(bounds.shape)}"
        )
    if hwf.shape != (3,):
        raise ValueError(f"hwf: expected (height, width, focal), found {hwf.tolist()}")
    for name, values in (("viewmats", viewmats), ("bounds", bounds), ("hwf", hwf)):
        if not np.isfinite(values).all():
            raise ValueError(f"{name}: values not finite (NaN or inf)")
    c2w = np.linalg.inv(viewmats)  # [N, 4, 4]
    poses = np.concatenate(
        [
            c2w[:, :3, :3] @ LLFF_TO_OPENCV,
            c2w[:, :3, 3:],
            np.tile(np.reshape(hwf, (1, 3, 1)), (len(c2w), 1, 1)),
        ],
        axis=2,
    )  # [N, 3, 5]
    return np.concatenate([poses.reshape(-1, 15), bounds], axis=1)


def frustum_sphere(
    viewmats: np.ndarray, bounds: np.ndarray, K: np.ndarray, width: int, height: int
):
    """Centre [3] and radius of the sphere around the box holding every view's image corners at
    its near and far depth (bounds [N, 2])."""
    u = np.array([0.0, width, 0.0, width])
    v = np.array([0.0, 0.0, height, height])
    rays = pixel_rays(u, v, K)  # [4, 3]
    points = bounds[:, :, None, None] * rays[None, None]  # [N, 2, 4, 3] camera coordinates
    c2w = np.linalg.inv(viewmats)  # [N, 4, 4]
    world = np.einsum("nij,nkcj->nkci", c2w[:, :3, :3], points) + c2w[:, None, None, :3, 3]
    world = world.reshape(-1, 3)
    center = (world.min(axis=0) + world.max(axis=0)) / 2
    return center, float(np.linalg.norm(world - center, axis=1).max())


def llff_sphere(
    viewmats: np.ndarray, bounds: np.ndarray, K: np.ndarray, width: int, height: int, source=""
):
    """Centre [3] and radius of the scene sphere. Inward-facing views (their directions spread,
    CONVERGING): centred on the point nearest to all optical axes, the radius reaching the
    cameras' near bounds (the 90th percentile over views of distance - near: one stray near
    bound, 0.01 of 50, made it 2.5 times the scene's), capped by the frustum sphere; where no
    near bound reaches in past that point, the frustum sphere, or, the near bounds OFF_SCALE
    times the cameras' distance to it (in other units than the poses: x10 lost 9 dB unsaid),
    the cameras' own sphere (`centre_of_view`), warned of. Forward-facing: the frustum
    sphere, each view's far bound capped at the 90th percentile of the far bounds. Warns when
    the result is LOOSE_SPHERE times the cameras' spread and near bound (loose far bounds): set
    scene_center and scene_radius in spikegs.json then."""
    far = np.minimum(bounds[:, 1], np.percentile(bounds[:, 1], 90))
    center, radius = frustum_sphere(viewmats, np.stack([bounds[:, 0], far], 1), K, width, height)
    eyes = optical_axes(viewmats)[0]  # [N, 3]
    converged = converging_centre(viewmats)
    if converged is not None:
        distance = np.linalg.norm(eyes - converged[0], axis=1)  # [N]
        # (the largest left out below 11 views: interpolated, one stray bound still counted)
        reach = float(np.percentile(distance - bounds[:, 0], 90, method="lower"))
        if reach > 0:
            center, radius = converged[0], min(radius, reach)
        elif (near := np.median(bounds[:, 0])) > OFF_SCALE * (meet := np.median(distance)):
            center, radius = converged
            warnings.warn(
                f"{source}: the near bounds (median {near:.3g}) lie over {OFF_SCALE:g} times as "
                f"far from the cameras as the point their optical axes meet at (median "
                f"{meet:.3g}): bounds in other units than the poses? The scene sphere is taken "
                f"from the cameras alone (centre there, radius {radius:.3g}, their mean distance "
                f"/ 2.5); set scene_center and scene_radius in {OPTIONS_FILE} if the scene is "
                f"known",
                stacklevel=3,
            )
    spread = np.linalg.norm(eyes - eyes.mean(0), axis=1).max()
    scale = max(spread, float(np.median(bounds[:, 0])))
    if radius > LOOSE_SPHERE * scale:
        warnings.warn(
            f"{source}: scene sphere radius {radius:.3g} is over {LOOSE_SPHERE:g} times the "
            f"cameras' spread and near bound ({scale:.3g}): the far bounds may be loose; set "
            f"scene_center and scene_radius in {OPTIONS_FILE} if the scene is smaller",
            stacklevel=3,
        )
    return center, radius


def _warn_if_looking_away(viewmats: np.ndarray, bounds: np.ndarray, source) -> None:
    """A UserWarning where the cameras (viewmats [N, 4, 4], depth bounds [N, 2]) look away from
    the point their optical axes meet at (BEHIND_COS), that point as far behind them as the
    scene's median near bound or further: an orbit read with its z axes reversed."""
    meeting = axes_meeting(viewmats)
    if meeting.spread < CONVERGING:
        return
    behind = meeting.depth < BEHIND_COS * meeting.distance  # [N]
    distance = float(np.median(meeting.distance))
    if behind.all() and distance >= np.median(bounds[:, 0]):
        warnings.warn(
            f"{source}: the cameras look away from the point their optical axes meet at (it "
            f"lies behind every one, {distance:.3g} away, the scene's near bounds "
            f"{np.median(bounds[:, 0]):.3g}), as an orbit's do whose poses were written in "
            f"another convention (OpenCV's axes, right, down and forwards, where LLFF's columns "
            f"are down, right, backwards; or OpenGL's matrices converted as OpenCV's): check the "
            f"poses' convention (a rig looking outwards from its middle is right so)",
            stacklevel=3,
        )


NPY_MAGIC, ZIP_MAGIC = b"\x93NUMPY", b"PK"  # how an .npy file and an .npz archive begin


def _read_poses_bounds(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Poses [N, 3, 5] and bounds [N, 2] of poses_bounds.npy, checked."""
    if not path.is_file():
        raise FileNotFoundError(f"LLFF poses file not found: {path}")
    with open(path, "rb") as file:
        head = file.read(len(NPY_MAGIC))
    if head != NPY_MAGIC and not head.startswith(ZIP_MAGIC):  # np.load's error spoke of pickles
        what = "empty" if not head else "no numpy header"
        if head and head.isascii() and head.decode().strip(" \t\r\n+-.0123456789eE") == "":
            what += ": text written by np.savetxt, say"  # (numbers as text)
        raise ValueError(f"{path}: not an .npy file ({what}): write the [N, 17] array with np.save")
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as err:
        raise ValueError(f"{path}: not a numeric .npy array ({err})") from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "iuf":  # (complex: numbers too)
        what = "an .npz archive" if not isinstance(arr, np.ndarray) else f"dtype {arr.dtype}"
        raise ValueError(f"{path}: expected a numeric .npy array [N, 17], found {what}")
    if arr.ndim != 2 or arr.shape[1] != 17 or len(arr) == 0:
        raise ValueError(
            f"{path}: expected [N, 17] (a 3x5 pose and near, far per view), found {list(arr.shape)}"
        )
    arr = arr.astype(np.float64)
    rows = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if rows.size:
        raise ValueError(
            f"{path}: non-finite (NaN/inf) values in the rows of views {rows.tolist()}"
        )
    poses, bounds = arr[:, :15].reshape(-1, 3, 5), arr[:, 15:]
    rows = np.flatnonzero(~((bounds[:, 0] > 0) & (bounds[:, 1] > bounds[:, 0])))
    if rows.size:
        raise ValueError(
            f"{path}: bounds expected 0 < near < far, not so for views {rows.tolist()}"
        )
    hwf = poses[:, :, 4]  # [N, 3]
    if not np.allclose(hwf, hwf[0], rtol=1e-6) or (hwf[0] <= 0).any():
        raise ValueError(
            f"{path}: height, width, focal expected positive and the same in every row"
        )
    return poses, bounds


def _read_readouts(path: Path, count: int) -> np.ndarray:
    """The readout [count] of each pose, strictly increasing, from readouts.txt."""
    if not path.is_file():
        raise FileNotFoundError(
            f"readouts file not found: {path} (one readout per pose, for {STREAM})"
        )
    readouts = read_column(path, "readout index")  # [P]
    if len(readouts) != count:
        raise ValueError(
            f"{path}: {len(readouts)} readouts for {count} poses; expected one per pose"
        )
    bad = np.flatnonzero(~np.isfinite(readouts))
    if not bad.size:
        bad = np.flatnonzero(np.diff(readouts) <= 0) + 1
    if bad.size:
        i = int(bad[0])
        after = (
            f" after {readout_number(readouts[i - 1])}" if i and np.isfinite(readouts[i]) else ""
        )
        raise ValueError(
            f"{path}: readouts expected finite and strictly increasing, found "
            f"{readout_number(readouts[i])} for pose {i}{after} (0-based indices into the spike "
            f"stream)"
        )
    return readouts


def llff_intrinsics(hwf: np.ndarray, options: Options, source: str) -> tuple[np.ndarray, int, int]:
    """K [3, 3], height and width of the spikes from hwf [3] (height, width, focal of the images
    the poses were made for) and the options. hwf's image is the spikes' frame, or the stored rows
    before a raw-row crop (raw_width, when its width is raw_width's at hwf's aspect): scaled to the
    spikes' height, the crop shifting cx by col_offset and keeping the focal. ValueError naming
    `source` when the aspect ratios differ by over a pixel (non-square pixels)."""
    h, w, f = hwf
    height, width = options.height or round(h), options.width or round(w)
    frame, shift = frame_columns(
        source, "hwf", (h, w), (height, width), ASPECT_FIX, options.raw_width, options.col_offset
    )
    K = np.array(
        [[f * frame / w, 0, frame / 2 - shift], [0, f * height / h, height / 2], [0, 0, 1]]
    )
    check_intrinsics(K, height, width, f"{source} (hwf {h:g}, {w:g}, {f:g})")
    return K, height, width


def _spike_files(folder: Path, count: int, source: Path) -> list[Path]:
    """The `count` .dat files [count] of spikes/, in pose order; ValueError when there are not
    `count`, or when their names order differently as strings (LLFF's order of the poses) and in
    natural order (ours): which pose is whose would be ambiguous."""
    # as strings, as LLFF's tools; a folder named *.dat is not a view's spikes, nor a hidden
    # file (macOS's ._000.dat beside 000.dat on a foreign disk: counted as views, unnamed)
    views = (p for p in folder.glob("*.dat") if p.is_file() and not p.name.startswith("."))
    files = sorted(views, key=lambda p: p.name)
    if len(files) != count:
        others = sorted(
            p.name
            for p in folder.iterdir()
            if p.is_file() and p.suffix != ".dat" and not p.name.startswith(".")
        )
        # a link to a disk not mounted, or a file moved: counted out unnamed ("15 .dat files"
        # where ls shows 16 names)
        dangling = sorted(p.name for p in folder.glob("*.dat") if p.is_symlink() and not p.exists())
        raise ValueError(
            f"{source} holds {count} poses but {folder} holds {len(files)} .dat files; "
            f"expected one per pose, in name order"
            + (f" (not read, not named *.dat: {first_of(others)})" if others else "")
            + (f" (links to nothing: {first_of(dangling)})" if dangling else "")
        )
    natural = sorted(files, key=lambda p: natural_key(p.name))
    if natural != files:
        i = next(i for i, (a, b) in enumerate(zip(natural, files)) if a != b)
        raise ValueError(
            f"{folder}: the .dat names order differently as strings and with numbers compared as "
            f"numbers (pose {i}: {files[i].name} as strings, {natural[i].name} in natural order), "
            f"so which pose of {POSES_BOUNDS} is whose is ambiguous: LLFF's tools (imgs2poses, "
            f"load_llff_data) order the poses by names sorted as strings, SpikeGS would pair them "
            f"in natural order. Zero-pad the numbers in the names (e.g. r_02.dat, r_10.dat) so "
            f"that both orders agree"
        )
    return files


def _check_stream_length(stream, readouts: np.ndarray, hwf: np.ndarray, options) -> None:
    """ValueError if readouts.txt reaches past the stream's end, saying whether the frame size
    came from hwf (spikes at another resolution than the poses' images read too few readouts)."""
    end = light_span(len(stream))[1]
    if readouts[-1] <= end:
        return
    size = f"{stream.height}x{stream.width}"
    in_us = microseconds_hint(readouts[-1], len(stream))
    if in_us:  # (the frame size was suggested first)
        cause = in_us.lstrip()
    elif readouts[0] > end:  # every pose past the end: a counter, not an index
        cause = (
            f"Every pose lies past the end (the first at {readout_number(readouts[0])}): "
            f"{READOUTS} holds 0-based readout indices into the spike file, not the camera's own "
            f"counter or timestamps (subtract the counter at the file's first readout)"
        )
    elif options.height and options.width:
        cause = f"The frame size {size} was set in {OPTIONS_FILE}; check it, or {READOUTS}"
    else:
        cause = (
            f"The frame size {size} was taken from hwf {hwf[:2].tolist()} in {POSES_BOUNDS}: if "
            f"the spikes are at another resolution, set height and width in {OPTIONS_FILE}; "
            f"else check {READOUTS}"
        )
    raise ValueError(
        f"{stream.path}: {len(stream)} readouts of {size}, but {READOUTS} places poses up to "
        f"readout {readout_number(readouts[-1])}. {cause}"
    )


def _warn_partial_span(stream, readouts: np.ndarray, hwf: np.ndarray) -> None:
    """Warn where the poses span less than half of the stream read at another frame size than
    hwf's: a frame size too small reads the file as more (scrambled) readouts. (Poses over part
    of a recording at hwf's size are this layout's use.)"""
    size_of_hwf = (stream.height, stream.width) == tuple(np.round(hwf[:2]).astype(int))
    if not size_of_hwf and readouts[-1] - readouts[0] < len(stream) / 2:
        warnings.warn(
            f"{stream.path}: {READOUTS}'s poses span readouts [{readout_number(readouts[0])}, "
            f"{readout_number(readouts[-1])}] of the {len(stream)} that the file holds at "
            f"{stream.height}x{stream.width}: the rest is not trained on; if that frame size is "
            f"wrong (set height and width in {OPTIONS_FILE}), the frames are read scrambled",
            stacklevel=3,
        )


def load_llff(path: PathLike, *, progress: bool = False, **overrides) -> Dataset:
    """Open an LLFF-layout directory (module docstring); `overrides` are spikegs.json options.
    Every file is checked before any spike is read. `progress`: a bar where one stream's pseudo
    ground truth searches long for a flicker."""
    root = Path(path)
    source = root / POSES_BOUNDS
    options = read_options(root, overrides)
    poses, bounds = _read_poses_bounds(source)
    viewmats = viewmats_from_llff(poses, str(source))  # [N, 4, 4]
    _warn_if_looking_away(viewmats, bounds, source)
    K, height, width = llff_intrinsics(poses[0, :, 4], options, str(source))
    test = held_out_mask(len(poses), options, str(source))
    given = options.scene_center is not None and options.scene_radius is not None
    computed = (None, None) if given else llff_sphere(viewmats, bounds, K, width, height, source)
    sphere = scene_sphere(options, *computed)
    near_far = {"near": float(bounds[:, 0].min()), "far": float(bounds[:, 1].max())}
    hwf = f"hwf ({poses[0, 0, 4]:g}, {poses[0, 1, 4]:g}) in {source}"  # what gives the size
    folder = root / SPIKES_DIR
    if (root / STREAM).is_file():
        if folder.is_dir():
            raise ValueError(
                f"{root}: both {STREAM} (one stream) and {SPIKES_DIR}/ (a stream per view) found; "
                f"keep one of them"
            )
        readouts = _read_readouts(root / READOUTS, len(poses))
        meta = camera_meta("llff-stream", root, K, height, width, options, **near_far, **sphere)
        stream, rates = open_spikes(root / STREAM, height, width, options, hwf)
        warn_rows_out_of_line(stream, options.frame_settings())
        warn_if_faint([rates], len(stream), stream.path, OPTIONS_FILE)
        _check_stream_length(stream, readouts, poses[0, :, 4], options)
        dataset = stream_dataset(
            root,
            meta,
            stream,
            readouts,
            viewmats,
            test,
            options,
            str(source),
            progress,
            readouts_file=root / READOUTS,
        )
        _warn_partial_span(stream, readouts, poses[0, :, 4])
        return dataset
    if not folder.is_dir():
        colour = [name for name in spike_files(3) if (root / name).exists()]
        raise FileNotFoundError(
            f"spikes not found in {root}: expected {SPIKES_DIR}/ (one .dat per view) or {STREAM} "
            f"with {READOUTS}"
            + (
                f" ({', '.join(colour)}: a colour camera's files, which the meta.json layout "
                f"reads; this layout is mono)"
                if colour
                else ""
            )
        )
    files = _spike_files(folder, len(poses), source)
    meta = camera_meta("llff", root, K, height, width, options, **near_far, **sphere)
    opened = [open_spikes(p, height, width, options, hwf) for p in files]  # (stream, rates)
    streams = [stream for stream, _ in opened]
    warn_rows_out_of_line(streams[0], options.frame_settings())  # (the views share a frame size)
    warn_if_faint([opened[0][1]], len(streams[0]), streams[0].path, OPTIONS_FILE)  # (a light)
    names = [p.stem for p in files]
    return views_dataset(
        root,
        meta,
        names,
        viewmats,
        streams,
        [None] * len(files),
        test,
        options,
        str(source),
    )
