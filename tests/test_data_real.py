"""Real-data layouts (LLFF per-view / one stream, NeRF with spike_data/): fixtures cut from a
simulated dataset, pose conventions, windows within one view, bad input, training end to end."""

from __future__ import annotations

import errno
import json
import math
import os
import pickle
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from spikegs import SpikeStream
from spikegs.cli import main
from spikegs.config import load_config
from spikegs.data import load_dataset, make_source, simulate_dataset
from spikegs.data.correlation import correlation
from spikegs.data.dataset import Dataset, scale_guessed
from spikegs.data.llff import (
    _check_stream_length,
    _read_poses_bounds,
    _read_readouts,
    _spike_files,
    _warn_if_looking_away,
    _warn_partial_span,
    frustum_sphere,
    llff_intrinsics,
    llff_sphere,
    load_llff,
    to_poses_bounds,
    viewmats_from_llff,
)
from spikegs.data.nerf_layout import _spike_candidates, load_nerf_layout
from spikegs.data.orientation import check_orientation, other_bit_order
from spikegs.data.real import (
    _spaced_hold_out,
    first_of,
    held_out_mask,
    rate_from_images,
    stream_dataset,
    view_tfps,
    warn_pose_gaps,
)
from spikegs.data.real_options import OPTIONS_FILE, Options, open_spikes, read_options
from spikegs.data.trajectory import Trajectory, look_at
from spikegs.data.transforms_file import OPENGL_TO_OPENCV
from spikegs.data.view_stream import ViewStreams
from spikegs.evaluate import evaluate_run
from spikegs.image_io import read_image, write_image
from spikegs.sim_scores import evaluate_dataset
from spikegs.sim_train import train_sim
from spikegs.spikes import DatWriter, save_dat
from spikegs.targets import check_targets
from spikegs.train import Trainer

# the NeRF fixture's sharp test image is scaled by the percentile guess, which warns (tested below)
# (and its test/r_1 has none beside r_0's: said, tested below)
pytestmark = [
    pytest.mark.filterwarnings("ignore:.*sharp images are put in firing-rate units"),
    pytest.mark.filterwarnings("ignore:.* held-out views have no sharp image"),
]

H, W, VIEWS, LENGTH = 32, 48, 10, 70  # a view: LENGTH readouts of the simulated stream
SMALL = dict(height=H, width=W, test_on_path=1, test_off_path=0, progress=False)
FAST = {
    "train": {"iterations": 30, "init_gaussians": 500, "eval_every": 30, "checkpoint_every": 30},
    "supervision": {"exposure_weight": 0.5, "exposure_poses": 3},
}


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """A simulated moving camera: VIEWS x LENGTH readouts."""
    root = tmp_path_factory.mktemp("sim") / "solids"
    return simulate_dataset("solids", root, readouts=VIEWS * LENGTH, **SMALL)


