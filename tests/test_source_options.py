"""Keyword options of the ground-truth sources that no caller passes: each one takes effect.

Trajectory.spiral(start_azimuth_deg), RenderSource(fov_deg, distance, elevation_deg),
FrameSequenceSource.from_transforms(background, test_path, center, radius)
and the built-in scenes' seed.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from spikegs.data import SCENES, ProceduralSource
from spikegs.data.sources import (
    FrameSequenceSource,
    RenderSource,
    warn_if_names_order_the_path,
)
from spikegs.data.trajectory import Trajectory, look_at, orbit_eye
from spikegs.data.transforms_file import OPENGL_TO_OPENCV
from spikegs.data.view_geometry import optical_axes
from spikegs.image_io import write_image


def azimuth_elevation(points, center) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth (degrees, in [0, 360)), elevation (degrees) and distance of points [P, 3] about
    `center` (+z up), as `orbit_eye` places them."""
    offset = np.asarray(points) - np.asarray(center)
    distance = np.linalg.norm(offset, axis=1)
    azimuth = np.degrees(np.arctan2(offset[:, 1], offset[:, 0])) % 360
    elevation = np.degrees(np.arcsin(offset[:, 2] / distance))
    return azimuth, elevation, distance


def assert_look_at(viewmats, target) -> None:
    """Each camera's optical axis passes through `target`."""
    eyes, dirs, _ = optical_axes(np.asarray(viewmats))
    to_target = np.asarray(target) - eyes
    to_target /= np.linalg.norm(to_target, axis=1, keepdims=True)
    np.testing.assert_allclose(dirs, to_target, atol=1e-9)


# --- Trajectory.spiral(start_azimuth_deg) ------------------------------------------------------


@pytest.mark.parametrize("start", [123.0, -90.0])
def test_spiral_starts_at_the_given_azimuth(start):
    target = (1.0, -2.0, 0.5)

    def spiral(**start_option) -> Trajectory:  # 11 readouts, 2 degrees each, at 20 degrees
        return Trajectory.spiral(
            11,
            radius=3.0,
            start_elevation_deg=20.0,
            end_elevation_deg=20.0,
            degrees_per_readout=2.0,
            look_at=target,
            **start_option,
        )

    traj = spiral(start_azimuth_deg=start)
    azimuth, elevation, distance = azimuth_elevation(traj.centers, target)
    assert azimuth[0] == pytest.approx(start % 360, abs=1e-9)  # the first pose
    np.testing.assert_allclose(azimuth, (start + 2.0 * traj.readouts) % 360, atol=1e-9)
    np.testing.assert_allclose(elevation, 20.0, atol=1e-9)
    np.testing.assert_allclose(distance, 3.0, atol=1e-9)
    assert_look_at(traj.viewmats, target)
    # the default start is azimuth 0: the option moves the path, it does not only relabel it
    assert azimuth_elevation(spiral().centers, target)[0][0] == pytest.approx(0.0, abs=1e-9)


# --- RenderSource(fov_deg, distance, elevation_deg) --------------------------------------------
# No concrete source forwards distance or elevation_deg (ProceduralSource passes none of the
# three, MitsubaSource only fov_deg): a minimal subclass reaches RenderSource's own handling.


class ProbeSource(RenderSource):
    """A RenderSource whose render is blank: only its cameras are under test."""

    name, kind = "probe", "probe"

    def render(self, viewmat: np.ndarray) -> np.ndarray:
        return np.zeros((self.height, self.width, self.channels), np.float32)


CENTER = np.array([0.5, -1.0, 2.0])


