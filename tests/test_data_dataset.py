"""Datasets: simulate -> write -> load round trip, determinism, calibration, bad input, the CLI."""

from __future__ import annotations

import errno
import json
import math
import os
import re
import shutil
import signal
import warnings
from pathlib import Path

import numpy as np
import pytest
from spikegs.cli import main
from spikegs.data import (
    SCENES,
    Dataset,
    FrameSequenceSource,
    ProceduralSource,
    Trajectory,
    load_dataset,
    simulate_dataset,
)
from spikegs.data.dataset import (
    META_KEYS,
    STAGING,
    DarkSpikesWarning,
    FaintLightWarning,
    check_meta_values,
    warn_rows_out_of_line,
    write_parts,
)
from spikegs.data.dataset import TestView as View
from spikegs.data.simulate import camera_motion, clean_source, warn_about_data
from spikegs.data.sources import intrinsics
from spikegs.data.trajectory import look_at
from spikegs.data.transforms_file import camera_matrix
from spikegs.spikes import SpikeStream
from spikegs.spikes.simulate import SimParams, simulate_spikes
from spikegs.spikes.stream import save_dat
from spikegs.targets import intensity_scale

SMALL = dict(height=24, width=32, readouts=400, test_on_path=2, test_off_path=2, progress=False)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A small dataset of the default scene."""
    return simulate_dataset("solids", tmp_path_factory.mktemp("ds") / "solids", seed=3, **SMALL)


def test_a_dataset_loaded_from_a_relative_path_stays_found_after_a_chdir(small, monkeypatch):
    """A dataset loaded as "data" kept its root relative: after a chdir, training looked for its
    points3d.ply and SIM cache under the new directory (random Gaussians, a new sim/ folder)
    and recorded a dataset path no eval could find, unsaid."""
    monkeypatch.chdir(small.root.parent)
    ds = load_dataset(small.root.name)
    monkeypatch.chdir(small.root.parent.parent)
    assert (ds.root / "meta.json").is_file() and ds.root == small.root.absolute()


def test_round_trip(small):
    ds = load_dataset(small.root)
    assert (ds.height, ds.width, ds.channels) == (24, 32, 1)
    assert ds.meta["scene"] == "solids" and ds.meta["seed"] == 3
    assert ds.meta["readout_period_s"] == 25e-6 and ds.meta["flip"] is True
    assert ds.meta["sim"]["rate_at_one"] == 0.25
    assert ds.meta["spp"] == 1  # a built-in scene's pixel centres, by default
    assert ds.meta["luma"] == "rec709-linear"  # mono: what its one channel holds
    assert ds.K.dtype == np.float32 and ds.K[0, 2] == 16 and ds.K[1, 2] == 12
    assert len(ds.stream) == ds.num_readouts == 400
    np.testing.assert_array_equal(ds.stream.packed(), small.stream.packed())
    np.testing.assert_allclose(ds.trajectory.viewmats, small.trajectory.viewmats)
    assert ds.trajectory.start == 0 and ds.trajectory.end == 399
    ts = ds.train_timestamps
    assert ts.dtype == np.int64 and ts.min() >= 32 and ts.max() <= 399 - 32
    assert ds.scene_radius > 0 and ds.scene_center.shape == (3,)
    assert [v.name for v in ds.test_views] == ["on_000", "on_001", "off_000", "off_001"]
    for name in ("trajectory.json", "test_views.json"):  # both carry the camera, as documented
        doc = json.loads((small.root / name).read_text())
        np.testing.assert_allclose(camera_matrix(name, doc, (24, 32), (24, 32)), ds.K, rtol=1e-6)


def test_the_default_frame_spacing_renders_a_faster_view_more_often(tmp_path, small, capsys):
    """The default 8 readouts between light frames moved a 512² frame's scene sphere 9.7 px:
    `spikegs simulate` at that size warned of ghosting at its defaults. Unless frame_every is
    given, the spacing shrinks to keep it within 6 px (here a view whose scene moves 7.9 px every
    8 readouts: 5, where 6 would move it 6.02 px); given, it is kept and warned of."""
    fast = {**SMALL, "speed": 2.7}  # (also warned of as motion blur: not this test's)
    for given in (None, 8):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ds = simulate_dataset("solids", tmp_path / str(given), frame_every=given, **fast)
        ghosting = [str(w.message) for w in caught if "between two rendered" in str(w.message)]
        assert ds.meta["frame_every"] == (given or 5)
        assert [m[:40] for m in ghosting] == (
            ["the scene moves up to 7.9 pixels between"] if given else []
        ), ghosting
    assert small.meta["frame_every"] == 8  # at the default speed
    cli = ["simulate", "--out", str(tmp_path / "cli"), "--speed", "2.7", "--no-progress"]
    cli += [f"--{k.replace('_', '-')}={v}" for k, v in SMALL.items() if k != "progress"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # (the motion blur's)
        assert main(cli) == 0
    said = "light rendered every 5 readouts, not 8: at this size the scene would move over 6 px"
    assert said in capsys.readouterr().out


@pytest.mark.parametrize("readouts, every", [(2100, None), (2100, 1)])
def test_training_timestamps_default_to_at_most_1024(tmp_path, readouts, every):
    """As for real streams: a stride of ceil(readouts / 1024), unless train_every is given."""
    options = {**SMALL, "height": 8, "width": 8, "readouts": readouts}
    ds = simulate_dataset("solids", tmp_path / "d", train_every=every, **options)
    stride = np.diff(ds.train_timestamps)
    assert stride.min() == (3 if every is None else 1) == ds.meta["train_every"]
    assert len(ds.train_timestamps) <= (1024 if every is None else readouts)


def test_test_views(small):
    on = [v for v in small.test_views if v.readout is not None]
    off = [v for v in small.test_views if v.readout is None]
    assert len(on) == 2 and len(off) == 2
    # spread evenly between the readouts 64 from either end of the 400 (65-readout windows fit)
    assert [v.readout for v in on] == [154, 245]
    for view in on:
        # on the path, clear of every training window of 65 readouts
        np.testing.assert_allclose(view.viewmat, small.trajectory.pose_at(view.readout), atol=1e-12)
        assert np.abs(small.train_timestamps - view.readout).min() > 64
    for view in off:  # another radius: off the spiral
        center = np.linalg.inv(view.viewmat)[:3, 3]
        distance = np.linalg.norm(center - small.scene_center)
        assert distance > 1.1 * np.linalg.norm(small.trajectory.centers[0] - small.scene_center)
    for view in small.test_views:
        assert view.image.shape == (24, 32, 1) and view.image.dtype == np.float32
        # firing-rate units: intensity (<= 1) x rate_at_one
        assert 0 < view.image.max() <= 0.25 + 1e-6


def test_spikes_see_the_scene(small):
    # TFP over a long window vs the clean image at its centre: correlated (0.91 and 0.92 for
    # the two views at 24x32; 0.45 and 0.50 over 9 readouts), same scale
    view = next(v for v in small.test_views if v.readout is not None)
    k = int(view.readout)
    tfp = small.stream.tfp(k, 33)
    assert np.corrcoef(tfp.ravel(), view.image[..., 0].ravel())[0, 1] > 0.8
    assert tfp.mean() == pytest.approx(view.image.mean(), rel=0.35)


def test_determinism_for_a_seed(tmp_path, small):
    again = simulate_dataset("solids", tmp_path / "again", seed=3, **SMALL)
    other = simulate_dataset("solids", tmp_path / "other", seed=4, **SMALL)
    assert (again.root / "spikes.dat").read_bytes() == (small.root / "spikes.dat").read_bytes()
    assert (other.root / "spikes.dat").read_bytes() != (small.root / "spikes.dat").read_bytes()
    for a, b in zip(again.test_views, small.test_views):
        np.testing.assert_array_equal(a.image, b.image)


def constant_source(
    level: float,
    size: int = 16,
    test_views: bool = True,
    lit: int | None = None,
    last: np.ndarray | None = None,
) -> FrameSequenceSource:
    """A static camera looking at a constant image (and, held out, from beside it); `lit`: at a
    square of that many pixels a side, on black; `last` [4, 4]: the second frame's pose
    (default: the first's)."""
    frames = np.full((2, size, size, 1), level, np.float32)
    if lit is not None:
        frames[:, lit:] = frames[:, :, lit:] = 0.0
    viewmat = look_at([0, -3, 0], [0, 0, 0])
    poses = [viewmat, viewmat if last is None else last]
    held_out = [("side", look_at([0.1, -3, 0], [0, 0, 0]), frames[0])] if test_views else []
    K = intrinsics(size, size, 40)
    return FrameSequenceSource(  # no axes to converge: the scene sphere given
        "constant", frames, poses, K, test_views=held_out, center=[0, 0, 0], radius=1.0
    )


def test_a_frame_sequence_of_image_codes_is_refused(tmp_path):
    """uint8 frames or test images (an image reader's) were simulated as light 255 times white,
    every pixel firing every readout, blamed on rate_at_one: refused as simulate_spikes does."""
    light = constant_source(0.6)
    codes = np.round(255 * light.frames).astype(np.uint8)  # [2, 16, 16, 1]
    said = r"found uint8 codes: convert them to float and linear light first"
    with pytest.raises(ValueError, match=rf"^frame sequence 'codes': frames expected .*{said}"):
        FrameSequenceSource("codes", codes, light.viewmats, light.K, center=[0, 0, 0], radius=1)
    name, viewmat, image = light.off_path_views(1)[0]
    coded = [(name, viewmat, np.round(255 * image).astype(np.uint8))]
    source = FrameSequenceSource(
        "test", light.frames, light.viewmats, light.K, test_views=coded, center=[0, 0, 0], radius=1
    )
    with pytest.raises(ValueError, match=rf"^scene 'test': test view 'side' expected .*{said}"):
        simulate_dataset(source, tmp_path / "d", height=16, width=16, readouts=400, test_on_path=1)
    assert not (tmp_path / "d").exists()


def test_static_camera_fires_at_the_calibrated_rate(tmp_path):
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):  # still, said
        ds = simulate_dataset(
            constant_source(0.6),
            tmp_path / "const",
            height=16,
            width=16,
            readouts=4000,
            progress=False,
        )  # the default count of test views: those the source has (two frames, one held-out view)
    p = ds.meta["sim"]
    rate = ds.stream.tfp(2000, 4000).mean()
    assert rate == pytest.approx(0.6 * p["rate_at_one"] + p["dark_rate"], rel=0.01)
    for view in ds.test_views:
        np.testing.assert_allclose(view.image, 0.6 * p["rate_at_one"], rtol=1e-6)


def test_a_camera_that_turns_or_moves_is_not_still(tmp_path):
    """The warning of a scene seen from one place needs both: a camera turning 10° where it
    stands, or moving 0.5 (half the scene radius) without turning, is not still. The turn is
    the angle between optical axes."""
    eye, turn = np.array([0.0, -3.0, 0.0]), np.radians(10.0)  # constant_source's camera
    turned = look_at(eye, eye + [np.sin(turn), np.cos(turn), 0])
    moved = look_at(eye + [0.5, 0, 0], [0.5, 0, 0])
    for name, pose, motion in (("turned", turned, (10.0, 0.0)), ("moved", moved, (0.0, 0.5))):
        source = constant_source(0.6, last=pose)
        assert camera_motion(source.trajectory(400, 0.0)) == pytest.approx(motion, abs=1e-3)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            simulate_dataset(
                source, tmp_path / name, **{**SMALL, "height": 16, "width": 16, "test_on_path": 0}
            )
        said = [str(w.message) for w in caught]
        assert not any("from one place" in m for m in said), said