def view_poses(sim) -> np.ndarray:
    """The pose [V, 4, 4] at the centre of each view's readouts."""
    return sim.trajectory.pose_at(np.arange(VIEWS) * LENGTH + LENGTH // 2)


def write_view(sim, path, i: int, length: int = LENGTH) -> None:
    """View i's readouts of the simulated stream as a .dat of its own."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with DatWriter(path, H, W) as writer:
        writer.write_packed(sim.stream.packed(i * LENGTH, i * LENGTH + length))


def bounds_of(sim, viewmats) -> np.ndarray:
    """Near and far [V, 2] around the scene sphere."""
    distance = np.linalg.norm(np.linalg.inv(viewmats)[:, :3, 3] - sim.scene_center, axis=1)
    return np.stack([distance - 1.5 * sim.scene_radius, distance + 1.5 * sim.scene_radius], 1)


@pytest.fixture(scope="module")
def llff(sim, tmp_path_factory):
    """LLFF with one spike file per view."""
    root = tmp_path_factory.mktemp("llff")
    viewmats = view_poses(sim)
    hwf = (H, W, sim.K[0, 0])
    np.save(root / "poses_bounds.npy", to_poses_bounds(viewmats, hwf, bounds_of(sim, viewmats)))
    for i in range(VIEWS):
        write_view(sim, root / "spikes" / f"{i:03d}.dat", i)
    return root


@pytest.fixture(scope="module")
def llff_stream(sim, tmp_path_factory):
    """LLFF with one continuous stream and readouts.txt: a pose every 50 readouts."""
    root = tmp_path_factory.mktemp("llff_stream")
    readouts = np.arange(0, VIEWS * LENGTH, 50)
    viewmats = sim.trajectory.pose_at(readouts)
    hwf = (H, W, sim.K[0, 0])
    np.save(root / "poses_bounds.npy", to_poses_bounds(viewmats, hwf, bounds_of(sim, viewmats)))
    np.savetxt(root / "readouts.txt", readouts, fmt="%d")
    shutil.copy(sim.root / "spikes.dat", root / "spikes.dat")
    return root


def nerf_frame(viewmat, file_path: str, **extra) -> dict:
    c2w = np.linalg.inv(viewmat) @ OPENGL_TO_OPENCV  # OpenGL camera-to-world
    return {"file_path": file_path, "transform_matrix": c2w.tolist(), **extra}


@pytest.fixture(scope="module")
def nerf(sim, tmp_path_factory):
    """transforms_{train,test}.json, spike_data/: test/r_0 has a sharp image, test/r_1 none."""
    root = tmp_path_factory.mktemp("nerf")
    viewmats = view_poses(sim)
    fov = float(2 * np.arctan(W / 2 / sim.K[0, 0]))
    train = [nerf_frame(viewmats[i], f"./train/r_{i}") for i in range(2, VIEWS - 1)]
    train.append(nerf_frame(viewmats[-1], "./train/last.png", spike_path="custom/last.dat"))
    test = [nerf_frame(viewmats[i], f"./test/r_{i}") for i in range(2)]
    for name, frames in (("train", train), ("test", test)):
        doc = {"camera_angle_x": fov, "w": W, "h": H, "frames": frames}
        (root / f"transforms_{name}.json").write_text(json.dumps(doc))
    for i in range(2, VIEWS - 1):
        write_view(sim, root / "spike_data" / "train" / f"r_{i}.dat", i)
    write_view(sim, root / "custom" / "last.dat", VIEWS - 1)
    write_view(sim, root / "spike_data" / "r_1.dat", 1)  # found by stem
    sharp = make_source("solids", W, H, 1).render(viewmats[0])  # [H, W, 1] intensity
    write_image(root / "test" / "r_0.exr", sharp)
    return root


def copy(root, tmp_path):
    out = tmp_path / root.name
    shutil.copytree(root, out)
    return out


def edit_json(path, edit) -> None:
    """Rewrite the JSON file at `path` with `edit(doc)` applied (in place)."""
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))


def write_options(root, **options) -> None:
    (root / "spikegs.json").write_text(json.dumps(options))


def edit_poses(root, edit) -> None:
    """Rewrite ROOT/poses_bounds.npy with `edit(rows)` [N, 17] applied (in place)."""
    rows = np.load(root / "poses_bounds.npy")
    edit(rows)
    np.save(root / "poses_bounds.npy", rows)


# -- loading ---------------------------------------------------------------------------------------
def test_llff_per_view_loads(sim, llff):
    ds = load_dataset(llff)
    assert ds.meta["layout"] == "llff" and (ds.height, ds.width, ds.channels) == (H, W, 1)
    assert len(ds.stream) == ds.num_readouts == VIEWS * LENGTH
    np.testing.assert_allclose(ds.K, sim.K, rtol=1e-6)
    assert [v.name for v in ds.test_views] == ["pseudo_000", "pseudo_008"]  # every 8th view
    assert (
        ds.meta["test_ground_truth"]["pseudo"] == 2
        and "pseudo_method" in ds.meta["test_ground_truth"]
    )
    centers = np.arange(VIEWS) * LENGTH + (LENGTH - 1) // 2
    np.testing.assert_array_equal(ds.train_timestamps, np.delete(centers, [0, 8]))
    # pseudo ground truth: TFP of the whole held-out view (69 readouts, odd)
    np.testing.assert_allclose(ds.test_views[1].image[..., 0], sim.stream.tfp(8 * LENGTH + 34, 69))
    # the sphere around the frustums holds the simulated scene's centre
    assert np.linalg.norm(ds.scene_center - sim.scene_center) < ds.scene_radius
    assert ds.meta["near"] > 0 and ds.meta["far"] > ds.meta["near"]
    # meta.json's keys: the rows as stored (raw_width defaults to the width) and the files in order
    assert (ds.meta["raw_width"], ds.meta["col_offset"]) == (W, 0)
    assert ds.meta["spike_files"] == [f"spikes/{i:03d}.dat" for i in range(VIEWS)]


def test_llff_stream_loads(sim, llff_stream):
    ds = load_dataset(llff_stream)
    assert ds.meta["layout"] == "llff-stream" and len(ds.stream) == VIEWS * LENGTH
    # poses 0 and 8 are held out; pose 0 (readout 0) has no room for a window, so only 8 is scored
    assert [v.name for v in ds.test_views] == ["pseudo_view_008"]
    assert ds.test_views[0].readout == 400
    ts = ds.train_timestamps
    assert np.abs(ts - 400).min() > 64 and np.abs(ts - 0).min() > 64
    assert ts.min() >= 32 and ts.max() <= 650 - 32  # exposure poses within the recorded ones
    np.testing.assert_allclose(ds.trajectory.pose_at(375), sim.trajectory.pose_at(375), atol=1e-2)


def test_nerf_layout_loads(sim, nerf):
    ds = load_dataset(nerf)
    assert ds.meta["layout"] == "nerf"
    assert [v.name for v in ds.test_views] == ["test_r_0", "pseudo_test_r_1"]
    assert ds.meta["test_ground_truth"]["sharp_images"] == 1
    sharp, pseudo = ds.test_views
    assert sharp.readout is None  # no spikes of r_0: off the path
    clean = make_source("solids", W, H, 1).render(view_poses(sim)[0])  # [H, W, 1]
    np.testing.assert_allclose(sharp.image, clean * ds.meta["image_scale"], rtol=1e-5)
    assert pseudo.readout is not None
    assert len(ds.stream) == 9 * LENGTH and len(ds.train_timestamps) == 8
    # each view's readouts hold its own pose, after test/r_0, which has no spikes (the poses of
    # the views with spikes, not the first 9, shifted test/r_1's onto r_0's)
    start, end = ds.meta["view_readouts"]["test_r_1"]
    np.testing.assert_allclose(ds.trajectory.pose_at(float(start)), pseudo.viewmat, atol=1e-9)
    np.testing.assert_allclose(ds.trajectory.pose_at(float(end - 1)), pseudo.viewmat, atol=1e-9)
    np.testing.assert_allclose(ds.K, sim.K, rtol=1e-6)
    assert np.linalg.norm(ds.scene_center - sim.scene_center) < 0.5 * sim.scene_radius


def test_nerf_paths_with_windows_separators_load_as_with_slashes(nerf, tmp_path):
    """A Windows tool's transforms file (`.\\train\\r_2`, spike_path `custom\\last.dat`) was
    told "spike file of frame '.\\train\\r_2' not found", and a held-out frame with a sharp
    image and such a spike_path loaded as an image-only view without its spikes, unsaid."""
    root = copy(nerf, tmp_path)
    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(
            root / name,
            lambda doc: [
                frame.update({k: frame[k].replace("/", "\\")})
                for frame in doc["frames"]
                for k in ("file_path", "spike_path")
                if k in frame
            ],
        )
    assert "\\\\last.dat" in (root / "transforms_train.json").read_text()  # (JSON's escape)
    ours, theirs = load_dataset(nerf), load_dataset(root)
    assert [v.name for v in theirs.test_views] == [v.name for v in ours.test_views]
    assert theirs.meta["spike_files"] == ours.meta["spike_files"]
    np.testing.assert_array_equal(theirs.train_timestamps, ours.train_timestamps)
    np.testing.assert_array_equal(theirs.test_views[0].image, ours.test_views[0].image)


def test_a_small_test_image_is_named_with_the_file_listing_it(nerf, tmp_path):
    """A test image smaller than the spikes' frames, listed in transforms_test.json, was warned
    of as transforms_train.json's."""
    root = copy(nerf, tmp_path)
    small = read_image(root / "test" / "r_0.exr")[::2, ::2]  # [H/2, W/2, 1]
    write_image(root / "test" / "r_0.exr", small)
    with pytest.warns(UserWarning, match=r"transforms_test\.json: 1 test image\(s\) smaller than"):
        load_dataset(root)


def test_raw_stream_options(sim, llff_stream, tmp_path):
    """Rows with extra columns, stored top-down: spikegs.json crops and un-flips."""
    root = copy(llff_stream, tmp_path)
    bits = np.unpackbits(sim.stream.packed(), axis=-1, bitorder="little")[..., :W]  # [T, H, W]
    raw = np.zeros((len(bits), H, W + 16), np.uint8)
    raw[..., 8 : 8 + W] = bits
    save_dat(root / "spikes.dat", raw, flip=False)
    with pytest.raises(ValueError, match="spikes.dat"):
        load_dataset(root)  # 64-pixel rows do not fit 32x48 readouts of this length
    (root / "spikegs.json").write_text(
        json.dumps({"raw_width": W + 16, "col_offset": 8, "flip": False})
    )
    ds = load_dataset(root)
    np.testing.assert_array_equal(ds.stream.packed(), sim.stream.packed())
    assert ds.meta["raw_width"] == W + 16


def test_rows_wider_than_the_image_without_raw_width_are_named(sim, llff_stream, tmp_path):
    """A camera's rows with extra columns read without raw_width: rows of W + 24 pixels taken W
    at a time start each 24 pixels further along the scene, and frames of the wrong size blur
    every image into noise, trained so without a word (11.8 dB where raw_width gave 25.4). Read
    with wider rows the file gives an image: the warning names the width; raw_width silences
    it."""
    root = copy(llff_stream, tmp_path)
    bits = np.unpackbits(sim.stream.packed(), axis=-1, bitorder="little")[..., :W]  # [T, H, W]
    raw = np.random.default_rng(0).integers(0, 2, (len(bits), H, W + 24), dtype=np.uint8)
    raw[..., 4 : 4 + W] = bits  # the extra columns: noise
    save_dat(root / "spikes.dat", raw)  # a whole number of 32x48 frames too
    write_options(root, height=H, width=W)
    with pytest.warns(
        UserWarning,
        match=rf"rows of {W} pixels .* correlate at -?0\.\d+, read "
        rf"with rows of {W + 24} pixels at 0\.\d+: .* set raw_width {W + 24}",
    ):
        load_dataset(root)
    keyed = r"in spikegs.json or the loader's keywords \(height, width\), which override it; "
    with pytest.warns(UserWarning, match=rf"set raw_width {W + 24}, and col_offset, .* {keyed}"):
        load_llff(root, height=H, width=W)
    write_options(root, height=H, width=W, raw_width=W + 24, col_offset=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = load_dataset(root)
    np.testing.assert_array_equal(ds.stream.packed(), sim.stream.packed())


def test_per_view_rows_wider_than_the_image_name_the_loaders_keywords(sim, llff, tmp_path):
    """LLFF's per-view files are checked as its stream is: a camera's rows of W + 24 pixels read
    W at a time are warned of, the advice naming the loader's keywords where they were given."""
    root = copy(llff, tmp_path)
    bits = np.unpackbits(sim.stream.packed(0, LENGTH), axis=-1, bitorder="little")[..., :W]
    raw = np.random.default_rng(0).integers(0, 2, (LENGTH, H, W + 24), dtype=np.uint8)
    raw[..., 4 : 4 + W] = bits  # [T, H, W + 24] the extra columns: noise
    save_dat(root / "spikes" / "000.dat", raw)
    keyed = r"in spikegs.json or the loader's keywords \(flip\), which override it; "
    with pytest.warns(UserWarning, match=rf"set raw_width {W + 24}, and col_offset, .* {keyed}"):
        load_llff(root, flip=True)  # (its default, given: where the advice says to look)


def test_a_dense_pose_log_holds_out_poses_spaced_in_readouts(sim, llff_stream, tmp_path):
    """A pose every 5 readouts (a motion-capture log): every 8th pose, 40 readouts apart, kept
    every training timestamp within 64 readouts of one and none was left, an error (a log a
    little sparser kept a handful). Where the default keeps under a quarter of what spaced
    poses keep, poses 8 clearances apart are held out instead (about 1 in 8 timestamps lost to
    them), of those whose pseudo ground truth fits, said in a warning; test_views still
    chooses."""
    root = copy(llff_stream, tmp_path)

    def log(readouts, **options) -> Dataset:  # [P]: the loaded dataset of poses there
        viewmats = sim.trajectory.pose_at(readouts)
        rows = to_poses_bounds(viewmats, (H, W, sim.K[0, 0]), bounds_of(sim, viewmats))
        np.save(root / "poses_bounds.npy", rows)
        np.savetxt(root / "readouts.txt", readouts, fmt="%d")
        write_options(root, **options)
        return load_dataset(root)

    said = r"every 8th pose, the default held-out views, leaves 0 training timestamps .* held out "
    every5 = np.arange(0, VIEWS * LENGTH, 5)  # [140]; windows fit at readouts 32-667: poses 7-133
    room = r"of those with room for the pseudo ground truth's window"
    with pytest.warns(  # (a review: "the middle one", where 7-133 fit)
        UserWarning, match=said + rf"pose 111 instead \(1 of 140, every 208th {room}, from the 105t"
    ):
        ds = log(every5)
    assert [(v.name, v.readout) for v in ds.test_views] == [("pseudo_view_111", 555.0)]
    assert len(ds.train_timestamps) and not (abs(ds.train_timestamps - 555) <= 64).any()
    with pytest.warns(UserWarning, match=said + r"pose 112 instead \(1 of 140, every 210th"):
        log(every5, train_every=2)  # 8 clearances of 129 + 2 readouts
    with pytest.warns(
        UserWarning, match=said + rf"pose 83 instead \(1 of 151, the middle one {room}"
    ):
        assert log(np.arange(0, 301, 2)).test_views[0].readout == 166.0  # the middle one
    # every 17 readouts: every 8th pose, 136 apart, leaves a few timestamps between them
    few = r"every 8th pose, the default held-out views, leaves [1-9]\d? training timestamps"
    with pytest.warns(UserWarning, match=few):
        assert len(log(np.arange(0, VIEWS * LENGTH, 17)).train_timestamps) > 400
    assert [v.readout for v in log(every5, test_views=[20, 120]).test_views] == [100.0, 600.0]
    with pytest.raises(ValueError, match="no training timestamp left"):  # the user's, kept
        log(every5, test_views=list(range(0, 140, 8)))
    # an uneven log, a pose every 10 readouts up to 350 then every 50: every 8th pose leaves
    # the dense half no timestamp, where the sparse half keeps enough that the spaced rule
    # stays out; the stretch is named (trained unsaid from the neighbouring stretches)
    uneven = np.concatenate([np.arange(0, 350, 10), np.arange(350, VIEWS * LENGTH, 50)])  # [42]
    untrained = r"no training timestamp between readouts 32-3\d\d: "
    with pytest.warns(UserWarning, match=untrained) as said:
        assert len(log(uneven).train_timestamps) > 100
    assert not any("a train_every under" in str(w.message) for w in said)  # train_every is 1
    with warnings.catch_warnings(record=True) as said:  # held-out poses of the user's: as
        warnings.simplefilter("always")  # chosen, unsaid; pose 3 (readout 30) is not scored
        log(uneven, test_views=[3, 11, 19, 27])  # 80 readouts apart: 32-334 untrained
    assert [str(w.message).split(": ", 1)[1] for w in said] == [
        "held-out pose 3 (readout 30) within 32 readouts of the stream's ends, where a "
        "65-readout pseudo ground truth does not fit, is not scored (3 of 4 held-out poses are; "
        "training stays clear of it all the same): test_views in spikegs.json with room around "
        "them, or a pseudo_gt_window of 61 or less, scores them"
    ]
    # a uniform log whose train_every steps over the strips between clearances: said too
    with pytest.warns(UserWarning, match=r"between readouts .*: .* a train_every under 130"):
        log(np.arange(0, VIEWS * LENGTH, 20), train_every=130)


def test_ordinals_read_as_english():
    from spikegs.data.real import ordinal

    assert [ordinal(n) for n in (1, 2, 3, 4, 11, 12, 13, 21, 22, 101, 111, 131, 208)] == [
        "1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "101st", "111th",
        "131st", "208th",
    ]  # fmt: skip


def test_a_list_in_a_message_counts_what_it_leaves_out():
    assert first_of(list("abcde")) == "a, b, c, d, e"
    assert first_of(list("abcdef")) == "a, b, c, d, e and 1 more"
    assert first_of(list("abc"), shown=2) == "a, b and 1 more"


def test_poses_whose_cameras_look_away_are_named(sim, llff_stream, tmp_path):
    """An orbit's poses with z reversed (OpenGL's matrices converted to LLFF's columns as
    OpenCV's, as here): every camera looks away from what it circles. The LLFF layout's frustum
    sphere lies ahead of them all, so the poses trained (18.7 dB where the right ones gave 25.4)
    without a word; the point the optical axes meet at lies behind every camera."""
    root = copy(llff_stream, tmp_path)
    readouts = np.loadtxt(root / "readouts.txt")
    flipped = np.diag([1.0, -1.0, -1.0, 1.0]) @ sim.trajectory.pose_at(readouts)  # [N, 4, 4]
    bounds = bounds_of(sim, sim.trajectory.pose_at(readouts))
    np.save(root / "poses_bounds.npy", to_poses_bounds(flipped, (H, W, sim.K[0, 0]), bounds))
    with pytest.warns(
        UserWarning,
        match=r"the cameras look away from the point their optical "
        r"axes meet at \(it lies behind every one",
    ):
        load_dataset(root)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_dataset(llff_stream)
        # a pan about a point 5 cm behind the lens (a tripod): the axes meet there, behind
        # every camera, but nearer than the scene's near bound of 1
        turns = np.radians(np.linspace(-40, 40, 9))
        ahead = np.stack([np.cos(turns), np.sin(turns), np.zeros(9)], 1)  # [9, 3]
        pan = np.stack([look_at(0.05 * d, 2.0 * d) for d in ahead])  # [9, 4, 4]
        _warn_if_looking_away(pan, np.tile([1.0, 5.0], (9, 1)), "pan")
        # half the orbit's cameras reversed: not every camera looks away
        half = sim.trajectory.pose_at(readouts).copy()  # [N, 4, 4]
        half[::2] = np.diag([1.0, -1.0, -1.0, 1.0]) @ half[::2]
        _warn_if_looking_away(half, bounds, "half")


def test_cameras_looking_away_within_60_degrees_of_straight_back_are_named():
    """A ring of cameras whose optical axes all point 50° off straight away from the ring's
    centre (the point the axes meet at lies 130° off each axis: behind, within 60° of straight
    back) is warned of; 75° off (105°: nearer sideways than back) is not. Guards against the
    cone (BEHIND_COS = cos 120°) widened to take sideways views for reversed ones, or narrowed."""
    ring = np.radians(np.arange(0, 360, 30))
    for off, warned in ((50, True), (75, False)):
        views = []
        for a in ring:
            away, along = np.array([np.cos(a), np.sin(a), 0]), np.array([-np.sin(a), np.cos(a), 0])
            look = np.cos(np.radians(off)) * away + np.sin(np.radians(off)) * along
            views.append(look_at(4 * away, 4 * away + look, up=(0.0, 0.0, 1.0)))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _warn_if_looking_away(np.stack(views), np.tile([1.0, 5.0], (12, 1)), "ring")
        said = [str(w.message) for w in caught]
        assert len(said) == warned and all("look away" in m for m in said), (off, said)


def test_poses_bounds_rows_checked_at_their_edges(tmp_path):
    """poses_bounds.npy: a near bound of 0 (a camera at the scene's surface, a depth nothing
    divides by), near == far, and a height, width or focal of 0 are refused naming the file, as
    is an hwf that differs by 1e-4 between rows (another camera). Guards against each check's
    bound relaxed by one step (>= 0, <= near, < 0, a 1e-2 tolerance)."""

    poses = np.tile(np.concatenate([np.eye(3), np.zeros((3, 1)), [[32], [48], [40]]], 1), (3, 1, 1))
    good = np.concatenate([poses.reshape(3, 15), np.tile([1.0, 5.0], (3, 1))], 1)  # [3, 17]
    path = tmp_path / "poses_bounds.npy"
    np.save(path, good)
    _read_poses_bounds(path)
    for (row, col), value, message in (
        ((1, 15), 0.0, r"bounds expected 0 < near < far, not so for views \[1\]"),
        ((2, 16), 1.0, r"bounds expected 0 < near < far, not so for views \[2\]"),
        ((slice(None), 4), 0.0, "height, width, focal expected positive"),
        ((1, 14), 40 * (1 + 1e-4), "height, width, focal expected positive and the same"),
    ):
        bad = good.copy()
        bad[row, col] = value
        np.save(path, bad)
        with pytest.raises(ValueError, match=f"poses_bounds.npy: {message}"):
            _read_poses_bounds(path)


def test_to_poses_bounds_names_an_argument_of_another_shape():
    """One viewmat [4, 4], one bounds pair for every view, an hwf of two values or a NaN pose
    failed inside numpy ("too many indices", a concatenation's dimensions) or were written:
    each is named; right arguments give the rows."""
    viewmats, hwf, bounds = np.tile(np.eye(4), (3, 1, 1)), (H, W, 50.0), np.tile([1.0, 9.0], (3, 1))
    assert to_poses_bounds(viewmats, hwf, bounds).shape == (3, 17)
    nan = viewmats.copy()
    nan[1, 0, 3] = np.nan
    for args, said in [
        ((viewmats[0], hwf, bounds[:1]), r"viewmats: expected \[N, 4, 4\], found \[4, 4\]"),
        ((viewmats, hwf, np.array([1.0, 9.0])), r"bounds: expected \[3, 2\] \(near, far a view"),
        ((viewmats, (H, W), bounds), r"hwf: expected \(height, width, focal\), found"),
        ((nan, hwf, bounds), "viewmats: values not finite"),
    ]:
        with pytest.raises(ValueError, match=said):
            to_poses_bounds(*args)


def test_a_poses_bounds_file_not_an_n_by_17_number_array_is_named(tmp_path):
    """poses_bounds.npy missing (load_llff called on another folder), an .npz archive, an
    array of text and one of another shape are refused naming the file."""
    path = tmp_path / "poses_bounds.npy"
    with pytest.raises(FileNotFoundError, match="LLFF poses file not found: .*poses_bounds.npy"):
        _read_poses_bounds(path)
    with path.open("wb") as f:  # (np.savez would add .npz to the name)
        np.savez(f, rows=np.ones((3, 17)))
    with pytest.raises(ValueError, match=r"poses_bounds.npy: expected .*\[N, 17\], found an .npz"):
        _read_poses_bounds(path)
    for array, found in [
        (np.full((3, 17), "1.0"), "found dtype <U3"),
        (np.ones((3, 15)), r"a 3x5 pose and near, far per view\), found \[3, 15\]"),
        (np.ones((0, 17)), r"found \[0, 17\]"),
        (np.ones(17), r"found \[17\]"),
    ]:
        np.save(path, array)
        with pytest.raises(ValueError, match=f"poses_bounds.npy: expected .*{found}"):
            _read_poses_bounds(path)


def test_forward_facing_views_toed_out_are_not_taken_for_looking_away(llff):
    """Forward-facing cameras toed out by 1° (their axes meet 7 behind them) spread their
    directions under CONVERGING: no convention warning (guards against the spread test skipped,
    which took a rig's slight divergence for reversed axes). meta's near and far: the bounds'
    least near and greatest far."""
    toe = np.radians(np.linspace(-1, 1, 5))
    xs = np.linspace(-0.125, 0.125, 5)
    views = np.stack([look_at([x, 0, 0], [x + np.sin(t), np.cos(t), 0]) for x, t in zip(xs, toe)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _warn_if_looking_away(views, np.tile([1.0, 5.0], (5, 1)), "forward")
    bounds = np.load(llff / "poses_bounds.npy")[:, 15:]
    ds = load_dataset(llff)
    assert (ds.meta["near"], ds.meta["far"]) == (bounds[:, 0].min(), bounds[:, 1].max())


def test_llff_spike_files_miscounted_name_the_other_files_but_not_hidden_ones(tmp_path):
    """spikes/ with 2 .dat files for 3 poses: the error names the files not read (003.bin, a
    view's spikes of another extension) but not hidden ones (.DS_Store, a Finder's), which only
    hid the one that matters (guards against the dot filter dropped)."""

    for name in ("001.dat", "002.dat", "003.bin", ".DS_Store"):
        (tmp_path / name).write_bytes(b"")
    with pytest.raises(
        ValueError, match=r"holds 2 \.dat files;.*\(not read, not named \*\.dat: "
    ) as e:
        _spike_files(tmp_path, 3, tmp_path / "poses_bounds.npy")
    assert "003.bin" in str(e.value) and ".DS_Store" not in str(e.value)


# -- conventions -----------------------------------------------------------------------------------
def random_viewmats(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([look_at(rng.normal(size=3) * 3, rng.normal(size=3) * 0.3) for _ in range(n)])


def test_llff_pose_round_trip_and_convention():
    viewmats = random_viewmats(6)
    rows = to_poses_bounds(viewmats, (H, W, 50.0), np.tile([1.0, 9.0], (6, 1)))
    poses = rows[:, :15].reshape(-1, 3, 5)
    np.testing.assert_allclose(viewmats_from_llff(poses), viewmats, atol=1e-6)
    # LLFF's columns are [down, right, backwards]: NeRF's reorder gives OpenGL [right, up, back]
    opengl = np.concatenate([poses[:, :, 1:2], -poses[:, :, 0:1], poses[:, :, 2:4]], 2)  # [N, 3, 4]
    c2w = np.linalg.inv(viewmats)
    np.testing.assert_allclose(
        opengl[:, :, :3] @ OPENGL_TO_OPENCV[:3, :3], c2w[:, :3, :3], atol=1e-9
    )
    np.testing.assert_allclose(opengl[:, :, 3], c2w[:, :3, 3], atol=1e-9)


def test_nerf_pose_round_trip(sim, nerf):
    ds = load_dataset(nerf)
    np.testing.assert_allclose(ds.test_views[0].viewmat, view_poses(sim)[0], atol=1e-6)
    np.testing.assert_allclose(ds.trajectory.pose_at(0), view_poses(sim)[2], atol=1e-6)


def test_sim_train_notes_pseudo_ground_truth(nerf, tmp_path, capsys, monkeypatch):
    args = ["sim-train", str(nerf), "--steps", "2", "--crop", "16", "--batch-size", "1"]
    out = tmp_path / "sim.pt"
    assert main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "note: 1 views without a sharp image" in printed
    assert "(PSNR of firing rates, spikes a readout, over a data range of 1: " in printed
    scores = json.loads((tmp_path / "sim.pt.json").read_text())  # the table, for a script
    # which views the means are over, on stdout too (the numbers audit: the JSON alone said)
    n = len(scores["views"])
    assert f"the means over the {n} test views on the camera's path, at their readouts)" in printed
    assert scores["sim"] == str(out.resolve()) and scores["trained_now"] and scores["seconds"] > 0
    assert set(scores["scores"]) >= {"SIM", "TFP(33)", "TFI"}
    assert all(f"{s['psnr']:.4g}" in printed for s in scores["scores"].values())  # the table's
    os.utime(out, (0, 0))
    assert main([*args, "--out", str(out)]) == 0  # reused: the latest SIM for poses --sim
    assert "reused" in capsys.readouterr().out and out.stat().st_mtime > 0

    def read_only(path, times=None):  # a read-only dataset's SIM: its reuse crashed on EROFS
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))

    monkeypatch.setattr("spikegs.sim_cli.os.utime", read_only)
    assert main([*args, "--out", str(out)]) == 0 and "reused" in capsys.readouterr().out
    monkeypatch.undo()
    named = tmp_path / "w.json"  # its table was written over the weights it named
    assert main([*args, "--out", str(named)]) == 0 and main([*args, "--out", str(named)]) == 0
    assert "reused" in capsys.readouterr().out and (tmp_path / "w.json.json").is_file()

    def refused(path, text):  # reused weights where this user cannot write (a shared disk)
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr("spikegs.sim_cli.write_text_atomically", refused)
    assert main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr()
    assert "reused" in printed.out and "TFP(33)" in printed.out  # the table stands
    assert f"scores not written beside the weights: [Errno 13] Permission denied: '{out}.json'" in (
        printed.err
    )


def test_nerf_of_no_stated_size_and_no_sharp_image_asks_for_one(nerf, tmp_path):
    """Transforms files without w, h and no sharp test image (r_0's left out): the frame size
    is unknown, and spikegs.json's height and width are asked for (and then read)."""
    root = copy(nerf, tmp_path / "sizeless")
    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / name, lambda doc: [doc.pop(k) for k in ("w", "h")])
    edit_json(root / "transforms_test.json", lambda doc: doc.update(frames=doc["frames"][1:]))
    with pytest.raises(ValueError, match="image size unknown .*: set height and width in spikegs"):
        load_dataset(root)
    write_options(root, height=H)  # one of the two: still unknown
    with pytest.raises(ValueError, match="image size unknown"):
        load_dataset(root)
    write_options(root, height=H, width=W)
    assert (load_dataset(root).height, load_dataset(root).width) == (H, W)


def test_nerf_of_no_stated_size_takes_the_images_and_names_the_one_it_took(sim, nerf, tmp_path):
    """Without w, h the frames' size is the first sharp test image's, else the first training
    image's: a camera_angle_x camera's training images were passed over ("no sharp image"
    said), and a test image of another crop was refused as "the camera's" size, unnamed."""
    root = copy(nerf, tmp_path / "sizeless")
    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / name, lambda doc: [doc.pop(k) for k in ("w", "h")])
    write_image(
        root / "train" / "r_2.exr", make_source("solids", W, H, 1).render(view_poses(sim)[2])
    )
    sharp = read_image(root / "test" / "r_0.exr")  # [H, W, 1]
    write_image(root / "test" / "r_0.exr", sharp[:, : W // 2])
    with pytest.raises(
        ValueError,
        match=rf"train/r_2: image {W}x{H} .*, the camera \(sized as its first sharp image, "
        rf"\./test/r_0\) is for {W // 2}x{H} images",
    ):
        load_dataset(root)
    edit_json(root / "transforms_test.json", lambda doc: doc.update(frames=doc["frames"][1:]))
    ds = load_dataset(root)  # r_1 held out, known by its spikes alone
    assert (ds.height, ds.width) == (H, W) and ds.test_views[0].name == "pseudo_test_r_1"
    np.testing.assert_allclose(ds.K, sim.K, rtol=1e-6)


def test_a_test_file_whose_poses_break_convergence_is_named(nerf, tmp_path):
    """transforms_test.json in OpenCV axes (read as OpenGL's) kept the optical axes from
    converging, and the error named transforms_train.json, whose poses were right (the
    real-layout trial): the test file is named."""
    root = copy(nerf, tmp_path)

    def opencv(doc):  # each camera turned about its own x axis: its optical axis reversed
        for frame in doc["frames"]:
            frame["transform_matrix"] = (
                np.array(frame["transform_matrix"]) @ OPENGL_TO_OPENCV
            ).tolist()

    edit_json(root / "transforms_test.json", opencv)
    with pytest.raises(
        ValueError,
        match=r"transforms_test.json: its poses keep the cameras' optical axes from converging "
        r"in front of them, where transforms_train.json's alone converge",
    ):
        load_dataset(root)


def test_nerf_unknown_convention_refused(nerf, tmp_path):
    """A convention other than opengl, opencv (any case) is refused by name; "OpenGL" reads as
    OpenGL (guards against a case-sensitive comparison reading it as OpenCV); two files of two
    conventions are warned of."""
    for value in (None, "colmap", 3):
        root = copy(nerf, tmp_path / str(value))
        edit_json(root / "transforms_train.json", lambda doc, v=value: doc.update(convention=v))
        found = f"convention {json.dumps(value)}"
        with pytest.raises(ValueError, match=rf"transforms_train.json: {found}"):
            load_dataset(root)
    root = copy(nerf, tmp_path / "cased")  # the label's case is free: "OpenGL" is OpenGL's
    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / name, lambda doc: doc.update(convention="OpenGL"))
    np.testing.assert_allclose(
        load_dataset(root).test_views[0].viewmat, load_dataset(nerf).test_views[0].viewmat
    )
    # one file relabelled: its OpenGL matrices read as OpenCV "do not converge" (set a centre)
    root = copy(nerf, tmp_path / "mixed")
    edit_json(root / "transforms_train.json", lambda doc: doc.update(convention="opencv"))
    with pytest.warns(UserWarning, match="convention opencv, .* opengl .unstated.: each file"):
        with pytest.raises(ValueError, match="do not converge"):
            load_dataset(root)
    (root / "transforms_train.json").unlink()  # was "transforms file not found: transforms.json"
    with pytest.raises(FileNotFoundError, match="transforms_test.json without training frames"):
        load_dataset(root)


def test_windows_never_straddle_two_views(llff):
    ds = load_dataset(llff)
    offsets = ds.stream.offsets
    for k in [*ds.train_timestamps, *(v.readout for v in ds.test_views)]:
        view = ds.stream.view_of(int(k))
        assert offsets[view] <= k - 32 and k + 32 < offsets[view + 1]
        # exposure poses anywhere in the window: the view's own pose
        np.testing.assert_allclose(  # (zeros of the rotation: 2e-16 against 2.3e-16 by numpy)
            ds.trajectory.pose_at(k + 32), ds.trajectory.pose_at(k - 32), atol=1e-12
        )
    with pytest.raises(ValueError, match="within one view"):
        ds.stream.tfp(LENGTH - 10, 33)
    with pytest.raises(ValueError, match="within one view"):
        ds.stream.window(np.array([100, LENGTH + 5]), 33)
    assert ds.stream.tfp(np.array([100, 10 + 35]), 21).shape == (2, H, W)
    # TFI at a view's last and first readouts: its own stream's, which stops at the view's ends
    np.testing.assert_array_equal(ds.stream.tfi(LENGTH - 1), ds.stream.streams[0].tfi(LENGTH - 1))
    np.testing.assert_array_equal(ds.stream.tfi(LENGTH), ds.stream.streams[1].tfi(0))
    # a window wider than the views, refused before any work, names the views' length
    wide = load_config("tfp33", {"supervision": {"instant_window": LENGTH + 1}})
    inside = "35 readouts or more inside their views' ends$"  # (a per-view layout lists none)
    with pytest.raises(
        ValueError, match=f"each in its view of {LENGTH} readouts.: at most .*{inside}"
    ):
        check_targets(ds, wide)


def test_sim_trains_and_evaluates_on_view_streams(llff):
    ds = load_dataset(llff)
    model, _ = train_sim(
        ds.stream, ds.train_timestamps, 33, steps=2, batch_size=2, crop=16, progress=False
    )
    scores = evaluate_dataset(model, ds)
    assert np.isfinite([s["psnr"] for s in scores.values()]).all()


# -- bad input -------------------------------------------------------------------------------------
def test_llff_bad_input(sim, llff, llff_stream, tmp_path):
    root = copy(llff, tmp_path / "count")
    (root / "spikes" / "009.dat").unlink()
    with pytest.raises(ValueError, match="poses_bounds.npy holds 10 poses .* 9 .dat"):
        load_dataset(root)
    shutil.copy(llff / "spikes" / "009.dat", root / "spikes" / "009.DAT")  # named otherwise
    with pytest.raises(
        ValueError, match=r"9 .dat files; .* \(not read, not named \*.dat: 009.DAT\)"
    ):
        load_dataset(root)
    (root / "spikes" / "009.DAT").unlink()
    (root / "spikes" / "009.dat").symlink_to(tmp_path / "unmounted" / "009.dat")  # dangling
    with pytest.raises(ValueError, match=r"9 .dat files; .* \(links to nothing: 009.dat\)"):
        load_dataset(root)
    (root / "spikes" / "009.dat").unlink()
    (root / "spikes" / "zz.dat").mkdir()  # a folder: counted as a view's spikes
    with pytest.raises(ValueError, match="holds 10 poses .* holds 9 .dat files"):
        load_dataset(root)
    (root / "spikes" / "zz.dat").rmdir()
    shutil.copy(llff / "spikes" / "009.dat", root / "spikes" / "009.dat")
    (root / "spikes" / "._009.dat").write_bytes(b"\0" * 4096)  # macOS's, on a foreign disk
    assert load_dataset(root).meta["spike_files"][-1] == os.path.join("spikes", "009.dat")

    root = copy(llff, tmp_path / "size")
    with open(root / "spikes" / "003.dat", "ab") as f:
        f.write(b"\0" * 3)
    with pytest.raises(ValueError, match="003.dat.*raw_width"):
        load_dataset(root)

    root = copy(llff, tmp_path / "nan")
    edit_poses(root, lambda rows: rows.__setitem__((2, 3), np.nan))
    with pytest.raises(ValueError, match="poses_bounds.npy.*NaN"):
        load_dataset(root)

    root = copy(llff, tmp_path / "short")
    write_view(sim, root / "spikes" / "004.dat", 4, length=40)
    with pytest.raises(ValueError, match="004.dat.*40 readouts.*at least 65"):
        load_dataset(root)

    root = copy(llff, tmp_path / "nospikes")
    shutil.rmtree(root / "spikes")
    with pytest.raises(FileNotFoundError, match=r"spikes/ .*readouts.txt$"):
        load_dataset(root)
    for channel in "rgb":  # a colour camera's files: said to be the meta.json layout's
        (root / f"spikes_{channel}.dat").write_bytes(b"")
    with pytest.raises(FileNotFoundError, match=r"\(spikes_r.dat, .*: a colour camera's files, wh"):
        load_dataset(root)

    root = copy(llff_stream, tmp_path / "noreadouts")
    (root / "readouts.txt").unlink()
    with pytest.raises(FileNotFoundError, match="readouts.txt"):
        load_dataset(root)
    np.savetxt(root / "readouts.txt", np.arange(0, 500, 50), fmt="%d")
    with pytest.raises(ValueError, match="readouts.txt: 10 readouts for 14 poses"):
        load_dataset(root)

    write_options(root, heigth=3)
    with pytest.raises(ValueError, match="spikegs.json: unknown options \\['heigth'\\]"):
        load_dataset(root)

    root = copy(llff, tmp_path / "every")  # a stream per view: train_every has nothing to space
    write_options(root, train_every=4)
    with pytest.warns(UserWarning, match="json: train_every is not used with a spike stream per"):
        load_dataset(root)
    with pytest.warns(UserWarning, match=r"^\S+: keyword option train_every is not used with"):
        load_llff(root, train_every=4)  # (named the file, whether or not it held the key)

    # readouts given in seconds (readout x 25 us) sent the user to pseudo_gt_window; a pose log
    # too dense for the held-out poses' margins said only "no training timestamp left", then
    # gave the spacing of all poses for the held-out ones' and advised a train_every below 1
    one = copy(llff_stream, tmp_path / "one")  # one pose: "(not seconds?)" was said too
    np.save(one / "poses_bounds.npy", np.load(one / "poses_bounds.npy")[:1])
    (one / "readouts.txt").write_text("300\n")
    with pytest.raises(ValueError, match=r"training window needs: one pose spans none \(poses al"):
        load_dataset(one)
    root = copy(llff_stream, tmp_path / "seconds")
    poses = len(np.loadtxt(root / "readouts.txt"))
    np.savetxt(root / "readouts.txt", np.arange(poses) * 50 * 25e-6)
    with pytest.raises(ValueError, match="readouts are indices, 25 µs apart \\(not seconds\\?\\)"):
        load_dataset(root)
    np.savetxt(root / "readouts.txt", np.arange(poses) * 10 + 200, fmt="%d")
    dense = (
        r"the 2 held-out poses, every 8th pose by default, which lie 80 readouts apart; fewer "
        r"held-out poses further apart \(test_views, pose indices, e.g. every 13th: 130 readouts"
    )
    with pytest.raises(ValueError, match=dense):  # train_every is 1 here
        load_dataset(root)
    write_options(root, train_every=3, test_views=list(range(0, poses, 2)))
    with pytest.raises(ValueError, match=r"\d held-out poses, which lie 20 readouts apart; fewer"):
        load_dataset(root)  # 20 apart: no train_every helps
    write_options(root, train_every=7, test_views=[0, 13])  # 130 apart: one readout between
    with pytest.raises(ValueError, match=r"130 readouts apart; a smaller train_every, or fewer"):
        load_dataset(root)
    write_options(root, train_every=300, test_views=[5])  # timestamps at 32, 332: none inside
    one = r"clear of the held-out pose; a smaller train_every, or fewer"  # no spacing of one
    with pytest.raises(ValueError, match=one):
        load_dataset(root)
    write_options(root, train_every=1, test_views=[0, 13])  # readout 265 trains
    assert load_dataset(root).train_timestamps.tolist() == [265]
    (root / "spikegs.json").unlink()
    # a frame size a quarter of the file's: 4x the readouts, the poses on the first quarter
    np.savetxt(root / "readouts.txt", np.arange(poses) * 8 + 40, fmt="%d")
    write_options(root, height=16, width=24, test_views=[0], pseudo_gt_window=33)
    with (
        pytest.warns(UserWarning, match=r"poses span readouts \[40, .* of the 2800 .* at 16x24"),
        pytest.warns(UserWarning, match=r"likely 48 pixels wide, 2 times the width given"),
    ):
        load_dataset(root)


MIXED = ".* held-out views have no sharp image"  # the NeRF fixture's: r_0 sharp, r_1 not


def test_a_test_set_mixing_sharp_and_pseudo_views_is_said(nerf, tmp_path):
    """A held-out frame without its image (missing or misnamed) beside sharp ones was scored
    against TFP of its own spikes, said at eval alone; all sharp, or all without: not said."""
    with pytest.warns(UserWarning, match=r"1 of the 2 held-out views have no sharp image \(test"):
        load_dataset(nerf)
    root = copy(nerf, tmp_path)
    edit_json(root / "transforms_test.json", lambda doc: doc["frames"].pop(0))  # r_1 alone
    sharp = copy(nerf, tmp_path / "sharp")
    edit_json(sharp / "transforms_test.json", lambda doc: doc["frames"].pop())  # r_0 alone
    for data, pseudo in ((root, True), (sharp, False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            names = [v.name for v in load_dataset(data).test_views]
        assert all(name.startswith("pseudo_") == pseudo for name in names), names
        assert not [w for w in caught if "no sharp image" in str(w.message)]


@pytest.mark.filterwarnings("default")
def test_guessed_intensity_scale_of_sharp_test_images_is_named(sim, nerf, tmp_path):
    """Sharp test images were put in firing-rate units by a percentile guess (27 % off in a
    walkthrough) without a word, though their PSNR depends on it."""
    with pytest.warns(UserWarning, match=r"by a guess, TFP\(33\)'s 99.5th percentile \(0\.\d+ "):
        guessed = load_dataset(nerf)
    # its meta says so (eval on another dataset weighs it): image_scale is set either way
    assert guessed.meta["image_scale_guessed"] is True and scale_guessed(guessed.meta)
    root = copy(nerf, tmp_path)
    (root / "spikegs.json").write_text(json.dumps({"rate_at_one": 0.25}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # stated: nothing to say
        warnings.filterwarnings("ignore", MIXED)  # (the fixture's r_1)
        stated = load_dataset(root)
    assert stated.meta["image_scale_guessed"] is False and not scale_guessed(stated.meta)


def test_sharp_test_images_in_other_units_are_named_from_their_spikes(sim, nerf, tmp_path):
    """A NeRF test image already in firing-rate units (or linear values in an sRGB PNG) beside a
    stated rate_at_one scored 16.5 dB where 26.9 was due, unsaid, where meta.json's layout warns
    (the real-layout trial): a held-out view with spikes and a sharp image checks the units."""
    root = copy(nerf, tmp_path)
    write_view(sim, root / "spike_data" / "r_0.dat", 0)  # test/r_0: its spikes and image
    (root / "spikegs.json").write_text(json.dumps({"rate_at_one": 0.25}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # intensities, as they should be: nothing to say
        warnings.filterwarnings("ignore", MIXED)  # (the fixture's r_1)
        load_dataset(root)
    sharp = make_source("solids", W, H, 1).render(view_poses(sim)[0])  # [H, W, 1]
    write_image(root / "test" / "r_0.exr", sharp * 0.25)  # firing rates
    with pytest.warns(
        UserWarning,
        match=r"the on-path test images average 0\.2\d* times their spikes' firing rate .* sharp "
        r"images are expected in linear intensity, 1 for white \(8- and 16-bit ones sRGB-encoded "
        r"unless tagged linear\)",
    ):
        load_dataset(root)


def test_wrong_flip_is_named_from_the_sharp_images(sim, nerf, tmp_path, monkeypatch):
    """A wrong `flip` trained the scene upside down without a word, though the training views'
    sharp images showed it."""
    root = copy(nerf, tmp_path)
    source, viewmats = make_source("solids", W, H, 1), view_poses(sim)
    for i in range(2, VIEWS - 1):
        write_image(root / "train" / f"r_{i}.exr", source.render(viewmats[i]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the right way up: nothing to say
        warnings.filterwarnings("ignore", MIXED)  # (the fixture's r_1)
        load_dataset(root)
    (root / "spikegs.json").write_text(json.dumps({"flip": False}))
    with pytest.warns(
        UserWarning,
        match=r"better upside down \(median correlation 0\.\d+ flipped against -?0\.\d+ as "
        r"read, over 7 views\): flip is likely wrong \(read with flip False; it is set in "
        r"spikegs.json\)",
    ):
        load_dataset(root)
    with pytest.warns(  # given as the loader's keyword, which overrides the file: named so
        UserWarning,
        match=r"flip is likely wrong \(read with flip False; it is set in spikegs.json or the "
        r"loader's keywords \(flip\), which override it\)",
    ):
        load_nerf_layout(root, flip=False)
    # a rate_at_one given left the training images unread, and the check skipped
    (root / "spikegs.json").write_text(json.dumps({"flip": False, "rate_at_one": 0.25}))
    with pytest.warns(
        UserWarning,
        match=r"better upside down .* over 7 views\): flip is likely wrong \(read with flip False",
    ):
        load_dataset(root)
    # images on later training frames alone: the first ORIENTATION_VIEWS frames, imageless,
    # were all that was read, and nothing checked (the layouts trial)
    monkeypatch.setattr("spikegs.data.nerf_layout.ORIENTATION_VIEWS", 2)
    for i in range(2, 6):
        (root / "train" / f"r_{i}.exr").unlink()
    with pytest.warns(
        UserWarning,
        match=r"better upside down .* over 2 views\): flip is likely wrong \(read with flip False",
    ):
        load_dataset(root)
    # the held-out views' sharp images, where the training views have none (unsaid before)
    root = copy(nerf, tmp_path / "held")
    write_view(sim, root / "spike_data" / "r_0.dat", 0)  # test/r_0: its spikes and image
    (root / "spikegs.json").write_text(json.dumps({"flip": False, "rate_at_one": 0.25}))
    with pytest.warns(
        UserWarning,
        match=r"better upside down .* over 1 views\): flip is likely wrong \(read with flip False",
    ):
        load_dataset(root)


def test_nerf_intensity_scale_from_training_images(sim, nerf, tmp_path):
    """Sharp images of training views calibrate the firing rate of intensity 1 (when spikegs.json
    gives no rate_at_one); the test views' images are scaled by it."""
    heuristic = load_dataset(nerf).meta["image_scale"]  # TFP(33)'s 99.5th percentile
    root = copy(nerf, tmp_path)
    source, viewmats = make_source("solids", W, H, 1), view_poses(sim)
    for i in range(2, VIEWS - 1):
        write_image(root / "train" / f"r_{i}.exr", source.render(viewmats[i]))
    ds = load_dataset(root)
    rate = sim.meta["sim"]["rate_at_one"]
    assert ds.meta["rate_at_one"] == pytest.approx(rate, rel=0.03)
    assert ds.meta["rate_at_one_from"] == "7 training views' sharp images"
    assert abs(heuristic / rate - 1) > 0.1  # the percentile is off on this scene
    sharp = source.render(viewmats[0])  # [H, W, 1]
    view = next(v for v in ds.test_views if v.name == "test_r_0")
    np.testing.assert_allclose(view.image, sharp * ds.meta["rate_at_one"], rtol=1e-5)
    write_image(root / "train" / "r_4.exr", np.zeros((H, W, 1), np.float32))  # a wrong image
    assert load_dataset(root).meta["rate_at_one"] == pytest.approx(rate, rel=0.03)  # the median
    (root / "train" / "r_4.exr").write_bytes(b"not an image")
    with pytest.raises(ValueError, match="cannot read .*r_4.exr"):  # not taken for absent
        load_dataset(root)
    write_options(root, rate_at_one=0.2)  # a calibration given wins; the images then only
    assert load_dataset(root).meta["rate_at_one"] == 0.2  # check the flip: one unreadable, or
    write_image(root / "train" / "r_4.exr", np.zeros((H, H, 1), np.float32))  # of another
    assert load_dataset(root).meta["rate_at_one"] == 0.2  # aspect, is left out of it
    (root / "spike_data" / "train" / "r_3.dat").unlink()  # a training frame needs its spikes,
    with pytest.raises(FileNotFoundError, match="r_3.dat"):  # whether or not it has an image
        load_dataset(root)


def test_eval_scores_a_runs_renders_in_the_datasets_scale_stated_since(nerf, tmp_path):
    """A run scored again after its dataset's intensity scale changed (rate_at_one set where it
    trained in a guessed or fitted one, as eval's warning asks) got the same scores, in the
    scale it trained in: a render is a firing rate over that scale, and is now scored in the
    scale stated, said; a pseudo ground truth (TFP) is put in the run's units, unchanged."""
    from spikegs.evaluate import render_view
    from spikegs.metrics import psnr
    from spikegs.ply import load_ply

    root = copy(nerf, tmp_path)
    ds = load_dataset(root)
    Trainer(ds, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    before = evaluate_run(tmp_path / "run", ds)["views"]
    assert set(before) == {"test_r_0", "pseudo_test_r_1"}  # one sharp, one pseudo
    fitted = ds.meta["image_scale"]
    write_options(root, rate_at_one=2 * fitted)
    stated = load_dataset(root)
    with pytest.warns(UserWarning, match=r"now states .*: its renders' firing rates are scored"):
        after = evaluate_run(tmp_path / "run", stated)["views"]
    assert after["pseudo_test_r_1"]["psnr"] == pytest.approx(before["pseudo_test_r_1"]["psnr"])
    view = next(v for v in stated.test_views if v.name == "test_r_0")
    render = render_view(load_ply(tmp_path / "run" / "scene.ply"), view.viewmat, stated)
    gt = np.clip(view.image / (2 * fitted), 0, 1)  # the sharp image's intensity
    assert after["test_r_0"]["psnr"] == pytest.approx(psnr(np.clip(render / 2, 0, 1), gt))
    assert after["test_r_0"]["psnr"] != pytest.approx(before["test_r_0"]["psnr"])


def test_nerf_bad_input(nerf, tmp_path):
    root = copy(nerf, tmp_path / "missing")
    (root / "spike_data" / "train" / "r_3.dat").unlink()
    with pytest.raises(FileNotFoundError, match="r_3.dat"):
        load_dataset(root)

    root = copy(nerf, tmp_path / "nan")
    edit_json(
        root / "transforms_train.json",
        lambda doc: doc["frames"][1]["transform_matrix"][0].__setitem__(0, float("inf")),
    )
    with pytest.raises(  # named as such (not as a pose that is not a rotation)
        ValueError, match=r"transforms_train.json: non-finite \(NaN/inf\) transform_matrix in fr"
    ):
        load_dataset(root)

    root = copy(nerf, tmp_path / "noimage")
    (root / "spike_data" / "r_1.dat").unlink()  # test/r_1: no spikes and no image
    with pytest.raises(  # the file that lists the frame named (not transforms_train.json)
        FileNotFoundError,
        match=r"transforms_test.json: spike file of frame './test/r_1' .*r_1.dat.*no sharp image",
    ):
        load_dataset(root)

    for spike_path, error in ((None, FileNotFoundError), (3, ValueError)):  # null: a TypeError
        root = copy(nerf, tmp_path / f"spike_path_{spike_path}")
        edit_json(
            root / "transforms_train.json",
            lambda doc: doc["frames"][2].update(spike_path=spike_path),  # noqa: B023
        )
        with pytest.raises(error, match=r"frame '\./train/r_\d+'.*spike_path"):
            load_dataset(root)


def test_nerf_image_of_another_aspect_ratio_refused(nerf, tmp_path):
    root = copy(nerf, tmp_path / "double")  # twice the size, same aspect: resized
    sharp = read_image(root / "test" / "r_0.exr")
    write_image(root / "test" / "r_0.exr", np.repeat(np.repeat(sharp, 2, 0), 2, 1))
    resized, original = (load_dataset(r).test_views[0].image for r in (root, nerf))  # [H, W, 1]
    assert resized.shape == original.shape
    np.testing.assert_allclose(resized.mean(), original.mean(), rtol=0.01)
    root = copy(nerf, tmp_path / "cropped")
    write_image(root / "test" / "r_0.exr", sharp[:, : W // 2])
    with pytest.raises(
        ValueError,
        match=rf"r_0: image {W // 2}x{H} .*the camera \(its w, h\) is for {W}x{H} images",
    ):
        load_dataset(root)
    write_image(root / "test" / "r_0.exr", sharp[:, 3:])  # 3 columns (6 %) short: another crop
    with pytest.raises(
        ValueError, match=rf"r_0: image {W - 3}x{H} .*the camera \(its w, h\) is for {W}x{H} images"
    ):
        load_dataset(root)


def test_nerf_test_images_are_read_one_at_a_time(nerf, tmp_path, monkeypatch, alive_arrays):
    """Each sharp test image is reduced to the spikes' size as it is read: all of a test set's
    held at full size at once filled the memory (60 test images of 960x1440: 2.3 GB peak against
    0.45 one at a time). Four test frames with sharp images; at most two read images alive, and
    each test image read through the counted reader (no count of nothing)."""
    from spikegs.data import nerf_layout

    root = copy(nerf, tmp_path)
    edit_json(
        root / "transforms_test.json",
        lambda doc: doc["frames"].extend(
            dict(doc["frames"][0], file_path=f"./test/r_{i}") for i in (2, 3)
        ),
    )
    for i in (1, 2, 3):
        shutil.copy(root / "test" / "r_0.exr", root / "test" / f"r_{i}.exr")
    read_paths = []
    read = nerf_layout._image

    def counted(root, frame, listings):
        image = read(root, frame, listings)
        if image is not None:
            read_paths.append(frame["file_path"])
            alive_arrays.track(image)
        return image

    monkeypatch.setattr(nerf_layout, "_image", counted)
    assert [v.name for v in load_dataset(root).test_views] == [f"test_r_{i}" for i in range(4)]
    assert sorted(read_paths) == [f"./test/r_{i}" for i in range(4)], read_paths
    assert 1 <= alive_arrays.most <= 2, alive_arrays.most
    for name in ("train", "test"):  # no stated size: the first test image gives it, read once
        edit_json(root / f"transforms_{name}.json", lambda doc: [doc.pop(k) for k in "wh"])
    read_paths.clear()
    assert load_dataset(root).test_views[0].image.shape == (H, W, 1)
    assert sorted(read_paths) == [f"./test/r_{i}" for i in range(4)], read_paths


def test_nerf_image_with_a_nan_pixel_refused(nerf, tmp_path):
    """A NaN firefly in a test view's EXR was loaded, and every score became NaN (null)."""
    root = copy(nerf, tmp_path / "nan")
    sharp = read_image(root / "test" / "r_0.exr")
    sharp[5, 7] = np.nan
    write_image(root / "test" / "r_0.exr", sharp)
    with pytest.raises(
        ValueError, match=r"r_0.exr: 1 pixel\(s\) of colour not finite, .* row 5, column 7"
    ):
        load_dataset(root)


def test_llff_spike_names_of_two_orders_refused(sim, llff, tmp_path):
    """view_1 ... view_10: LLFF's tools order the poses by names as strings (view_10 second), ours
    in natural order (view_10 last): ambiguous, refused; zero-padded, both orders agree."""
    root = copy(llff, tmp_path)
    for i in range(VIEWS):
        (root / "spikes" / f"{i:03d}.dat").rename(root / "spikes" / f"view_{i + 1}.dat")
    with pytest.raises(
        ValueError,
        match=r"spikes: the .dat names order differently .*pose 1: view_10.dat as strings, "
        r"view_2.dat in natural order.*imgs2poses.*Zero-pad",
    ):
        load_dataset(root)
    for i in range(VIEWS):
        (root / "spikes" / f"view_{i + 1}.dat").rename(root / "spikes" / f"view_{i + 1:02d}.dat")
    ds = load_dataset(root)
    assert list(ds.meta["view_readouts"]) == [f"view_{i + 1:02d}" for i in range(VIEWS)]
    centers = np.arange(VIEWS) * LENGTH + LENGTH // 2
    np.testing.assert_allclose(ds.trajectory.pose_at(centers), view_poses(sim), atol=1e-6)


@pytest.mark.parametrize(
    "text, found",
    [
        ("0 0\n1 50\n", r"line 1: .*found '0 0' \(2 fields\)"),
        ("0,0\n1,50\n", r"line 1: .*found '0,0' \(2 fields\)"),
        ("readout\n0\n50\n", r"line 1: .*found 'readout'"),
    ],
)
def test_llff_malformed_readouts_named(llff_stream, tmp_path, text, found):
    root = copy(llff_stream, tmp_path)
    (root / "readouts.txt").write_text(text)
    with pytest.raises(ValueError, match=r"readouts.txt: " + found):
        load_dataset(root)


def test_llff_hwf_of_another_aspect_or_a_raw_crop(sim, llff_stream, tmp_path):
    """hwf for the stored raw rows, the spikes a crop of them: the focal is kept and cx shifts by
    col_offset; hwf of another aspect ratio than the spikes' is refused (non-square pixels)."""
    root = copy(llff_stream, tmp_path)
    bits = np.unpackbits(sim.stream.packed(), axis=-1, bitorder="little")[..., :W]  # [T, H, W]
    raw = np.zeros((len(bits), H, W + 16), np.uint8)
    raw[..., 4 : 4 + W] = bits
    save_dat(root / "spikes.dat", raw)
    f = sim.K[0, 0]
    edit_poses(root, lambda rows: rows.__setitem__((slice(None), [4, 9, 14]), (H, W + 16, f)))
    write_options(root, width=W)  # no raw_width: hwf 32x64 for 32x48 spikes
    with pytest.raises(ValueError, match=r"poses_bounds.npy: hwf is for 32x64 .* 32x48 spikes"):
        load_dataset(root)
    write_options(root, width=W, raw_width=W + 16, col_offset=4)
    ds = load_dataset(root)
    np.testing.assert_array_equal(ds.stream.packed(), sim.stream.packed())
    np.testing.assert_allclose(ds.K, [[f, 0, W / 2 + 4], [0, f, H / 2], [0, 0, 1]], rtol=1e-6)
    # hwf written width first, the size set right: told to set the size it had set (the trial)
    root = copy(llff_stream, tmp_path / "wh")
    edit_poses(root, lambda rows: rows.__setitem__((slice(None), [4, 9, 14]), (W, H, f)))
    write_options(root, height=H, width=W)
    with pytest.raises(
        ValueError,
        match=rf"hwf is for {W}x{H} images .*; hwf gives the spikes' height and width in the "
        r"other order: one of the two transposed\? \(LLFF's hwf is height, width, focal\)$",
    ):
        load_dataset(root)


def test_streams_without_information_refused(sim, llff, llff_stream, nerf, tmp_path):
    """No spike at all, or every pixel at every readout: PSNR inf against its own TFP; in every
    layout."""
    root = copy(llff, tmp_path / "dark")
    save_dat(root / "spikes" / "003.dat", np.zeros((LENGTH, H, W), bool))
    with pytest.raises(ValueError, match=r"003.dat: no spikes in its 70 readouts of 32x48"):
        load_dataset(root)
    save_dat(root / "spikes" / "003.dat", np.ones((LENGTH, H, W), bool))
    with pytest.raises(ValueError, match=r"003.dat: every pixel firing at every readout"):
        load_dataset(root)
    root = copy(llff_stream, tmp_path / "stream")
    save_dat(root / "spikes.dat", np.zeros((VIEWS * LENGTH, H, W), bool))
    with pytest.raises(ValueError, match=r"spikes.dat: no spikes in its 700 readouts"):
        load_dataset(root)
    root = copy(nerf, tmp_path / "nerf")
    save_dat(root / "spike_data" / "r_1.dat", np.zeros((LENGTH, H, W), bool))
    with pytest.raises(ValueError, match=r"r_1.dat: no spikes"):
        load_dataset(root)
    # a simulated (meta.json) dataset's stream was not checked at all; nor does a hot pixel in
    # a dark stream, or a dead one in a saturated stream, make an image
    root = copy(sim.root, tmp_path / "meta")
    hot = np.zeros((VIEWS * LENGTH, H, W), bool)
    hot[:, 3, 5] = True
    save_dat(root / "spikes.dat", hot)
    with pytest.raises(
        ValueError,
        match=r"spikes.dat: spikes at 0.07% of the pixels only .*"
        r"a dark simulation, rate_at_one 0.25 in meta.json: simulate it again with more light "
        r"or a higher --rate-at-one, at most 1; or a wrong file\)",
    ):
        load_dataset(root)
    save_dat(root / "spikes.dat", ~hot)
    saturated = r"99.93% of the pixels firing at every .*a saturated simulation.*less light"
    saturated += r" or a lower --rate-at-one;"  # (the simulator's own knob, as for a dark one)
    with pytest.raises(ValueError, match=saturated):
        load_dataset(root)


def test_intrinsics_that_meta_json_refuses_are_refused_in_every_layout(llff, nerf, tmp_path):
    """A focal of 0.01 px (180° of view) or a principal point 50 widths off the image loaded and
    trained in the LLFF and NeRF layouts, where meta.json's fx, fy, cx, cy refuse them."""
    root = copy(llff, tmp_path / "llff")
    edit_poses(root, lambda rows: rows.__setitem__((slice(None), 14), 0.01))
    with pytest.raises(ValueError, match=r"poses_bounds.npy \(hwf 32, 48, 0.01\): fx 0.01 gives"):
        load_dataset(root)
    cases = {"fl_x": (0.01, "fx 0.01 gives a 180° field"), "cx": (50 * W, "cx 2400.0 puts the")}
    for key, (value, message) in cases.items():
        root = copy(nerf, tmp_path / key)

        def edit(doc, key=key, value=value):
            doc[key] = value
            if key == "fl_x":  # the focal alone: camera_angle_x would disagree (warned)
                del doc["camera_angle_x"]

        for name in ("train", "test"):
            edit_json(root / f"transforms_{name}.json", edit)
        with pytest.raises(ValueError, match=r"transforms_train.json: " + message):
            load_dataset(root)


def test_llff_stream_frame_size_errors(sim, llff_stream, tmp_path):
    root = copy(llff_stream, tmp_path)
    hwf = (2 * H, 2 * W, 2 * sim.K[0, 0])  # poses made for images at twice the spikes' size
    edit_poses(root, lambda rows: rows.__setitem__((slice(None), [4, 9, 14]), hwf))
    with (
        pytest.raises(ValueError, match="hwf .*set height and width in spikegs.json"),
        pytest.warns(UserWarning, match=f"the frames are likely {H}x{W}, 1/2 of the size given"),
    ):
        load_dataset(root)  # 64x96 frames: a quarter of the readouts
    write_options(root, height=H, width=W)
    assert len(load_dataset(root).stream) == VIEWS * LENGTH
    readouts = np.loadtxt(root / "readouts.txt")
    np.savetxt(root / "readouts.txt", readouts + 50100, fmt="%d")  # the camera's own counter
    with pytest.raises(ValueError, match=r"the first at 50100\): readouts.txt holds 0-based"):
        load_dataset(root)
    np.savetxt(root / "readouts.txt", readouts * 25, fmt="%d")  # a clock in µs
    with pytest.raises(ValueError, match=r"up to readout \d+\. Readouts in µs\? They are readout"):
        load_dataset(root)  # (it asked for the spikes' frame size first)
    np.savetxt(root / "readouts.txt", readouts - readouts[0] - 5, fmt="%d")  # a negative first
    with pytest.raises(ValueError, match=r"readouts.txt: pose readouts span \[-5, "):  # (it named
        load_dataset(root)  # poses_bounds.npy)
    np.savetxt(root / "readouts.txt", readouts, fmt="%d")
    (root / "spikes.dat").write_bytes(b"")
    with pytest.raises(ValueError, match="spikes.dat: empty spike file"):
        load_dataset(root)


@pytest.mark.parametrize(
    "key, value",
    [
        ("rate_at_one", -1),
        ("rate_at_one", 0),
        ("rate_at_one", 5),  # more than one spike a readout (was accepted, used as the scale)
        ("rate_at_one", 1.01),
        ("scene_radius", -1),
        ("scene_radius", 0),
        ("scene_center", [0, 0]),
        ("scene_center", [0, 0, 1, 2]),  # LLFF took it as it was, to meta
        ("flip", "false"),
        ("height", "48"),
        ("width", 0),
        ("col_offset", -1),
        ("train_every", 2.5),
        ("train_every", 0),  # no stride between timestamps
        ("test_views", [0.5]),
        ("test_views", [-1]),  # the last view, to Python
        ("pseudo_gt_window", 64),
    ],
)
def test_options_validated(key, value, tmp_path):
    write_options(tmp_path, **{key: value})
    with pytest.raises(
        ValueError, match=f"spikegs.json: {key} expected .*found {re.escape(json.dumps(value))}"
    ):
        read_options(tmp_path, {})


def test_options_valid_values_pass(tmp_path):
    values = dict(height=16, width=24, flip=False, test_views=[1], scene_center=[0, 0.5, 1])
    write_options(tmp_path, **values, rate_at_one=0.25, scene_radius=2)
    options = read_options(tmp_path, {"train_every": np.int64(3)})
    assert options.train_every == 3 and options.scene_radius == 2 and options.flip is False


def test_options_accept_the_ends_of_their_ranges(tmp_path):
    """The ends of each option's range are valid: col_offset 0 (the raw camera's rows cropped from
    their first column), rate_at_one 1 (a spike every readout), a pseudo_gt_window and train_every
    of 1, view 0 held out; a range closed one step too far refused them as the wrong type."""
    values = dict(col_offset=0, rate_at_one=1, pseudo_gt_window=1, train_every=1, test_views=[0])
    write_options(tmp_path, **values, raw_width=1, height=1, width=1)
    options = read_options(tmp_path, {})
    assert [getattr(options, key) for key in values] == list(values.values())


def test_no_held_out_view_is_refused(llff, tmp_path):
    """test_views [] holds no view out: a ValueError saying so (a dataset without test views
    trains and then has nothing to score); every view held out leaves none to train on, said
    too."""
    root = copy(llff, tmp_path)
    write_options(root, test_views=[])
    with pytest.raises(ValueError, match=r"test_views expected a non-empty list .*, found \[\]"):
        load_dataset(root)
    write_options(root, test_views=list(range(VIEWS)))
    said = rf"no training timestamp left once the test views are held out \({VIEWS} of them\): "
    said += r"fewer held-out views \(test_views in spikegs.* or more views \(each trains at one"
    with pytest.raises(ValueError, match=said):
        load_dataset(root)


def test_options_of_none_leave_the_files_values(tmp_path):
    """A keyword option of None (load_llff(DIR, height=None), a command-line flag not given)
    leaves spikegs.json's value: None is the layout's default only where the file gives none."""
    write_options(tmp_path, height=16, flip=False)
    options = read_options(tmp_path, {"height": None, "flip": None, "width": 24})
    assert (options.height, options.width, options.flip) == (16, 24, False)
    # null in the file is the default, for every key (flip's and col_offset's reached the
    # reader as None, and its error blamed the .dat)
    (tmp_path / "spikegs.json").write_text('{"flip": null, "col_offset": null, "height": null}')
    assert read_options(tmp_path, {}) == Options()


def test_a_bad_keyword_option_is_named_as_a_keyword_not_the_file(tmp_path):
    """load_llff(DIR, hieght=32) and load_nerf_layout(DIR, rate_at_one=0) were told
    "DIR/spikegs.json: unknown options" and "...rate_at_one ... found 0": a file absent, or
    holding another value. The file's own errors still name it, after a keyword's."""
    with pytest.raises(ValueError, match=r": keyword option\(s\) hieght: unknown options"):
        read_options(tmp_path, {"hieght": 32})
    write_options(tmp_path, rate_at_one=0.25, heigth=3)
    with pytest.raises(ValueError, match=r"keyword option\(s\) hieght: unknown .*\['hieght'\];"):
        read_options(tmp_path, {"hieght": 32})
    with pytest.raises(ValueError, match=r"spikegs\.json: unknown options \['heigth'\]"):
        read_options(tmp_path, {})
    write_options(tmp_path, rate_at_one=0.25)
    with pytest.raises(ValueError, match=r"keyword option\(s\) rate_at_one: rate_at_one expected"):
        read_options(tmp_path, {"rate_at_one": 0})
    with pytest.raises(ValueError, match=r"keyword option\(s\) scene_center: scene_center needs"):
        read_options(tmp_path, {"scene_center": [0, 0, 1]})
    with pytest.warns(UserWarning, match=r"keyword option\(s\) test_views: test_views lists \[3\]"):
        read_options(tmp_path, {"test_views": [3, 1, 3]})


def test_a_dat_of_another_frame_size_names_the_rows_read(tmp_path):
    """A .dat that is no whole number of readouts at the options' frame size: the error names
    the stored rows read (raw_width's 12 pixels, not the image's 6) and the first column kept;
    and the file, once, whether the stream's own message named it or not (rows too narrow)."""
    save_dat(tmp_path / "view.dat", np.ones((10, 4, 8), bool))  # 40 bytes: not 4x12 frames
    options = Options(raw_width=12, col_offset=2)
    rows = r"view.dat: .*frames of 4x6 pixels, the size of x, rows of 12 from col"
    with pytest.raises(ValueError, match=rows) as said:
        open_spikes(tmp_path / "view.dat", 4, 6, options, "x")
    assert str(said.value).count("view.dat") == 1
    narrow = Options(raw_width=7, col_offset=2)
    with pytest.raises(ValueError, match=r"view.dat: stored rows of at least col_offset \+ width"):
        open_spikes(tmp_path / "view.dat", 4, 6, narrow, "x")


def test_options_scene_center_needs_its_radius(tmp_path):
    write_options(tmp_path, scene_center=[0, 0, 1])
    with pytest.raises(ValueError, match="scene_center needs scene_radius"):
        read_options(tmp_path, {})
    assert read_options(tmp_path, {"scene_radius": 2.0}).scene_radius == 2.0
    write_options(tmp_path, scene_radius=2.0)  # about the computed centre
    assert read_options(tmp_path, {}).scene_center is None


def test_options_test_view_listed_twice_warns(tmp_path):
    write_options(tmp_path, test_views=[3, 1, 3])
    with pytest.warns(UserWarning, match=r"test_views lists \[3\] more than once"):
        assert read_options(tmp_path, {}).test_views == [3, 1, 3]


def test_llff_sphere_ignores_loose_far_bounds(sim, llff, tmp_path):
    """Cameras orbiting the scene: the sphere is centred where the optical axes meet and reaches
    each camera's near bound, in whatever units the poses are in."""
    root = copy(llff, tmp_path)
    edit_poses(root, lambda rows: rows.__setitem__((slice(None), 16), 1000.0))
    ds = load_dataset(root)
    assert ds.scene_radius < 2 * sim.scene_radius
    assert np.linalg.norm(ds.scene_center - sim.scene_center) < 0.1 * sim.scene_radius
    rows = np.load(root / "poses_bounds.npy")  # [N, 17]: t in columns 3, 8, 13; near in 15
    reach = np.linalg.norm(rows[:, [3, 8, 13]] - ds.scene_center, axis=1) - rows[:, 15]
    assert ds.scene_radius == pytest.approx(np.percentile(reach, 90, method="lower"))
    write_options(root, scene_radius=7)  # about the computed centre
    alone = load_dataset(root)
    assert alone.meta["scene_radius"] == 7 and np.allclose(alone.scene_center, ds.scene_center)
    write_options(root, scene_center=[1, 2, 3], scene_radius=7)  # the override stays
    given = load_dataset(root)
    assert given.meta["scene_center"] == [1, 2, 3] and given.meta["scene_radius"] == 7
    (root / "spikegs.json").unlink()
    rows[:, [3, 8, 13, 15, 16]] /= 100  # every length: in units 100 times larger, a reach under 1
    np.save(root / "poses_bounds.npy", rows)
    assert load_dataset(root).scene_radius == pytest.approx(ds.scene_radius / 100)


def test_llff_inward_sphere_reaches_the_near_bounds_but_a_stray_one(sim):
    """50 views 4 from the origin, near bounds 3 (a reach of 1): one stray near bound of 0.01 (a
    point close to one camera) tripled the radius, unsaid (the layouts trial); bounds in 10x
    the poses' units (none reaching in past the point the axes meet at) took the frustum sphere
    of those bounds, 9 dB lost unsaid: the cameras' own sphere now, warned of."""
    angles = np.radians(np.linspace(0.0, 300.0, 50))
    eyes = 4 * np.stack([np.cos(angles), np.sin(angles), 0.5 * np.sin(3 * angles)], 1)
    viewmats = np.stack([look_at(eye, [0, 0, 0]) for eye in eyes])
    distance = np.linalg.norm(eyes, axis=1)  # [50]
    bounds = np.stack([distance - 1.0, distance + 1.0], 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        center, radius = llff_sphere(viewmats, bounds, sim.K, W, H)
        bounds[7, 0] = 0.01
        assert llff_sphere(viewmats, bounds, sim.K, W, H)[1] == pytest.approx(radius)
    np.testing.assert_allclose(center, 0, atol=1e-9)
    assert radius == pytest.approx(1.0)
    said = r"the near bounds \(median 3\d.*\) lie over 2 times as far from the cameras as the"
    with pytest.warns(UserWarning, match=said):
        center, radius = llff_sphere(viewmats, 10 * bounds, sim.K, W, H, "p.npy")
    np.testing.assert_allclose(center, 0, atol=1e-9)
    assert radius == pytest.approx(distance.mean() / 2.5)
    # ten views, one stray: left out too (the 90th percentile interpolated it in: the review)
    few = np.stack([look_at(eye, [0, 0, 0]) for eye in eyes[::5]])  # [10, 4, 4]
    near = distance[::5] - 1.0
    near[3] = 0.01
    assert llff_sphere(few, np.stack([near, near + 2], 1), sim.K, W, H)[1] == pytest.approx(1.0)
    spread = distance[::5] - np.linspace(0.1, 1.0, 10)  # reaches 0.1..1.0: the 9th, 0.9
    assert llff_sphere(few, np.stack([spread, spread + 2], 1), sim.K, W, H)[1] == pytest.approx(0.9)
    # the axes meeting in front of every near bound, in the poses' units: the frustum sphere, as
    # before, unsaid (the review: a sphere about the meeting point left the scene out)
    behind = np.stack([distance + 0.5, distance + 3], 1)  # the scene 0.5-3 past the point
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        center, radius = llff_sphere(viewmats, behind, sim.K, W, H)
    far = np.minimum(behind[:, 1], np.percentile(behind[:, 1], 90))  # (capped: far bounds)
    expected = frustum_sphere(viewmats, np.stack([behind[:, 0], far], 1), sim.K, W, H)
    np.testing.assert_allclose(center, expected[0])
    assert radius == pytest.approx(expected[1])


def test_llff_sphere_warns_when_loose(sim):
    """Forward-facing cameras with far bounds 1000, or 40, times the near ones: a warning (a
    sphere over LOOSE_SPHERE = 20 times the near bound)."""
    viewmats = np.stack([look_at([x, 0, 0], [x, 10, 0]) for x in np.linspace(-0.2, 0.2, 5)])
    bounds = np.tile([1.0, 8.0], (5, 1))
    _, radius = llff_sphere(viewmats, bounds, sim.K, W, H)  # no warning
    assert 4 < radius < 8
    with pytest.warns(UserWarning, match="far bounds may be loose.*scene_radius in spikegs"):
        llff_sphere(viewmats, np.tile([1.0, 1000.0], (5, 1)), sim.K, W, H)
    # the limit is 20 times the near bound (1 here): far bounds 20 (a sphere of some 17) pass,
    # 40 (some 35) are warned of (a limit of 200 let a sphere 35 times the scene's through)
    assert llff_sphere(viewmats, np.tile([1.0, 20.0], (5, 1)), sim.K, W, H)[1] < 20
    with pytest.warns(UserWarning, match=r"radius 3\d\.?\d* is over 20 times"):
        llff_sphere(viewmats, np.tile([1.0, 40.0], (5, 1)), sim.K, W, H)


def test_nerf_absolute_file_paths(nerf, tmp_path):
    root = copy(nerf, tmp_path / "in")
    absolute = [str(root / "test" / "r_0"), str(root / "test" / "r_1.png")]
    edit_json(
        root / "transforms_test.json",
        lambda doc: [f.update(file_path=p) for f, p in zip(doc["frames"], absolute)],
    )
    ds = load_dataset(root)
    assert [v.name for v in ds.test_views] == ["test_r_0", "pseudo_test_r_1"]
    assert ds.test_views[1].readout is not None  # spike_data/r_1.dat found
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (root / "test" / "r_0.exr").rename(elsewhere / "r_0.exr")
    edit_json(
        root / "transforms_test.json",
        lambda doc: doc["frames"][0].update(file_path=str(elsewhere / "r_0")),
    )
    assert [v.name for v in load_dataset(root).test_views] == ["r_0", "pseudo_test_r_1"]


def test_rounded_poses_accepted_bent_rejected(sim, llff, nerf, tmp_path):
    root = copy(llff, tmp_path / "llff")
    edit_poses(root, lambda rows: rows.__setitem__(slice(None), rows.round(4)))
    ds = load_dataset(root)
    np.testing.assert_allclose(ds.trajectory.pose_at(LENGTH // 2), view_poses(sim)[0], atol=1e-3)
    edit_poses(root, lambda rows: rows.__setitem__((3, [0, 5, 10]), rows[3, [0, 5, 10]] * 1.01))
    with pytest.raises(
        ValueError, match="poses_bounds.npy: the pose of view 3 is not.*= 0.0[12].*tolerance 0.001"
    ):
        load_dataset(root)

    root = copy(nerf, tmp_path / "nerf")

    def round_matrices(doc):
        for frame in doc["frames"]:
            frame["transform_matrix"] = np.round(frame["transform_matrix"], 4).tolist()

    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / name, round_matrices)
    load_dataset(root)
    edit_json(
        root / "transforms_train.json",
        lambda doc: doc["frames"][2]["transform_matrix"][0].__setitem__(0, 2.0),
    )
    with pytest.raises(ValueError, match="transforms_train.json: the pose of frame 2 "):
        load_dataset(root)


def test_pseudo_window_longer_than_stream(llff_stream, tmp_path):
    root = copy(llff_stream, tmp_path)
    write_options(root, pseudo_gt_window=VIEWS * LENGTH + 1)
    with pytest.raises(ValueError, match="pseudo_gt_window of 701 readouts .* 700 readouts"):
        load_dataset(root)


def test_pseudo_window_bounds_only_the_views_it_scores(sim, llff, tmp_path):
    """pseudo_gt_window longer than the training views (the held-out ones longer still) was
    refused by the first training view it did not fit."""
    root = copy(llff, tmp_path)
    for i in (0, 8):  # the held-out views, 101 readouts each
        write_view(sim, root / "spikes" / f"{i:03d}.dat", i, length=101)
    write_options(root, pseudo_gt_window=101)
    ds = load_dataset(root)
    np.testing.assert_allclose(ds.test_views[1].image[..., 0], sim.stream.tfp(8 * LENGTH + 50, 101))
    write_options(root, pseudo_gt_window=103)
    with pytest.raises(ValueError, match="held-out view '000' .* 101 readouts, fewer than"):
        load_dataset(root)


def test_a_window_longer_than_a_view_is_refused_before_any_work(llff, tmp_path, monkeypatch):
    """The per-view check took the joined views for one stream: a window longer than a view
    passed it where the outermost views were held out, and failed at the first step."""
    ds = load_dataset(llff)  # views of 70 readouts: windows of 69 at most
    monkeypatch.setattr("spikegs.targets.trained_sim", lambda *a, **k: pytest.fail("SIM"))
    for method, key in (("tfp33", "instant_window"), ("spikegs", "exposure_window")):
        config = load_config(method, {"supervision": {key: 71}})
        with pytest.raises(ValueError, match=f"supervision.{key} = 71 .* at most 69"):
            Trainer(ds, config, tmp_path / "run", progress=False).train()
        assert not (tmp_path / "run").exists()


def test_malformed_files(llff, nerf, tmp_path):
    root = copy(llff, tmp_path / "llff")
    (root / "spikegs.json").write_text('{"flip": false,')
    with pytest.raises(ValueError, match="spikegs.json: not valid JSON"):
        load_dataset(root)
    (root / "spikegs.json").write_text('{"flip": false, "height": 8, "flip": true}')  # last won
    with pytest.raises(ValueError, match=r"spikegs.json: keys given twice .* \['flip'\]"):
        load_dataset(root)
    (root / "spikegs.json").unlink()
    (root / "poses_bounds.npy").write_bytes(pickle.dumps([[0.0] * 17]))
    with pytest.raises(ValueError, match=r"poses_bounds.npy: not an .npy file \(no numpy header\)"):
        load_dataset(root)
    (root / "poses_bounds.npy").write_bytes(b"")  # (a copy cut short: was called savetxt's text)
    with pytest.raises(ValueError, match=r"poses_bounds.npy: not an .npy file \(empty\): write"):
        load_dataset(root)
    np.savetxt(root / "poses_bounds.npy", np.zeros((3, 17)))  # numpy spoke of allow_pickle
    with pytest.raises(ValueError, match=r"not an \.npy file \(no numpy header: text .* np.save"):
        load_dataset(root)
    np.save(root / "poses_bounds.npy", np.array([[None] * 17]), allow_pickle=True)
    with pytest.raises(ValueError, match="poses_bounds.npy: not a numeric .npy array"):
        load_dataset(root)
    np.save(root / "poses_bounds.npy", np.full((3, 17), 1 + 1j))  # its imaginary parts dropped
    with pytest.raises(
        ValueError, match=r"expected a numeric .npy array \[N, 17\], found dtype co"
    ):
        load_dataset(root)

    root = copy(nerf, tmp_path / "nerf")
    edit_json(root / "transforms_test.json", lambda doc: doc["frames"][1]["transform_matrix"].pop())
    with pytest.raises(ValueError, match="transforms_test.json: frame 1 .*4 rows of 4 numbers"):
        load_dataset(root)
    fresh = copy(nerf, tmp_path / "fresh")
    edit_json(fresh / "transforms_train.json", lambda doc: doc["frames"][0].update(file_path=7))
    with pytest.raises(ValueError, match=r"frame 0 needs a file_path \(text\)"):
        load_dataset(fresh)
    (root / "transforms_train.json").write_text('{"frames": [')
    with pytest.raises(ValueError, match="transforms_train.json: not valid JSON"):
        load_dataset(root)


def test_llff_stream_and_per_view_spikes_both_present(llff, llff_stream, tmp_path):
    root = copy(llff_stream, tmp_path)
    shutil.copytree(llff / "spikes", root / "spikes")
    with pytest.raises(ValueError, match="both spikes.dat .* and spikes/ .* keep one"):
        load_dataset(root)


def test_nerf_test_views_and_transforms_train_alone(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    write_options(root, test_views=[1])
    with pytest.raises(ValueError, match="spikegs.json: test_views is for a single transforms"):
        load_dataset(root)
    # a keyword's named as such (spikegs.json was named, whether or not it held the key)
    (root / "spikegs.json").write_text("{}")
    keyword = rf"^{re.escape(str(root))}: keyword option test_views is for a single transforms"
    with pytest.raises(ValueError, match=keyword):
        load_nerf_layout(root, test_views=[1])
    write_options(root, test_views=[1])
    (root / "transforms_test.json").unlink()  # transforms_train.json alone: test_views apply
    assert [v.name for v in load_dataset(root).test_views] == ["pseudo_train_r_3"]
    with pytest.raises(ValueError, match=r"^\S+: keyword option test_views \[99\] outside the "):
        load_nerf_layout(root, test_views=[99])
    (root / "spikegs.json").unlink()  # default: every 8th frame
    assert [v.name for v in load_dataset(root).test_views] == ["pseudo_train_r_2"]


def test_nerf_transforms_files_left_unread_are_named(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    shutil.copy(root / "transforms_train.json", root / "transforms.json")
    with pytest.warns(
        UserWarning,
        match=r"reading transforms_train.json, transforms_test.json; "
        r"transforms.json not read",
    ):
        load_dataset(root)
    (root / "transforms_test.json").unlink()
    with pytest.warns(UserWarning, match=r"reading transforms_train.json; transforms.json not"):
        load_dataset(root)


def test_files_of_another_layout_are_named(sim, llff_stream, tmp_path):
    """A stray meta.json (a camera vendor's) hid an LLFF folder's poses_bounds.npy behind "no
    trajectory.json", and a transforms.json beside poses_bounds.npy was passed over in silence."""
    root = copy(llff_stream, tmp_path)
    shutil.copy(sim.root / "trajectory.json", root / "transforms.json")
    with pytest.warns(UserWarning, match=r"transforms.json not read: with poses_bounds.npy here"):
        load_dataset(root)
    (root / "meta.json").write_text(json.dumps({"camera": "Vidar-1"}))
    with pytest.raises(
        FileNotFoundError,
        match=r"trajectory.json .*; poses_bounds.npy, transforms.json here belong to the LLFF / "
        r"NeRF layouts, read only where there is no meta.json",
    ):
        load_dataset(root)
    dataset = copy(sim.root, tmp_path / "own")  # spikegs's layout says what it does not read
    shutil.copy(llff_stream / "poses_bounds.npy", dataset / "poses_bounds.npy")
    with pytest.warns(UserWarning, match=r"poses_bounds.npy here belong to the LLFF / NeRF"):
        assert load_dataset(dataset).num_readouts == sim.num_readouts


def test_gap_in_the_pose_log_is_named(llff_stream, tmp_path):
    """Training timestamps in a dropout of the pose log got poses interpolated across it without
    a word."""
    root = copy(llff_stream, tmp_path)
    readouts = np.loadtxt(root / "readouts.txt")  # a pose every 50 readouts
    keep = (readouts <= 100) | (readouts >= 400)
    np.savetxt(root / "readouts.txt", readouts[keep], fmt="%d")
    np.save(root / "poses_bounds.npy", np.load(root / "poses_bounds.npy")[keep])
    with pytest.warns(
        UserWarning,
        match=r"training timestamps in gaps of the poses .* \[100, 400\] \(\d+\), against a "
        r"median spacing of 50 readouts",
    ) as caught:
        dataset = load_dataset(root)
    inside = np.sum((dataset.train_timestamps > 100) & (dataset.train_timestamps < 400))
    assert f"[100, 400] ({inside})" in str(caught[0].message) and inside > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no gap, no warning
        load_dataset(llff_stream)


def test_held_out_poses_chosen_whose_window_does_not_fit_are_said_unscored(llff_stream, tmp_path):
    """test_views choosing pose 0 (readout 0) beside 8: its pseudo ground truth's window does not
    fit, so only pose 8 is scored, said as the dataset loads (eval scored 1 view in silence);
    a pose with room for a shorter window is told its length. The default's pose 0, at readout
    0 in every LLFF log, is left unscored without a word (docs/datasets.md says so)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert [v.name for v in load_dataset(llff_stream).test_views] == ["pseudo_view_008"]
    root = copy(llff_stream, tmp_path)
    write_options(root, test_views=[0, 8])
    said = r"held-out pose 0 \(readout 0\) within 32 readouts of the stream's ends, .* is not"
    with pytest.warns(UserWarning, match=said + r" scored \(1 of 2 .*with room around them scor"):
        ds = load_dataset(root)
    assert [v.name for v in ds.test_views] == ["pseudo_view_008"]
    write_options(root, test_views=[1, 8], pseudo_gt_window=129)  # pose 1: 50 readouts in
    with pytest.warns(UserWarning, match=r"around them, or a pseudo_gt_window of 101 or less, s"):
        load_dataset(root)
    write_options(root, test_views=[0])  # none scored: the error alone, not "0 of 1 are" first
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"none of the 1 held-out poses \(test_views \[0\]\)"):
            load_dataset(root)


def test_stream_cut_mid_frame_and_unsorted_readouts_say_what_to_do(llff_stream, tmp_path):
    root = copy(llff_stream, tmp_path)
    frame = H * W // 8
    with open(root / "spikes.dat", "ab") as f:
        f.write(b"\0" * 7)  # a recording cut off 7 bytes into a frame
    whole = VIEWS * LENGTH * frame
    with pytest.raises(
        ValueError,
        match=rf"{VIEWS * LENGTH} frames and 7 bytes over: .*truncated to {whole} bytes.* "
        rf"\(expected frames of {H}x{W} pixels",
    ):
        load_dataset(root)
    shutil.copy(llff_stream / "spikes.dat", root / "spikes.dat")
    readouts = np.loadtxt(root / "readouts.txt")
    readouts[3] = readouts[1]
    np.savetxt(root / "readouts.txt", readouts, fmt="%d")
    with pytest.raises(
        ValueError, match=r"strictly increasing, found 50 for pose 3 after 100 \(0-based"
    ):
        load_dataset(root)


def test_spikes_at_a_fraction_of_hwfs_size_are_named_so(llff, llff_stream, nerf, tmp_path):
    """Spikes at half the size of the images the poses were made from: the error names hwf as
    what gave the size, and the size the file holds whole frames of (it advised truncating the
    file alone); not where spikegs.json sets the size."""
    root = copy(llff_stream, tmp_path)
    table = np.load(root / "poses_bounds.npy")  # [N, 17]: hwf at columns 4, 9 and 14
    table[:, [4, 9, 14]] *= 2
    np.save(root / "poses_bounds.npy", table)
    frames = VIEWS * LENGTH - 1  # (700 fill 175 frames of hwf's size: readouts.txt told that)
    os.truncate(root / "spikes.dat", frames * H * W // 8)
    with pytest.raises(
        ValueError,
        match=rf"expected frames of {2 * H}x{2 * W} pixels, the size of hwf \({2 * H}, {2 * W}\) "
        rf"in {re.escape(str(root))}/poses_bounds.npy, .* if these are wrong; the file holds "
        rf"{frames} whole frames of {H}x{W}: spikes at 1/2 of that size\?\)$",
    ):
        load_dataset(root)
    write_options(root, height=2 * H)  # (the width still hwf's: named)
    with pytest.raises(ValueError, match=r"pixels, the size of hwf \("):
        load_dataset(root)
    (root / "spikegs.json").write_text(json.dumps({"height": 2 * H, "width": 2 * W}))
    with pytest.raises(ValueError, match=r"pixels, rows of \d+ from column 0: .* are wrong\)$"):
        load_dataset(root)
    # a NeRF layout whose w, h are twice its spikes': the transforms file named
    doubled = copy(nerf, tmp_path / "nerf")
    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(doubled / name, lambda doc: doc.update(w=2 * W, h=2 * H))
    with pytest.raises(ValueError, match=r"the size of the camera \(its w, h\) in .*transforms_"):
        load_dataset(doubled)
    # a stream per view, its files at half the size: the same
    views = copy(llff, tmp_path / "views")
    table = np.load(views / "poses_bounds.npy")
    table[:, [4, 9, 14]] *= 2
    np.save(views / "poses_bounds.npy", table)
    with pytest.raises(ValueError, match=rf"000.dat: .* the size of hwf \({2 * H}, {2 * W}\) in"):
        load_dataset(views)


def test_readouts_one_per_pose_strictly_increasing(tmp_path):
    """readouts.txt: two poses at one readout (a pose logged twice) and a line more than there
    are poses (another take's file) are refused; guards against a non-strict order check and a
    count check that let extra lines through."""

    path = tmp_path / "readouts.txt"
    np.savetxt(path, [0, 10, 20], fmt="%d")
    np.testing.assert_array_equal(_read_readouts(path, 3), [0, 10, 20])
    np.savetxt(path, [0, 10, 10], fmt="%d")
    with pytest.raises(ValueError, match="strictly increasing, found 10 for pose 2 after 10"):
        _read_readouts(path, 3)
    np.savetxt(path, [0, 10, 20, 30], fmt="%d")
    with pytest.raises(ValueError, match="readouts.txt: 4 readouts for 3 poses; expected one per"):
        _read_readouts(path, 3)
    path.write_text("0\n1_0\n20\n")  # (Python's float read it as 10: a typo taken as a number)
    with pytest.raises(ValueError, match=r"readouts.txt: line 2: expected one readout index a li"):
        _read_readouts(path, 3)


def test_llff_stream_length_checked_at_its_last_readout():
    """A stream of 100 readouts (0-99) records the light to readout 99.5: a last pose at 99.5, the
    end of the last readout's integration, fits (guards against refusing it, < for <=; 99.6 is
    refused); a first pose at 100, past the end, is every pose past the end, a counter rather
    than an index, and said so (guards against that case read from 101 on only). With height
    alone set, the frame size is still said to come from hwf (not from spikegs.json); with both,
    from spikegs.json."""

    class Stream:
        path, height, width = "s.dat", 32, 48

        def __len__(self):
            return 100

    hwf, options = np.array([32.0, 48.0, 40.0]), Options()
    _check_stream_length(Stream(), np.array([0.0, 50.0, 99.5]), hwf, options)
    with pytest.raises(ValueError, match=r"up to readout 99\.6\. The frame size 32x48 was taken"):
        _check_stream_length(Stream(), np.array([0.0, 50.0, 99.6]), hwf, options)
    with pytest.raises(ValueError, match=r"Every pose lies past the end \(the first at 100\)"):
        _check_stream_length(Stream(), np.array([100.0, 150.0]), hwf, options)
    # height alone set: the frame size still came from hwf, and the message says so
    with pytest.raises(ValueError, match=r"The frame size 32x48 was taken from hwf"):
        _check_stream_length(Stream(), np.array([0.0, 100.0]), hwf, Options(height=32))
    # both set: the frame size is spikegs.json's, which is the one to check
    with pytest.raises(ValueError, match=r"The frame size 32x48 was set in spikegs.json; check"):
        _check_stream_length(Stream(), np.array([0.0, 100.0]), hwf, Options(height=32, width=48))


def test_llff_poses_over_under_half_a_stream_read_at_another_size_are_warned_of():
    """Poses spanning readouts 0-30 of a 100-readout stream read at 32x48 where hwf says 64x96:
    under half the stream, warned of (a wrong frame size reads it as more, scrambled, readouts);
    guards against a threshold of a twentieth. At hwf's size, or over half, no warning."""

    class Stream:
        path, height, width = "s.dat", 32, 48

        def __len__(self):
            return 100

    with pytest.warns(UserWarning, match=r"span readouts \[0, 30\] of the 100 .* at 32x48"):
        _warn_partial_span(Stream(), np.array([0.0, 30.0]), np.array([64.0, 96.0, 40.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _warn_partial_span(Stream(), np.array([0.0, 30.0]), np.array([32.0, 48.0, 40.0]))
        _warn_partial_span(Stream(), np.array([0.0, 60.0]), np.array([64.0, 96.0, 40.0]))


def test_pose_gap_warning_ignores_short_gaps_and_stays_short():
    dense = np.arange(0, 2000, 2.0)  # a pose every 2 readouts, 12 missing: within one window
    dense = dense[(dense <= 998) | (dense >= 1012)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_pose_gaps(dense, np.arange(40, 1960, 3), "log")
    starts = 1_000_000 + 1000 * np.arange(8)  # eight 200-readout dropouts, poses 10 apart
    readouts = np.concatenate([np.arange(a, a + 800, 10) for a in starts] + [[starts[-1] + 1000]])
    with pytest.warns(UserWarning) as caught:
        warn_pose_gaps(readouts, readouts[:-1] + 195, "log")
    message = str(caught[0].message)
    assert "[1000790, 1001000] (20), [1001790, 1002000] (20)" in message  # whole readouts
    assert (
        message.count("] (20)") == 5 and " and 3 more, against a median spacing of 10 " in message
    )


def test_gaps_in_a_trajectory_json_are_warned_of(sim, tmp_path):
    """A trajectory.json (the simulator's, or `spikegs poses`') missing 199 poses is slerped
    across as a pose log's gaps are, and said so (unsaid until 2026-12-06)."""
    root = copy(sim.root, tmp_path)
    full = Trajectory.load_json(root / "trajectory.json")
    keep = (full.readouts <= 200) | (full.readouts >= 400)
    Trajectory(full.readouts[keep], full.viewmats[keep]).save_json(root / "trajectory.json")
    inside = np.sum((sim.train_timestamps > 200) & (sim.train_timestamps < 400))
    with pytest.warns(UserWarning, match=rf"trajectory.json: .* gaps .* \[200, 400\] \({inside}\)"):
        load_dataset(root)
    edit_json(root / "meta.json", lambda meta: meta.update(poses_from="sfm"))  # `spikegs poses`'
    with pytest.warns(UserWarning, match=r"each gap; SfM registered no image there: `spikegs pos"):
        load_dataset(root)
    # as `spikegs poses` pads its registered poses to the stream's ends, its timestamps between
    # them: no gap said
    registered = (full.readouts >= 150) & (full.readouts <= 500)
    padded = np.concatenate([[0.0], full.readouts[registered], [full.end]])
    ends = full.viewmats[registered][[0, -1]]
    views = np.concatenate([ends[:1], full.viewmats[registered], ends[1:]])
    Trajectory(padded, views).save_json(root / "trajectory.json")
    kept = sim.train_timestamps[(sim.train_timestamps > 166) & (sim.train_timestamps < 484)]
    (root / "train_timestamps.txt").write_text("".join(f"{k}\n" for k in kept))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        load_dataset(root)


def test_partial_trajectory_points_to_the_llff_layout(sim, tmp_path):
    root = copy(sim.root, tmp_path)
    part = Trajectory.load_json(root / "trajectory.json")
    keep = part.readouts >= 100
    Trajectory(part.readouts[keep], part.viewmats[keep]).save_json(root / "trajectory.json")
    with pytest.raises(ValueError, match=r"poses cover readouts \[1\d\d.*readouts.txt"):
        load_dataset(root)


def test_nerf_frame_listed_twice_names_the_files_listing_it(nerf, tmp_path):
    """A test frame listed twice in transforms_test.json is named with that file (it named
    transforms_train.json, which did not list it); listed in both files, both."""
    root = copy(nerf, tmp_path)
    test = root / "transforms_test.json"
    edit_json(test, lambda doc: doc["frames"].append(doc["frames"][0]))
    with pytest.raises(
        ValueError, match=r"^frame \"./test/r_0\" listed 2 times \(in \S*transforms_test.json\)"
    ):
        load_dataset(root)
    edit_json(test, lambda doc: doc["frames"].pop())
    second = json.loads(test.read_text())["frames"][1]  # test/r_1, spikes without image
    edit_json(root / "transforms_train.json", lambda doc: doc["frames"].append(second))
    with pytest.raises(
        ValueError,
        match=r"listed 2 times \(in \S*transforms_train.json and \S*transforms_test.json\)",
    ):
        load_dataset(root)


def test_nerf_image_in_two_formats_named(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    sharp = read_image(root / "test" / "r_0.exr")
    write_image(root / "test" / "r_0.png", np.zeros_like(sharp))
    with pytest.warns(
        UserWarning,
        match=r"test: frame images in several formats \(.png, .exr\): "
        r".png is read",
    ):
        load_dataset(root)


def test_nerf_image_of_an_upper_case_extension_is_read(nerf, tmp_path):
    """A file_path without an extension finds r_0.EXR as r_0.exr (a camera's upper-case
    extensions were passed over unsaid: the view held out as a pseudo ground truth)."""
    root = copy(nerf, tmp_path)
    (root / "test" / "r_0.exr").rename(root / "test" / "r_0.EXR")
    upper, lower = load_dataset(root), load_dataset(nerf)
    assert [v.name for v in upper.test_views] == ["test_r_0", "pseudo_test_r_1"]
    np.testing.assert_array_equal(upper.test_views[0].image, lower.test_views[0].image)
    write_image(root / "test" / "r_0.Png", np.zeros_like(read_image(root / "test" / "r_0.EXR")))
    with pytest.warns(UserWarning, match=r"several formats \(.Png, .EXR\): .Png is read"):
        load_dataset(root)  # in IMAGE_EXTENSIONS' order, as lower-case ones


def test_nerf_image_named_with_another_extension_is_read_and_said(nerf, tmp_path):
    """A file_path ending in .png beside the frame's r_0.exr: the image was not found (the
    view held out against its own TFP, unsaid, where the size was given); it is read, said."""
    root = copy(nerf, tmp_path)
    edit_json(
        root / "transforms_test.json",
        lambda doc: doc["frames"][0].update(file_path="./test/r_0.png"),
    )
    with pytest.warns(
        UserWarning, match=r"test: frame images named .png \(file_path\), found as .exr: read"
    ):
        named = load_dataset(root)
    assert [v.name for v in named.test_views] == ["test_r_0", "pseudo_test_r_1"]
    np.testing.assert_array_equal(named.test_views[0].image, load_dataset(nerf).test_views[0].image)


def test_nerf_image_folders_are_listed_once_a_load(nerf, tmp_path, listed_folders):
    """Each folder of frame images is listed once a load, not once a frame (a 1000-frame folder:
    1000 listings, each of 1000 names)."""
    root = copy(nerf, tmp_path)
    load_dataset(root)
    assert [listed_folders[str(root / name)] for name in ("train", "test")] == [1, 1]


def test_nerf_frame_size_from_the_options_scales_the_camera(sim, nerf, tmp_path):
    root = copy(nerf, tmp_path)
    write_options(root, height=H // 2, width=W // 2)  # the same .dat files as 16x24 frames
    with pytest.warns(UserWarning, match=r"likely 48 pixels wide, 2 times the width given"):
        ds = load_dataset(root)  # (its spikes read so are noise)
    assert (ds.height, ds.width) == (H // 2, W // 2)
    np.testing.assert_allclose(np.diag(ds.K)[:2], np.diag(sim.K)[:2] / 2, rtol=1e-6)
    write_options(root, height=H // 2)  # 16x48: non-square pixels (fy halved, fx kept)
    with pytest.raises(ValueError, match="another aspect ratio than the 16x48 spikes"):
        load_dataset(root)


def test_nerf_wrong_frame_size_points_at_it(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    write_options(root, height=2 * H)  # the .dat files read as half as many 64x48 frames
    with pytest.raises(
        ValueError, match=rf"is for {H}x{W} images .*{2 * H}x{W} spikes.*set height"
    ):
        load_dataset(root)


def test_nerfstudios_point_cloud_and_masks_are_said_to_be_unread(nerf, tmp_path):
    """nerfstudio's ply_file_path (its sparse points) and frames' mask_path were passed over
    without a word: the Gaussians started at random, masked pixels trained. Each is warned of; the
    cloud no more once it is the dataset's points3d.ply."""
    root = copy(nerf, tmp_path)
    edit_json(root / "transforms_train.json", lambda doc: doc.update(ply_file_path="sparse.ply"))
    with pytest.warns(UserWarning, match="ply_file_path 'sparse.ply' is not read; copy it to "):
        load_dataset(root)
    (root / "points3d.ply").write_bytes(b"")  # copied (read by the trainer, not the loader)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        load_dataset(root)
    assert not [w for w in said if "ply_file_path" in str(w.message)]
    masks = lambda doc: [f.update(mask_path=f"m/{i}.png") for i, f in enumerate(doc["frames"])]  # noqa: E731
    edit_json(root / "transforms_test.json", masks)
    with pytest.warns(UserWarning, match="2 frame\\(s\\) state a mask_path, which is not read"):
        load_dataset(root)


def test_nerf_per_frame_intrinsics_and_distortion(sim, nerf, tmp_path):
    root = copy(nerf, tmp_path)
    fx, fy, cx, cy = (float(sim.K[i, j]) for i, j in ((0, 0), (1, 1), (0, 2), (1, 2)))
    camera = dict(fl_x=fx, fl_y=fy, cx=cx, cy=cy, w=W, h=H)

    def per_frame(doc):
        del doc["camera_angle_x"], doc["w"], doc["h"]
        for frame in doc["frames"]:
            frame.update(camera)

    for name in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / name, per_frame)
    np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)
    edit_json(root / "transforms_test.json", lambda doc: doc["frames"][1].update(fl_x=99.0))
    with pytest.raises(ValueError, match=f"test/r_1' has intrinsics fl_x 99, .* w {W}, h {H} \\("):
        load_dataset(root)
    edit_json(
        root / "transforms_test.json", lambda doc: doc["frames"][1].update(fl_x=camera["fl_x"])
    )
    edit_json(root / "transforms_train.json", lambda doc: doc.update(k1=0.0, p1=0.0))
    edit_json(root / "transforms_test.json", lambda doc: doc.update(camera_model="OPENCV"))
    load_dataset(root)  # zero distortion, a pinhole model: no warning
    fisheye = lambda doc: doc["frames"][1].update(camera_model="OPENCV_FISHEYE")  # noqa: E731
    edit_json(root / "transforms_test.json", fisheye)  # it loaded as a pinhole, without a word
    with pytest.raises(ValueError, match="camera_model \"OPENCV_FISHEYE\" of frame './test/r_1'"):
        load_dataset(root)
    edit_json(root / "transforms_test.json", lambda doc: doc["frames"][1].pop("camera_model"))
    edit_json(root / "transforms_test.json", lambda doc: doc.update(is_fisheye=True))  # instant-
    with pytest.raises(ValueError, match="is_fisheye true of frame './test/r_0'"):  # ngp's: read
        load_dataset(root)  # as a pinhole without a word
    edit_json(root / "transforms_test.json", lambda doc: doc.update(is_fisheye=False))
    load_dataset(root)
    edit_json(root / "transforms_train.json", lambda doc: doc.update(k1=0.1))
    with pytest.warns(UserWarning, match="distortion \\{'k1': 0.1\\} ignored.*pinhole"):
        load_dataset(root)
    edit_json(root / "transforms_train.json", lambda doc: doc.update(k1=-0.1))  # barrel: as
    with pytest.warns(UserWarning, match="distortion \\{'k1': -0.1\\} ignored"):  # unmodelled
        load_dataset(root)
    edit_json(root / "transforms_train.json", lambda doc: doc.update(k1=0, k6=0.01))  # COLMAP's
    with pytest.warns(UserWarning, match="distortion \\{'k6': 0.01\\} ignored"):  # FULL_OPENCV:
        load_dataset(root)  # k5, k6 were not looked at
    edit_json(root / "transforms_train.json", lambda doc: doc.update(k6=0))
    for value in ("abc", None, float("nan"), True, str(fx)):  # a number as text was read
        edit_json(
            root / "transforms_train.json", lambda doc, v=value: doc["frames"][0].update(fl_x=v)
        )
        with pytest.raises(ValueError, match="transforms_train.json: fl_x expected a finite nu"):
            load_dataset(root)


def test_nerf_camera_stated_with_other_keys_is_one_camera(sim, nerf, tmp_path):
    """transforms_test.json stating camera_angle_y, cx, cy, a zero distortion and the size at half
    resolution beside a training file with camera_angle_x, w and h alone was refused as 'one
    camera expected' (its keys differed): the same K is one camera; a camera_angle_y 2 % off, or
    distortion one file alone states, is another, and the message says which differs."""
    root = copy(nerf, tmp_path)
    angle_y = 2 * np.arctan(H / 2 / float(sim.K[0, 0]))

    def camera(factor: float):  # instant-ngp's keys, at half the size
        same = dict(cx=W / 4, cy=H / 4, w=W // 2, h=H // 2, k1=0.0, p1=0)
        return lambda doc: doc.update(camera_angle_y=angle_y * factor, **same)

    edit_json(root / "transforms_test.json", camera(1.0))
    np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)
    edit_json(root / "transforms_test.json", camera(1.02))
    other = r"test/r_0' has intrinsics .*camera_angle_y .* \(fx, fy, cx, cy [\d.]+, [\d.]+, "
    with pytest.warns(UserWarning, match="non-square pixels"):
        with pytest.raises(ValueError, match=other + ".*fx, fy, cx, cy differ; one camera exp"):
            load_dataset(root)
    edit_json(root / "transforms_test.json", camera(1.0))
    edit_json(root / "transforms_test.json", lambda doc: doc.update(k1=0.1))
    with pytest.raises(ValueError, match="k1 0.1, .*their distortion differs; one camera exp"):
        load_dataset(root)


def test_nerf_focal_given_once_or_twice(sim, nerf, tmp_path):
    """fl_y alone was refused as 'no intrinsics' (fl_x alone meant fy = fx); fl_x beside a
    camera_angle_x that disagrees with it was taken silently."""
    fx = float(sim.K[0, 0])
    for key, name in (("fl_y", "only_fy"), ("fl_x", "both")):
        root = copy(nerf, tmp_path / name)
        for part in ("transforms_train.json", "transforms_test.json"):
            edit_json(root / part, lambda doc, k=key: doc.update({k: fx}))
            if name == "only_fy":
                edit_json(root / part, lambda doc: doc.pop("camera_angle_x"))
        np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)
    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, lambda doc: doc.update(fl_x=0.5 * fx))
    with pytest.warns(UserWarning, match="fl_x .* and camera_angle_x .* disagree; fl_x is used"):
        assert load_dataset(root).K[0, 0] == pytest.approx(0.5 * fx)
    for part in ("transforms_train.json", "transforms_test.json"):  # 5 %: over the 1 % allowed
        edit_json(root / part, lambda doc: doc.update(fl_x=1.05 * fx))
    with pytest.warns(UserWarning, match="fl_x .* and camera_angle_x .* disagree; fl_x is used"):
        load_dataset(root)


def test_nerf_camera_angle_y_gives_the_focal_in_y(sim, nerf, tmp_path):
    """instant-ngp writes camera_angle_y beside camera_angle_x: it was ignored (fy = fx, unsaid).
    Non-square pixels are warned of (Blender's angle_y follows its sensor, not the render), as is
    an angle beside a focal in pixels that disagrees with it; an angle in degrees is named."""
    root = copy(nerf, tmp_path)
    fy = 1.1 * float(sim.K[1, 1])
    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, lambda doc: doc.update(camera_angle_y=2 * math.atan(H / 2 / fy)))
    with pytest.warns(UserWarning, match="non-square pixels, taken as given"):
        K = load_dataset(root).K
    assert K[1, 1] == pytest.approx(fy) and K[0, 0] == pytest.approx(sim.K[0, 0])
    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, lambda doc: doc.update(fl_x=float(sim.K[0, 0])))
    with pytest.warns(UserWarning, match="fl_y .* and camera_angle_y .* disagree; fl_y is used"):
        assert load_dataset(root).K[1, 1] == pytest.approx(sim.K[1, 1])
    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, lambda doc: doc.update(camera_angle_y=38.2))
    with pytest.raises(ValueError, match="camera_angle_y .* \\(38.2 degrees would be 0.66"):
        load_dataset(root)


CAMERA_ENTRIES = {"fl_x": (0, 0), "fl_y": (1, 1), "cx": (0, 2), "cy": (1, 2)}  # K's entry of each


def test_nerf_focal_in_pixels_of_the_training_images(sim, nerf, tmp_path):
    """fl_x, fl_y, cx, cy without w, h are for the frames' images: where no test frame has one,
    the first training image's size. The spikes' size (spikegs.json) was taken instead, the
    intrinsics of 2x images unscaled: 34 px off in a helper's rig, unsaid."""
    root = copy(nerf, tmp_path)
    write_view(sim, root / "spike_data" / "test" / "r_0.dat", 0)
    (root / "test" / "r_0.exr").unlink()
    source, viewmats = make_source("solids", 2 * W, 2 * H, 1), view_poses(sim)
    for i in range(2, VIEWS - 1):
        write_image(root / "train" / f"r_{i}.exr", source.render(viewmats[i]))
    camera = {k: 2 * float(sim.K[i, j]) for k, (i, j) in CAMERA_ENTRIES.items()}
    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, lambda doc: [doc.pop(k) for k in ("camera_angle_x", "w", "h")])
        edit_json(root / part, lambda doc: doc.update(camera))
    write_options(root, height=H, width=W)
    np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)
    # the first training image unreadable (a copy cut short), the calibration given: the size is
    # the next readable one's (the images then only check the flip)
    (root / "train" / "r_2.exr").write_bytes(b"not an image")
    write_options(root, height=H, width=W, rate_at_one=0.25)
    np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)

    def angle_only(doc):  # a focal as an angle needs no image size
        for key in CAMERA_ENTRIES:
            doc.pop(key)
        doc["camera_angle_x"] = float(2 * np.arctan(W / 2 / sim.K[0, 0]))

    for part in ("transforms_train.json", "transforms_test.json"):
        edit_json(root / part, angle_only)
    write_image(root / "train" / "r_2.exr", np.ones((2 * H, 3 * W, 1), np.float32))
    write_options(root, height=H, width=W, rate_at_one=0.25)  # (no image calibrates)
    np.testing.assert_allclose(load_dataset(root).K, sim.K, rtol=1e-6)  # (that one was the size)


def test_nerf_matrix_of_text_refused(nerf, tmp_path):
    """A transform_matrix of numbers written as strings loaded (numpy reads '1.0')."""
    root = copy(nerf, tmp_path)
    edit_json(
        root / "transforms_train.json",
        lambda doc: doc["frames"][0].update(
            transform_matrix=[[str(v) for v in row] for row in doc["frames"][0]["transform_matrix"]]
        ),
    )
    with pytest.raises(ValueError, match="transform_matrix expected 4 rows of 4 numbers"):
        load_dataset(root)


# -- training end to end ---------------------------------------------------------------------------
@pytest.mark.parametrize("layout", ["llff", "llff_stream", "nerf"])
def test_trains_end_to_end(layout, request, tmp_path):
    ds = load_dataset(request.getfixturevalue(layout))
    summary = Trainer(ds, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    result = evaluate_run(tmp_path / "run", ds)
    assert summary["iterations"] == 30 and np.isfinite(summary["intensity_scale"])
    assert np.isfinite(result["psnr"]) and np.isfinite(result["ssim"])
    assert set(result["views"]) == {v.name for v in ds.test_views}


def test_nerf_test_views_of_one_name_refused(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    (root / "test_r").mkdir()
    shutil.copy(root / "test" / "r_0.exr", root / "test_r" / "0.exr")  # both named test_r_0

    def add_twin(doc):
        doc["frames"].append({**doc["frames"][0], "file_path": "./test_r/0"})

    edit_json(root / "transforms_test.json", add_twin)
    with pytest.raises(
        ValueError,
        match=r"frames \['test/r_0', 'test_r/0'\] \(in \S*transforms_test.json\) both become "
        r"view 'test_r_0'",
    ):
        load_dataset(root)


def test_nerf_spike_candidates_listed_once(tmp_path):

    for file_path in ("r_0", str(tmp_path.parent / "elsewhere" / "r_0.png")):  # no folder in DIR
        assert _spike_candidates(tmp_path, {"file_path": file_path}, "t.json") == [
            tmp_path / "spike_data" / "r_0.dat"
        ]
    assert len(_spike_candidates(tmp_path, {"file_path": "./train/r_0"}, "t.json")) == 2


def test_nerf_spike_files_found_by_path_first_and_never_shared(nerf, tmp_path):
    """A frame's spikes: spike_data/<file_path less its image extension, of any case>.dat before
    spike_data/<stem>.dat. Guards against an upper-case extension kept in the name (r_2.PNG.dat
    sought, the frame refused), the stem tried first (a stray spike_data/r_2.dat, another view's
    spikes, trained at train/r_2's pose) and two frames reading one spike file unrefused."""
    root = copy(nerf, tmp_path / "found")
    edit_json(
        root / "transforms_train.json",
        lambda doc: doc["frames"][0].update(file_path="./train/r_2.PNG"),
    )
    shutil.copy(root / "custom" / "last.dat", root / "spike_data" / "r_2.dat")
    files = load_dataset(root).meta["spike_files"]
    assert files[0] == os.path.join("spike_data", "train", "r_2.dat"), files
    assert os.path.join("spike_data", "r_2.dat") not in files

    root = copy(nerf, tmp_path / "shared")
    edit_json(
        root / "transforms_train.json",
        lambda doc: doc["frames"][0].update(spike_path="custom/last.dat"),
    )
    with pytest.raises(
        ValueError, match=r"frames '\./train/r_2' and '\./train/last.png' share the spike file"
    ):
        load_dataset(root)


def test_nerf_spike_candidates_keep_other_suffixes_and_resolve_dir(tmp_path, monkeypatch):
    """Only an image extension leaves a frame's file_path for its spike file: scan.001 is sought
    as spike_data/scan.001.dat, not spike_data/scan.dat (another frame's, or none). An absolute
    file_path inside a DIR given relative (or through a link) keeps its folders: compared
    unresolved it read as outside DIR, named by its file name alone."""

    def candidates(root, file_path):
        found = _spike_candidates(root, {"file_path": file_path}, "t.json")
        return [p.relative_to(root).as_posix() for p in found]

    assert candidates(tmp_path, "./train/scan.001") == [
        "spike_data/train/scan.001.dat",
        "spike_data/scan.001.dat",
    ]
    assert candidates(tmp_path, "./train/r_0.JPG")[0] == "spike_data/train/r_0.dat"
    monkeypatch.chdir(tmp_path.parent)
    inside = str(tmp_path / "train" / "r_0.png")
    assert candidates(Path(tmp_path.name), inside)[0] == "spike_data/train/r_0.dat"


def test_nerf_spikes_with_rows_wider_than_the_camera_are_named(sim, nerf, tmp_path):
    """The NeRF layout checks its first spike file's rows as the stream layouts do: a camera's
    rows of W + 24 pixels read W at a time are warned of, raw_width named (guards against the
    check left out of this layout: noise trained without a word)."""
    root = copy(nerf, tmp_path)
    packed = sim.stream.packed(2 * LENGTH, 3 * LENGTH)  # train/r_2, the first training view
    bits = np.unpackbits(packed, axis=-1, bitorder="little")[..., :W]  # [T, H, W]
    raw = np.random.default_rng(0).integers(0, 2, (LENGTH, H, W + 24), dtype=np.uint8)
    raw[..., 4 : 4 + W] = bits  # the extra columns: noise; 105 whole 32x48 frames too
    save_dat(root / "spike_data" / "train" / "r_2.dat", raw)
    with pytest.warns(UserWarning, match=rf"rows of {W + 24} pixels .* set raw_width {W + 24}"):
        load_dataset(root)
    keyed = r"in spikegs.json or the loader's keywords \(flip\), which override it; "
    with pytest.warns(UserWarning, match=rf"set raw_width {W + 24}, and col_offset, .* {keyed}"):
        load_nerf_layout(root, flip=True)  # (its default, given: where the advice says to look)


def test_nerf_training_views_of_one_name_refused(nerf, tmp_path):
    root = copy(nerf, tmp_path)
    shutil.copy(root / "custom" / "last.dat", root / "custom" / "twin.dat")

    def add_twin(doc):  # the same image name, other spikes
        doc["frames"].append({**doc["frames"][1], "spike_path": "custom/twin.dat"})

    edit_json(root / "transforms_train.json", add_twin)
    with pytest.raises(
        ValueError, match=r'frame "./train/r_3" listed 2 times \(in \S*train.json\)'
    ):
        load_dataset(root)


def test_llff_intrinsics_scale_with_the_spikes_frame_size():
    """hwf (64, 96, focal 80) for spikes of 32x48 (half the poses' images): K is hwf's halved,
    fx = fy = 40, cx = 24, cy = 16 (an unscaled fx read 80, a cy of hwf's h / 2 read 32)."""
    K, height, width = llff_intrinsics(
        np.array([64.0, 96.0, 80.0]), Options(height=32, width=48), "x"
    )
    assert (height, width) == (32, 48)
    np.testing.assert_allclose(K, [[40, 0, 24], [0, 40, 16], [0, 0, 1]])
    # images 97 wide (48.5 at height 32, within a pixel): each axis scaled by its own ratio,
    # fy by the heights' (fy from the widths' ratio read 80 * 48 / 97 = 39.6)
    K, *_ = llff_intrinsics(np.array([64.0, 97.0, 80.0]), Options(height=32, width=48), "x")
    np.testing.assert_allclose(K, [[80 * 48 / 97, 0, 24], [0, 40, 16], [0, 0, 1]])


def test_llff_intrinsics_of_a_raw_row_crop_keep_the_focal_and_shift_cx():
    """hwf for the 64 stored pixels of a row, spikes its 48 columns from col_offset 8: the focal
    stays 50, cx = 64 / 2 - 8 = 24, cy = 16."""
    options = Options(height=32, width=48, raw_width=64, col_offset=8)
    K, _, _ = llff_intrinsics(np.array([32.0, 64.0, 50.0]), options, "x")
    np.testing.assert_allclose(K, [[50, 0, 24], [0, 50, 16], [0, 0, 1]])


def test_llff_holds_out_every_8th_view_from_view_0():
    """LLFF's convention: views 0, 8, 16, ... (a mask from 1 held out 1, 9 instead)."""
    assert np.flatnonzero(held_out_mask(17, Options(), "x")).tolist() == [0, 8, 16]
    assert np.flatnonzero(held_out_mask(5, Options(test_views=[1, 3]), "x")).tolist() == [1, 3]
    with pytest.raises(
        ValueError, match=r"^d/spikegs.json: test_views \[5\] outside the 5 views \[0, 5\) of d/x$"
    ):
        held_out_mask(5, Options(test_views=[1, 5]), "d/x")  # one past the last: no IndexError


def test_view_tfp_spans_the_whole_odd_view():
    """A view's TFP (intensity calibration, and the pseudo ground truth's default window) spans
    all of an odd-length view, and all but one readout of an even one: spikes only at a 5-readout
    view's first and last readouts read 2/5 (a window of 3 read 0)."""
    bits = np.zeros((5, 2, 8), np.uint8)
    bits[[0, 4]] = 1
    ((tfp, _),) = view_tfps([(SpikeStream.from_bits(bits), None)])
    np.testing.assert_allclose(tfp, 0.4)
    bits6 = np.zeros((6, 2, 8), np.uint8)
    bits6[[1, 5]] = 1  # the 5 readouts [1, 6) centred on 3
    ((tfp6, _),) = view_tfps([(SpikeStream.from_bits(bits6), None)])
    np.testing.assert_allclose(tfp6, 0.4)


def test_intensity_calibration_is_the_median_over_views():
    """rate_from_images: the median of the views' rate / intensity ratios, so one wrong image
    (another view's, five times darker) does not move it: 0.25 (the mean read 0.583)."""
    image = np.linspace(0.2, 1.0, 48, dtype=np.float32).reshape(6, 8, 1)
    views = [(0.25 * image[..., 0], image), (0.25 * image[..., 0], image)]
    views.append((0.25 * image[..., 0], image / 5))  # a wrong, darker image: ratio 1.25
    assert rate_from_images(views, "x") == pytest.approx(0.25)
    black = (0.25 * image[..., 0], 0 * image)  # a black image: no ratio (an infinite one moved
    assert rate_from_images([views[0], views[2], black], "x") == pytest.approx(0.75)  # the median)
    with pytest.raises(ValueError, match="all black or their spikes too few"):
        rate_from_images([black, black], "x")
    # images five times darker than their spikes' light: 1.25 was refused later as stated in
    # meta.json or spikegs.json, files the user never wrote
    with pytest.raises(
        ValueError,
        match=r"x: rate_at_one calibrated from 2 training views' sharp "
        r"images is 1\.25, over 1 .* 16-bit image not tagged linear",
    ):
        rate_from_images([views[2], views[2]], "x")


def test_spikes_upside_down_against_their_images_warn_of_flip():
    """check_orientation compares each TFP with its image turned upside down (rows reversed):
    spikes read with the wrong flip warn, spikes mirrored left-right do not (comparing with the
    image mirrored left-right instead missed the upside-down case); spikes that match neither
    way warn of the reading (loaded unsaid before)."""
    rows, cols = np.mgrid[0:12, 0:16].astype(np.float32)
    image = (rows / 11 + 0.3 * (cols > 10))[..., None]  # dark top, bright bottom, a right stripe
    upside_down = [(image[::-1, :, 0] * 0.25, image)] * 3
    with pytest.warns(UserWarning, match="better upside down"):
        check_orientation(upside_down, True, "x", OPTIONS_FILE)
    mirrored = [(image[:, ::-1, 0] * 0.25, image)] * 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_orientation(mirrored, True, "x", OPTIONS_FILE)
    # a .dat packed most significant bit first: each byte's 8 pixels reversed (a 48x64 view of
    # solids correlated at 0.57 so, above MATCH_MIN: loaded unsaid before)
    texture = np.random.default_rng(1).random((12, 16, 1))
    for flip in (True, False):
        packed_msb = [(other_bit_order(texture[..., 0], flip) * 0.25, texture)] * 3
        with pytest.warns(UserWarning, match=r"bits read in the other order .* most significant"):
            check_orientation(packed_msb, flip, "x", OPTIONS_FILE)
    # spikes that match neither way up (another pixel order, say)
    scrambled = np.random.default_rng(0).permutation(image.reshape(-1)).reshape(image.shape)
    with pytest.warns(UserWarning, match=r"hardly match .* \(median correlation -?0\.\d\d over 3"):
        check_orientation([(scrambled[..., 0] * 0.25, image)] * 3, True, "x", OPTIONS_FILE)


def test_correlation_refuses_images_of_two_shapes():
    """Pearson's r of two images; an image against one of another shape (its row means, say)
    raises where numpy broadcast it into a number."""
    image = np.random.default_rng(0).random((12, 16))
    assert correlation(image, 2 * image + 1) == pytest.approx(1.0)
    assert correlation(image, -image) == pytest.approx(-1.0)
    assert correlation(image, np.ones_like(image)) == 0.0  # flat
    assert correlation(1e-4 * image, 1e-4 * image) == pytest.approx(1.0)  # faint, not flat
    with pytest.raises(ValueError, match=r"shapes \(12, 16\) and \(12, 1\)"):
        correlation(image, image.mean(-1, keepdims=True))


def test_flip_warning_needs_most_views_to_match_upside_down_by_a_margin():
    """TFPs mixing each image with itself upside down (weights cos θ, sin θ: correlations about
    those): flipped better by 0.37 (θ 60°) in most views warns of flip; by 0.10 (θ 49°, within
    FLIP_MARGIN 0.2, a noisy view's difference) or in only half the views it does not."""
    image = np.random.default_rng(0).random((64, 64, 1))
    flat = image[..., 0]

    def view(degrees):  # (TFP [H, W], image [H, W, 1]) of a view mixed at θ
        t = np.radians(degrees)
        return np.cos(t) * flat + np.sin(t) * flat[::-1], image

    with pytest.warns(UserWarning, match="better upside down"):
        check_orientation([view(60)] * 3, True, "x", OPTIONS_FILE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_orientation([view(49)] * 3, True, "x", OPTIONS_FILE)
        check_orientation([view(60), view(30)], True, "x", OPTIONS_FILE)  # one view of two


def test_a_view_of_the_longest_window_loads_and_one_readout_less_is_refused(sim, llff, tmp_path):
    """A view of 65 readouts holds TFP(65), the longest window training reads: it loads; one of
    64 is refused naming the file (a bound one readout off either way refused the first or let
    the second fail at training)."""
    root = copy(llff, tmp_path)
    write_view(sim, root / "spikes" / "004.dat", 4, length=65)
    assert load_dataset(root).meta["view_readouts"]["004"] == [280, 345]
    write_view(sim, root / "spikes" / "004.dat", 4, length=64)
    with pytest.raises(ValueError, match="004.dat: view '004' has 64 readouts.*at least 65"):
        load_dataset(root)


def _three_poses(tmp_path, middle: float, ends: tuple = (0.0, 199.0)):
    """A random 4x8 stream of 200 readouts with poses at readouts `ends[0]`, `middle` and
    `ends[1]`, the middle one held out: the SpikeStream and its dataset."""
    bits = np.random.default_rng(0).random((200, 4, 8)) < 0.3
    save_dat(tmp_path / "spikes.dat", bits)
    stream = SpikeStream.open(tmp_path / "spikes.dat", 4, 8)
    angles = np.radians([0.0, 25.0, 50.0])
    viewmats = np.stack([look_at([3 * np.cos(a), 3 * np.sin(a), 1.0], [0, 0, 0]) for a in angles])
    meta = {"height": 4, "width": 8, "channels": 1, "fx": 8.0, "fy": 8.0, "cx": 4.0, "cy": 2.0}
    meta |= {"scene_center": [0.0, 0.0, 0.0], "scene_radius": 1.0}
    readouts, test = np.array([ends[0], middle, ends[1]]), np.array([False, True, False])
    return stream, stream_dataset(tmp_path, meta, stream, readouts, viewmats, test, Options(), "x")


def test_stream_poses_outside_the_streams_light_refused(tmp_path):
    """One stream of 200 readouts records the light of readouts (-0.5, 199.5]: poses stamped at
    the start of the first readout's integration and the end of the last's load (they were
    refused as outside [0, 199]) with the timestamps of poses at 0 and 199; poses at -0.6 or
    199.6 are a ValueError naming the stream (the LLFF loader checks the end before;
    stream_dataset itself refuses both ends)."""
    ds = _three_poses(tmp_path, 100.0, ends=(-0.5, 199.5))[1]
    assert ds.train_timestamps.tolist() == [32, 33, 34, 35, 165, 166, 167]
    for ends in ((-0.6, 199.0), (0.0, 199.6)):
        with pytest.raises(ValueError, match=r"outside \[-0.5, 199.5\], the light the stream's"):
            _three_poses(tmp_path, 100.0, ends)


def test_stream_timestamps_reach_the_first_and_last_pose_by_half_a_window(tmp_path):
    """One stream of 200 readouts, poses at 0, 100, 199, the middle one held out: training
    timestamps are every readout whose TFP(65) lies between the first and last pose and that keeps
    64 readouts clear of readout 100, 32-35 and 165-167 (a strict bound at either end lost the
    first or last; a clearance of 63 or 65 moved 35 or 165)."""
    ds = _three_poses(tmp_path, 100.0)[1]
    assert ds.train_timestamps.tolist() == [32, 33, 34, 35, 165, 166, 167]


def test_spaced_held_out_poses_follow_the_documented_stride():
    """docs/datasets.md: held-out poses of a dense log every ⌈8·(129 + train_every) / s⌉-th, s
    the median readouts between poses: every 1040th for a pose a readout and train_every 1,
    ⌈8 · 131 / 3⌉ = 350th for one every 3 readouts and train_every 2; never under every 8th."""
    assert _spaced_hold_out(np.arange(5000.0), 1) == 1040
    assert _spaced_hold_out(np.arange(0.0, 5000.0, 3.0), 2) == 350
    assert _spaced_hold_out(np.arange(0.0, 50000.0, 1000.0), 1) == 8


def test_a_fractional_held_out_pose_is_scored_on_the_nearest_readout(tmp_path):
    """A held-out pose at readout 100.7 (readouts.txt may be fractional) gets the pseudo ground
    truth TFP(65) centred on readout 101, the nearest (truncating centred it on 100)."""
    stream, ds = _three_poses(tmp_path, 100.7)
    assert ds.test_views[0].readout == pytest.approx(100.7)
    np.testing.assert_array_equal(ds.test_views[0].image[..., 0], stream.tfp(101, 65))
    assert not np.array_equal(stream.tfp(100, 65), stream.tfp(101, 65))


def test_view_streams_put_a_views_first_readout_in_that_view():
    """Views of 3 and 4 readouts: readout 3 is view 1's first (not view 0's), TFP(1) there reads
    view 1's spikes, and the held trajectory gives readout 3 view 1's pose (the last readout of
    view 0 is 2; holding view 0 to readout 3 gave readout 3 view 0's pose)."""
    a = np.zeros((3, 2, 8), np.uint8)
    b = np.ones((4, 2, 8), np.uint8)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    assert views.view_of(np.array([0, 2, 3, 6])).tolist() == [0, 0, 1, 1]
    np.testing.assert_array_equal(views.tfp(3, 1), 1.0)
    np.testing.assert_array_equal(views.tfp(2, 1), 0.0)
    poses = np.stack([look_at([3.0, 0.0, 1.0], [0, 0, 0]), look_at([0.0, 3.0, 1.0], [0, 0, 0])])
    trajectory = views.held_trajectory(poses, "x")
    assert trajectory.readouts.tolist() == [0, 2, 3, 6]
    np.testing.assert_allclose(trajectory.pose_at(3.0), poses[1], atol=1e-12)
    np.testing.assert_allclose(trajectory.pose_at(2.0), poses[0], atol=1e-12)


def test_view_streams_report_their_frame_size_and_refuse_mixed_sizes():
    """Views of 2x8 frames: height 2 and width 8 (a width read from the height passed every
    loader test, whose datasets take their size from meta), and a view of another size is refused
    (views of two sizes cannot share one readout axis)."""
    a, b = np.zeros((3, 2, 8), bool), np.ones((4, 2, 8), bool)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    assert (views.height, views.width, len(views)) == (2, 8, 7)
    assert repr(views) == "ViewStreams(views=2, readouts=7, 2x8)"
    with pytest.raises(ValueError, match=r"one size expected, found sizes \[\(2, 8\), \(8, 2\)\]"):
        ViewStreams(
            [SpikeStream.from_bits(a), SpikeStream.from_bits(np.ones((4, 8, 2), bool))], "ab"
        )


def test_view_streams_refuse_a_readout_at_the_end_naming_the_stream():
    """Readout 7 of views of 3 and 4 readouts lies past the stream: a ValueError naming the
    stream's [0, 7) (a bound one readout loose took it for a view's and failed on an index)."""
    a, b = np.zeros((3, 2, 8), bool), np.ones((4, 2, 8), bool)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    np.testing.assert_array_equal(views.tfp(6, 1), 1.0)  # the last readout
    for k in (7, -1):
        with pytest.raises(ValueError, match=r"outside the stream's \[0, 7\)"):
            views.tfp(k, 1)


def test_view_streams_read_no_timestamps_as_one_stream_does():
    """No timestamps at all (an empty batch): empty windows, TFPs and TFIs of the frame size,
    as a single stream gives (gathered from no view's read, there is no first to shape them)."""
    a, b = np.zeros((3, 2, 8), bool), np.ones((4, 2, 8), bool)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    single, none = SpikeStream.from_bits(b), np.array([], np.int64)
    for read, args in (("window", (1,)), ("tfp", (1,)), ("tfi", ())):
        got, want = getattr(views, read)(none, *args), getattr(single, read)(none, *args)
        assert got.shape == want.shape and got.shape[0] == 0 and got.dtype == want.dtype, read


def test_a_one_readout_view_holds_one_pose():
    """A view of one readout (its first readout its last) is one pose of the held trajectory: the
    two equal readouts would be refused as not strictly increasing."""
    a, b = np.zeros((1, 2, 8), bool), np.ones((4, 2, 8), bool)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    poses = np.stack([look_at([3.0, 0.0, 1.0], [0, 0, 0]), look_at([0.0, 3.0, 1.0], [0, 0, 0])])
    trajectory = views.held_trajectory(poses, "x")
    assert trajectory.readouts.tolist() == [0, 1, 4]
    np.testing.assert_allclose(trajectory.pose_at(0.0), poses[0], atol=1e-12)


def test_frustum_sphere_holds_the_image_corners_at_both_bounds():
    """A camera at the origin looking along +z (OpenCV), 16x6 pixels, fx = fy = 10, cx = 8,
    cy = 3, bounds 1 and 2: the corners lie at x = ±0.8 d, y = ±0.3 d, so the box is
    [-1.6, 1.6] x [-0.6, 0.6] x [1, 2], centred at (0, 0, 1.5), radius √3.17 (columns taken
    for rows gave another box)."""
    K = np.array([[10.0, 0, 8], [0, 10, 3], [0, 0, 1]])
    center, radius = frustum_sphere(np.eye(4)[None], np.array([[1.0, 2.0]]), K, 16, 6)
    np.testing.assert_allclose(center, [0, 0, 1.5], atol=1e-12)
    assert radius == pytest.approx(np.sqrt(1.6**2 + 0.6**2 + 0.5**2))
    # turned to look along world x (camera x -> world y, y -> z, z -> x): the box turns with it
    # (the rotation applied transposed put it along world y)
    c2w = np.eye(4)
    c2w[:3, :3] = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]
    turned = frustum_sphere(np.linalg.inv(c2w)[None], np.array([[1.0, 2.0]]), K, 16, 6)
    np.testing.assert_allclose(turned[0], [1.5, 0, 0], atol=1e-12)
    assert turned[1] == pytest.approx(radius)


def test_llff_forward_sphere_caps_far_bounds_at_their_90th_percentile(sim):
    """Forward-facing views with far bounds 3 to 8: each is capped at their 90th percentile (7.5)
    only, so the sphere holds every view's far image corners but the last's; a cap at the
    median (5.5) left the far half of most views' content outside the sphere."""
    viewmats = np.stack([look_at([x, 0, 0], [x, 10, 0]) for x in np.linspace(-0.5, 0.5, 10)])
    near, far = np.ones(10), np.linspace(3.0, 8.0, 10)
    center, radius = llff_sphere(viewmats, np.stack([near, far], 1), sim.K, W, H)
    capped = frustum_sphere(viewmats, np.stack([near, np.minimum(far, 7.5)], 1), sim.K, W, H)
    np.testing.assert_allclose(center, capped[0], atol=1e-9)
    assert radius == pytest.approx(capped[1])
    corners = [(u, v, 1.0) for u in (0, W) for v in (0, H)]  # pixel corners, homogeneous
    rays = np.linalg.solve(sim.K, np.array(corners, dtype=float).T).T  # [4, 3], z = 1
    c2w = np.linalg.inv(viewmats)
    points = np.einsum("nij,nkj->nki", c2w[:, :3, :3], far[:, None, None] * rays)
    distance = np.linalg.norm(points + c2w[:, None, :3, 3] - center, axis=-1)  # [10, 4]
    assert (distance[:9] <= radius + 1e-9).all() and (distance[9] > radius).any()


def test_llff_inward_radius_is_capped_by_the_frustum_sphere(sim):
    """Inward views on a 90° arc of radius 4 about the origin, near 0.1 and far 0.5: the sphere is
    centred where the axes meet (the origin), its radius the frustum sphere's (the views' content
    reaches at most 0.5 in), not their reach to the near bound, 3.9 (uncapped, the sphere held
    the whole empty middle)."""
    angles = np.radians(np.linspace(0.0, 90.0, 7))
    eyes = 4 * np.stack([np.cos(angles), np.sin(angles), np.zeros(7)], 1)
    viewmats = np.stack([look_at(eye, [0, 0, 0]) for eye in eyes])
    bounds = np.tile([0.1, 0.5], (7, 1))
    center, radius = llff_sphere(viewmats, bounds, sim.K, W, H)
    frustum = frustum_sphere(viewmats, bounds, sim.K, W, H)[1]
    np.testing.assert_allclose(center, 0.0, atol=1e-9)
    assert radius == pytest.approx(frustum) and frustum < 3.9


def test_llff_views_within_20_degrees_take_the_frustum_sphere(sim):
    """An arc of ±10° aimed at the origin spreads its view directions 0.013, under the ±20°
    (0.03) that LLFF takes as inward-facing: the sphere is the frustums' (the near and far bounds
    placing the scene), not one about where the optical axes meet, which a forward-facing
    capture's pose noise sets; at ±30° it is centred there."""
    for degrees, inward in ((10, False), (30, True)):
        arc = np.radians(np.linspace(-degrees, degrees, 7))
        viewmats = np.stack([look_at([4 * np.sin(a), -4 * np.cos(a), 0], [0, 0, 0]) for a in arc])
        bounds = np.tile([2.0, 6.0], (len(arc), 1))
        center, radius = llff_sphere(viewmats, bounds, sim.K, W, H)
        if inward:
            np.testing.assert_allclose(center, 0, atol=1e-9)
        else:
            expected = frustum_sphere(viewmats, bounds, sim.K, W, H)
            np.testing.assert_allclose(center, expected[0])
            assert radius == pytest.approx(expected[1])


def test_a_held_out_pose_whose_window_just_fits_is_scored(tmp_path):
    """One stream of 200 readouts, poses at 0, 32, 100, 167, 199, the ones at 32 and 167 held
    out: TFP(65) centred there covers [0, 65) and [135, 200), inside the stream, so both are
    scored (pseudo ground truth); a strict bound dropped both and refused the dataset."""
    T, H, W = 200, 4, 8
    bits = (np.random.default_rng(0).random((T, H, W)) < 0.3).astype(np.uint8)
    save_dat(tmp_path / "spikes.dat", bits)
    stream = SpikeStream.open(tmp_path / "spikes.dat", H, W)
    readouts = np.array([0.0, 32.0, 100.0, 167.0, 199.0])
    angles = np.radians(readouts / 4)
    viewmats = np.stack([look_at([3 * np.cos(a), 3 * np.sin(a), 1.0], [0, 0, 0]) for a in angles])
    meta = {
        "height": H,
        "width": W,
        "channels": 1,
        "fx": 8.0,
        "fy": 8.0,
        "cx": 4.0,
        "cy": 2.0,
        "scene_center": [0.0, 0.0, 0.0],
        "scene_radius": 1.0,
    }
    test = np.array([False, True, False, True, False])
    ds = stream_dataset(tmp_path, meta, stream, readouts, viewmats, test, Options(), "x")
    assert [v.name for v in ds.test_views] == ["pseudo_view_001", "pseudo_view_003"]
    np.testing.assert_allclose(ds.test_views[0].image[..., 0], stream.tfp(32, 65))


def test_a_window_one_readout_into_the_next_view_names_the_view():
    """A window of 3 centred on readout 2 (view 0's last) reaches readout 3, view 1's first: the
    view streams refuse it themselves, naming the view (a bound one readout loose left it to the
    view's own stream, whose message speaks of its local readouts)."""
    a, b = np.zeros((3, 2, 8), bool), np.ones((4, 2, 8), bool)
    views = ViewStreams([SpikeStream.from_bits(a), SpikeStream.from_bits(b)], ["a", "b"])
    np.testing.assert_array_equal(views.tfp(1, 3), 0.0)  # [0, 3): inside view a
    with pytest.raises(ValueError, match=r"covers \[1, 4\), outside view 'a' at readouts \[0, 3\)"):
        views.tfp(2, 3)


def test_default_train_every_spaces_the_readouts_the_poses_span(llff_stream, tmp_path):
    """Poses over the first quarter of a recording (the pose log's file 4 times over): the
    default stride gives ~1024 timestamps over the readouts the poses span (1 here), not over the
    whole file (3: a third as many timestamps, in silence)."""
    root = copy(llff_stream, tmp_path)
    (root / "spikes.dat").write_bytes((root / "spikes.dat").read_bytes() * 4)  # 2800 readouts
    ds = load_dataset(root)
    assert len(ds.stream) == 2800 and ds.trajectory.end == 650
    assert ds.meta["train_every"] == 1 and np.diff(ds.train_timestamps).min() == 1


def test_a_dataset_file_that_is_no_file_is_named(nerf, llff_stream, tmp_path):
    """A transforms_test.json or spikegs.json that is a link to nothing, a folder or a device read
    as left out: its held-out views or its options were dropped without a word, and a folder
    named meta.json or poses_bounds.npy was told missing."""
    root = copy(nerf, tmp_path / "test_link")
    (root / "transforms_test.json").unlink()
    (root / "transforms_test.json").symlink_to(root / "gone.json")
    with pytest.raises(ValueError, match=r"transforms_test.json: a link to nothing .*, not a file"):
        load_dataset(root)
    root = copy(llff_stream, tmp_path / "options")
    (root / "spikegs.json").symlink_to("/dev/null")
    with pytest.raises(ValueError, match=r"spikegs.json: a device, FIFO or socket, not a file"):
        load_dataset(root)
    (root / "spikegs.json").unlink()
    (root / "poses_bounds.npy").unlink()
    (root / "poses_bounds.npy").mkdir()
    with pytest.raises(ValueError, match=r"poses_bounds.npy: a folder, not a file"):
        load_dataset(root)