def test_render_source_fov_sets_the_focal():
    """fov_deg spans the frame's shorter side, wide or tall: a 250x400 frame framed by its
    width cut the scene off at the top or bottom in 11 of 16 test views."""
    wide = ProbeSource(64, 48, 1, CENTER, 2.0, fov_deg=90.0)
    np.testing.assert_allclose(wide.K, [[24.0, 0, 32.0], [0, 24.0, 24.0], [0, 0, 1]], atol=1e-9)
    tall = ProbeSource(48, 64, 1, CENTER, 2.0, fov_deg=90.0)
    np.testing.assert_allclose(tall.K, [[24.0, 0, 24.0], [0, 24.0, 32.0], [0, 0, 1]], atol=1e-9)
    narrow = ProbeSource(64, 48, 1, CENTER, 2.0, fov_deg=20.0)
    assert narrow.K[0, 0] == pytest.approx(24.0 / np.tan(np.radians(10.0)))
    assert narrow.K[1, 1] == narrow.K[0, 0]  # square pixels
    # a point at half the field of view off the axis projects onto the image's edge (y = height)
    cam = np.array([0.0, np.tan(np.radians(10.0)), 1.0])
    assert (narrow.K @ cam)[1] / cam[2] == pytest.approx(48.0)
    # the default is 40 degrees
    default = ProbeSource(64, 48, 1, CENTER, 2.0)
    assert default.K[0, 0] == pytest.approx(24.0 / np.tan(np.radians(20.0)))
    # a strip or a line of pixels sees 120° along its length (40° across its one pixel made the
    # focal 1.4 px, a ~180° view that is refused), with no jump where that takes over (~4.76:1)
    line = ProbeSource(1000, 1, 1, CENTER, 2.0)
    assert line.K[0, 0] == pytest.approx(500.0 / np.tan(np.radians(60.0)))
    for width in (474, 478):  # 4.74:1 and 4.78:1
        strip = ProbeSource(width, 100, 1, CENTER, 2.0)
        focal = max(50 / np.tan(np.radians(20)), width / 2 / np.tan(np.radians(60)))
        assert strip.K[0, 0] == pytest.approx(focal)


def test_render_source_distance_is_in_scene_radii():
    source = ProbeSource(16, 16, 1, CENTER, 2.0, distance=4.0)
    traj = source.trajectory(101, 1.5)
    _, _, distance = azimuth_elevation(traj.centers, CENTER)
    np.testing.assert_allclose(distance, 8.0, atol=1e-9)  # 4 radii of 2
    assert_look_at(traj.viewmats, CENTER)
    views = source.off_path_views(3)  # on a circle 1.2 times as wide
    viewmats = np.stack([v for _, v, _ in views])
    np.testing.assert_allclose(azimuth_elevation(optical_axes(viewmats)[0], CENTER)[2], 9.6)
    assert_look_at(viewmats, CENTER)
    # the default: 2.5 radii
    default = ProbeSource(16, 16, 1, CENTER, 2.0).trajectory(101, 1.5)
    np.testing.assert_allclose(azimuth_elevation(default.centers, CENTER)[2], 5.0, atol=1e-9)


def test_render_source_elevation_bounds_the_spiral():
    source = ProbeSource(16, 16, 1, CENTER, 2.0, elevation_deg=(-15.0, 65.0))
    traj = source.trajectory(101, 1.0)
    _, elevation, _ = azimuth_elevation(traj.centers, CENTER)
    assert elevation[0] == pytest.approx(-15.0) and elevation[-1] == pytest.approx(65.0)
    np.testing.assert_allclose(elevation, -15.0 + 80.0 * traj.readouts / 100, atol=1e-9)
    views = source.off_path_views(4)  # at mid elevation
    viewmats = np.stack([v for _, v, _ in views])
    _, off_elevation, _ = azimuth_elevation(optical_axes(viewmats)[0], CENTER)
    np.testing.assert_allclose(off_elevation, 25.0, atol=1e-9)
    assert [name for name, _, _ in views] == ["off_000", "off_001", "off_002", "off_003"]


def test_procedural_source_gets_the_render_defaults():
    """The built-in scenes' source cannot pass the options: it has the defaults (2.5 radii,
    10-50 degrees of elevation, a 40-degree field of view)."""
    scene = SCENES["fine-texture"]()
    source = ProceduralSource("fine-texture", scene, 32, 24)
    traj = source.trajectory(51, 1.0)
    _, elevation, distance = azimuth_elevation(traj.centers, scene.center)
    np.testing.assert_allclose(distance, 2.5 * scene.radius, rtol=1e-9)
    assert elevation[0] == pytest.approx(10.0) and elevation[-1] == pytest.approx(50.0)
    assert source.K[0, 0] == pytest.approx(12.0 / np.tan(np.radians(20.0)))  # 24 px high