def test_a_refused_simulation_leaves_no_dataset_and_keeps_the_one_it_would_replace(tmp_path):
    """A simulation whose light saturated the sensor was written whole, then refused on loading:
    its folder stayed, a dataset that training refused, and `--overwrite` had deleted the good
    dataset it was to replace."""
    still = {**SMALL, "height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    saturated = r"every pixel firing at every readout .*a saturated simulation.*; the simulation"
    saturated += " is not kept"
    new = tmp_path / "new"
    with pytest.warns(UserWarning), pytest.raises(ValueError, match=saturated) as said:
        simulate_dataset(constant_source(5.0), new, **still)
    assert str(said.value).startswith(f"{new / 'spikes.dat'}: every pixel")  # as it would be
    assert not new.exists()
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
        old = simulate_dataset(constant_source(0.6), tmp_path / "old", **still).root
    files = sorted(p for p in old.rglob("*") if p.is_file())
    before = [p.read_bytes() for p in files]
    with pytest.warns(UserWarning), pytest.raises(ValueError, match=saturated):
        simulate_dataset(constant_source(5.0), old, overwrite=True, **still)
    assert sorted(p for p in old.rglob("*") if p.is_file()) == files  # the lock among them
    assert [p.read_bytes() for p in files] == before
    assert load_dataset(old).meta["sim"]["rate_at_one"] == 0.25


def test_a_failed_overwrite_keeps_a_dataset_made_while_it_waited_for_the_lock(
    tmp_path, monkeypatch
):
    """A simulation looks whether its folder exists before it takes the lock, to remove a folder
    it made where it fails: another simulation into the same folder that finished meanwhile made
    it, and the failure of this one (--overwrite, its light saturating) deleted that dataset."""
    import spikegs.data.simulate as simulate_module

    still = {**SMALL, "height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    out, locked = tmp_path / "d", simulate_module.writing_dataset

    def finished_meanwhile(root, remedy=""):  # the other simulation, then this one's lock
        monkeypatch.setattr(simulate_module, "writing_dataset", locked)
        with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
            simulate_dataset(constant_source(0.6), root, **still)
        return locked(root, remedy)

    monkeypatch.setattr(simulate_module, "writing_dataset", finished_meanwhile)
    with pytest.warns(UserWarning), pytest.raises(ValueError, match="a saturated simulation"):
        simulate_dataset(constant_source(5.0), out, overwrite=True, **still)
    assert load_dataset(out).meta["sim"]["rate_at_one"] == 0.25 and not (out / STAGING).exists()


def test_a_stop_while_the_new_dataset_moves_in_lets_it_finish(tmp_path, monkeypatch, ctrl_c):
    """A Ctrl-C (SIGTERM, SIGHUP) while --overwrite deleted the old dataset's files and moved the
    new one's in left a folder of both, or of neither's whole set: the move finishes, then the
    simulation stops."""
    import spikegs.data.simulate as simulate_module

    still = {**SMALL, "height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
        old = simulate_dataset(constant_source(0.6), tmp_path / "d", **still).root
    move_in, rename = simulate_module.move_in, Path.rename

    def stopped_midway(out):  # a Ctrl-C as the first of the new files moves in
        def first(self, target):
            monkeypatch.setattr(Path, "rename", rename)
            moved = rename(self, target)
            signal.raise_signal(signal.SIGINT)
            return moved

        monkeypatch.setattr(Path, "rename", first)
        move_in(out)

    monkeypatch.setattr(simulate_module, "move_in", stopped_midway)
    with pytest.warns(UserWarning), pytest.raises(KeyboardInterrupt):
        simulate_dataset(constant_source(0.3), old, overwrite=True, **still)
    new = load_dataset(old)
    assert new.test_views[0].image.mean() == pytest.approx(0.3 * 0.25, rel=1e-5)
    assert not (old / STAGING).exists()


def test_a_dataset_moves_in_with_meta_json_deleted_first_and_moved_in_last(tmp_path, monkeypatch):
    """meta.json is written last, so that a folder without it is simulated again; --overwrite's
    swap deleted and moved in the files in the directory's order, and a kill between left a
    meta.json beside a part of them (the kill trial): it goes first, and comes in last."""
    from spikegs.data.dataset import move_in

    names = ["a_spikes.dat", "meta.json", "trajectory.json", "z_test_views.json"]
    for folder in (tmp_path, tmp_path / STAGING):
        folder.mkdir(exist_ok=True)
        for name in names:
            (folder / name).write_text(folder.name)
    done = []
    unlink, rename, iterdir = Path.unlink, Path.rename, Path.iterdir
    # (a directory's own order: meta.json amid the others, whatever the disk lists first)
    monkeypatch.setattr(Path, "iterdir", lambda p: iter(sorted(iterdir(p), reverse=True)))
    monkeypatch.setattr(Path, "unlink", lambda p, *a: done.append(("-", p.name)) or unlink(p, *a))
    monkeypatch.setattr(Path, "rename", lambda p, t: done.append(("+", p.name)) or rename(p, t))
    move_in(tmp_path)
    assert done[0] == ("-", "meta.json") and done[-1] == ("+", "meta.json")
    assert sorted(done) == sorted([(sign, name) for sign in "+-" for name in names])
    assert all((tmp_path / name).read_text() == STAGING for name in names)


def test_a_staging_folder_a_killed_simulation_left_is_replaced_under_overwrite(tmp_path):
    """A simulation killed (SIGKILL, a machine's reboot) leaves its staging folder inside the
    dataset: `--overwrite` clears it before staging anew, none of its files kept."""
    still = {**SMALL, "height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
        old = simulate_dataset(constant_source(0.6), tmp_path / "old", **still).root
    (old / STAGING).mkdir()
    (old / STAGING / "spikes.dat").write_bytes(b"torn")
    (old / STAGING / "stray.txt").write_text("left by the killed run")
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
        simulate_dataset(constant_source(0.3), old, overwrite=True, **still)
    assert not (old / STAGING).exists() and not (old / "stray.txt").exists()
    assert load_dataset(old).test_views[0].image.mean() == pytest.approx(0.3 * 0.25, rel=1e-5)


def test_a_full_disk_under_overwrite_names_the_old_dataset_kept(tmp_path, monkeypatch):
    """The new dataset is written beside the one it replaces: a disk without room for both
    failed with '[Errno 28] No space left on device: DATASET/.simulating/spikes.dat', a path
    gone by then, not saying why the room ran out nor what to do (a 1.6 MB dataset on a 2.2 MB
    tmpfs, which --overwrite replaced before the staging, 4ddc4fe)."""
    still = {**SMALL, "height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    with pytest.warns(UserWarning, match="the camera turns 0° and moves 0"):
        old = simulate_dataset(constant_source(0.6), tmp_path / "old", **still).root
    before = (old / "spikes.dat").read_bytes()

    def full(source, trajectory, times, out, *args):
        (out / "spikes.dat").write_bytes(b"\0" * 10)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out / "spikes.dat"))

    monkeypatch.setattr("spikegs.data.simulate.write_spikes", full)
    said = r"No space left .* 0\.0 MiB\), written beside the one it replaces.*kept; delete"
    with pytest.warns(UserWarning), pytest.raises(OSError, match=said) as raised:
        simulate_dataset(constant_source(0.6), old, overwrite=True, **still)
    assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(old)
    assert (old / "spikes.dat").read_bytes() == before and not (old / STAGING).exists()
    new = tmp_path / "new"  # no old dataset: no folder left, none named
    with (
        pytest.warns(UserWarning),
        pytest.raises(OSError, match=r"MiB\); the simulation is not") as e,
    ):
        simulate_dataset(constant_source(0.6), new, **still)
    assert e.value.filename == str(new) and not new.exists()


def test_data_that_defeats_every_method_is_flagged(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the built-in scenes at the defaults: no warning
        for scene in SCENES:
            simulate_dataset(scene, tmp_path / scene, **SMALL)
        simulate_dataset("wires", tmp_path / "rgb", color=True, **SMALL)
    cases = [
        # (not also that the test images average 0.05 times their spikes: the dark current is
        # not the images', and meta.json states it; on every later load too)
        ("solids", {"dark_rate": 0.9}, r"dark_rate 0.9 spikes per readout against .* 0\.0[34]"),
        # more readouts at one speed turn it as fast (they were advised)
        ("solids", {"speed": 1.0}, r"up to 32\.\d° in 33 readouts: .*: a lower speed \(--speed, d"),
        # still on its orbit, or slow on it, a short recording's climb turns it: a lower speed
        # was advised (at 0.01 still, where it left 19.7° of 20.3)
        (
            "solids",
            {"speed": 0.0, "readouts": 80, "test_on_path": 0, "test_off_path": 1},
            r"turns up to 16\.\d° in 33 readouts: .*; slow the camera: more readouts \(the orbit",
        ),
        (
            "solids",
            {"speed": 0.01, "readouts": 80, "test_on_path": 0, "test_off_path": 1},
            r"turns up to 16\.\d° in 33 readouts: .*; slow the camera: more readouts \(the orbit",
        ),
        # where the orbit turns it half the blur or more, a lower speed helps: said so
        (
            "solids",
            {"speed": 0.4, "readouts": 80, "test_on_path": 0, "test_off_path": 1},
            r"turns up to 20\.\d° in 33 readouts: .*; slow the camera: a lower speed",
        ),
        # a frame sequence turning 324° over 400 readouts: its frames spread over more (no
        # speed to lower)
        (
            FrameSequenceSource(
                "turning",
                np.full((5, 24, 32, 1), 0.5, np.float32),
                [
                    look_at([3 * np.cos(a), 3 * np.sin(a), 0.5], [0, 0, 0])
                    for a in np.linspace(0, 5.65, 5)
                ],
                intrinsics(32, 24, 40),
                center=[0, 0, 0],
                radius=1.0,
            ),
            {"readouts": 400, "test_on_path": 1, "test_off_path": 0},
            (
                r"turns up to 2\d\.\d° in 33 readouts: .*: more readouts, over which the frames",
                "between two frames of the sequence: the simulator cross-fades them",
            ),
        ),
        # not the 0° between the ends; and 90° a readout crosses pixels between the light frames
        ("solids", {"speed": 90.0}, (r"turns up to 288\d\.\d°", "cross-fades them")),
    ]
    cases.append(("fine-texture", {"color": True}, "the scene is grey"))
    # light too faint to count a spike in a TFP window; a turn a readout that aliases
    faint = {"rate_at_one": 1e-4, "dark_rate": 0.0}
    faint_said = ("a 33-readout TFP counts under one spike", "fainter than any light measured")
    cases.append(("solids", faint, faint_said))
    # faint, but as bright as light the mean-fitting methods were measured to see (dim solids)
    dim = ("a 33-readout TFP counts under one spike", r"tfp33_smooth_l1\) still see it")
    cases.append(("solids", {"rate_at_one": 0.1}, dim))
    # a small object on black is not faint light (the views' mean, 1/28 of the object's, was)
    still = {"height": 16, "width": 16, "test_on_path": 0, "test_off_path": 1}
    cases.append((constant_source(0.6, lit=3), still, "turns 0° and moves 0"))
    cases.append((constant_source(0.1, lit=3), still, ("turns 0° and", "lit pixels .* fire 0.025")))
    # a held-out view that shows almost nothing (a one-pixel scene): its PSNR is a render's black
    empty = r"1 of 1 held-out views have under 1% of their pixels lit \(.*: side\)"
    cases.append((constant_source(0.6, lit=1), still, ("turns 0° and", empty)))
    # no lit pixel at all (a black scene): said to be black, too few spikes to see anything by
    black = ("all under intensity 0.01: black; too few to see the scene by", "light rate of 0 ")
    black_case = (constant_source(0.6, lit=0), still, ("turns 0° and", empty, *black))
    cases.append(black_case)
    cases.append(("solids", {"speed": 360.0}, "appears still or turning backwards"))
    # twice a turn, the least speed that aliases (and blurs, and crosses pixels between frames)
    aliased = (r"turns up to 5760\.0°", "cross-fades them", "appears still or turning backwards")
    cases.append(("solids", {"speed": 180.0}, aliased))
    # 18.9 dB against 21.4; a rendered scene's remedy, not a frame sequence's
    cases.append(("solids", {"frame_every": 100.0}, "cross-fades them.*; a smaller frame_every"))
    # a frame every readout already: the least frame_every (a smaller one was advised, refused)
    fastest = r"cross-fades them.*; a slower camera \(--speed\), or one further"
    cases.append(
        ("solids", {"speed": 60.0, "frame_every": 1.0}, (r"turns up to 1920\.0°", fastest))
    )
    # one training view, which cannot place a scene in depth (it trained in silence)
    cases.append(("solids", {"train_every": 5000}, r"one training timestamp .*--train-every"))
    one = {"readouts": 195, "test_on_path": 1, "train_every": 129}  # 161 beside the view
    kept_one = r"^the 1 on-path held-out views keep 129 of the 131 readouts"
    cases.append(
        ("solids", one, (r"one training timestamp \(readout 32;.*a smaller train_", kept_one))
    )
    cases.append(("solids", {"train_every": 100}, ()))  # two: not warned of
    # on-path views asked for that keep most of the path from training (unsaid)
    most = {"readouts": 1000, "test_on_path": 7}
    kept = r"^the 7 on-path held-out views keep 782 of the 936 readouts .*: it trains on 16 % "
    cases.append(("solids", most, kept + r".*; more readouts, or fewer on-path held-out views"))
    cases.append(("solids", {"readouts": 1000, "test_on_path": 5}, ()))  # 30 %: not warned of
    # the on-path views' count asked for, the off-path ones' not
    cases.append(("solids", {**most, "test_off_path": None}, kept))
    # a stride's timestamps mostly beside the held-out views (2 of 10 kept, unsaid)
    sparse = {"readouts": 1500, "test_on_path": 8, "train_every": 150}
    cases.append(
        (
            "solids",
            sparse,
            r"^2 training timestamps of the 10 that train_every 150 .*"
            r"of the 8 on-path held-out views .*; a smaller train_every",
        )
    )
    # the least readouts for one on-path view give two timestamps (194 gave one: 32 and 161 lie
    # within 64 of the view at 96, 161 of 97)
    least = {**SMALL, "readouts": 195, "test_on_path": 1, "train_every": 1}
    fewer = r"^2 training timestamps of the 131 that train_every 1 .*; more readouts, or fewer "
    with pytest.warns(UserWarning, match=fewer):
        least_ds = simulate_dataset("solids", tmp_path / "least", **least)
    assert list(least_ds.train_timestamps) == [32, 162]
    with pytest.raises(ValueError, match=r"expected >= 195, found 194: 66 for two .* 129 for"):
        simulate_dataset("solids", tmp_path / "fewer", **{**least, "readouts": 194})
    # frames at readouts 0, 64.7, 129.3 and 194: the view at 64.7 keeps 32 from training
    frames = np.full((4, 24, 32, 1), 0.5, np.float32)
    poses = [look_at([np.cos(a), -3, 0], [0, 0, 0]) for a in range(4)]
    K = intrinsics(32, 24, 40)
    source = FrameSequenceSource("four", frames, poses, K, center=[0, 0, 0], radius=1.0)
    with pytest.raises(ValueError, match=r"no training timestamp: .*; a smaller train_every"):
        simulate_dataset(
            source, tmp_path / "none", **{**least, "train_every": 200, "test_off_path": 0}
        )
    # light that saturates every pixel: flagged while simulating, then refused on loading
    saturated = ("100% of the held-out views' pixels fire every readout", "turns 0° and moves 0")
    cases.append((constant_source(5.0), still, saturated))
    # brighter than white, below the camera's ceiling: recorded, scored as white
    white = r"100.0% of the held-out views' pixels are brighter than white .* clipped to \[0, 1\]"
    cases.append((constant_source(2.0), still, (white, "turns 0° and moves 0")))
    for i, (scene, options, messages) in enumerate(cases):
        messages = (messages,) if isinstance(messages, str) else messages
        error = ""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                simulate_dataset(scene, tmp_path / str(i), **{**SMALL, **options})
            except ValueError as err:
                error = str(err)
        assert ("every pixel firing at every readout" in error) == (messages is saturated), error
        # the simulation's light named at fault, not a real camera's frame-size keys
        said_sim = "a saturated simulation, rate_at_one 0.25 in meta.json: simulate it again with"
        assert (said_sim in error and "raw_width" not in error) == (messages is saturated), error
        assert error == "" or messages is saturated, error
        said = [str(w.message) for w in caught if w.category is UserWarning]
        assert len(said) == len(caught), [w.category for w in caught]
        # each expected warning given, and no other
        assert all(any(re.search(m, x) for x in said) for m in messages), (messages, said)
        assert all(any(re.search(m, x) for m in messages) for x in said), (messages, said)
    # loading says it again where the light adds no more spikes than the dark current (the
    # dark_rate 0.9 dataset's 0.04 and the black scene's 0), or is fainter than any measured
    # (rate_at_one 1e-4's); not the units, nor of other data
    for i, case in enumerate(cases):
        if case[2] is saturated:  # (refused)
            continue
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            load_dataset(tmp_path / str(i))
        expected = [DarkSpikesWarning] if i == 0 or case is black_case else []
        expected += [FaintLightWarning] if case[1] is faint else []
        assert [w.category for w in caught] == expected, [str(w.message) for w in caught]
        said = {DarkSpikesWarning: "no more than the dark current", FaintLightWarning: "fainter"}
        assert all(said[w.category] in str(w.message) for w in caught)


def test_off_path_views_lie_along_the_arc_the_camera_turns(tmp_path):
    """A path over part of a circle (400 readouts at 0.15°: 60°) had its off-path views evenly
    around the scene, at 90° and 270°, sides it never saw (a 20° path: 17-22 dB there, 44 on its
    own views); each now lies within 15° of a camera on the path, as in a full orbit."""
    for name, options in (("arc", SMALL), ("orbit", {**SMALL, "readouts": 2500})):
        ds = simulate_dataset("solids", tmp_path / name, **options)
        axes = ds.trajectory.viewmats[:, 2, :3]  # [P, 3] the path's optical axes
        off = [v.viewmat[2, :3] for v in ds.test_views if v.readout is None]
        nearest = np.degrees(np.arccos(np.clip(np.stack(off) @ axes.T, -1, 1))).min(1)
        assert len(off) == 2 and nearest.max() < 15, (name, nearest)
    # a camera that does not turn (it rises): one off-path view, not copies of it, said
    with pytest.warns(UserWarning, match="0 .*1 off-path test views of the 0 and 3 asked"):
        still = simulate_dataset(
            "solids",
            tmp_path / "still",
            **{**SMALL, "speed": 0.0, "test_on_path": 0, "test_off_path": 3},
        )
    assert [v.name for v in still.test_views] == ["off_000"]
    # by default too (it held one of the default 8 unsaid); a frame sequence's defaults are as
    # many as it has (tests/test_data_sources.py)
    default = {**SMALL, "speed": 0.0, "test_on_path": 0, "test_off_path": None}
    with pytest.warns(UserWarning, match="1 off-path test views of the 0 and 8 asked or by def"):
        simulate_dataset("solids", tmp_path / "still8", **default)


def test_a_source_of_ones_own_gives_its_off_path_views_from_a_count(tmp_path):
    """Source.off_path_views takes the count alone: a Source of the user's own (spikegs.data
    exports the class), or a subclass of its orbits (ProceduralSource, MitsubaSource) written to
    that signature, is not passed the arc an orbit's views follow (a TypeError). Its name is
    its class's and its kind "custom" (both unset were AttributeErrors inside simulate_dataset)."""
    from spikegs.data import ProceduralSource, Source

    orbit = ProceduralSource("solids", SCENES["solids"](), SMALL["width"], SMALL["height"], 1)

    class Own(Source):
        def __init__(self):
            super().__init__(orbit.width, orbit.height, 1, orbit.K, orbit.scene_center, 1.0)

        def trajectory(self, num_readouts, degrees_per_readout):
            return orbit.trajectory(num_readouts, degrees_per_readout)

        def image_at(self, trajectory, t):
            return orbit.image_at(trajectory, t)

        def light_times(self, num_readouts, frame_every):
            return orbit.light_times(num_readouts, frame_every)

        def on_path_times(self, num_readouts, count, margin):
            return orbit.on_path_times(num_readouts, count, margin)

        def off_path_views(self, count):
            return orbit.off_path_views(count)[::-1]

    views = simulate_dataset(Own(), tmp_path / "own", **SMALL).test_views
    assert [v.name for v in views if v.readout is None] == ["off_001", "off_000"]
    meta = json.loads((tmp_path / "own" / "meta.json").read_text())
    assert (meta["scene"], meta["source"]) == ("Own", "custom")

    class Named(Own):  # a name of its own, as a class attribute or a property: kept
        name = "mine"

    class Property(Own):
        @property
        def name(self):
            return "mine too"

    assert (Named().name, Property().name) == ("mine", "mine too")
    # light times short of the last readout: the method named (the simulator's "frame times"
    # named none), before any spike
    short = Own()
    short.light_times = lambda num_readouts, frame_every: np.arange(0, num_readouts - 50, 8.0)
    with pytest.raises(
        ValueError, match=r"^scene 'Own': light_times: frame times expected .*\[0, 399\]"
    ):
        simulate_dataset(short, tmp_path / "short", **SMALL)
    assert not (tmp_path / "short").exists()

    class Reversed(ProceduralSource):  # an orbit of one's own, overriding to that signature
        def off_path_views(self, count):
            return super().off_path_views(count)[::-1]

    source = Reversed("solids", SCENES["solids"](), SMALL["width"], SMALL["height"], 1)
    views = simulate_dataset(source, tmp_path / "orbit", **SMALL).test_views
    assert [v.name for v in views if v.readout is None] == ["off_001", "off_000"]


def test_numpy_integers_simulate_a_dataset_that_loads(tmp_path):
    """numpy integers (a loop over np.arange, a value read from an array) reached meta.json: a
    TypeError after the simulation, and a half-written dataset in the way of the next one."""
    sizes = {"height": np.int64(24), "width": np.int32(32), "readouts": np.int64(400)}
    ds = simulate_dataset(
        "solids",
        tmp_path / "x",
        **{**SMALL, **sizes, "seed": np.uint64(3), "speed": np.float32(0.1), "flip": np.bool_(1)},
    )
    assert (ds.height, ds.width, ds.num_readouts, ds.meta["seed"]) == (24, 32, 400, 3)
    assert load_dataset(tmp_path / "x").num_readouts == 400


def test_a_source_of_ones_own_without_light_times_is_refused_by_name(tmp_path):
    """A Source of the user's own (spikegs.data exports the class) whose light_times gives no
    readout: the simulator's message naming frame_times, not numpy's IndexError from the
    ghosting check (which needs two light frames and has nothing to say of fewer); one light
    frame is simulated as constant light."""
    from spikegs.data import ProceduralSource

    class Lit(ProceduralSource):
        times: list = []

        def light_times(self, num_readouts, frame_every):
            return np.array(self.times, np.float64)

    source = Lit("solids", SCENES["solids"](), SMALL["width"], SMALL["height"], channels=1)
    with pytest.raises(ValueError, match=r"frame_times expected \[F\] with F >= 1, found \[0\]"):
        simulate_dataset(source, tmp_path / "none", **SMALL)
    source.times = [0.0]
    assert len(simulate_dataset(source, tmp_path / "one", **SMALL).stream) == SMALL["readouts"]


def test_negative_view_counts_refused(tmp_path):
    for counts in ({"test_on_path": -1}, {"test_off_path": -2}):
        with pytest.raises(ValueError, match="expected counts >= 0"):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, **counts})
    for size in ({"height": 2}, {"height": 1, "width": 1}):  # 1x1 was simulated, then unscored
        with pytest.raises(ValueError, match="images cannot be scored"):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, **size})
    # a camera that its own meta.json refuses (a frame 40 times as tall as wide, its focal
    # length set by the width) was written whole, then refused
    from spikegs.data import ProceduralSource

    K = np.array([[4.12, 0.0, 1.5], [0.0, 4.12, 64.0], [0.0, 0.0, 1.0]])
    source = ProceduralSource("solids", SCENES["solids"](), 3, 128, K=K)
    tall = {**SMALL, "height": 128, "width": 3}
    with pytest.raises(ValueError, match=r"fy 4.12 gives a 173° .*: the camera scene 'solids' g"):
        simulate_dataset(source, tmp_path / "tall", **tall)
    assert not (tmp_path / "tall").exists()
    with pytest.raises(ValueError, match=r"source 'solids' gives 128x3x1 images, expected 24x32"):
        simulate_dataset(source, tmp_path / "x", **SMALL)  # another size than asked for
    for readouts in (40, -1):  # (-1 was named as if the held-out views alone wanted more)
        with pytest.raises(
            ValueError,
            match=rf"readouts \(--readouts\): expected >= 324, found {readouts}: 66 for two "
            r"training timestamps, .* and 129 for each of the 2 on-path held-out views",
        ):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, "readouts": readouts})
    # the default 8 on-path views need 2128 readouts: as many as keep at most half the stream
    # from training, said (refused, though a frame sequence holds out as many as it has without
    # the option); as many as fit (4) left training timestamps at the two ends alone
    fewer = {**SMALL, "readouts": 700, "test_on_path": None}
    said = (
        r"700 readouts hold 2 on-path held-out views of the default 8 \(each keeps the 129 "
        r"readouts around it from training; the default keeps at most half of the 636 training "
        r"could use: 2128 readouts for 8\)"
    )
    with pytest.warns(UserWarning, match=said):
        ds = simulate_dataset("solids", tmp_path / "fewer", **fewer)
    on_path = sorted(v.readout for v in ds.test_views if v.readout is not None)
    assert len(on_path) == 2
    between = ds.train_timestamps[
        (ds.train_timestamps > on_path[0]) & (ds.train_timestamps < on_path[1])
    ]
    assert len(between) > 0
    # none fit: said too, the views off the path alone (it was said where some fit)
    with pytest.warns(UserWarning, match=r"200 readouts hold 0 on-path held-out views of the de"):
        none = simulate_dataset("solids", tmp_path / "none_fit", **{**fewer, "readouts": 200})
    assert all(v.readout is None for v in none.test_views) and none.test_views
    # an unknown scene is refused first, not warned of its run's length before (the API's
    # names beside the command's)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="unknown scene 'sphere'"):
            simulate_dataset("sphere", tmp_path / "unknown", **fewer)
    with pytest.warns(UserWarning, match=r"or set test_on_path \(--test-on-path\)"):
        simulate_dataset("solids", tmp_path / "fewer2", **fewer)
    # none held out: it said to hold out fewer
    with pytest.raises(ValueError, match=r"readouts \(--readouts\): expected >= 66, found 65: two"):
        simulate_dataset("solids", tmp_path / "x", **{**fewer, "readouts": 65})
    for zero in ({"frame_every": 0}, {"train_every": 0}):
        with pytest.raises(ValueError, match=f"{next(iter(zero))} .*: expected >= 1"):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, **zero})
    (tmp_path / "file").write_text("")
    with pytest.raises(FileExistsError, match="file is a file, not a dataset folder"):
        simulate_dataset("solids", tmp_path / "file", **SMALL)
    with pytest.raises(ValueError, match="frame_every"):  # NaN reached numpy's arange
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "frame_every": float("nan")})
    with pytest.raises(
        ValueError, match=r"frame_every \(--frame-every\): expected >= 1, found 1e-05"
    ):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "frame_every": 1e-5})
    ds = simulate_dataset("solids", tmp_path / "every", **{**SMALL, "frame_every": 1})  # the least
    assert ds.meta["frame_every"] == 1
    # a bad size was named after a complaint about readouts; a NaN speed as non-rigid poses
    with pytest.raises(
        ValueError, match=r"height, width \(--height, --width\): expected >= 1 pixel, found 0, 32"
    ):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "height": 0, "readouts": 10})
    with pytest.raises(ValueError, match="expected finite numbers, found speed=nan"):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "speed": float("nan")})
    # a speed whose orbit overflows: numpy's warnings, then "the pose of index 2 is not rigid"
    with pytest.raises(ValueError, match=r"speed \(--speed\): .* over the 400 .*, found 1e\+308"):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "speed": 1e308})
    # whole floats were simulated, then not loaded; a fractional train_every gave timestamps
    # inside the held-out windows
    for bad in ({"readouts": 400.0}, {"height": 16.0}, {"train_every": 2.5}):
        with pytest.raises(ValueError, match=f"{next(iter(bad))}: expected an int, found"):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, **bad})
    for seed in (-1, 2**64):  # wrapped around to another seed's data (a colour one: an empty out)
        with pytest.raises(ValueError, match="seed"):
            simulate_dataset("solids", tmp_path / "x", **{**SMALL, "seed": seed, "color": True})
    with pytest.raises(ValueError, match="spp .* expected samples per pixel >= 1, found 0"):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "spp": 0})
    assert not (tmp_path / "x").exists()


