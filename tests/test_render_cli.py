"""The orbit of `spikegs render` (render_cli.py): its radius, elevation and frames, a circle or a
loop over the cameras' span, the up of cameras rolled every way, directions that are not finite,
and the frames' 8-bit values."""

import argparse
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from spikegs import evaluate
from spikegs.data.trajectory import Trajectory, look_at, orbit_eye
from spikegs.image_io import srgb_to_linear
from spikegs.render_cli import dataset_orbit, direction, orbit_frames, orbit_viewmats, world_up

CENTER = np.array([1.0, -2.0, 0.5])


def _looking_in(eyes) -> Trajectory:
    """Cameras at `eyes` [P, 3] looking at CENTER."""
    return Trajectory(np.arange(float(len(eyes))), np.stack([look_at(e, CENTER) for e in eyes]))


def _cameras(distances, elevation_deg=30.0, step_deg=40.0):
    """Upright cameras looking at CENTER from `distances` at azimuths 0, step, 2 step, ... degrees
    and one elevation (+z up)."""
    return _looking_in(
        [orbit_eye(CENTER, d, step_deg * i, elevation_deg) for i, d in enumerate(distances)]
    )


def _eyes(viewmats):
    return np.linalg.inv(viewmats)[:, :3, 3]  # [F, 3] camera centres


def _azimuths_elevations(viewmats) -> tuple[np.ndarray, np.ndarray]:
    """Azimuths and elevations (degrees, +z up) [F] of the eyes of viewmats [F, 4, 4] about
    CENTER."""
    offsets = _eyes(viewmats) - CENTER
    azimuths = np.degrees(np.arctan2(offsets[:, 1], offsets[:, 0]))
    return azimuths, np.degrees(np.arcsin(offsets[:, 2] / np.linalg.norm(offsets, axis=1)))


def test_the_orbit_keeps_the_cameras_mean_distance_and_elevation():
    """Cameras at 3, 3, 3 and 7 units (mean 4, median 3) every 90 degrees, 30 degrees up, surround
    the centre: a circle, every eye 4 from the centre, 2 = 4 sin 30 above it, the first at the
    first camera's azimuth."""
    orbit, path = orbit_viewmats(_cameras([3.0, 3.0, 3.0, 7.0], step_deg=90.0), CENTER, 6)
    offsets = _eyes(orbit) - CENTER  # [6, 3]
    assert path == "circle"
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), 4.0, rtol=1e-9)
    np.testing.assert_allclose(offsets[:, 2], 4.0 * np.sin(np.radians(30.0)), rtol=1e-9)
    np.testing.assert_allclose(offsets[0], orbit_eye((0, 0, 0), 4.0, 0.0, 30.0), atol=1e-9)


def test_the_orbit_frames_are_evenly_spaced_around_the_whole_circle():
    """F frames 360/F degrees apart, turning counter-clockwise about up (right-handed, as the
    azimuth of `orbit_eye`): the last is one step before the first, not on it (a looping video
    would show the first view twice)."""
    frames = 8
    orbit = orbit_viewmats(_cameras([4.0, 4.0, 4.0], step_deg=120.0), CENTER, frames)[0]
    azimuths = _azimuths_elevations(orbit)[0]  # [F]
    steps = np.diff(np.concatenate([azimuths, azimuths[:1] + 360.0])) % 360.0
    np.testing.assert_allclose(steps, 360.0 / frames, atol=1e-9)


@pytest.mark.parametrize("first", [0.0, 170.0])
def test_cameras_over_a_part_of_the_circle_are_looped_over_their_span(first):
    """Cameras over 80 degrees of azimuth (0, 40, 80 from `first`; across +-180 from 170) at
    elevations 10 to 50 leave a 280-degree gap: the path loops within their span of azimuth and
    elevation (a circle showed 280 degrees no camera saw) at their mean distance, around their
    mean; with --path circle, the whole circle."""
    views = ((3, 0, 10), (4, 40, 50), (5, 80, 30))  # distance, azimuth from first, elevation
    cameras = _looking_in([orbit_eye(CENTER, d, first + a, e) for d, a, e in views])
    span, path = orbit_viewmats(cameras, CENTER, 40)
    azimuths, elevations = _azimuths_elevations(span)
    turned = (azimuths - first + 180.0) % 360.0 - 180.0  # from the first camera's azimuth
    assert path == "span"
    assert turned.min() >= -1e-9 and turned.max() <= 80 + 1e-9 and np.ptp(turned) > 40
    assert elevations.min() >= 10 - 1e-9 and elevations.max() <= 50 + 1e-9
    np.testing.assert_allclose([turned.mean(), elevations.mean()], [40.0, 30.0], atol=2.0)
    np.testing.assert_allclose(np.linalg.norm(_eyes(span) - CENTER, axis=1), 4.0, rtol=1e-9)
    circle, path = orbit_viewmats(cameras, CENTER, 40, path="circle")
    assert path == "circle" and np.ptp(_azimuths_elevations(circle)[0] % 360.0) > 350.0