# --- FrameSequenceSource.from_transforms(background, test_path, center, radius) -----------------

SIZE = 8
FOV_X = 1.0  # radians
RING = np.array([1.0, 2.0, 0.5])  # the point the cameras look at, from 3 units away
COLOUR, ALPHA = 0.1, 0.25  # every frame's colour (premultiplied in EXR) and alpha


def ring_viewmats(azimuths, elevation: float = 20.0) -> np.ndarray:
    """Viewmats [P, 4, 4] of cameras 3 units from RING at `azimuths` (degrees), looking at it."""
    return np.stack([look_at(orbit_eye(RING, 3.0, a, elevation), RING) for a in azimuths])


def write_transforms(
    path,
    folder: str,
    viewmats,
    colour: float = COLOUR,
    fov_x: float | None = FOV_X,
    size: int = SIZE,
    **extra,
):
    """A NeRF-style transforms JSON at `path` (OpenGL camera-to-world, extensionless file paths;
    camera_angle_x `fov_x` unless None) with one RGBA EXR of `colour` (premultiplied) at ALPHA,
    `size` pixels square, per pose, in `folder` beside it."""
    (path.parent / folder).mkdir(parents=True, exist_ok=True)
    frames = []
    for i, viewmat in enumerate(viewmats):
        image = np.empty((size, size, 4), np.float32)
        image[..., :3], image[..., 3] = colour, ALPHA
        write_image(path.parent / folder / f"r_{i}.exr", image)
        c2w = np.linalg.inv(viewmat) @ OPENGL_TO_OPENCV  # OpenCV -> OpenGL camera axes
        frames.append({"file_path": f"{folder}/r_{i}", "transform_matrix": c2w.tolist()})
    camera = {} if fov_x is None else {"camera_angle_x": fov_x}
    path.write_text(json.dumps({**camera, **extra, "frames": frames}))


@pytest.fixture
def nerf_dir(tmp_path):
    """transforms.json (4 frames), a sibling transforms_test.json (2 frames of colour 0.2) and
    held_out.json (3 frames of colour 0.3 at other poses)."""
    write_transforms(tmp_path / "transforms.json", "train", ring_viewmats([0, 90, 180, 270]))
    write_transforms(tmp_path / "transforms_test.json", "test", ring_viewmats([30, 200]), 0.2)
    held_out = ring_viewmats([45, 135, 225], elevation=35.0)
    write_transforms(tmp_path / "held_out.json", "held", held_out, 0.3)
    return tmp_path


@pytest.mark.parametrize("background", [None, 0.0, 0.5])
def test_from_transforms_background_fills_transparent_pixels(nerf_dir, background):
    options = {} if background is None else {"background": background}
    source = FrameSequenceSource.from_transforms(
        nerf_dir / "transforms.json", SIZE, SIZE, 3, **options
    )
    expected = COLOUR + (1.0 if background is None else background) * (1 - ALPHA)  # over bg
    assert source.frames.shape == (4, SIZE, SIZE, 3)
    np.testing.assert_allclose(source.frames, expected, atol=1e-6)
    tests = source.off_path_views(5)  # the test frames are composited on it too
    assert len(tests) == 2
    for _, _, image in tests:
        np.testing.assert_allclose(image, 0.2 + (expected - COLOUR), atol=1e-6)


def test_from_transforms_test_path_replaces_the_sibling(nerf_dir):
    sibling = FrameSequenceSource.from_transforms(nerf_dir / "transforms.json", SIZE, SIZE, 1)
    np.testing.assert_allclose(
        np.stack([v for _, v, _ in sibling.off_path_views(5)]), ring_viewmats([30, 200]), atol=1e-9
    )
    for test_path in (nerf_dir / "held_out.json", str(nerf_dir / "held_out.json")):
        source = FrameSequenceSource.from_transforms(
            nerf_dir / "transforms.json", SIZE, SIZE, 1, test_path=test_path, background=0.0
        )
        views = source.off_path_views(5)
        assert [name for name, _, _ in views] == ["off_000", "off_001", "off_002"]
        viewmats = np.stack([v for _, v, _ in views])
        np.testing.assert_allclose(viewmats, ring_viewmats([45, 135, 225], 35.0), atol=1e-9)
        for _, _, image in views:
            assert image.shape == (SIZE, SIZE, 1)
            np.testing.assert_allclose(image, 0.3, atol=1e-6)  # mono luma of grey 0.3 over black
        np.testing.assert_allclose(source.viewmats, ring_viewmats([0, 90, 180, 270]), atol=1e-9)