def test_a_built_in_scene_simulated_at_an_spp_keeps_it_to_its_clean_images(tmp_path):
    """--spp 4 for a built-in scene: each pixel its box's mean light, in the held-out images and
    in what meta.json rebuilds (clean_source: the oracle's targets); refused unless a square."""
    ds = simulate_dataset("solids", tmp_path / "s4", **{**SMALL, "spp": 4})
    assert ds.meta["spp"] == 4 and load_dataset(ds.root).meta["spp"] == 4
    view = next(v for v in ds.test_views if v.readout is not None)
    source = clean_source(ds)
    clean = source.image_at(ds.trajectory, view.readout)  # [H, W, 1]
    np.testing.assert_allclose(clean, view.image / intensity_scale(ds), atol=1e-6)
    centres = ProceduralSource("solids", SCENES["solids"](), 32, 24, K=source.K)
    assert np.abs(centres.image_at(ds.trajectory, view.readout) - clean).max() > 0.05
    del ds.meta["spp"]  # a dataset from before meta.json held it: simulated at pixel centres
    assert clean_source(ds).spp == 1
    with pytest.raises(ValueError, match=r"spp \(--spp\): .* expected a square .* found 2"):
        simulate_dataset("solids", tmp_path / "x", **{**SMALL, "spp": 2})
    with pytest.raises(ValueError, match="spp: the source 'solids' given sets its own"):
        simulate_dataset(centres, tmp_path / "x", **{**SMALL, "spp": 16})  # (16 was dropped)
    assert not (tmp_path / "x").exists()


def test_simulate_names_each_option_it_refuses(tmp_path, capsys):
    """--train-every 0 said "frame_every and train_every expected positive, found 8.0, 0" (a
    frame_every never given), --test-off-path -1 named test_off_path only, --speed nan
    "expected finite numbers, found speed=nan" and --threshold 0 "threshold expected in ...":
    each names its option now."""
    cases = [
        ("--train-every", "0", "train_every (--train-every): expected >= 1 readout, found 0"),
        ("--frame-every", "0", "frame_every (--frame-every): expected >= 1, found 0"),
        ("--test-off-path", "-1", "(--test-on-path, --test-off-path): expected counts >= 0"),
        ("--speed", "nan", "argument --speed: expected a finite number, found 'nan'"),
        ("--threshold", "inf", "argument --threshold: expected a finite number, found 'inf'"),
        # the simulator's ranges named the field alone ("threshold expected in [0.001, 1e30]")
        ("--threshold", "0", "argument --threshold: threshold expected in [0.001, 1e30], found 0"),
        ("--rate-at-one", "2", "argument --rate-at-one: rate_at_one expected in (0, 1], found 2"),
        ("--dark-sigma", "-1", "argument --dark-sigma: dark_sigma expected finite, >= 0"),
    ]
    for option, value, message in cases:
        argv = ["simulate", "--out", str(tmp_path / "x"), option, value]
        try:
            status = main(argv)
        except SystemExit as stop:  # (refused while parsing)
            status = stop.code
        assert status == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_source_without_held_out_views_is_refused_before_any_work(tmp_path):
    with pytest.raises(
        ValueError, match=r"scene 'constant' \(its frames .*\): no held-out test view"
    ):
        source = constant_source(0.6, test_views=False)
        simulate_dataset(source, tmp_path / "x", height=16, width=16, readouts=4000)
    assert not (tmp_path / "x").exists()