def test_cameras_along_an_ascending_arc_are_followed_to_and_fro():
    """Cameras rising along a spiral's arc (azimuths 0-60, elevations 10-40 with them): the loop
    stays on their line, from one end to the other (an ellipse over their box of azimuths and
    elevations visited its empty corners, at 0 degrees and 40 up), and it is not a circle."""
    cameras = _looking_in([orbit_eye(CENTER, 4.0, a, 10 + a / 2) for a in range(0, 61, 10)])
    span, path = orbit_viewmats(cameras, CENTER, 24)
    azimuths, elevations = _azimuths_elevations(span)
    assert path == "span"
    np.testing.assert_allclose(elevations, 10 + azimuths / 2, atol=1e-9)
    # to within the quarter step's 30 (1 - cos(pi / 48)) = 0.064 degrees of either end (the
    # ends exactly were the clip's, which held the path there for frames running)
    np.testing.assert_allclose([azimuths.min(), azimuths.max()], [0.0, 60.0], atol=0.07)
    assert azimuths.min() >= 0.0 and azimuths.max() <= 60.0


@pytest.mark.parametrize(
    "azimuths, elevations",
    [
        ((0, 40), (20, 20)),  # two cameras
        ((0, 40, 80), (20, 20, 20)),  # three on an arc
        ((170, 250), (10, 40)),  # two, across +-180, rising
        (tuple(range(0, 61, 10)), tuple(10 + a / 2 for a in range(0, 61, 10))),  # a spiral's arc
        ((0, 10, 20, 80), (20, 20, 20, 20)),  # bunched at one end: 27.5 and 52.5 from the mean
    ],
)
def test_no_span_view_shows_twice_running(azimuths, elevations):
    """Few cameras, or a spread not uniform, reach less than sqrt(3) standard deviations from
    their mean: an ellipse that wide, clipped to their extremes, stood still at its ends for
    frames running (a GIF of two cameras' 12 frames held 7); so did one as wide as the farther
    extreme where the cameras bunch at one end (the nearer one bounds it)."""
    cameras = _looking_in([orbit_eye(CENTER, 4.0, a, e) for a, e in zip(azimuths, elevations)])
    viewmats, path = orbit_viewmats(cameras, CENTER, 24)
    steps = np.linalg.norm(np.diff(_eyes(viewmats), axis=0), axis=1)  # [F - 1]
    assert path == "span" and (steps > 1e-6).all()


def test_cameras_spanning_no_views_are_circled():
    """One camera, or cameras at one azimuth and elevation (a dolly towards the centre), span no
    views: a circle, not a video of one view; a camera straight above the centre has no azimuth
    and widens no span (its 90 degrees up made the dolly a span)."""
    for distances in ([4.0], [3.0, 4.0, 5.0]):
        cameras = _looking_in([orbit_eye(CENTER, d, 30.0, 20.0) for d in distances])
        assert orbit_viewmats(cameras, CENTER, 4)[1] == "circle"
    assert orbit_viewmats(cameras, CENTER, 4, path="span")[1] == "span"  # as asked
    above = Trajectory(np.arange(4.0), np.concatenate([cameras.viewmats, _above([3.0])]))
    assert orbit_viewmats(above, CENTER, 4, UP)[1] == "circle"


UP = np.array([0.0, 0.0, 1.0])


def _above(heights) -> np.ndarray:
    """Viewmats [P, 4, 4] of cameras `heights` straight above (negative: below) CENTER, looking
    at it."""
    return np.stack([look_at(CENTER + [0.0, 0.0, h], CENTER, up=(0.0, 1.0, 0.0)) for h in heights])


