"""Trajectory: slerp/linear interpolation, continuity, the spiral, the JSON file."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from spikegs.data import Trajectory
from spikegs.data.trajectory import (
    CONVENTION,
    check_rigid,
    look_at,
    pixels_in_view,
    point_parts,
    project_points,
    read_camera_doc,
    rigid_c2w,
    unit_vector,
)


def pose(rotvec, center) -> np.ndarray:
    """Viewmat [4, 4] of a camera with camera-to-world rotation `rotvec` at `center`."""
    c2w = np.eye(4)
    c2w[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    c2w[:3, 3] = center
    return np.linalg.inv(c2w)


def c2w_parts(viewmat: np.ndarray) -> tuple[Rotation, np.ndarray]:
    c2w = np.linalg.inv(viewmat)
    return Rotation.from_matrix(c2w[:3, :3]), c2w[:3, 3]


@pytest.fixture
def two_poses() -> Trajectory:
    # 90° about z and a 2-unit move along x between readouts 10 and 30
    return Trajectory(
        np.array([10.0, 30.0]),
        np.stack([pose([0, 0, 0], [0, 0, 0]), pose([0, 0, np.pi / 2], [2, 0, 0])]),
    )


def test_ends_are_the_recorded_poses(two_poses):
    np.testing.assert_allclose(two_poses.pose_at(10.0), two_poses.viewmats[0], atol=1e-12)
    np.testing.assert_allclose(two_poses.pose_at(30), two_poses.viewmats[1], atol=1e-12)


def test_middle_is_slerp_and_linear(two_poses):
    for u in (0.25, 0.5, 0.75):
        rot, center = c2w_parts(two_poses.pose_at(10 + 20 * u))
        np.testing.assert_allclose(rot.as_rotvec(), [0, 0, u * np.pi / 2], atol=1e-12)
        np.testing.assert_allclose(center, [2 * u, 0, 0], atol=1e-12)


def test_batch_matches_scalar_and_stays_rigid(two_poses):
    ts = np.linspace(10, 30, 7)
    batch = two_poses.pose_at(ts)  # [7, 4, 4]
    assert batch.shape == (7, 4, 4) and batch.dtype == np.float64
    for t, m in zip(ts, batch):
        np.testing.assert_allclose(m, two_poses.pose_at(float(t)), atol=1e-12)
        np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-12)


def test_continuity_across_recorded_poses():
    traj = Trajectory.spiral(
        200,
        radius=3,
        start_elevation_deg=10,
        end_elevation_deg=40,
        degrees_per_readout=0.5,
        every=16,
    )
    ts = np.linspace(0, 199, 4001)  # steps of ~0.05 readouts, across every recorded pose
    poses = traj.pose_at(ts)
    steps = np.abs(np.diff(poses, axis=0)).max(axis=(1, 2))
    # 0.5°/readout at radius 3: ~1.3e-3 per step; a jump would be orders larger
    assert steps.max() < 3e-3
    assert steps.max() < 3 * np.median(steps)


def test_outside_the_recorded_readouts_is_an_error(two_poses):
    for t in (9.999, 30.001, np.nan):
        with pytest.raises(ValueError, match="outside"):
            two_poses.pose_at(t)
    with pytest.raises(ValueError, match="outside"):
        two_poses.pose_at(np.array([15.0, 31.0]))


def test_spiral_orbits_ascends_and_looks_at_the_centre():
    target = (0.5, -0.2, 0.1)
    traj = Trajectory.spiral(
        101,
        radius=4,
        start_elevation_deg=0,
        end_elevation_deg=30,
        degrees_per_readout=0.2,
        look_at=target,
    )
    assert len(traj) == 101
    offsets = traj.centers - np.array(target)  # [P, 3]
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), 4, atol=1e-12)
    azimuth = np.degrees(np.unwrap(np.arctan2(offsets[:, 1], offsets[:, 0])))
    np.testing.assert_allclose(np.diff(azimuth), 0.2, atol=1e-9)
    elevation = np.degrees(np.arcsin(offsets[:, 2] / 4))
    np.testing.assert_allclose(elevation[[0, 50, 100]], [0, 15, 30], atol=1e-9)
    # the target is on the optical axis (OpenCV: +z forward) and the image is upright (+y down)
    for m in traj.viewmats:
        cam = m[:3, :3] @ np.array(target) + m[:3, 3]
        np.testing.assert_allclose(cam[:2], 0, atol=1e-12)
        assert cam[2] == pytest.approx(4)
        assert (m[:3, :3] @ np.array([0, 0, 1.0]))[1] < 0  # world up is image up


def test_spiral_every_n_keeps_both_ends():
    traj = Trajectory.spiral(
        100, radius=2, start_elevation_deg=5, end_elevation_deg=5, degrees_per_readout=1, every=30
    )
    np.testing.assert_array_equal(traj.readouts, [0, 30, 60, 90, 99])


def test_json_round_trip_states_the_convention(tmp_path, two_poses):
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path, fl_x=175.8, w=128)
    doc = json.loads(path.read_text())
    assert doc["convention"] == "opencv" and doc["camera_model"] == "OPENCV"
    assert (doc["fl_x"], doc["w"], list(doc)[-1]) == (175.8, 128, "frames")
    # a frame a line (written one by one: a pose a readout of a long recording)
    lines = [line.strip().rstrip(",") for line in path.read_text().splitlines()]
    assert [json.loads(line) for line in lines if line.startswith('{"readout"')] == doc["frames"]
    assert [f["readout"] for f in doc["frames"]] == [10, 30]
    np.testing.assert_allclose(
        doc["frames"][1]["transform_matrix"], np.linalg.inv(two_poses.viewmats[1])
    )
    back = Trajectory.load_json(path)
    np.testing.assert_allclose(back.readouts, two_poses.readouts)
    # numpy values (a Dataset's float32 K, its sizes) as Python's (json's TypeError for them)
    K = np.array([[175.8, 0.0, 63.5], [0.0, 175.8, 47.5], [0, 0, 1]], np.float32)
    two_poses.save_json(path, fl_x=K[0, 0], cx=K[0, 2], w=np.int64(128), K=K)
    doc = json.loads(path.read_text())
    assert (doc["fl_x"], doc["cx"], doc["w"]) == (float(K[0, 0]), 63.5, 128)
    assert doc["K"] == K.tolist()
    np.testing.assert_allclose(back.viewmats, two_poses.viewmats, atol=1e-12)


def test_json_must_state_the_opencv_convention(tmp_path, two_poses):
    """A hand-written trajectory.json without "convention" (NeRF exports are OpenGL) was read as
    OpenCV: cameras facing away from the scene, trained without a word."""
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    for convention in (None, "opengl", 1):
        if convention is None:
            doc.pop("convention")
        else:
            doc["convention"] = convention
        path.write_text(json.dumps(doc))
        found = "no convention" if convention is None else f"convention {json.dumps(convention)}"
        with pytest.raises(ValueError, match=rf"trajectory.json: {found}; expected .*diag\(1, -1"):
            Trajectory.load_json(path)
    doc["convention"] = "OpenCV"  # as the NeRF layout reads it, in any case
    path.write_text(json.dumps(doc))
    np.testing.assert_allclose(Trajectory.load_json(path).viewmats, two_poses.viewmats, atol=1e-12)


def test_json_with_nan_or_missing_file_is_an_error(tmp_path, two_poses):
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    doc["frames"][0]["transform_matrix"][0][3] = float("nan")
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="trajectory.json"):
        Trajectory.load_json(path)
    with pytest.raises(FileNotFoundError, match="nothing.json"):
        Trajectory.load_json(tmp_path / "nothing.json")


def test_bad_poses_are_rejected():
    with pytest.raises(ValueError, match="increasing"):
        Trajectory(np.array([0.0, 0.0]), np.stack([np.eye(4)] * 2))
    with pytest.raises(ValueError, match="rigid"):
        Trajectory(np.array([0.0]), np.diag([2.0, 1, 1, 1])[None])
    with pytest.raises(ValueError, match="parallel"):
        look_at([0, 0, 5], [0, 0, 0])
    for readouts, viewmats, found in [
        ([], np.zeros((0, 4, 4)), r"found \[0\] and \[0, 4, 4\]"),  # no pose
        ([0.0, 1.0], np.stack([np.eye(4)] * 3), r"found \[2\] and \[3, 4, 4\]"),
    ]:
        with pytest.raises(ValueError, match=f"poses: expected readouts .*P >= 1, {found}"):
            Trajectory(np.array(readouts), viewmats)
    with pytest.raises(ValueError, match=r"poses: non-finite readouts \(NaN/inf\)"):
        Trajectory(np.array([0.0, np.nan]), np.stack([np.eye(4)] * 2))
    orbit = dict(radius=4, start_elevation_deg=0, end_elevation_deg=30, degrees_per_readout=1)
    for num_readouts, every in ((1, 1), (10, 0)):
        with pytest.raises(ValueError, match=f"spiral: .* found {num_readouts}, {every}"):
            Trajectory.spiral(num_readouts, every=every, **orbit)


def test_an_up_that_is_no_vector_of_numbers_is_named():
    """meta.json's up (or --up) of a word, a mapping or ragged lists: refused naming it, as a
    zero or 2-number one is (numpy's TypeError or ValueError was caught for it)."""
    for up in ("z", {"z": 1}, [[0, 0], [1]], [0, 0, 0], [0, 1]):
        with pytest.raises(ValueError, match="meta.json's up: expected a non-zero direction"):
            unit_vector("meta.json's up", up)
    np.testing.assert_allclose(unit_vector("up", [0, 0, 2]), [0, 0, 1])


def test_a_long_pose_log_is_read_without_a_python_list_a_number(tmp_path):
    """Each frame's transform_matrix becomes an array as the file is parsed: the lists and floats
    of a pose a readout, all held, took 1.7 kB a pose at the peak of reading (200k readouts:
    load_dataset's peak RSS +404 MB over its start, +276 MB now); numpy's and Python's traced
    peak over 3000 poses under 1.4 kB a pose (1.1 now). The poses are the lists' to the last bit,
    and a frame that is not 4x4 numbers among them is refused as before."""
    import tracemalloc

    from spikegs.number_checks import number_array

    path = tmp_path / "trajectory.json"
    orbit = dict(start_elevation_deg=10.0, end_elevation_deg=50.0, degrees_per_readout=0.1)
    Trajectory.spiral(3000, radius=3.0, **orbit).save_json(path)
    tracemalloc.start()
    try:
        back = Trajectory.load_json(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1400 * 3000, peak / 3000
    doc = json.loads(path.read_text())
    c2w = number_array([frame["transform_matrix"] for frame in doc["frames"]])
    np.testing.assert_array_equal(back.viewmats, np.linalg.inv(rigid_c2w(c2w, "", "frame")))
    doc["frames"][2]["transform_matrix"][1] = [0.0, 1.0, 0.0]  # ragged, the others arrays
    path.write_text(json.dumps(doc))
    with pytest.raises(
        ValueError, match=r"json: frame 2 \(readout 2\): transform_matrix expected 4"
    ):
        Trajectory.load_json(path)


def test_only_the_frames_matrices_become_arrays_as_the_file_is_parsed(tmp_path, two_poses):
    """The parse's hook turns a frame's transform_matrix into an array; an object elsewhere with a
    transform_matrix (here a convention that is one) stays as written, and is named so: it was
    named as a numpy array over five lines, its 0 as 0."""
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    written = [[1, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    doc["convention"] = {"transform_matrix": written}
    path.write_text(json.dumps(doc))
    found = re.escape(f"convention {json.dumps({'transform_matrix': written})}; expected")
    with pytest.raises(ValueError, match=f"trajectory.json: {found}"):
        Trajectory.load_json(path)


def test_a_true_or_false_among_a_poses_numbers_is_named(tmp_path, two_poses):
    """numpy reads a true among numbers as 1: one in a pose's translation, which rigidity leaves
    free, loaded as a camera moved to x = 1 (one in its rotation was refused as not rigid); each
    is named as a true or false, as transforms.json's is."""
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    for row, col in ((0, 3), (0, 0)):
        edited = json.loads(json.dumps(doc))
        edited["frames"][1]["transform_matrix"][row][col] = True
        path.write_text(json.dumps(edited))
        with pytest.raises(
            ValueError, match=r"frame 1 \(readout 30\): transform_matrix expected nu"
        ):
            Trajectory.load_json(path)


def test_json_poses_of_3x4_are_named(tmp_path, two_poses):
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    for frame in doc["frames"]:
        frame["transform_matrix"] = frame["transform_matrix"][:3]  # a 3x4 camera-to-world
    path.write_text(json.dumps(doc))
    with pytest.raises(
        ValueError, match=r"trajectory.json: frame 0 \(readout 10\): transform_matrix expected 4 r"
    ):
        Trajectory.load_json(path)


def test_json_rounded_to_4_decimals_is_made_rigid(tmp_path, two_poses):
    """As the LLFF/NeRF loaders: within 1e-3 of rigid, re-orthonormalised (SVD), centres kept."""
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    turn = pose([0.3, -0.2, 0.7], [1.23456, 0, 0])  # not exact in 4 decimals
    doc["frames"][1]["transform_matrix"] = np.round(np.linalg.inv(turn), 4).tolist()
    path.write_text(json.dumps(doc))
    back = Trajectory.load_json(path)
    rot = back.viewmats[:, :3, :3]
    np.testing.assert_allclose(
        rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12
    )
    np.testing.assert_allclose(back.viewmats[1], turn, atol=1e-3)
    np.testing.assert_allclose(back.centers[1], [1.2346, 0, 0], atol=1e-12)


def test_json_singular_or_bent_pose_names_file_frame_and_deviation(tmp_path, two_poses):
    """Checked before inverting: an all-zero matrix is no "Singular matrix" naming nothing."""
    path = tmp_path / "trajectory.json"
    two_poses.save_json(path)
    doc = json.loads(path.read_text())
    doc["frames"][1]["transform_matrix"] = [[0.0] * 4] * 4
    path.write_text(json.dumps(doc))
    with pytest.raises(
        ValueError, match=r"trajectory.json: the pose of frame 1 is not rigid.* = 1 "
    ):
        Trajectory.load_json(path)


def test_one_rigidity_rule_reports_the_worst_matrix():
    matrices = np.stack([np.eye(4)] * 4)  # [4, 4, 4]
    matrices[1, 0, 0] = 1.002  # bent by 4e-3
    matrices[2, 0, 0] = 1.3  # the worst
    matrices[3, 0, 0] = 1.0004  # rounding: kept
    with pytest.raises(ValueError, match=r"src: the pose of view 2 .* = 0.69 .*refused: \[1, 2\]"):
        rigid_c2w(matrices, "src")
    with pytest.raises(ValueError, match=r"src: the pose of view 2 "):
        check_rigid(matrices, "src")
    np.testing.assert_allclose(
        rigid_c2w(matrices[[0, 3]], "src"), np.stack([np.eye(4)] * 2), atol=1e-12
    )
    check_rigid(matrices[3], "src")
    for bad, message in (
        (np.diag([1.0, 1, -1, 1]), "det R = -1"),
        (np.full((4, 4), np.nan), "NaN"),
    ):
        with pytest.raises(ValueError, match=f"src: the pose is not rigid.*{message}"):
            rigid_c2w(bad, "src")


def test_project_points_pinhole():
    """A point on the optical axis lands on the principal point, one to the side at f·x/z from
    it; a point behind the camera or at its centre has no position (NaN), only its depth."""
    K = np.array([[100.0, 0, 40.5], [0, 120.0, 30.25], [0, 0, 1]])
    eye, target = np.array([0.0, -5, 1]), np.array([0.0, 0, 1])
    viewmat = look_at(eye, target)
    right, down = viewmat[0, :3], viewmat[1, :3]  # the camera's x and y axes in the world
    points = np.stack([target, target + 0.5 * right - 0.25 * down, 2 * eye - target, eye])  # [4, 3]
    pixels, depth = project_points(points, np.stack([viewmat, viewmat]), K)  # [2, 4, 2], [2, 4]
    assert pixels.shape == (2, 4, 2) and depth.shape == (2, 4)
    np.testing.assert_allclose(depth[0], [5, 5, -5, 0], atol=1e-12)
    np.testing.assert_allclose(pixels[0, 0], [40.5, 30.25], atol=1e-12)
    np.testing.assert_allclose(pixels[0, 1], [40.5 + 100 * 0.1, 30.25 - 120 * 0.05], atol=1e-12)
    assert np.isnan(pixels[:, 2:]).all() and np.array_equal(pixels[0], pixels[1], equal_nan=True)
    # in the camera's plane off its axis (depth 0): no position either (z >= 0 dividing by it
    # gave inf there, and the centre's 0 / 0 NaN hid it)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nor numpy's divide-by-zero warning
        pixels, depth = project_points((eye + right)[None], viewmat[None], K)
    assert depth[0, 0] == pytest.approx(0, abs=1e-12) and np.isnan(pixels).all()


def test_point_parts_hold_at_most_their_size_and_every_point_in_order():
    """A cloud one point over a part's size is two parts (floor division made it one part of
    all the points, the whole cloud's temporaries that the parts exist to bound)."""
    points = np.arange(3 * 11, dtype=np.float64).reshape(11, 3)
    for size, lengths in ((5, [4, 4, 3]), (10, [6, 5]), (11, [11]), (20, [11])):
        parts = point_parts(points, size)
        assert [len(p) for p in parts] == lengths, size
        np.testing.assert_array_equal(np.concatenate(parts), points)
    assert len(point_parts(np.zeros((0, 3)))) == 1


def test_pixels_in_view_floors_to_the_pixel_holding_the_point():
    """OpenCV pixel centres at +0.5: a point projected at u = 3.7 lies in pixel column 3, one at
    u = -0.3 left of the image and one at u = width + 0.5 right of it (round() put the first in
    column 4 and the second in column 0; `u <= width` counted the third as inside)."""
    K = np.array([[10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 1.0]])  # pixel = 10 * x / z
    width, height = 8, 6
    # at depth 1, pixel (u, v) = (10 x, 10 y)
    points = np.array(
        [
            [0.37, 0.22, 1.0],  # (3.7, 2.2): pixel (3, 2)
            [-0.03, 0.22, 1.0],  # u = -0.3: outside (left)
            [0.85, 0.22, 1.0],  # u = 8.5 = width + 0.5: outside (right)
            [0.797, 0.597, 1.0],  # (7.97, 5.97): the last pixel (7, 5), inside
            [0.37, 0.22, -1.0],  # behind the camera
        ]
    )
    u, v, inside = pixels_in_view(points, np.eye(4)[None], K, width, height)
    assert (u[0, 0], v[0, 0]) == (3.0, 2.0)
    assert (u[0, 3], v[0, 3]) == (7.0, 5.0)
    assert inside[0].tolist() == [True, False, False, True, False]


def test_a_camera_file_stating_another_focal_by_one_percent_warns(tmp_path):
    """read_camera_doc warns where trajectory.json / test_views.json state a camera 1 % off the
    dataset's (a wrong file edited); rounding (1e-3 relative) passes. A tolerance of 10 % let
    the 1 % one through silently."""
    path = tmp_path / "trajectory.json"
    doc = {"convention": CONVENTION, "fl_x": 101.0, "cx": 32.02, "frames": []}
    path.write_text(json.dumps(doc))
    with pytest.warns(UserWarning, match="fl_x 101.0"):
        read_camera_doc(path, {"fl_x": 100.0, "cx": 32.0})
    doc["fl_x"] = 100.04  # rounding: silent
    path.write_text(json.dumps(doc))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_camera_doc(path, {"fl_x": 100.0, "cx": 32.0})