def test_from_transforms_test_path_from_a_file_without_sibling(tmp_path):
    write_transforms(tmp_path / "train.json", "train", ring_viewmats([0, 90, 180, 270]))
    alone = FrameSequenceSource.from_transforms(tmp_path / "train.json", SIZE, SIZE)
    assert alone.off_path_views(5) == []
    write_transforms(tmp_path / "other" / "views.json", "v", ring_viewmats([10]), 0.4)
    source = FrameSequenceSource.from_transforms(
        tmp_path / "train.json", SIZE, SIZE, test_path=tmp_path / "other" / "views.json"
    )
    ((name, viewmat, image),) = source.off_path_views(5)
    assert name == "off_000"
    np.testing.assert_allclose(viewmat, ring_viewmats([10])[0], atol=1e-9)
    np.testing.assert_allclose(image, 0.4 + 1.0 * (1 - ALPHA), atol=1e-6)


def test_from_transforms_test_path_of_another_camera_is_refused(nerf_dir):
    """The test file's intrinsics were dropped: another camera's views were scored with the
    training K."""
    write_transforms(nerf_dir / "wide.json", "wide", ring_viewmats([45, 60]), 0.3, fov_x=1.5)
    (nerf_dir / "wide" / "r_1.exr").unlink()  # the cameras are compared before it is sought
    with pytest.raises(ValueError, match=r"wide.json: frame 'wide/r_0' has .* differ; one camera"):
        FrameSequenceSource.from_transforms(
            nerf_dir / "transforms.json", SIZE, SIZE, test_path=nerf_dir / "wide.json"
        )


def test_from_transforms_test_path_of_another_distortion_is_refused(nerf_dir):
    """The test file's distortion was not compared with the training file's (its K alone)."""
    write_transforms(nerf_dir / "bent.json", "bent", ring_viewmats([45]), 0.3, k1=-0.2)
    with pytest.raises(ValueError, match=r"bent.json: .* their distortion differs; one camera"):
        FrameSequenceSource.from_transforms(
            nerf_dir / "transforms.json", SIZE, SIZE, test_path=nerf_dir / "bent.json"
        )


def test_from_transforms_test_camera_is_its_own_files_keys(tmp_path):
    """A test file stating its camera takes none of the training file's keys: a wider camera by
    camera_angle_x under a training fl_x (which won, with a warning naming it in the test file)
    is another camera; the error shows the test frame's own keys."""
    focal = SIZE / 2 / np.tan(FOV_X / 2)  # camera_angle_x FOV_X's, in pixels
    write_transforms(tmp_path / "transforms.json", "train", ring_viewmats([0, 90]), fl_x=focal)
    write_transforms(tmp_path / "transforms_test.json", "test", ring_viewmats([45]), fov_x=1.5)
    with pytest.raises(ValueError, match=r"has intrinsics camera_angle_x 1.5 \(fx"):
        FrameSequenceSource.from_transforms(tmp_path / "transforms.json", SIZE, SIZE)


def test_from_transforms_test_camera_in_its_own_images_pixels(tmp_path):
    """Neither file states w, h and the test images are twice the training images' size, the
    test fl_x in their pixels: the same camera (it was measured at the training images' size
    and refused)."""
    focal = SIZE / 2 / np.tan(FOV_X / 2)
    write_transforms(tmp_path / "transforms.json", "train", ring_viewmats([0, 90]), fl_x=focal)
    write_transforms(
        tmp_path / "transforms_test.json",
        "test",
        ring_viewmats([45]),
        fov_x=None,
        size=2 * SIZE,
        fl_x=2 * focal,
    )
    source = FrameSequenceSource.from_transforms(tmp_path / "transforms.json", SIZE, SIZE)
    assert [name for name, *_ in source.off_path_views(5)] == ["off_000"]
    np.testing.assert_allclose(source.K[0, 0], focal, rtol=1e-6)