def test_cameras_without_an_azimuth_take_a_circle_even_when_a_span_is_asked():
    """Cameras straight above and below the centre have no azimuths to span: --path span gives
    the circle at their mean elevation (0) and says it is one."""
    cameras = Trajectory(np.arange(2.0), _above([3.0, -5.0]))
    orbit, path = orbit_viewmats(cameras, CENTER, 8, UP, path="span")
    assert path == "circle"
    np.testing.assert_allclose(_azimuths_elevations(orbit)[1], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(_eyes(orbit) - CENTER, axis=1), 4.0, rtol=1e-9)


def test_a_camera_straight_above_the_centre_leaves_the_span_to_the_others():
    """Cameras at azimuths 100 to 180 and 20 degrees up, and one straight above the centre: the
    span loops over the others' azimuths and elevation (that camera, counted at azimuth 0 and
    90 degrees up, stretched the loop over 0 to 180 and up to the top)."""
    others = np.stack([look_at(orbit_eye(CENTER, 4.0, a, 20.0), CENTER) for a in (100, 140, 180)])
    cameras = Trajectory(np.arange(4.0), np.concatenate([others, _above([4.0])]))
    span, path = orbit_viewmats(cameras, CENTER, 24, UP)
    azimuths, elevations = _azimuths_elevations(span)
    assert path == "span"
    assert azimuths.min() >= 100 - 1e-9 and azimuths.max() <= 180 + 1e-9 and np.ptp(azimuths) > 60
    np.testing.assert_allclose(elevations, 20.0, atol=1e-9)


def test_a_camera_at_the_centre_has_no_elevation_in_the_circles():
    """Cameras 30 degrees up every 90 degrees and one at the centre: the circle is 30 degrees up
    (the centre's camera, counted at 0, lowered it to 24)."""
    cameras = _cameras([4.0] * 4, step_deg=90.0)
    at = look_at(CENTER + [1.0, 0.0, 0.0], CENTER)  # then moved to the centre: t = -R c
    at[:3, 3] = -at[:3, :3] @ CENTER
    with_centre = Trajectory(np.arange(5.0), np.concatenate([cameras.viewmats, at[None]]))
    orbit, path = orbit_viewmats(with_centre, CENTER, 6)
    assert path == "circle"
    np.testing.assert_allclose(_azimuths_elevations(orbit)[1], 30.0, atol=1e-9)


def test_cameras_at_one_azimuth_over_elevations_are_looped_over_them():
    """Cameras at one azimuth, 0 to 60 degrees up (a crane shot), span views: the path goes up and
    down their arc (a circle showed what none saw)."""
    cameras = _looking_in([orbit_eye(CENTER, 4.0, 30.0, e) for e in range(0, 61, 15)])
    span, path = orbit_viewmats(cameras, CENTER, 24, UP)
    azimuths, elevations = _azimuths_elevations(span)
    assert path == "span"
    np.testing.assert_allclose(azimuths, 30.0, atol=1e-9)
    assert elevations.min() >= -1e-9 and elevations.max() <= 60 + 1e-9 and np.ptp(elevations) > 55


def test_the_span_stays_within_the_cameras_extremes():
    """Cameras on a tilted square (azimuths 0 to 20, elevations 10 to 30, its diagonals the
    principal directions): the ellipse over them reaches 1.2 degrees past their extremes in
    azimuth and elevation; the path is kept within them."""
    views = ((0, 10), (20, 30), (5, 25), (15, 15))  # azimuth, elevation
    cameras = _looking_in([orbit_eye(CENTER, 4.0, a, e) for a, e in views])
    span, path = orbit_viewmats(cameras, CENTER, 48, UP)
    azimuths, elevations = _azimuths_elevations(span)
    assert path == "span"
    assert azimuths.min() >= -1e-9 and azimuths.max() <= 20 + 1e-9
    assert elevations.min() >= 10 - 1e-9 and elevations.max() <= 30 + 1e-9


def test_the_span_is_sqrt_3_standard_deviations_wide_within_the_cameras_reach():
    """Cameras at azimuths 0, 30 (eight of them) and 60, level: their standard deviation is
    sqrt(180) degrees (over the cameras, not an unbiased estimate's sqrt(200)), and sqrt(3) of it
    (23.2) is within their reach (30): the loop runs 30 +- 23.2 (times cos(pi / 48), the quarter
    step's nearest frame to either end)."""
    azimuths = [0.0] + [30.0] * 8 + [60.0]
    cameras = _looking_in([orbit_eye(CENTER, 4.0, a, 0.0) for a in azimuths])
    span, path = orbit_viewmats(cameras, CENTER, 24, UP)
    turned = _azimuths_elevations(span)[0]
    assert path == "span"
    half = np.sqrt(3.0 * 180.0) * np.cos(np.pi / 48)
    np.testing.assert_allclose([turned.min(), turned.max()], [30 - half, 30 + half], atol=1e-6)