def test_colour_dataset_has_one_stream_per_channel(tmp_path):
    ds = simulate_dataset("wires", tmp_path / "rgb", color=True, **SMALL)
    assert ds.channels == 3 and len(ds.streams) == 3 and ds.stream == ds.streams
    assert [s.path.name for s in ds.streams] == ["spikes_r.dat", "spikes_g.dat", "spikes_b.dat"]
    assert ds.test_views[0].image.shape == (24, 32, 3)
    assert ds.meta["luma"] is None  # no luma: the channels as they are
    assert len({s.path.read_bytes() for s in ds.streams}) == 3  # independent channel noise
    # meta.json stating a mono camera beside a colour camera's files: "spikes.dat not found"
    # said nothing of spikes_r/g/b.dat
    meta = json.loads((ds.root / "meta.json").read_text())
    meta.update(channels=1)
    del meta["spike_files"]
    (ds.root / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(FileNotFoundError, match="spikes_b.dat, a colour camera's: meta.json's"):
        load_dataset(ds.root)


def test_colour_files_in_another_order_or_one_upside_down_are_named(tmp_path):
    """spike_files listing red and blue swapped (a colour mosaic split with its pattern read
    wrong), or one channel's file stored the other way up, trained 3 to 7 dB low unsaid: the
    check of the channels' mean passed both. Each file is matched with its channel of the sharp
    test images: the swap and the flipped file are named, the right dataset is not."""
    options = {**SMALL, "height": 32, "width": 32, "readouts": 600, "test_on_path": 4}
    ds = simulate_dataset("solids", tmp_path / "rgb", color=True, **options)

    def channel_warnings() -> list[str]:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            load_dataset(ds.root)
        return [str(w.message) for w in said if "views, " in str(w.message)]

    assert channel_warnings() == []
    red, blue = ds.root / "spikes_r.dat", ds.root / "spikes_b.dat"
    red.rename(tmp_path / "r.dat")
    blue.rename(red)
    (tmp_path / "r.dat").rename(blue)
    (said,) = channel_warnings()
    assert (
        re.search(
            r"channel 0's images match spikes_b\.dat \(median correlation 0\.\d+\) "
            r"better than spikes_r\.dat",
            said,
        )
        and "another order" in said
    ), said
    red.rename(tmp_path / "b.dat")
    blue.rename(red)
    (tmp_path / "b.dat").rename(blue)
    stream = load_dataset(ds.root).streams[2]
    bits = stream.window(len(stream) // 2, len(stream))  # [T, H, W]: every readout
    save_dat(blue, bits, flip=not ds.meta["flip"])
    (said,) = channel_warnings()
    assert "the spikes of spikes_b.dat match their channel of the images better upside" in said


def test_light_with_no_lit_pixel_is_said_as_such():
    """Light so faint that no pixel fires LIT_SPIKES spikes over the stream was said to fire "0
    spikes a readout" (0.00047: the extreme-scenes trial); its brightest pixels' rate now."""
    from spikegs.data.dataset import warn_if_faint

    rates = np.full((16, 16), 0.0004)
    rates[:4] = 0.0005
    said = r"d/spikes.dat: no pixel fires 3 spikes in its 600 readouts \(the brightest 0.1 % fire "
    with pytest.warns(FaintLightWarning, match=said + r"0.0005 spikes a readout\), fainter .* 0.0"):
        warn_if_faint([rates], 600, Path("d/spikes.dat"), "meta.json")
    for readouts in (1070, 600):  # 3 spikes, LIT_SPIKES, are lit (3 / 1070 * 1070 < 3)
        rates = np.zeros((16, 16))
        rates[:4] = 3 / readouts
        said = rf"its lit pixels fire {3 / readouts:.3g} spikes a readout on average"
        with pytest.warns(FaintLightWarning, match=said):
            warn_if_faint([rates], readouts, Path("d/spikes.dat"), "meta.json")


def test_faint_light_is_named_on_loading(small, tmp_path):
    """A stream whose lit pixels fire under FAINTEST_MEASURED was warned of only as `spikegs
    simulate` made it: a recording's loaded unsaid, and training's falling PSNR was blamed on
    its learning rates. Loading names it (not again as simulate loads what it made); the
    default light, none."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        faint = simulate_dataset("solids", tmp_path / "faint", rate_at_one=0.02, **SMALL)
    assert not [w for w in said if w.category is FaintLightWarning]
    with pytest.warns(FaintLightWarning, match=r"lit pixels fire 0\.00\d+ spikes a readout on av"):
        load_dataset(faint.root)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FaintLightWarning)
        load_dataset(small.root)


@pytest.mark.parametrize("blue", [0.05, 0.3])
def test_a_dim_channel_in_its_own_file_is_not_named_out_of_order(blue):
    """Blue at 5-30 % of red (a warm light): its own file's few spikes match the blue image
    worse than red's file does, which named spikes_r.dat as blue's though red's file was red's
    own best match (the review); files in another order are judged as an order. A true swap
    of red and blue is named whatever the blue's level."""
    from spikegs.data.channel_order import check_channels

    rng = np.random.default_rng(1)
    y, x = np.mgrid[:48, :48]
    base, other = 0.5 + 0.5 * np.sin(x / 5) * np.cos(y / 7), 0.5 + 0.5 * np.cos(x / 4 + y / 6)
    files = ["spikes_r.dat", "spikes_g.dat", "spikes_b.dat"]
    for structure in ("shared", "apart"):  # blue as red's pattern, and a pattern of its own
        views = []
        for shift in range(0, 18, 3):
            red = np.roll(base, shift, axis=1)
            own = red if structure == "shared" else np.roll(other, shift, axis=1)
            image = np.stack([red, 0.8 * red, blue * own], -1) * 0.25  # firing rates
            views.append(([rng.poisson(image[..., c] * 33) / 33 for c in range(3)], image))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_channels(views, files, "meta.json")
        if structure == "apart":
            swapped = [([tfps[2], tfps[1], tfps[0]], image) for tfps, image in views]
            with pytest.warns(UserWarning, match="channel 0's images match spikes_b.dat"):
                check_channels(swapped, files, "meta.json")


def test_a_mosaic_split_wrong_is_named_file_by_file():
    """An RGGB mosaic's stored rows split as GBRG: red's and blue's files hold green, green's
    blue. No order fits that: the order warning named green and blue swapped alone (red's file
    still green, unsaid, 12.6 dB where 19.4 was due) and called both files upside down (-0.01
    against -0.26). Each file holding another channel is named; none is called upside down."""
    from spikegs.data.channel_order import check_channels

    rng = np.random.default_rng(2)
    y, x = np.mgrid[:48, :48]
    patterns = [np.sin(x / 5) * np.cos(y / 7), np.cos(x / 4 + y / 6), np.sin(x / 3 - y / 9)]
    files = ["spikes_r.dat", "spikes_g.dat", "spikes_b.dat"]
    views = []
    for shift in range(0, 18, 3):
        image = np.stack([0.5 + 0.5 * np.roll(p, shift, axis=1) for p in patterns], -1) * 0.25
        tfps = [rng.poisson(image[..., c] * 33) / 33 for c in range(3)]
        views.append(([tfps[1], tfps[2], tfps[1]], image))  # r: green, g: blue, b: green
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        check_channels(views, files, "meta.json")
    said = [str(w.message) for w in said]
    assert any("spikes_r.dat matches the images' channel 1" in text for text in said), said
    assert not any("upside down" in text for text in said), said
    assert any("another order" in text for text in said), said  # green and blue: an order


def test_a_file_is_named_by_one_colour_check_and_in_most_views():
    """The colour checks' bounds: a file matching its channel neither way up (an inverted one,
    -0.95 as read, 0 flipped) is not called stored upside down; a file stored upside down
    (independent channels, or blue at a quarter of the light) is called so, not a holder of
    another channel (its own as read near 0, a channel alike by 0.27 named it: the review); a
    file named as holding another channel (red's holding green, partly red upside down) is not
    also called upside down; a file ahead of its own channel in half the views, not most, is
    not named."""
    from spikegs.data.channel_order import check_channels

    rng = np.random.default_rng(3)
    y, x = np.mgrid[:48, :48]
    wave = np.sin(2 * np.pi * y / 48) + np.cos(2 * np.pi * y / 48)  # uncorrelated flipped
    files = ["spikes_r.dat", "spikes_g.dat", "spikes_b.dat"]

    def said(views) -> list[str]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_channels(views, files, "meta.json")
        return [str(w.message) for w in caught]

    def noisy(light):  # a TFP of 33 readouts of firing rates `light` [H, W]
        return rng.poisson(light * 33) / 33

    inverted, flipped, dim, held, mixed = [], [], [], [], []
    for shift in range(0, 18, 3):
        p = 0.5 + 0.25 * np.roll(wave * np.cos(x / 6), shift, axis=1)
        grey = np.stack([p, p, p], -1) * 0.25
        inverted.append(
            ([noisy(grey[..., 0]), noisy(grey[..., 1]), noisy(0.25 - grey[..., 2])], grey)
        )
        q = 0.5 + 0.25 * np.roll(np.sin(x / 3 - y / 9), shift, axis=1)
        r = 0.5 + 0.25 * np.roll(np.cos(x / 4 + y / 6), shift, axis=1)
        apart = np.stack([p, r, q], -1) * 0.25
        tfps = [noisy(apart[..., c]) for c in range(3)]
        flipped.append(([tfps[0], tfps[1], tfps[2][::-1]], apart))
        faint = apart * [1, 1, 0.25]
        dim.append(
            ([noisy(faint[..., 0]), noisy(faint[..., 1]), noisy(faint[..., 2])[::-1]], faint)
        )
        green = 0.6 * p[::-1] + 0.8 * r  # partly red upside down
        coloured = np.stack([p, green / 1.4, q], -1) * 0.25
        tfps = [rng.poisson(coloured[..., c] * 330) / 330 for c in range(3)]  # 330 readouts
        held.append(([tfps[1], tfps[1], tfps[2]], coloured))  # red's file holds green
        mixed.append(([tfps[1] if shift < 9 else tfps[0], tfps[1], tfps[2]], coloured))
    assert said(inverted) == []
    for views in (flipped, dim):
        (upside,) = said(views)
        assert (
            "the spikes of spikes_b.dat match their channel of the images better upside" in upside
        )
    (named,) = said(held)
    assert "spikes_r.dat matches the images' channel 1" in named
    assert said(mixed) == []  # red's file holds green in 3 of 6 views: not most


def test_keys_meta_json_does_not_read_are_named(small, tmp_path):
    """A `"bayer_pattern": "RGGB"` beside a mosaic's one spikes.dat (trained as a mono camera's
    checkerboard) or a misspelt optional key (`rate_at_1`: the rate guessed) loaded unsaid:
    each key nothing reads is named; every key spikegs writes is read without a word."""
    root = tmp_path / "keys"
    shutil.copytree(small.root, root)
    meta = json.loads((root / "meta.json").read_text())
    assert set(meta) <= set(META_KEYS)
    (root / "meta.json").write_text(json.dumps({**meta, "bayer_pattern": "RGGB", "rate_at_1": 1}))
    with pytest.warns(
        UserWarning, match=r"meta.json: bayer_pattern, rate_at_1: not meta.json's "
    ) as said:
        load_dataset(root)
    assert [w.filename for w in said if "bayer" in str(w.message)] == [__file__]  # the caller's


def test_the_other_cameras_spike_files_beside_a_datasets_own_are_named_unread(tmp_path):
    """A mono camera's spikes.dat beside a colour dataset's spikes_r/g/b.dat, and a colour
    camera's beside a mono one's, are warned of as not read; the dataset loads as before."""
    for color in (True, False):
        ds = simulate_dataset("wires", tmp_path / f"c{color}", color=color, **SMALL)
        stray = ["spikes.dat"] if color else ["spikes_r.dat", "spikes_g.dat", "spikes_b.dat"]
        for name in stray:
            (ds.root / name).write_bytes(ds.streams[0].path.read_bytes())
        with pytest.warns(UserWarning, match=f"{', '.join(stray)} not read: meta.json's ch"):
            again = load_dataset(ds.root)
        assert [s.path.name for s in again.streams] == [s.path.name for s in ds.streams]


def test_missing_files_and_nan_poses(tmp_path, small):
    for name in (
        "meta.json",
        "spikes.dat",
        "trajectory.json",
        "train_timestamps.txt",
        "test/on_000.exr",
    ):
        root = tmp_path / name.replace("/", "_")
        shutil.copytree(small.root, root)
        (root / name).unlink()
        with pytest.raises(FileNotFoundError, match=name.split("/")[-1]):
            load_dataset(root)
    # a pose log of one's own in this layout was told the file missing alone (the docs trial)
    for name in ("train_timestamps.txt", "test_views.json"):
        root = tmp_path / f"split_{name}"
        shutil.copytree(small.root, root)
        (root / name).unlink()
        said = rf"{name} \(train_timestamps.txt and test_views.json, .* near and far .* the LLFF "
        said += r"layout \(.* in a folder without meta.json\), .*poses`"
        with pytest.raises(FileNotFoundError, match=said):
            load_dataset(root)
    with pytest.raises(FileNotFoundError, match=r"no dataset found: none of meta.json .*LLFF"):
        load_dataset(tmp_path / "meta.json")  # the copy above without its meta.json
    with pytest.raises(FileNotFoundError, match="from `spikegs poses"):  # a raw recording's
        load_dataset(tmp_path / "trajectory.json")
    spaced = tmp_path / "my recording"  # the command it suggests pastes into a shell
    shutil.move(tmp_path / "trajectory.json", spaced)
    with pytest.raises(FileNotFoundError, match=f"from `spikegs poses '{spaced}'`"):
        load_dataset(spaced)
    root = tmp_path / "nan"
    shutil.copytree(small.root, root)
    doc = json.loads((root / "trajectory.json").read_text())
    doc["frames"][5]["transform_matrix"][1][1] = float("nan")
    (root / "trajectory.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="trajectory.json"):
        load_dataset(root)
    # "folder", as the help and the docs say, and the messages of run folders
    with pytest.raises(FileNotFoundError, match="dataset folder not found: .*nowhere"):
        load_dataset(tmp_path / "nowhere")
    with pytest.raises(NotADirectoryError, match="meta.json is a file, not a dataset folder"):
        load_dataset(small.root / "meta.json")


def _edited_copy(small, root: Path, name: str, edit) -> Path:
    """A copy of the dataset at `root` with `edit(text) -> text` applied to its file `name`."""
    shutil.copytree(small.root, root)
    (root / name).write_text(edit((root / name).read_text()))
    return root


def test_readouts_in_microseconds_are_told_from_a_log_that_ran_on():
    """Readouts reaching past a 400-readout stream as a µs clock's would (÷ 25: half the stream
    to half as far past it) are said to be µs: one that ran on a readout past the recording was
    not; a log that ran on a little, or 60 times as far, is not said to be µs."""
    from spikegs.data.dataset import microseconds_hint

    for last in (399 * 25, 400 * 25, 200 * 25, 600 * 25):
        assert "Readouts in µs? They are readout indices, 25 µs apart" in microseconds_hint(
            last, 400
        )
    for last in (399, 420, 4000, 60 * 400, 199 * 25 - 1):
        assert microseconds_hint(last, 400) == "", last


def _microsecond_poses(text: str) -> str:
    """trajectory.json's text with each pose's readout in µs (x 25)."""
    doc = json.loads(text)
    for frame in doc["frames"]:
        frame["readout"] *= 25
    return json.dumps(doc)


def _far_poses(text: str) -> str:
    """trajectory.json's text with every camera 1e300 units along x."""
    doc = json.loads(text)
    for frame in doc["frames"]:
        frame["transform_matrix"][0][3] = 1e300
    return json.dumps(doc)


def test_test_views_sharing_an_image_are_warned_of(tmp_path, small):
    """Two test views whose file_path names one image (a frame copied, its path left): each is
    scored against it, said (unsaid until 2026-12-06); views of their own images are not."""

    def share(text):
        doc = json.loads(text)
        doc["frames"][1]["file_path"] = doc["frames"][0]["file_path"]
        return json.dumps(doc)

    names = [v.name for v in small.test_views[:2]]
    root = _edited_copy(small, tmp_path / "shared", "test_views.json", share)
    with pytest.warns(
        UserWarning, match=rf"test views {re.escape(repr(names))} read \S+: each is scored"
    ):
        load_dataset(root)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_dataset(small.root)


def test_malformed_test_views_and_json_refused(tmp_path, small):
    def views(edit):
        return lambda text: json.dumps(edit(json.loads(text)))

    def no_views(doc):
        return {**doc, "frames": []}

    def same_names(doc):
        return {**doc, "frames": [{**f, "name": "view"} for f in doc["frames"]]}

    def moved_out(doc):
        return {**doc, "frames": [{**doc["frames"][0], "readout": 5000.0}]}

    def leak(text):  # the first on-path view's readout becomes a training timestamp
        on = next(v for v in small.test_views if v.readout is not None)
        return text + f"{round(on.readout)}\n"

    def frame0(**changes):  # the first view's frame edited
        return lambda d: {**d, "frames": [{**d["frames"][0], **changes}, *d["frames"][1:]]}

    def rename(name):
        return frame0(name=name)

    def skewed_last_row():  # a rotation and translation, but a last row of 0.5 0 0 1
        m = np.eye(4)
        m[3, 0] = 0.5
        return m

    def pose(matrix):
        return frame0(transform_matrix=np.asarray(matrix).tolist() if np.ndim(matrix) else matrix)

    def zero_pose(text):  # an all-zero matrix: refused before inverting
        doc = json.loads(text)
        doc["frames"][5]["transform_matrix"] = [[0] * 4] * 4
        return json.dumps(doc)

    def rewrite_meta(**changes):
        return lambda text: json.dumps({**json.loads(text), **changes})

    cases = {
        "outside": ("test_views.json", views(moved_out), "at readout 5000.0, outside"),
        "leak": ("train_timestamps.txt", leak, "would train on its spikes"),
        "float": ("train_timestamps.txt", lambda t: t + "40.5\n", r"integer readouts.*40\.5"),
        "repeated": ("train_timestamps.txt", lambda t: t + t.split()[3] + "\n", "listed twice"),
        "empty": ("train_timestamps.txt", lambda t: "", "train_timestamps.txt: no training"),
        "words": ("train_timestamps.txt", lambda t: t + "abc\n", "train_timestamps.txt: line"),
        "columns": (
            "train_timestamps.txt",
            lambda t: "40 41\n" + t,
            r"line 1: .*'40 41' \(2 fields",
        ),
        "radius": ("meta.json", rewrite_meta(scene_radius=-1), "scene_radius"),
        "fx nan": ("meta.json", rewrite_meta(fx=float("nan")), r"meta.json: fx expected a finite"),
        "fy 0": ("meta.json", rewrite_meta(fy=0), r"meta.json: fy expected a finite number > 0"),
        "cx text": ("meta.json", rewrite_meta(cx="x"), r"meta.json: cx expected a finite"),
        "readouts": ("meta.json", rewrite_meta(num_readouts="many"), "num_readouts expected an"),
        "height": ("meta.json", rewrite_meta(height=16.5), r"height expected an integer > 0"),
        "channels": ("meta.json", rewrite_meta(channels=2), "channels expected 1 .mono. or 3"),
        "centre": ("meta.json", rewrite_meta(scene_center="abc"), "scene_center expected 3"),
        "spike files": (
            "meta.json",
            rewrite_meta(spike_files=["rec.dat"]),
            r'spike_files \["rec.dat"\], but 1 channel\(s\) are read from \["spikes.dat"\]',
        ),
        "version": ("meta.json", rewrite_meta(format_version=2), "format_version 2"),
        # a name that was not a string crashed the oracle's lookup (TypeError: unhashable); a
        # value of the wrong JSON type was printed so that it looked right ("format_version 1,
        # this SpikeGS reads 1")
        "scene list": ("meta.json", rewrite_meta(scene=["solids"]), r"scene expected a name"),
        "source dict": ("meta.json", rewrite_meta(source={"a": 1}), r"source expected a name"),
        "scene null": ("meta.json", rewrite_meta(scene=None, fx=0), r"fx expected"),  # no name
        "scene id": ("meta.json", rewrite_meta(scene=24, fx=0), r"fx expected"),  # a scan id
        "version 1.0": ("meta.json", rewrite_meta(format_version=1.0, fx=0), r"fx expected"),
        "version text": (
            "meta.json",
            rewrite_meta(format_version="1"),
            r'format_version "1", this SpikeGS reads 1 \(an integer\)',
        ),
        "spike files text": (
            "meta.json",
            rewrite_meta(spike_files="spikes.dat"),
            r'spike_files "spikes.dat", .* \(a list of file names;',
        ),
        "flip": ("meta.json", rewrite_meta(flip="true"), "meta.json: flip expected true or false"),
        "none": ("test_views.json", views(no_views), "no held-out test view"),
        "twice": ("test_views.json", views(same_names), r"found twice: \['view'\]"),
        "json": ("meta.json", lambda text: text[:-3], r"meta.json: not valid JSON"),
        "keys": (
            "test_views.json",
            views(lambda d: {**d, "frames": [{"name": "a"}]}),
            "frame 0 has no transform_matrix, file_path",
        ),
        "trajectory": (
            "trajectory.json",
            lambda text: text[:-3],
            "trajectory.json: not valid JSON",
        ),
        "meta list": ("meta.json", lambda text: "[1, 2]", r"meta.json: expected a JSON object"),
        "meta number": ("meta.json", lambda text: "3", r"meta.json: expected a JSON object"),
        "views list": ("test_views.json", lambda text: "[]", r"expected a JSON object \{"),
        "escape": ("test_views.json", views(rename("../../x")), r"name '../../x' expected a file"),
        "number": ("test_views.json", views(rename(3)), "name 3 expected a file name"),
        "matrix": (
            "test_views.json",
            views(pose("abc")),
            r"view 'on_000': transform_matrix expected 4 rows of 4 numbers, found \"abc\"",
        ),
        "scaled": (
            "test_views.json",
            views(pose(2 * np.eye(4))),
            "'on_000': the pose is not rigid",
        ),
        "last row": ("test_views.json", views(pose(skewed_last_row())), r"not rigid.* = 0.5 "),
        "3x4": (
            "test_views.json",
            views(pose(np.eye(4)[:3])),
            r"expected 4 rows of 4 numbers, found \[\[1.0, 0.0, 0.0, 0.0\], \[0.0, 1.0, 0",
        ),
        "missing keys": (
            "meta.json",
            lambda text: json.dumps({k: v for k, v in json.loads(text).items() if k != "fy"}),
            r"meta.json: missing keys \['fy'\]",
        ),
        # removed as `spikegs poses` told, to have them estimated: what estimates them said
        "missing sphere": (
            "meta.json",
            lambda text: json.dumps(
                {k: v for k, v in json.loads(text).items() if not k.startswith("scene_")}
            ),
            r"missing keys \['scene_center', 'scene_radius'\] \(`spikegs poses .*` estimates th",
        ),
        "missing cx": (  # (poses refuses intrinsics stated in part: not told to run it)
            "meta.json",
            lambda text: json.dumps({k: v for k, v in json.loads(text).items() if k != "cx"}),
            r"meta.json: missing keys \['cx'\]$",
        ),
        "missing height": (
            "meta.json",
            lambda text: json.dumps({k: v for k, v in json.loads(text).items() if k != "height"}),
            r"meta.json: missing keys \['height'\]$",
        ),
        "zero": ("trajectory.json", zero_pose, r"trajectory.json: the pose of frame 5 .* = 1 "),
        "path": ("test_views.json", views(frame0(file_path=3)), "file_path expected a path"),
        # an empty one was "frame image not found: DATASET", naming neither view nor file
        "empty path": (
            "test_views.json",
            views(frame0(file_path="")),
            r"test_views.json: view 'on_000': file_path expected a path .*, found \"\" and",
        ),
        "nan readout": ("test_views.json", views(frame0(readout=float("nan"))), "readout a finite"),
        "readout": (
            "test_views.json",
            views(frame0(readout="abc")),
            "view 'on_000'.* finite number",
        ),
        # a number written as a string was read as one (the docs refuse it, as in transforms files)
        "string readout": ("test_views.json", views(frame0(readout="200")), "readout a finite"),
        "string trajectory": (
            "trajectory.json",
            lambda text: json.dumps(
                {
                    **json.loads(text),
                    "frames": [
                        {**f, "readout": str(f["readout"])} for f in json.loads(text)["frames"]
                    ],
                }
            ),
            "trajectory.json: malformed frames",
        ),
        # a frame without its readout said "malformed frames ('readout')"
        "time for readout": (
            "trajectory.json",
            lambda text: json.dumps(
                {
                    **json.loads(text),
                    "frames": [
                        {"time": f["readout"], "transform_matrix": f["transform_matrix"]}
                        for f in json.loads(text)["frames"]
                    ],
                }
            ),
            r"trajectory.json: frame 0 has no readout \(each frame .* \['time', 'transform_m",
        ),
        # numpy reads a true among numbers as 1: a pose with its first entry true
        "bool in a pose": (
            "trajectory.json",
            lambda text: json.dumps(
                {
                    **json.loads(text),
                    "frames": [
                        {
                            **f,
                            "transform_matrix": [[True, *f["transform_matrix"][0][1:]]]
                            + f["transform_matrix"][1:],
                        }
                        for f in json.loads(text)["frames"]
                    ],
                }
            ),
            r"trajectory.json: frame 0 \(readout 0\): transform_matrix .*true or false",
        ),
        "frames": (
            "test_views.json",
            views(lambda d: {**d, "frames": 3}),
            "'frames' expected a list of objects",
        ),
        "frame": (
            "trajectory.json",
            lambda text: json.dumps({**json.loads(text), "frames": ["a"]}),
            "'frames' expected a list of objects",
        ),
        # each of these trained silently: ignored, garbage, or a numpy warning before the error
        "frames dict": (
            "trajectory.json",
            lambda text: json.dumps({**json.loads(text), "frames": {}}),
            "'frames' expected a list of objects",
        ),
        "no poses": (
            "trajectory.json",
            lambda text: json.dumps({**json.loads(text), "frames": []}),
            r"trajectory.json: no frames \(poses\)",
        ),
        "cx off": ("meta.json", rewrite_meta(cx=1000), r"cx 1000 puts the image centre 88.1° off"),
        "cy off": (
            "meta.json",
            rewrite_meta(cy=-100),
            r"cy -100 puts the image centre \d\d\.\d° off",
        ),
        # a 180° pinhole trained without a word
        "fx tiny": ("meta.json", rewrite_meta(fx=1e-9), r"fx 1e-09 gives a 180° field of view"),
        # ... and a 0° one was inf in float32 (training blamed the poses)
        "fx huge": ("meta.json", rewrite_meta(fx=1e300), r"fx 1e\+300 gives a .*, 0.001° to 170°"),
        # translations of 1e300 loaded; training stopped on an infinite view matrix, no file named
        "far poses": ("trajectory.json", _far_poses, r"lie 1e\+300 units from the origin: exp"),
        "inf": ("train_timestamps.txt", lambda t: t + "1e400\n", r"integer readouts.*inf"),
        # a 30-digit one was named as -9223372036854775808 (int64's cast)
        "digits": (
            "train_timestamps.txt",
            lambda t: t + "1" * 30 + "\n",
            r"readouts, found \[1\.1+e\+29",
        ),
        "past the end": (
            "train_timestamps.txt",
            lambda t: t + "5\n",
            r"expected timestamps within \[32, .*found \[5\]",
        ),
        # the clock in µs: readouts past the end, named as such, not as a stray line
        "timestamps in µs": (
            "train_timestamps.txt",
            lambda t: "".join(f"{25 * int(k)}\n" for k in t.split()),
            r"found \[\d+, .*\]\. Readouts in µs\? .*25 µs apart: divided by 25, the last",
        ),
        # trained on the poses' first 1/25, warned of as 'a pose log that ran on'
        "poses in µs": ("trajectory.json", _microsecond_poses, r"Readouts in µs\? .*25 µs apart"),
    }
    for case, (name, edit, message) in cases.items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # inf's cast warned before the error
            with pytest.raises(ValueError, match=message):
                load_dataset(_edited_copy(small, tmp_path / case, name, edit))


def test_wider_rows_that_read_as_more_readouts_name_raw_width(tmp_path, small):
    """A camera's rows twice the image's width read as twice the readouts: "N readouts of HxW,
    meta.json says M (or its height and width are wrong)", raw_width unnamed (the real-layout
    trial); the width at which the file holds meta.json's readouts is said."""
    root = tmp_path / "wide"
    shutil.copytree(small.root, root)
    stream = small.streams[0]
    bits = stream.window(len(stream) // 2, len(stream))  # [T, H, W]: every readout
    wide = np.zeros((*bits.shape[:2], 2 * bits.shape[2]), bool)
    wide[:, :, : bits.shape[2]] = bits
    save_dat(root / "spikes.dat", wide, flip=small.meta["flip"])
    height, width = bits.shape[1:]
    with pytest.raises(
        ValueError,
        match=rf"{2 * len(stream)} readouts of {height}x{width}, meta.json says {len(stream)} "
        rf"\(or its height and width are wrong; it holds {len(stream)} readouts of "
        rf"{height}x{2 * width}: rows wider than the image\? raw_width {2 * width} and col_",
    ):
        load_dataset(root)


@pytest.mark.parametrize("extra", [1, 4, 10])
def test_wider_rows_are_not_named_swapped_where_they_read_more_alike(tmp_path, small, extra):
    """Rows of a few noise columns more than the image, whose frames read with height and width
    swapped have alike rows too (36-pixel rows of a 24x32 image: 0.68 swapped), were named a
    swapped size; set so, they train noise unsaid. The more alike reading, the wider rows (0.78
    there), is named."""
    stream = small.streams[0]
    bits = stream.window(len(stream) // 2, len(stream))  # [T, H, W]: every readout
    height, width = bits.shape[1:]
    bits = bits[: len(bits) // width * width]  # whole frames as read, and swapped
    wide = np.random.default_rng(1).random((len(bits), height, width + extra)) < 0.3
    wide[:, :, :width] = bits  # the extra columns: noise
    path = tmp_path / "spikes.dat"
    save_dat(path, wide, flip=True)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        warn_rows_out_of_line(SpikeStream.open(path, height, width, True), "spikegs.json")
    messages = [str(w.message) for w in said]
    assert len(messages) == 1 and f"set raw_width {width + extra}" in messages[0], messages
    # the readouts read so (meta.json states them: a second refusal named them)
    assert f"in spikegs.json; {len(bits)} readouts so)" in messages[0], messages


def _wider_rows_copy(data, root: Path, offset: int) -> tuple[np.ndarray, dict]:
    """`data` copied to `root` with its spikes stored in rows of 9 pixels more, the image from
    column `offset`, the rest random; its bits [T, H, W] and meta.json (unchanged)."""
    shutil.copytree(data.root, root)
    stream = data.streams[0]
    bits = stream.window(len(stream) // 2, len(stream))  # [T, H, W]: every readout
    wide = np.random.default_rng(0).random((*bits.shape[:2], bits.shape[2] + 9)) < 0.5
    wide[:, :, offset : offset + bits.shape[2]] = bits
    save_dat(root / "spikes.dat", wide, flip=data.meta["flip"])
    return bits, json.loads((root / "meta.json").read_text())


@pytest.mark.parametrize("offset", [4, 0])
def test_a_cameras_wider_rows_are_cropped_by_meta_json(tmp_path, small, offset):
    """A real camera stores 416-pixel rows for a 400-pixel image: meta.json's raw_width and
    col_offset were ignored (a raw recording could not be read); a spikegs.json beside meta.json
    is not read, and says so. The extra columns after the image (col_offset 0) too: such rows
    are the camera's, not a frame to try read with height and width swapped."""
    root = tmp_path / "wide"
    bits, meta = _wider_rows_copy(small, root, offset)
    stream = small.streams[0]
    with pytest.raises(ValueError, match="whole number"):  # rows wider than meta.json says
        load_dataset(root)
    (root / "meta.json").write_text(
        json.dumps({**meta, "raw_width": bits.shape[2] + 9, "col_offset": offset})
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # read as meta.json says, nothing to warn of
        loaded = load_dataset(root).streams[0]
    np.testing.assert_array_equal(loaded.tfp(100, 33), stream.tfp(100, 33))
    for bad in ({"raw_width": bits.shape[2] + 3, "col_offset": 4}, {"col_offset": -1}):
        (root / "meta.json").write_text(json.dumps({**meta, **bad}))
        with pytest.raises(ValueError, match="raw_width|col_offset"):
            load_dataset(root)
    (root / "meta.json").write_text(
        json.dumps({**meta, "raw_width": bits.shape[2] + 9, "col_offset": offset})
    )
    (root / "spikegs.json").write_text('{"rate_at_one": 0.3}')
    with pytest.warns(UserWarning, match=r"spikegs.json is not read: .* in meta.json$"):
        load_dataset(root)
    # its split's options have no place in meta.json (train_every moved there as told was
    # read by `spikegs poses` alone): the files that list it named
    (root / "spikegs.json").write_text('{"train_every": 16, "pseudo_gt_window": 99}')
    listed = r"train_timestamps.txt and test_views.json list .* \(train_every, pseudo_gt_window in"
    with pytest.warns(UserWarning, match=listed):
        load_dataset(root)


@pytest.mark.parametrize(("offset", "stated"), [(4, 0), (0, 4), (9, 3), (4, 4)])
def test_a_wrong_col_offset_is_named_by_the_sharp_test_views(tmp_path, small, offset, stated):
    """A camera's wider rows cropped from another column than the image's (raw_width right,
    col_offset left out or wrong) trained on a crop beside the test images', unsaid (20.3 dB
    where 26.9 was due): the sharp test views match the spikes better from the right column,
    which the warning names. A hot column at the image's edge, which a shift drops, named a
    wrong one for a right col_offset (the review): not now."""
    root = tmp_path / "wide"
    bits, meta = _wider_rows_copy(small, root, offset)
    if offset == stated:  # a hot first column of the image: it fires every readout
        stored = np.random.default_rng(0).random((*bits.shape[:2], bits.shape[2] + 9)) < 0.5
        stored[:, :, offset : offset + bits.shape[2]] = bits
        stored[:, :, offset] = True
        save_dat(root / "spikes.dat", stored, flip=small.meta["flip"])
    meta.update(raw_width=bits.shape[2] + 9, col_offset=stated)
    (root / "meta.json").write_text(json.dumps(meta))
    way = "further along" if offset > stated else "back"
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        load_dataset(root)
    shifted = [str(w.message) for w in said if "their stored rows" in str(w.message)]
    assert len(shifted) == (offset != stated), [str(w.message) for w in said]
    if offset == stated:
        return
    assert f"{abs(offset - stated)} columns {way} their stored rows" in shifted[0]
    assert (
        f"col_offset is likely {offset}, the first stored column of the image (read with "
        in shifted[0]
    )
    assert f"col_offset {stated}; it is set in meta.json)" in shifted[0]


def test_test_images_unlike_the_frame_and_binary_timestamps_are_named(tmp_path, small):
    """A test image of another size or with an alpha channel, and a timestamps file that is no
    text, are refused naming the file; blank lines and # comments in it are skipped."""
    from spikegs.image_io import write_image

    image = small.test_views[0].image  # [H, W, 1]
    for case, stored, message in [
        ("narrow", image[:, :-1], r"on_000.exr: expected an image of shape \[\d+, \d+, 1\] .*1\]$"),
        # (it named the image, not meta.json, where height and width were swapped)
        ("turned", image.transpose(1, 0, 2), r"\]: height and width swapped in meta.json\?"),
        ("alpha", np.concatenate([image] * 4, axis=2), "on_000.exr: a test view with an alpha"),
    ]:
        root = tmp_path / case
        shutil.copytree(small.root, root)
        write_image(root / "test" / "on_000.exr", stored)
        with pytest.raises(ValueError, match=message):
            load_dataset(root)
    root = tmp_path / "binary"
    shutil.copytree(small.root, root)
    (root / "train_timestamps.txt").write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(ValueError, match="train_timestamps.txt: expected text, .* binary data"):
        load_dataset(root)
    commented = "# readouts\n\n" + (small.root / "train_timestamps.txt").read_text() + "\n# end\n"
    (root / "train_timestamps.txt").write_text(commented)
    np.testing.assert_array_equal(load_dataset(root).train_timestamps, small.train_timestamps)


def test_an_8_bit_test_view_is_decoded_from_srgb(tmp_path, small):
    """A PNG test view was read as stored: sRGB values taken for firing rates."""
    from spikegs.image_io import write_image

    root = tmp_path / "png"
    shutil.copytree(small.root, root)
    doc = json.loads((root / "test_views.json").read_text())
    first = doc["frames"][0]
    view = next(v for v in small.test_views if v.name == first["name"])
    first["file_path"] = first["file_path"].rsplit(".", 1)[0] + ".png"
    write_image(root / first["file_path"], view.image)  # linear in, sRGB stored
    (root / "test_views.json").write_text(json.dumps(doc))
    loaded = next(v for v in load_dataset(root).test_views if v.name == first["name"])
    np.testing.assert_allclose(loaded.image, view.image, atol=2e-3)


def test_a_test_views_file_path_without_extension_finds_its_image(tmp_path, small):
    """A test view's file_path finds its image without an extension, in any case, as a transforms
    file's frame does (test_views.json alone needed it: "dataset file not found")."""
    root = tmp_path / "bare"
    shutil.copytree(small.root, root)
    doc = json.loads((root / "test_views.json").read_text())
    first = doc["frames"][0]
    stored = root / first["file_path"]
    stored.rename(stored.with_suffix(".EXR"))
    first["file_path"] = first["file_path"].rsplit(".", 1)[0]
    (root / "test_views.json").write_text(json.dumps(doc))
    for loaded, view in zip(load_dataset(root).test_views, small.test_views, strict=True):
        assert loaded.name == view.name
        np.testing.assert_array_equal(loaded.image, view.image)


def test_poses_rounded_to_4_decimals_load(tmp_path, small):
    """One rigidity rule with the LLFF/NeRF loaders: poses within 1e-3 of rigid are made rigid."""

    def rounded(text):
        doc = json.loads(text)
        for frame in doc["frames"]:
            frame["transform_matrix"] = np.round(frame["transform_matrix"], 4).tolist()
        return json.dumps(doc)

    root = _edited_copy(small, tmp_path / "rounded", "trajectory.json", rounded)
    (root / "test_views.json").write_text(rounded((root / "test_views.json").read_text()))
    ds = load_dataset(root)
    rot = ds.trajectory.viewmats[:, :3, :3]  # [P, 3, 3]
    np.testing.assert_allclose(
        rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12
    )
    np.testing.assert_allclose(ds.trajectory.viewmats, small.trajectory.viewmats, atol=1e-3)
    for view, expected in zip(ds.test_views, small.test_views):
        np.testing.assert_allclose(
            view.viewmat[:3, :3] @ view.viewmat[:3, :3].T, np.eye(3), atol=1e-12
        )
        np.testing.assert_allclose(view.viewmat, expected.viewmat, atol=1e-3)


def test_existing_dataset_needs_overwrite(tmp_path):
    out = tmp_path / "ds"
    simulate_dataset("wires", out, **SMALL)
    (out / "sim").mkdir()  # a cache derived from the old spikes
    cached = ["sim_w33_seed0.pt", "sim_w33_seed0.pt.json", "sim_w33_seed0.pt.lock", "a.pt.partial"]
    for name in [*cached, ".sim_w33_seed0.pt.123.tmp"]:
        (out / "sim" / name).write_bytes(b"")
    with pytest.raises(FileExistsError, match="--overwrite"):
        simulate_dataset("wires", out, **SMALL)
    (out / "sim" / "readme.txt").write_text("mine")  # deleted with the cache, unasked
    with pytest.raises(FileExistsError, match=r"not a dataset's \(sim/readme.txt\)"):
        simulate_dataset("wires", out, overwrite=True, **SMALL)
    (out / "sim" / "readme.txt").unlink()
    ds = simulate_dataset("wires", out, overwrite=True, seed=1, **SMALL)
    assert ds.meta["seed"] == 1 and not (out / "sim").exists()
    (out / "notes.txt").write_text("mine")  # --overwrite deletes the directory: refused
    with pytest.raises(FileExistsError, match=r"not a dataset's \(notes.txt\)"):
        simulate_dataset("wires", out, overwrite=True, **SMALL)
    assert (out / "notes.txt").exists()
    with pytest.raises(FileExistsError, match=r"not a dataset's \(ds\)"):  # nor mixed in
        simulate_dataset("wires", tmp_path, **SMALL)
    # a simulation killed while simulating leaves its spikes' temporary file (the folder was
    # refused for good, "not a dataset's", even with --overwrite), one killed before 2026-11-29
    # while rendering its light .light.npy
    for left in (".spikes_g.dat.0123abcd.tmp", ".light.npy"):
        killed = tmp_path / f"killed{left}"
        killed.mkdir()
        (killed / left).write_bytes(b"\0" * 64)
        with pytest.raises(FileNotFoundError, match="an interrupted simulation"):
            load_dataset(killed)
        with pytest.raises(FileExistsError, match="an interrupted simulation left.*--overwrite"):
            simulate_dataset("wires", killed, **SMALL)
        assert simulate_dataset("wires", killed, overwrite=True, **SMALL).meta["scene"] == "wires"
        assert not (killed / left).exists()
    # a temporary file beside a derived file is no dataset's part (nor is it removed)
    stray = tmp_path / "stray"
    stray.mkdir()
    (stray / ".points3d.ply.99.tmp").write_bytes(b"")
    with pytest.raises(FileExistsError, match=r"not a dataset's \(.points3d.ply.99.tmp\)"):
        simulate_dataset("wires", stray, overwrite=True, **SMALL)


def test_unknown_scene_lists_the_known_ones(tmp_path):
    with pytest.raises(ValueError) as err:
        simulate_dataset("teapot", tmp_path / "x", **SMALL)
    assert all(name in str(err.value) for name in SCENES)
    assert not (tmp_path / "x").exists()  # nothing written before the scene is known
    with pytest.raises(FileNotFoundError, match="scene scenes/teapot not found"):  # a path
        simulate_dataset("scenes/teapot", tmp_path / "x", **SMALL)


def test_frames_and_poses_of_different_counts():
    frames = np.zeros((3, 8, 8, 1), np.float32)
    with pytest.raises(ValueError, match="3 frames but 2 poses"):
        FrameSequenceSource("x", frames, [np.eye(4)] * 2, intrinsics(8, 8, 40))
    for few in (frames[:1], frames[0]):  # one frame: nothing to move between; no frame axis
        with pytest.raises(ValueError, match=r"frames expected \[F, H, W, C\] with F >= 2, found"):
            FrameSequenceSource("x", few, [np.eye(4)], intrinsics(8, 8, 40))
    with pytest.raises(ValueError, match="channels expected 1 .mono. or 3 .colour., found 2"):
        FrameSequenceSource(
            "x",
            np.zeros((3, 8, 8, 2)),
            [np.eye(4)] * 3,
            intrinsics(8, 8, 40),
            center=[0, 0, 3],
            radius=1.0,
        )


def test_cli(tmp_path, capsys):
    out = tmp_path / "cli"
    args = ["simulate", "--scene", "fine-texture", "--out", str(out), "--height", "16"]
    args += ["--width", "16", "--readouts", "330", "--test-on-path", "2", "--no-progress"]
    assert main(args + ["--seed", "5", "--rate-at-one", "0.3"]) == 0
    ds = load_dataset(out)
    assert ds.meta["seed"] == 5 and ds.meta["sim"]["rate_at_one"] == 0.3
    assert "light rendered every" not in capsys.readouterr().out  # 8 readouts, said nowhere
    assert main(args) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(["simulate", "--scene", "teapot", "--out", str(tmp_path / "t")]) == 2
    assert "solids" in capsys.readouterr().err


def test_a_scene_far_from_the_origin_is_warned_of(small, moved_world):
    """Poses in UTM-like coordinates: float32 positions round by pixels there (1e6 units away
    cost 2 dB at 64²), said, not silent; a scene near the origin is not warned of."""
    with pytest.warns(UserWarning, match="lies 1.73e\\+06 units from the origin, .* round by"):
        moved_world(small, np.full(3, 1e6))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        moved_world(small, np.full(3, 100.0))
    # a scene in other units, its cameras under a unit from its centre (0.3): judged alike
    with pytest.warns(UserWarning, match="lies 1.73e\\+05 units from the origin, .* round by"):
        moved_world(small, np.full(3, 1e5), scale=0.1)
    # judged by the longer focal length, fy's where it is (fx alone: one tenth of the rounding
    # said, or none; the geometry trial)
    for key in ("fx", "fy"):
        meta = {**small.meta, key: small.meta[key] / 10}
        trajectory, timestamps = small.trajectory, small.train_timestamps
        narrow = Dataset(small.root, meta, small.streams, trajectory, timestamps, [])
        with pytest.warns(UserWarning, match="lies 1.73e\\+05 units .* round by ~0.1"):
            moved_world(narrow, np.full(3, 1e5))


def test_a_scene_radius_out_of_scale_with_the_cameras_is_warned_of(small):
    """meta.json's scene_radius 1e4 or 1e-20 with cameras ~3 units away trained without a word
    (1e300 ended in a traceback from Adam); within 100x of their distance nothing is said."""
    distance = np.median(np.linalg.norm(small.trajectory.centers - small.scene_center, axis=1))

    def sized(radius: float) -> Dataset:
        meta = {**small.meta, "scene_radius": radius}
        trajectory, timestamps = small.trajectory, small.train_timestamps
        return Dataset(small.root, meta, small.streams, trajectory, timestamps, [])

    for radius in (1e4, 1e-20, 101 * distance):
        said = re.escape(f"scene_radius {radius:.3g} is ")
        with pytest.warns(UserWarning, match=said + ".* times the cameras"):
            sized(radius)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sized(99 * distance)
        sized(distance / 99)
        sized(small.scene_radius)


def test_test_images_without_their_units_warn(tmp_path, small):
    """A hand-written meta.json without sim.rate_at_one or image_scale: the trainer guesses the
    test images' units, which sets their PSNR; that was silent for this layout."""
    root = _edited_copy(
        small,
        tmp_path / "units",
        "meta.json",
        lambda text: json.dumps(
            {k: v for k, v in json.loads(text).items() if k not in ("sim", "image_scale")}
        ),
    )
    with pytest.warns(UserWarning, match="neither image_scale nor sim.rate_at_one"):
        load_dataset(root)
    meta = json.loads((root / "meta.json").read_text())
    (root / "meta.json").write_text(json.dumps({**meta, "image_scale": 0.25}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # image_scale alone states the units
        load_dataset(root)


def test_camera_copies_that_differ_from_meta_json_are_said(tmp_path, small):
    """trajectory.json's and test_views.json's fl_x, cx, w ... were ignored without a word; where
    `spikegs poses` estimated the intrinsics the copies predate them, and are not compared."""
    root = _edited_copy(
        small,
        tmp_path / "copies",
        "trajectory.json",
        lambda text: json.dumps({**json.loads(text), "fl_x": 100.0}),
    )
    with pytest.warns(UserWarning, match="trajectory.json: fl_x 100.0, the dataset's camera has"):
        load_dataset(root)
    meta = json.loads((root / "meta.json").read_text())
    (root / "meta.json").write_text(json.dumps({**meta, "intrinsics_from": "sfm"}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_dataset(root)


def test_a_cropped_cameras_principal_point_is_accepted(tmp_path):
    """A 64-column crop of a 400-wide camera has cx ~ 200: off the image, 23° off its axis."""
    meta = {"width": 64, "height": 48, "fx": 400.0, "fy": 400.0, "cx": 200.0, "cy": 24.0}
    check_meta_values(meta, tmp_path / "meta.json", ["cx", "cy"])
    with pytest.raises(ValueError, match="cx 1200.0 puts the image centre 71.1° off"):
        check_meta_values({**meta, "cx": 1200.0}, tmp_path / "meta.json", ["cx"])
    # a focal under a pixel (an 8-pixel frame at fx 0.5: 166° of view, accepted) is judged too
    tiny = {"width": 8, "height": 8, "fx": 0.5, "fy": 0.5, "cx": 6.0, "cy": 4.0}
    with pytest.raises(ValueError, match="cx 6.0 puts the image centre 76° off"):
        check_meta_values(tiny, tmp_path / "meta.json", ["fx", "fy", "cx", "cy"])


@pytest.mark.parametrize("key, size", [("cx", 64), ("cy", 48)])
@pytest.mark.parametrize("side", [1, -1])
def test_the_principal_points_angle_is_taken_from_the_image_centre(tmp_path, key, size, side):
    """The bound of 60° off the optical axis holds either side of the image's centre (width / 2
    for cx, height / 2 for cy): 59.9° accepted, 60.1° refused (a centre at a third of the width,
    which moves the bound 0.4° here, passed every test, whose points lay far inside or out)."""
    meta = {"width": 64, "height": 48, "fx": 400.0, "fy": 400.0}
    for angle in (59.9, 60.1):
        point = size / 2 + side * 400 * math.tan(math.radians(angle))
        edited = ({**meta, key: point}, tmp_path / "meta.json", [key])
        if angle < 60:
            check_meta_values(*edited)
        else:
            with pytest.raises(ValueError, match=f"{key} .* puts the image centre 60.1° off"):
                check_meta_values(*edited)  # (shown as 60°, under its own bound: a trial)
    fx = 32 / math.tan(math.radians(170.3 / 2))  # 170.3° across 64 pixels, shown as 170°
    with pytest.raises(ValueError, match=r"gives a 170.3° field of view .* to 170° of view"):
        check_meta_values({**meta, "fx": fx}, tmp_path / "meta.json", ["fx"])


def test_raw_width_equal_to_the_width_is_accepted_without_col_offset(tmp_path):
    """Rows stored as wide as the image (raw_width = width, col_offset unset: 0) are read; a
    col_offset of 1 then leaves the last column out of the stored rows."""
    meta, path = {"width": 64, "raw_width": 64}, tmp_path / "meta.json"
    check_meta_values(meta, path, ["raw_width"])
    with pytest.raises(ValueError, match="width \\+ col_offset = 65, found 64"):
        check_meta_values({**meta, "col_offset": 1}, path, ["raw_width", "col_offset"])


@pytest.mark.parametrize(
    "key, value, message",
    [  # an int past a float's range (JSON reads 309 digits as one): an OverflowError
        ("fx", 10**400, "fx expected a finite number > 0"),
        ("width", 10**400, "width expected an integer > 0 and at most 1048576"),  # passed
        ("height", 2**20 + 1, "height expected an integer > 0 and at most 1048576"),
        ("spp", 0, "spp expected an integer > 0, found 0"),  # a hand edit: it read as 1
        ("spp", 2.5, "spp expected an integer > 0, found 2.5"),
    ],
)
def test_meta_values_out_of_range_are_named(tmp_path, key, value, message):
    meta = {"width": 64, "height": 48, "fx": 40.0, key: value}
    with pytest.raises(ValueError, match=message):
        check_meta_values(meta, tmp_path / "meta.json", ["height", "width", "fx", key])
    check_meta_values({**meta, "spp": None}, tmp_path / "meta.json", ["spp"])  # a frame sequence


@pytest.mark.parametrize(
    "key, value, shown",
    [("height", None, "null"), ("channels", True, "true"), ("flip", "yes", '"yes"')],
)
def test_meta_values_are_shown_as_the_json_file_spells_them(tmp_path, key, value, shown):
    """meta.json's null read "found None", and true "found True": Python's words for them."""
    meta = {"width": 64, "height": 48, "channels": 1, "flip": True, key: value}
    with pytest.raises(ValueError, match=f"{key} expected .*, found {shown}$"):
        check_meta_values(meta, tmp_path / "meta.json", ["height", "width", "channels", "flip"])


# a dataset written by hand (no simulation): readouts, rows, columns
T, H, W = 100, 6, 8


def write_tiny(root, timestamps=(40, 50), readouts=(0.0, T - 1.0), view_readout=None, window=None):
    """A mono dataset of T readouts (no spike), two poses at `readouts`, training `timestamps`,
    one held-out view (off the path, or on it at `view_readout`; a pseudo ground truth of TFP over
    `window` readouts)."""
    root.mkdir(parents=True, exist_ok=True)
    poses = np.stack([look_at([3.0, 0.0, 1.0], [0, 0, 0]), look_at([0.0, 3.0, 1.0], [0, 0, 0])])
    meta = {
        "format_version": 1,
        "height": H,
        "width": W,
        "channels": 1,
        "num_readouts": T,
        "flip": True,
        "fx": 8.0,
        "fy": 8.0,
        "cx": W / 2,
        "cy": H / 2,
        "scene_center": [0.0, 0.0, 0.0],
        "scene_radius": 1.0,
        "image_scale": 0.25,
    }
    view = View("v", poses[0], np.full((H, W, 1), 0.1, np.float32), view_readout, window)
    write_parts(root, meta, Trajectory(np.array(readouts), poses), np.array(timestamps), [view])
    save_dat(root / "spikes.dat", np.random.default_rng(0).random((T, H, W)) < 0.1)
    return root


def test_test_images_in_other_units_than_firing_rates_are_warned_of(tmp_path):
    """Test images written as intensities (a rate of 0.25 at 1) scored 5.6 dB where 18.7 was
    due, without a word; firing rates (the simulator's) load unsaid."""
    from spikegs.image_io import read_image, write_image

    root = simulate_dataset("solids", tmp_path / "d", **SMALL).root
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dataset = load_dataset(root)
    for frame in json.loads((root / "test_views.json").read_text())["frames"]:
        path = root / frame["file_path"]
        write_image(path, read_image(path) / dataset.meta["image_scale"])
    with pytest.warns(UserWarning, match=r"test images average [34]\.\d+ times their spikes'"):
        load_dataset(root)


def test_light_past_saturation_is_not_taken_for_other_units(tmp_path):
    """A lamp past the sensor's saturation (its pixels fire every readout) shows brighter in its
    image than any spikes: images in the right units were told "6.65 times their spikes'" (the
    extreme-scenes trial). Saturated pixels are left out; images in other units are still told."""
    from spikegs.data.dataset import TestView, warn_about_test_units

    class Stream:  # a constant-light stream: TFP `rate` [H, W] at any readout
        height, width = 32, 32

        def __init__(self, rate):
            self.rate = rate

        def __len__(self):
            return 200

        def tfp(self, k, window):
            return self.rate

    light = np.full((32, 32), 0.2)
    light[:8, :8] = 40.0  # a lamp: its image 40 spikes a readout, its spikes one
    views = [TestView("v", np.eye(4), light[..., None], 100.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_about_test_units([Stream(np.minimum(light, 1.0))], views, tmp_path, 0.0)
    views = [TestView("v", np.eye(4), 255 * light[..., None], 100.0)]  # 8-bit units
    with pytest.warns(UserWarning, match=r"test images average 255 times their spikes'"):
        warn_about_test_units([Stream(np.minimum(light, 1.0))], views, tmp_path, 0.0)


def test_the_tiny_dataset_loads(tmp_path):
    ds = load_dataset(write_tiny(tmp_path / "d", timestamps=(32, T - 33)))
    assert ds.train_timestamps.tolist() == [32, T - 33]
    # a byte-order mark (a Windows editor's) is not a line's text: "'\ufeff32' is not a number"
    timestamps = ds.root / "train_timestamps.txt"
    timestamps.write_bytes(b"\xef\xbb\xbf" + timestamps.read_bytes())
    assert load_dataset(ds.root).train_timestamps.tolist() == [32, T - 33]


def test_a_timestamp_whose_65_readout_window_leaves_the_stream_is_refused(tmp_path):
    """Readout T - 32's window [T - 64, T] reaches one readout past the end: refused on load
    (an upper bound of T - 32 accepted it; the stream then refuses TFP(65) at 68, mid-training)."""
    with pytest.raises(ValueError, match=r"expected timestamps within \[32, 67\].*\[68\]"):
        load_dataset(write_tiny(tmp_path / "d", timestamps=(40, T - 32)))


@pytest.mark.parametrize("first, last", [(0.0, T - 2.0), (1.0, T - 1.0)])
def test_poses_that_miss_the_first_or_the_last_readout_are_refused(tmp_path, first, last):
    """trajectory.json must cover [0, T - 1]: poses ending at T - 2 leave the last readout
    without a pose (pose_at(T - 1) raises), poses from readout 1 the first; refused on load."""
    covered = rf"poses cover readouts \[{first}, {last}\], expected \[0, 99\]"
    with pytest.raises(ValueError, match=covered):
        load_dataset(write_tiny(tmp_path / "d", readouts=(first, last)))


def test_poses_past_the_last_readout_are_said_to_be_unused(tmp_path):
    """A trajectory longer than the stream (a pose log that ran on, a recording cut short) was
    read without a word, where one a readout short is refused."""
    with pytest.warns(UserWarning, match=r"poses cover readouts \[0, 150\], the stream holds 100"):
        load_dataset(write_tiny(tmp_path / "d", readouts=(0.0, T + 50.0)))


def test_a_pseudo_ground_truths_window_is_kept(tmp_path):
    """`spikegs poses`' held-out views are TFP(65) of their own spikes: the window is written with
    them and read back (sim-train leaves that TFP out of their scores by it; it was left out where
    equal to its image alone, which a repaired defect is not); a window that is not a whole
    number of readouts is refused."""
    root = write_tiny(tmp_path / "d", timestamps=(32,), view_readout=T - 1.0, window=65)
    assert [v.window for v in load_dataset(root).test_views] == [65]
    path = root / "test_views.json"
    doc = json.loads(path.read_text())
    doc["frames"][0]["pseudo_window"] = 1  # the least: one readout's spikes (> 1 passed)
    path.write_text(json.dumps(doc))
    assert [v.window for v in load_dataset(root).test_views] == [1]
    for bad in ("65", 6.5, 0, True):
        doc["frames"][0]["pseudo_window"] = bad
        path.write_text(json.dumps(doc))
        with pytest.raises(ValueError, match="'v': pseudo_window expected a whole number"):
            load_dataset(root)


def test_an_on_path_view_past_the_last_readout_is_refused(tmp_path):
    """A held-out view at readout T (one past the last) is outside the stream: refused."""
    with pytest.raises(ValueError, match=r"at readout 100.0, outside the stream's \[0, 99\]"):
        load_dataset(write_tiny(tmp_path / "d", view_readout=float(T)))


def test_camera_files_state_width_and_height_as_nerfstudio_reads_them(tmp_path):
    """trajectory.json and test_views.json carry the camera in nerfstudio's keys: w the width
    (8 here), h the height (6); swapped, every tool that reads them sized the images 6 wide."""
    root = write_tiny(tmp_path / "d")
    for name in ("trajectory.json", "test_views.json"):
        doc = json.loads((root / name).read_text())
        assert (doc["w"], doc["h"], doc["cx"], doc["cy"]) == (W, H, W / 2, H / 2)


def test_simulate_holds_its_test_images_once(tmp_path, monkeypatch, alive_arrays):
    """The off-path views' rendered images are not kept beside their firing rates through the
    simulation, and the test views are not held twice while the dataset written is loaded
    (simulate at 1080x1920 colour, 8 + 8 views: anonymous peak 1380 -> 1113 MB, RSS 2337 ->
    1731). 2 + 2 views: none of the rendered off-path images alive as the spikes are simulated
    (2 before), and none of those nor of the 4 views written as the dataset is loaded (6)."""
    from spikegs.data import simulate
    from spikegs.data.sources import RenderSource

    counted = {}

    def track(arrays) -> None:
        for array in arrays:
            alive_arrays.track(array)

    def counting(name: str, function):
        def call(*args):
            counted[name] = len(alive_arrays)
            return function(*args)

        return call

    off_path_views, write_parts = RenderSource.off_path_views, simulate.write_parts

    def rendered(self, count, arc_deg):
        views = off_path_views(self, count, arc_deg=arc_deg)
        track(image for *_, image in views)
        return views

    def written(out, meta, trajectory, timestamps, views):
        write_parts(out, meta, trajectory, timestamps, views)
        track(view.image for view in views)

    monkeypatch.setattr(RenderSource, "off_path_views", rendered)
    monkeypatch.setattr(simulate, "write_parts", written)
    monkeypatch.setattr(simulate, "write_spikes", counting("spikes", simulate.write_spikes))
    monkeypatch.setattr(simulate, "load_dataset", counting("load", simulate.load_dataset))
    ds = simulate_dataset("solids", tmp_path / "d", **SMALL)
    assert counted == {"spikes": 0, "load": 0}, counted
    assert alive_arrays.most >= 4, alive_arrays.most  # the 4 written, counted (not 0: elsewhere)
    assert len(ds.test_views) == 4


def data_warnings(images: list[np.ndarray], params: SimParams) -> str:
    """The warnings, joined, of `warn_about_data` for held-out views of `images` [H, W, C]
    (firing rates) from a camera standing still for two readouts."""
    views = [View(f"v{i}", np.eye(4), image, None) for i, image in enumerate(images)]
    trajectory = Trajectory(np.array([0.0, 1.0]), np.stack([np.eye(4)] * 2))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_about_data(views, trajectory, params)
    return " ".join(str(w.message) for w in caught)


def test_a_view_lit_in_one_colour_is_lit():
    """The empty-view warning counts pixels, not channel values: a red object over 2.4 % of a
    colour view on black is a view of something (it counted a third of its area, 0.8 %)."""
    image = np.zeros((128, 128, 3), np.float32)
    image[:20, :20, 0] = 0.2  # red only
    assert "pixels lit" not in data_warnings([image], SimParams(rate_at_one=0.25))
    image[:20, :20, 0], image[:10, :10, 0] = 0.0, 0.2  # 0.6 %: said
    said = "1 of 1 held-out views have under 1% of their pixels"
    assert said in data_warnings([image], SimParams(rate_at_one=0.25))


def test_a_scene_is_grey_only_where_its_three_channels_agree():
    """R = G = B in every held-out view is a grey scene, said; two channels alike (R = B, or
    G = B) are colour."""
    grey = np.full((8, 8, 3), 0.1, np.float32)
    assert "the scene is grey" in data_warnings([grey], SimParams(rate_at_one=0.25))
    for channel in (1, 0):  # green unlike red and blue, red unlike green and blue
        coloured = grey.copy()
        coloured[..., channel] = 0.2
        assert "grey" not in data_warnings([grey, coloured], SimParams(rate_at_one=0.25))


def test_the_light_checks_at_their_edges():
    """Light firing once every readout (intensity 1/rate_at_one) saturates the camera, said;
    white (intensity 1, an 8-bit frame's 255) is not brighter than white; a black scene without
    a dark current is not said to be buried by one (a dark_rate of 0 against light of 0)."""
    params = SimParams(rate_at_one=0.25, dark_rate=0.0)

    def said(rate: float) -> str:
        return data_warnings([np.full((8, 8, 1), rate, np.float32)], params)

    assert "100% of the held-out views' pixels fire every readout" in said(1.0)
    assert said(0.25) == "" and "brighter than white" in said(0.26)
    assert "black" in said(0.0) and "dark_rate" not in said(0.0)


def test_the_light_checks_gather_the_lit_rates_a_view_at_a_time():
    """warn_about_data counts saturated pixels and gathers the lit ones view by view: the views'
    images concatenated, with their masks and a copy of the lit values, took 2.2 times the
    images before simulating (16 views of 1080x1920 colour: +851 MB over their 380, +401 now).
    16 views of 48x64 colour, 5 % lit (1 % saturated), one in float64 (a frame sequence's view at
    a readout): numpy's traced peak under half the images (2.3 times before), the lit
    values and the numbers said np.concatenate's and np.mean's."""
    import tracemalloc

    from spikegs.data import simulate

    rng = np.random.default_rng(0)
    views = []
    for i in range(16):
        image = np.zeros((48, 64, 3), np.float64 if i == 3 else np.float32)
        lit = rng.random(image.shape) < 0.05
        image[lit] = rng.uniform(0.003, 1.0, lit.sum())
        image[rng.random(image.shape) < 0.011] = 1.5
        views.append(View(f"v{i}", np.eye(4), image, None))
    params = SimParams(rate_at_one=0.25, dark_rate=1.0)  # its warning names the lit mean
    trajectory = Trajectory(np.array([0.0, 1.0]), np.stack([np.eye(4)] * 2))
    tracemalloc.start()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            warn_about_data(views, trajectory, params)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.5 * sum(v.image.nbytes for v in views), peak
    threshold = 0.01 * params.rate_at_one
    rates = np.concatenate([np.ravel(v.image) for v in views])
    lit = simulate._lit_rates(views, threshold)
    assert lit.dtype == rates.dtype == np.float64
    np.testing.assert_array_equal(lit, rates[rates > threshold])
    said = [
        f"{np.mean(rates >= 1.0):.0%} of the held-out",
        f"{rates[rates > threshold].mean():.3g}",
    ]
    messages = " ".join(str(w.message) for w in caught)
    assert all(text in messages for text in said), (said, messages)


@pytest.mark.parametrize("height, judged", [(16, True), (15, False)])
def test_rows_wider_than_given_are_judged_from_16_rows(tmp_path, height, judged):
    """A camera's rows of 8 pixels more than the width, read without raw_width: warned of in a
    frame of 16 rows (WIDER_MIN_SIZE, where random frames stop scoring as wider by chance), not
    in one of 15 (a floor of 17 passed: the tests' frames were 32 rows or more). 402 readouts
    make whole frames of either row width."""
    width = 24
    data = simulate_dataset(
        "solids", tmp_path / "d", **{**SMALL, "height": height, "width": width, "readouts": 402}
    )
    n = len(data.stream)
    raw = np.random.default_rng(0).integers(0, 2, (n, height, width + 8), dtype=np.uint8)
    raw[..., 4 : 4 + width] = data.stream.window(n // 2, n)  # [n, height, width]
    save_dat(tmp_path / "raw.dat", raw)
    stream = SpikeStream.open(tmp_path / "raw.dat", height, width)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_rows_out_of_line(stream, "meta.json")
    said = [str(w.message) for w in caught]
    assert len(said) == judged and all(f"set raw_width {width + 8}" in m for m in said), said
    assert all(f"in meta.json; num_readouts {n})" in m for m in said), said  # (its count)


def test_frames_given_at_half_their_size_are_warned_of(tmp_path):
    """32x48 frames given as 16x24 (LLFF's hwf of images downsampled by 2, say) read each true
    row as two rows, four frames to a frame: loaded and trained without a word. Read with rows
    of 48, the width's double, the file gives an image: the size is named."""
    data = simulate_dataset("solids", tmp_path / "d", **{**SMALL, "height": 32, "width": 48})
    with pytest.warns(
        UserWarning,
        match=r"read as 16x24 give an image whose neighbouring rows correlate at -?0\.\d+, read "
        r"with rows of 48 pixels at 0\.\d+: the frames are likely 48 pixels wide, 2 times the "
        r"width given \(32x48 if the height is as far off",
    ):
        warn_rows_out_of_line(SpikeStream.open(data.stream.path, 16, 24), "meta.json")


@pytest.mark.parametrize("scene", list(SCENES))
def test_frames_given_at_twice_their_size_are_warned_of(scene, tmp_path):
    """32x48 frames given as 64x96 (the full-size images' hwf, or a transforms file's w and h)
    read four readouts as one frame, each row two true rows side by side, and loaded without a
    word: the rows as read, true rows two apart, still alike. Read at half the size the file
    gives an image, and the size is named; a right file read so gives none, and is not warned
    of."""
    data = simulate_dataset(scene, tmp_path / "d", **{**SMALL, "height": 32, "width": 48})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_rows_out_of_line(SpikeStream.open(data.stream.path, 32, 48, flip=True), "meta.json")
    with pytest.warns(
        UserWarning,
        match=r"read as 64x96 give an image whose neighbouring rows correlate at -?0\.\d+, read "
        r"as 32x48 at 0\.\d+: the frames are likely 32x48, 1/2 of the size given .* set height "
        r"and width in meta.json\); read so, each frame holds 4 readouts",
    ):
        warn_rows_out_of_line(SpikeStream.open(data.stream.path, 64, 96, flip=True), "meta.json")


@pytest.mark.parametrize("half_period", [1, 3, 8])
def test_right_files_of_horizontal_stripes_are_not_warned_of(half_period, tmp_path):
    """A right 64x64 file of horizontal stripes was told its frames are likely 32x32 or 16x16
    (half periods 2-8 rows) or its rows 120 or 384 pixels (1, 3): read so, its rows are pieces of
    one uniform row, alike as much as true neighbours. Read so, its frames do not follow one
    another as a camera's readouts do (each pixel's next one is another pixel's)."""
    rows = np.arange(64)[:, None] // half_period % 2 == 0
    light = np.where(rows, 1.6, 0.2) * np.ones((1, 64), np.float32)  # [64, 64]
    simulate_spikes(light[None], 1200, out=tmp_path / "s.dat", seed=half_period)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_rows_out_of_line(SpikeStream.open(tmp_path / "s.dat", 64, 64), "meta.json")


def test_a_flip_stated_wrong_in_meta_json_is_warned_of(small, tmp_path):
    """A meta.json whose flip is wrong read every frame upside down without a word, where its
    on-path test images show it (the LLFF and NeRF layouts warned from theirs)."""
    wrong = _edited_copy(
        small,
        tmp_path / "wrong",
        "meta.json",
        lambda t: json.dumps({**json.loads(t), "flip": False}),
    )
    with pytest.warns(
        UserWarning,
        match=r"meta.json: the spikes match their views' sharp images better upside down .* over "
        r"2 views\): flip is likely wrong \(read with flip False; it is set in meta.json\)",
    ):
        load_dataset(wrong)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_dataset(small.root)


def test_a_dat_packed_most_significant_bit_first_is_warned_of_by_meta_json(small, tmp_path):
    """Each byte's bits in the other order (np.packbits' default) read every frame scrambled
    without a word in the meta.json layout (4.3 dB lower on a 48x64 `solids`), where its on-path
    test images show it, as they show a wrong flip (the LLFF and NeRF layouts warned)."""
    msb = tmp_path / "msb"
    shutil.copytree(small.root, msb)
    dat = msb / "spikes.dat"
    bits = np.unpackbits(np.fromfile(dat, np.uint8), bitorder="little")
    np.packbits(bits, bitorder="big").tofile(dat)
    with pytest.warns(
        UserWarning,
        match=r"meta.json: the spikes match their views' sharp images better with each byte's "
        r"bits read in the other order .* over 2 views\): the .dat files are likely written most",
    ):
        load_dataset(msb)


def test_a_noisy_simulation_is_not_said_to_hardly_match_its_images(tmp_path):
    """A simulation whose noise alone holds TFP(33)'s correlation with its sharp images under
    0.5 (fine-texture, 24x32, rate_at_one 0.1, threshold 2 photo-electrons: 0.30-0.38) was said
    to 'hardly match' them, as if read in another bit or pixel order: a simulated meta.json's
    views compare the readings (flip, bit order), not judge the match alone."""
    noisy = {**SMALL, "rate_at_one": 0.1, "threshold": 2.0}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate_dataset("fine-texture", tmp_path / "noisy", **noisy)


@pytest.mark.parametrize("scene", list(SCENES))
def test_a_recording_read_with_height_and_width_swapped_is_warned_of(scene, tmp_path):
    """Height and width swapped give frames of as many bytes: the spikes were read without a
    word and trained into noise (SfM, if run, failed later). Read swapped, such frames give a
    clearly more coherent image; right ones do not (with a camera's hot pixels too, in a small
    frame under motion blur, or as a line of pixels)."""
    data = simulate_dataset(scene, tmp_path / "d", **{**SMALL, "readouts": 500})
    path, (h, w), n = data.stream.path, (data.height, data.width), len(data.stream)
    hot = np.random.default_rng(0).random((h, w)) < 0.03  # a camera's hot pixels
    bits = data.stream.window(n // 2, n)  # [n, h, w]
    bits[:, hot] = 1
    save_dat(tmp_path / "hot.dat", bits)
    small = simulate_dataset(scene, tmp_path / "small", **{**SMALL, "height": 12, "width": 8})
    tall = simulate_dataset(scene, tmp_path / "tall", **{**SMALL, "height": 32, "width": 16})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_rows_out_of_line(SpikeStream.open(path, h, w, flip=True), "meta.json")
        warn_rows_out_of_line(SpikeStream.open(tmp_path / "hot.dat", h, w), "meta.json")
        warn_rows_out_of_line(SpikeStream.open(small.stream.path, 12, 8, flip=True), "meta.json")
        warn_rows_out_of_line(SpikeStream.open(path, 1, h * w), "meta.json")  # a line: no rows
    said = r"read as (\d+)x(\d+) give .* read as \2x\1 at .*: height and width are likely swapped"
    for file, size in [
        (path, (w, h)),
        (tmp_path / "hot.dat", (w, h)),
        (tall.stream.path, (16, 32)),
    ]:
        with pytest.warns(UserWarning, match=said):  # (32x16 read as 16x32: rows two apart)
            warn_rows_out_of_line(SpikeStream.open(file, *size), "meta.json")