def test_from_transforms_test_path_stating_one_camera_otherwise(nerf_dir):
    """A test file stating the training camera by other keys (instant-ngp's camera_angle_y, cx, cy
    at twice the resolution) is the same camera."""
    fov_y = 2 * np.arctan(np.tan(FOV_X / 2))  # square images: the same angle in y
    stated = {"camera_angle_y": fov_y, "cx": SIZE, "cy": SIZE, "w": 2 * SIZE, "h": 2 * SIZE}
    write_transforms(nerf_dir / "same.json", "same", ring_viewmats([45]), 0.3, **stated)
    source = FrameSequenceSource.from_transforms(
        nerf_dir / "transforms.json", SIZE, SIZE, test_path=nerf_dir / "same.json"
    )
    assert [name for name, *_ in source.off_path_views(5)] == ["off_000"]


def test_from_transforms_scene_sphere_options(nerf_dir):
    path = nerf_dir / "transforms.json"
    computed = FrameSequenceSource.from_transforms(path, SIZE, SIZE)  # the views' own sphere
    np.testing.assert_allclose(computed.scene_center, RING, atol=1e-9)
    assert computed.scene_radius == pytest.approx(3.0 / 2.5)

    given = FrameSequenceSource.from_transforms(
        path, SIZE, SIZE, center=[0.0, 0.0, 0.25], radius=0.75
    )
    np.testing.assert_array_equal(given.scene_center, [0.0, 0.0, 0.25])
    assert given.scene_radius == 0.75

    alone = FrameSequenceSource.from_transforms(path, SIZE, SIZE, radius=0.75)  # keeps the centre
    np.testing.assert_allclose(alone.scene_center, RING, atol=1e-9)
    assert alone.scene_radius == 0.75

    with pytest.raises(ValueError, match="a scene centre needs its radius"):
        FrameSequenceSource.from_transforms(path, SIZE, SIZE, center=[0.0, 0.0, 0.25])
    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "1"):  # the sphere's size
        with pytest.raises(ValueError, match="scene radius expected a finite number > 0"):
            FrameSequenceSource.from_transforms(path, SIZE, SIZE, radius=bad)
    for bad in ([0.0, 0.0], [0.0, float("nan"), 0.0], ["0", "0", "0"]):
        with pytest.raises(ValueError, match="scene centre expected 3 finite numbers"):
            FrameSequenceSource.from_transforms(path, SIZE, SIZE, center=bad, radius=1.0)


def test_from_transforms_options_override_the_files_sphere(tmp_path):
    path = tmp_path / "transforms.json"
    sphere = {"scene_center": [5.0, 6.0, 7.0], "scene_radius": 2.0}
    write_transforms(path, "train", ring_viewmats([0, 90, 180, 270]), **sphere)
    from_file = FrameSequenceSource.from_transforms(path, SIZE, SIZE)
    np.testing.assert_array_equal(from_file.scene_center, [5.0, 6.0, 7.0])
    assert from_file.scene_radius == 2.0

    given = FrameSequenceSource.from_transforms(path, SIZE, SIZE, center=[1, 1, 1], radius=0.5)
    np.testing.assert_array_equal(given.scene_center, [1.0, 1.0, 1.0])
    assert given.scene_radius == 0.5
    radius_only = FrameSequenceSource.from_transforms(path, SIZE, SIZE, radius=0.5)
    np.testing.assert_array_equal(radius_only.scene_center, [5.0, 6.0, 7.0])  # the file's
    assert radius_only.scene_radius == 0.5
    center_only = FrameSequenceSource.from_transforms(path, SIZE, SIZE, center=[1, 1, 1])
    np.testing.assert_array_equal(center_only.scene_center, [1.0, 1.0, 1.0])
    assert center_only.scene_radius == 2.0  # the file's


# --- the built-in scenes' seed -----------------------------------------------------------------