def test_the_span_is_an_ellipse_over_both_principal_directions():
    """Cameras on a grid of azimuths 0 to 40 and elevations 0 to 20 (its principal directions
    the axes): the loop is the ellipse about (20, 10) with radii 20 and 10 (each their reach,
    under sqrt(3) standard deviations: 24.5 and 14.1) -- not a line along the major axis."""
    views = [(a, e) for a in range(0, 41, 10) for e in (0, 10, 20)]
    cameras = _looking_in([orbit_eye(CENTER, 4.0, a, e) for a, e in views])
    span, path = orbit_viewmats(cameras, CENTER, 24, UP)
    azimuths, elevations = _azimuths_elevations(span)
    assert path == "span"
    radius = np.hypot((azimuths - 20.0) / 20.0, (elevations - 10.0) / 10.0)  # [F]
    np.testing.assert_allclose(radius, 1.0, atol=1e-9)


def test_cameras_straight_along_a_tilted_up_give_a_finite_circle():
    """Cameras straight above and below the centre along 40 tilted ups: their offsets' share
    along the up, rounded, passes +-1 for some, clipped before its arcsine (else a NaN
    elevation, and a NaN orbit)."""
    for up in Rotation.random(40, random_state=1).apply(UP):
        eyes = [CENTER + 3.0 * up, CENTER - 4.0 * up]
        hint = np.eye(3)[np.argmin(np.abs(up))]  # an axis across the up
        cameras = Trajectory(np.arange(2.0), np.stack([look_at(e, CENTER, hint) for e in eyes]))
        orbit, path = orbit_viewmats(cameras, CENTER, 4, up)
        assert path == "circle" and np.isfinite(orbit).all()


def test_cameras_pitched_alike_show_their_mean_up():
    """Cameras at one azimuth pitched -30 to 30 degrees towards the centre (a crane shot) all
    share a level right axis, which leaves the up open within the plane across it: their mean
    up, +z, completes it (the first camera's alone is 30 degrees off)."""
    cameras = _looking_in([orbit_eye(CENTER, 4.0, 30.0, e) for e in (-30, -15, 0, 15, 30)])
    np.testing.assert_allclose(world_up(np.linalg.inv(cameras.viewmats)), UP, atol=1e-9)


def test_cameras_straight_above_the_centre_circle_just_off_the_pole():
    """Cameras straight above the centre along the given up (a top-down capture with --up along
    their view) have no azimuth: a circle at their mean elevation, 90 degrees, put every eye on
    the pole and look_at refused it; now at TOP_DEG (89), the view turning about the up."""
    cameras = Trajectory(np.arange(2.0), _above([3.0, 4.0]))
    for path in ("auto", "span"):
        orbit, taken = orbit_viewmats(cameras, CENTER, 4, UP, path)
        azimuths, elevations = _azimuths_elevations(orbit)
        assert taken == "circle" and np.isfinite(orbit).all()
        np.testing.assert_allclose(elevations, 89.0, atol=1e-9)
        np.testing.assert_allclose(np.diff(azimuths) % 360.0, 90.0, atol=1e-6)


def test_a_gap_of_120_degrees_is_circled_and_one_over_it_looped():
    """Three cameras 120 degrees apart surround the centre (a circle); 121 degrees apart, one gap
    is 118 and the others 121 (a span) -- the auto choice's threshold, SURROUND_GAP_DEG."""
    assert orbit_viewmats(_cameras([4.0] * 3, step_deg=120.0), CENTER, 4)[1] == "circle"
    assert orbit_viewmats(_cameras([4.0] * 3, step_deg=121.0), CENTER, 4)[1] == "span"


def test_cameras_rolled_every_way_leave_the_world_up_to_the_default():
    """Cameras whose right axes point every way span no level direction: the world's up is
    +z (WORLD_UP), not a NaN orbit."""
    rotations = Rotation.random(12, random_state=0).as_matrix()  # camera to world [12, 3, 3]
    c2w = np.tile(np.eye(4), (12, 1, 1))
    c2w[:, :3, :3] = rotations
    c2w[:, :3, 3] = np.random.default_rng(0).normal(size=(12, 3))
    np.testing.assert_array_equal(world_up(c2w), [0.0, 0.0, 1.0])