FIELDS = ("means", "quats", "scales", "opacities", "colors", "background")


@pytest.mark.parametrize("name", list(SCENES))
def test_scene_seed_sets_the_jitter(name):
    build = SCENES[name]
    a, again, other = build(seed=7), build(seed=7), build(seed=8)
    for field in FIELDS:  # the same seed: the same scene
        np.testing.assert_array_equal(getattr(a, field), getattr(again, field), err_msg=field)
    default, zero = build(), build(seed=0)  # the default is seed 0
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(default, field), getattr(zero, field), err_msg=field)
    changed = [f for f in FIELDS if not np.array_equal(getattr(a, f), getattr(other, f))]
    assert changed, f"{name}: seeds 7 and 8 give the same scene"
    # only the jitter moves: the geometry (means) and the size of the scene stay
    np.testing.assert_array_equal(a.means, other.means)
    assert len(a.means) == len(other.means)


def test_frames_listed_out_of_their_names_time_order_are_warned_of(tmp_path):
    """A frame sequence's list is the simulated camera's time: a file listing its frames in
    another order than their names' (COLMAP's, which nerfstudio sorts by name) made a camera that
    jumps between far views, without a word."""
    path = tmp_path / "transforms.json"
    write_transforms(path, "seq", ring_viewmats(np.arange(0, 80, 10)))  # r_0 .. r_7 in time order
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FrameSequenceSource.from_transforms(path, SIZE, SIZE, 1)
    doc = json.loads(path.read_text())
    doc["frames"] = [doc["frames"][i] for i in (0, 7, 1, 6, 2, 5, 3, 4)]  # the same frames
    path.write_text(json.dumps(doc))
    with pytest.warns(UserWarning, match="times as long as in their file names' order"):
        FrameSequenceSource.from_transforms(path, SIZE, SIZE, 1)


def test_a_frame_sequence_is_named_after_its_folder(tmp_path):
    """A transforms file's scene (meta.json's `scene`, the tables' rows) is its folder's name,
    lego for lego/transforms.json; the file's own name only for a path without a folder (`and`
    for `or`, which named every such scene 'transforms', passed)."""
    path = tmp_path / "lego" / "transforms.json"
    write_transforms(path, "seq", ring_viewmats(np.arange(0, 80, 10)))
    assert FrameSequenceSource.from_transforms(path, SIZE, SIZE, 1).name == "lego"


@pytest.mark.parametrize("keys", [("time",), ("timestamp",), ("time", "timestamp")])
def test_frames_with_times_of_their_own_are_said_unread(tmp_path, keys):
    """D-NeRF's per-frame `time` was ignored unsaid (the frames spread evenly in the listed
    order, whatever their times): named, as not read; a file without one says nothing."""
    path = tmp_path / "seq" / "transforms.json"
    write_transforms(path, "seq", ring_viewmats(np.arange(0, 80, 10)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FrameSequenceSource.from_transforms(path, SIZE, SIZE, 1)
    doc = json.loads(path.read_text())
    for i, frame in enumerate(doc["frames"]):
        frame.update({key: (i / 7) ** 2 for key in keys})
    path.write_text(json.dumps(doc))
    stated = " and ".join(keys)
    with pytest.warns(UserWarning, match=rf"transforms.json: its frames state {stated}, which is "):
        FrameSequenceSource.from_transforms(path, SIZE, SIZE, 1)


def test_a_dollys_frames_listed_out_of_order_are_warned_of(tmp_path):
    """The path is the cameras' centres: a sideways dolly (every camera looking the same way)
    listed out of its names' order is warned of (its optical axes' path, of length 0 for a
    dolly, passed every test: a ring's axes turn as its centres move)."""
    viewmats = np.stack([look_at([x, -3.0, 0.0], [x, 0.0, 0.0]) for x in np.arange(8.0)])
    order = [0, 7, 1, 6, 2, 5, 3, 4]
    names = [f"r_{i}" for i in order]
    with pytest.warns(UserWarning, match="times as long as in their file names' order"):
        warn_if_names_order_the_path(tmp_path / "dolly.json", names, viewmats[order])