@pytest.mark.parametrize("text", ["inf,0,0", "0,-inf,1"])
def test_a_direction_that_is_not_finite_is_refused(text):
    with pytest.raises(argparse.ArgumentTypeError, match="non-zero direction"):
        direction(text)


def test_an_up_with_a_leading_minus_sign_is_read_as_a_value():
    """`--up -1,0,0` was argparse's "expected one argument" (a word starting with a minus sign
    read as an option); `--up=-1,0,0` alone worked."""
    from spikegs.cli import build_parser, joined_vectors

    for command in (["render", "RUN", "--out", "v.gif"], ["simulate", "--out", "D"]):
        for up in ("-1,0,0", "-.5,0,1", "0,-1,0"):
            args = build_parser().parse_args(joined_vectors([*command, "--up", up]))
            assert np.allclose(args.up, direction(up)), (command, up)
    assert joined_vectors(["render", "R", "--up", "--out", "v.gif"])[2:4] == ["--up", "--out"]


def test_an_up_with_the_recorded_path_is_refused_before_any_work(tmp_path, capsys):
    """--up with --path trajectory was ignored without a word (the video byte-identical to one
    without it): refused, before the run is looked for."""
    from spikegs.cli import main

    argv = ["render", str(tmp_path / "no-run"), "--out", str(tmp_path / "v.gif")]
    assert main([*argv, "--path", "trajectory", "--up", "1,0,0"]) == 2
    assert "--up sets the axis of an orbit" in capsys.readouterr().err
    assert main([*argv, "--path", "circle", "--up", "1,0,0"]) == 2  # then: the run is missing
    assert "--up" not in capsys.readouterr().err


def test_orbit_frames_round_to_the_nearest_8_bit_value(monkeypatch):
    """Each frame is the render sRGB-encoded and rounded to 8 bits (not truncated), a mono render
    repeated on R, G and B: renders of sRGB 100.53/255 and 100.47/255 give 101 and 100 (halves
    round up)."""
    values = np.array([100.53, 100.47]) / 255.0
    mono = np.empty((2, 3, 1))
    mono[0], mono[1] = srgb_to_linear(values[0]), srgb_to_linear(values[1])  # rows: [2, 3, 1]
    monkeypatch.setattr(evaluate, "render_view", lambda model, viewmat, dataset: mono)
    dataset = SimpleNamespace(trajectory=_cameras([4.0, 4.0]), scene_center=CENTER, meta={})
    frames = np.stack(list(orbit_frames(None, dataset, dataset_orbit(dataset, 2)[0])))
    assert frames.dtype == np.uint8 and frames.shape == (2, 2, 3, 3)
    assert (frames[:, 0] == 101).all() and (frames[:, 1] == 100).all()


def test_orbit_frames_turn_about_the_up_the_dataset_was_simulated_with(monkeypatch):
    """meta.json's `up` (simulate --up) is the orbit's axis where --up is not given, the
    cameras' up where it is null or absent; --up wins over both."""
    eyes = []
    monkeypatch.setattr(
        evaluate,
        "render_view",
        lambda model, viewmat, dataset: (
            eyes.append(np.linalg.inv(viewmat)[:3, 3]) or np.zeros((1, 1, 1))
        ),
    )

    def axis(meta, up=None):
        """The orbit's axis: the normal of the plane its eyes lie in."""
        eyes.clear()
        dataset = SimpleNamespace(trajectory=_cameras([4.0] * 5), scene_center=CENTER, meta=meta)
        list(orbit_frames(None, dataset, dataset_orbit(dataset, 8, up, "circle")[0]))
        normal = np.linalg.svd(np.stack(eyes) - np.mean(eyes, axis=0))[2][-1]
        return normal * np.sign(normal @ [1.0, 1.0, 1.0])

    np.testing.assert_allclose(axis({"up": [0.0, 2.0, 0.0]}), [0.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(axis({"up": None}), [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(axis({}), [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(axis({"up": [0, 2, 0]}, np.array([1.0, 0, 0])), [1, 0, 0], atol=1e-9)
    with pytest.raises(ValueError, match="meta.json's up: expected a non-zero direction"):
        axis({"up": [0, 0, 0]})
