"""Ground-truth sources: procedural scenes, frame sequences (NeRF-style transforms), Mitsuba."""

from __future__ import annotations

import json
import re
import shutil
import sys
import warnings

import numpy as np
import pytest
from scipy import special
from scipy.spatial.transform import Rotation
from spikegs.data import (
    SCENES,
    FrameSequenceSource,
    ProceduralSource,
    load_dataset,
    make_source,
    real,
    simulate_dataset,
)
from spikegs.data.scenes import GaussianScene
from spikegs.data.sources import MissingDependencyError, MitsubaSource, import_mitsuba
from spikegs.data.trajectory import check_rigid, look_at
from spikegs.data.transforms_file import (
    OPENGL_TO_OPENCV,
    frame_columns,
    read_frame,
    read_transforms_doc,
    transforms_viewmats,
)
from spikegs.data.view_geometry import (
    AXES_SPREAD_MIN,
    centre_of_view,
    converging_centre,
    view_sphere,
)
from spikegs.image_io import LUMA_709, srgb_to_linear, write_image
from spikegs.rasterize import MAX_SIZE
from spikegs.spikes import save_dat

# the warnings of a frame sequence whose frames lie 100 readouts apart, ~1 degree a readout
MOTION = (
    r"33\.\d pixels between two frames of the sequence",
    r"the camera turns up to 32\.\d° in 33 readouts",
)


def _said(caught, *patterns) -> None:
    """Each regular expression of `patterns` matches one of the warnings `caught`."""
    messages = [str(w.message) for w in caught]
    for pattern in patterns:
        assert any(re.search(pattern, m) for m in messages), (pattern, messages)


@pytest.mark.parametrize("name", list(SCENES))
def test_procedural_scenes(name):
    scene = SCENES[name]()
    assert len(scene.means) > 1000 and np.isfinite(scene.means).all()
    assert 0 <= scene.colors.min() and scene.colors.max() <= 1
    np.testing.assert_array_equal(SCENES[name]().colors, scene.colors)  # fixed by the seed
    mono = ProceduralSource(name, scene, 40, 30)
    rgb = ProceduralSource(name, scene, 40, 30, channels=3)
    viewmat = mono.trajectory(100, 1.0).pose_at(50.0)
    gray, color = mono.render(viewmat), rgb.render(viewmat)
    assert gray.shape == (30, 40, 1) and color.shape == (30, 40, 3) and gray.dtype == np.float32
    np.testing.assert_allclose(gray[..., 0], color @ LUMA_709, atol=1e-5)  # Rec. 709 luma
    assert gray.std() > 0.02  # the scene is in view


def _splat_scene(sigma_px: float, opacity: float, focal: float, depth: float) -> GaussianScene:
    """A white round Gaussian `depth` ahead of a camera at the origin looking along +z, whose
    image has std `sigma_px` pixels at `focal`, and a second one behind the camera (culled), so
    that the scene has a radius."""
    sigma = sigma_px * depth / focal
    return GaussianScene(
        means=np.array([[0.0, 0.0, depth], [0.0, 0.0, -depth]]),
        quats=np.array([[1.0, 0, 0, 0]] * 2),
        scales=np.full((2, 3), sigma),
        opacities=np.full(2, opacity),
        colors=np.ones((2, 3)),
        background=np.zeros(3),
    )


def _box_means(opacity, var, centre, width, height) -> np.ndarray:
    """Each pixel's mean over its unit box of opacity · exp(-|x - centre|² / (2 var)), pixel i
    spanning [i, i + 1) on each axis (centres at +0.5): [height, width]."""

    def mass(side, c):  # [side]: each pixel's share of a unit-peak 1D Gaussian's integral
        return np.diff(special.ndtr((np.arange(side + 1) - c) / np.sqrt(var))) * np.sqrt(
            2 * np.pi * var
        )

    return opacity * mass(height, centre[1])[:, None] * mass(width, centre[0])[None, :]


def test_a_built_in_scene_s_pixels_take_their_box_s_mean_light_at_spp():
    """spp = s² draws s×s samples a pixel and averages them: each pixel the mean of a sub-pixel
    Gaussian over its box (closed form, erf), within the midpoint rule's error; spp 1 (the
    default) samples the centre, widened by the rasterizer's 0.3 px², and misses it by far."""
    focal, width, height = 50.0, 12, 9  # a wide frame: rows and columns told apart
    centre = (6.3, 4.2)  # the splat off the pixel grid, x and y apart
    scene = _splat_scene(0.45, 0.8, focal, depth=3.0)
    K = np.array([[focal, 0, centre[0]], [0, focal, centre[1]], [0, 0, 1]])
    errors = {}
    for spp in (1, 16, 64):
        image = ProceduralSource("splat", scene, width, height, K=K, spp=spp).render(np.eye(4))
        assert image.shape == (height, width, 1) and image.dtype == np.float32
        # the rasterizer widens each fine pixel's splat by 0.3 fine px²: 0.3 / spp px²
        expected = _box_means(0.8, 0.45**2 + 0.3 / spp, centre, width, height)
        errors[spp] = np.abs(image[..., 0] - expected).max()
    assert errors[64] < 0.003 and errors[16] < 0.01, errors  # of a peak of 0.47
    assert errors[1] > 0.05, errors  # (0.09) a point sample of the splat, not its box's light
    colour = ProceduralSource("splat", scene, width, height, channels=3, K=K, spp=16)
    image = colour.render(np.eye(4))
    assert image.shape == (height, width, 3) and colour.spp == 16
    np.testing.assert_array_equal(image[..., :1], image[..., 1:2])  # white: each channel alike


@pytest.mark.parametrize("spp", [0, 2, 8, -4, 2.0, True, "4"])
def test_a_built_in_scene_s_spp_is_a_square(spp):
    with pytest.raises(ValueError, match=r"spp \(--spp\): .* s×s grid, so expected a square"):
        ProceduralSource("solids", SCENES["solids"](), 16, 16, spp=spp)


def test_a_built_in_scene_s_spp_is_refused_where_its_frame_would_pass_the_rasterizer_s_size():
    """Refused when made, not at its first render: the rasterizer's side, s times a frame's."""
    side = MAX_SIZE // 4 + 1
    with pytest.raises(ValueError, match=rf"spp \(--spp\) 16: {side}x4 frames would be drawn at"):
        ProceduralSource("solids", SCENES["solids"](), side, 4, spp=16)
    assert ProceduralSource("solids", SCENES["solids"](), side - 1, 4, spp=16).spp == 16


def test_a_built_in_scene_s_spp_is_refused_where_its_frame_would_fill_half_the_memory(monkeypatch):
    """A frame drawn s times larger needs (C + 3) floats a fine pixel: refused when made where
    that passes half the memory this process may use (it was an allocation of 64 GiB at 64² and
    spp 2048², a machine's whole memory at less), accepted at the half."""
    from spikegs.data import sources

    half = 64 * 4 * 64 * 4 * (3 + 3) * 4  # 64x64 colour at spp 16: 1.5 MiB
    monkeypatch.setattr(sources, "machine_memory", lambda: 2 * half)
    assert ProceduralSource("solids", SCENES["solids"](), 64, 64, channels=3, spp=16).spp == 16
    monkeypatch.setattr(sources, "machine_memory", lambda: 2 * half - 1)
    match = r"spp \(--spp\) 16: 64x64 frames would be drawn at 256x256, 0.0 GiB a frame, over half"
    with pytest.raises(ValueError, match=match):
        ProceduralSource("solids", SCENES["solids"](), 64, 64, channels=3, spp=16)
    assert ProceduralSource("solids", SCENES["solids"](), 64, 64, spp=16).spp == 16  # mono: 1 MiB
    # one sample a pixel (the default): the frames' size is at fault, not spp ("a smaller spp",
    # below the least, was the remedy)
    monkeypatch.setattr(sources, "machine_memory", lambda: 64 * 64 * 4 * 4)
    match = r"height, width \(--height, --width\) 64, 64: frames drawn at their size, .*frames$"
    with pytest.raises(ValueError, match=match) as said:
        ProceduralSource("solids", SCENES["solids"](), 64, 64, spp=1)
    assert "spp" not in str(said.value)


def write_transforms(path, name, frames, viewmats, K, ext):
    """A NeRF-synthetic-style transforms JSON: OpenGL camera-to-world, extensionless file paths."""
    (path.parent / name).mkdir(parents=True, exist_ok=True)
    entries = []
    for i, (frame, viewmat) in enumerate(zip(frames, viewmats)):
        stem = f"{name}/r_{i}"
        write_image(path.parent / (stem + ext), frame)  # linear; an 8-bit file is sRGB-encoded
        c2w = np.linalg.inv(viewmat) @ OPENGL_TO_OPENCV  # OpenCV -> OpenGL camera axes
        entries.append({"file_path": stem, "transform_matrix": c2w.tolist()})
    fov = 2 * np.arctan(K[0, 2] / K[0, 0])
    path.write_text(json.dumps({"camera_angle_x": fov, "frames": entries}))


def test_a_transforms_files_image_folder_is_listed_once(tmp_path, listed_folders):
    """The frames' folder is listed once, not once a frame (a 1000-frame folder: 1000 listings,
    each of 1000 names)."""
    truth = ProceduralSource("solids", SCENES["solids"](), 8, 8)
    poses = truth.trajectory(1001, 0.5).pose_at(np.linspace(0, 1000, 4))  # [4, 4, 4]
    frames = np.stack([truth.render(v) for v in poses])  # [4, 8, 8, 1]
    write_transforms(tmp_path / "transforms.json", "train", frames, poses, truth.K, ".png")
    FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 8, 8)
    assert listed_folders[str(tmp_path / "train")] == 1


def test_frames_named_by_another_case_of_extension_are_said_once_a_folder(tmp_path):
    """file_path r_0.PNG for r_0.png: the warning came twice, once from the first frame read for
    the size, once from the others, where it is one a folder."""
    truth = ProceduralSource("solids", SCENES["solids"](), 8, 8)
    poses = truth.trajectory(1001, 0.5).pose_at(np.linspace(0, 1000, 4))  # [4, 4, 4]
    frames = np.stack([truth.render(v) for v in poses])  # [4, 8, 8, 1]
    write_transforms(tmp_path / "transforms.json", "train", frames, poses, truth.K, ".png")
    doc = json.loads((tmp_path / "transforms.json").read_text())
    for frame in doc["frames"]:
        frame["file_path"] += ".PNG"
    (tmp_path / "transforms.json").write_text(json.dumps(doc))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")  # as a command shows them: once a message and place
        FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 8, 8)
    said = [
        w for w in caught if "frame images named .PNG (file_path), found as .png" in str(w.message)
    ]
    assert len(said) == 1


def test_8_bit_images_hold_srgb_as_they_are_tagged(tmp_path):
    """Eval PNGs, comparison.png and videos held linear values in files tagged sRGB: a mid grey
    (linear 0.216, sRGB 128) was stored as 55 and shown 5.7x too dark."""
    from spikegs.image_io import read_image

    grey = np.full((4, 6, 3), 0.2158605, np.float32)  # sRGB 128 / 255
    write_image(tmp_path / "g.png", grey)
    np.testing.assert_allclose(read_image(tmp_path / "g.png"), 128 / 255, atol=1e-6)  # stored
    np.testing.assert_allclose(read_frame(tmp_path / "g", 0.0), grey, atol=2e-3)  # read back
    write_image(tmp_path / "g.exr", grey)  # float files stay linear
    np.testing.assert_array_equal(read_image(tmp_path / "g.exr"), grey)


def test_a_truncated_image_is_refused_by_name(tmp_path):
    """An image cut short (a copy stopped, a full disk): a ValueError naming the file, where
    OpenImageIO opens it and then reads no pixels, saying nothing why (3.2's readers, which the
    fallback then says; another release may give a reason of its own, said instead)."""
    from spikegs.image_io import _reason, read_image

    for name in ("t.png", "t.exr"):
        write_image(tmp_path / name, np.random.default_rng(0).random((64, 64, 3)))
        whole = (tmp_path / name).read_bytes()
        (tmp_path / name).write_bytes(whole[: len(whole) // 2])
        with pytest.raises(ValueError, match=rf"cannot read .*{name}: \S"):
            read_image(tmp_path / name)
    # (a truncated PNG: libpng's "IDAT: Read error: hit end of file" printed above "gave no reason")
    assert _reason(" \n").startswith("OpenImageIO returned no reason (a truncated file, or no")
    assert _reason(" \n").endswith("its image library may have printed one above)")


def test_frame_sequence_source(tmp_path, monkeypatch):
    truth = ProceduralSource("solids", SCENES["solids"](), 32, 32, channels=3)
    path = truth.trajectory(1001, 0.5)
    train_poses = path.pose_at(np.linspace(0, 1000, 6))  # [6, 4, 4]
    train = np.stack([truth.render(v) for v in train_poses])  # [6, 32, 32, 3]
    test_poses = [v for _, v, _ in truth.off_path_views(2)]
    test = np.stack([truth.render(v) for v in test_poses])
    write_transforms(
        tmp_path / "transforms_train.json", "train", train, train_poses, truth.K, ".exr"
    )
    write_transforms(tmp_path / "transforms_test.json", "test", test, test_poses, truth.K, ".png")

    source = FrameSequenceSource.from_transforms(tmp_path / "transforms_train.json", 32, 32, 3)
    assert source.name == tmp_path.name
    monkeypatch.chdir(tmp_path)  # `--scene .` was named after the file, transforms_train
    assert make_source(".", 32, 32, 3).name == tmp_path.name
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path / "sub")  # and `--scene ..` as ".."
    assert make_source("..", 32, 32, 3).name == tmp_path.name
    np.testing.assert_allclose(source.viewmats, train_poses, atol=1e-6)  # OpenGL -> OpenCV
    np.testing.assert_allclose(source.K, truth.K, rtol=1e-6)
    np.testing.assert_allclose(source.frames, train, atol=1e-6)
    traj = source.trajectory(501, 0.0)
    np.testing.assert_allclose(traj.readouts, np.linspace(0, 500, 6))
    np.testing.assert_allclose(source.image_at(traj, 150.0), train[1] / 2 + train[2] / 2, atol=1e-6)
    (_, v0, im0), _ = source.off_path_views(5)
    # a test file's first 8 of 20 views listed around a ring saw 126° of it (the scene-sources
    # trial): they are taken evenly over its list, named by their place in it
    ring = [(f"off_{i:03d}", test_poses[i % 2], test[i % 2]) for i in range(20)]
    spread = FrameSequenceSource("ring", train, train_poses, truth.K, test_views=ring)
    assert [name for name, *_ in spread.off_path_views(8)] == [
        f"off_{i:03d}" for i in (0, 3, 5, 8, 11, 14, 16, 19)
    ]
    assert len(spread.off_path_views(20)) == len(spread.off_path_views(99)) == 20
    assert spread.off_path_views(0) == [] and spread.off_path_views(1)[0][0] == "off_000"
    np.testing.assert_allclose(v0, test_poses[0], atol=1e-6)
    np.testing.assert_allclose(im0, test[0], atol=0.01)  # 8-bit sRGB, decoded
    # test frames smaller than the dataset were upsampled as its ground truth unsaid (a blurred
    # truth: +2.3 dB for a trial's 32x32 test frames at 64x64); training frames are the light
    with pytest.warns(UserWarning) as said:
        FrameSequenceSource.from_transforms(tmp_path / "transforms_train.json", 64, 64, 3)
    upsampled = r"transforms_test.json: 2 test image\(s\) smaller than the dataset's 64x64 \(first "
    assert [w for w in said if re.search(upsampled + r".*, 32x32\) are upsampled", str(w.message))]
    assert not [w for w in said if "transforms_train.json: " in str(w.message)]
    # a training frame smaller than the others: its light and the on-path truth from it blurred,
    # unsaid (the scene-sources trial)
    small = tmp_path / "small"
    shutil.copytree(tmp_path, small, ignore=shutil.ignore_patterns("small"))
    frame = json.loads((small / "transforms_train.json").read_text())["frames"][3]["file_path"]
    write_image(small / f"{frame}.exr", train[3][::2, ::2])  # 16x16 of 32x32
    with pytest.warns(
        UserWarning,
        match=r"transforms_train.json: 1 frame\(s\) smaller than its largest, 32x32, and than "
        r"the dataset's 32x32 \(first .*, 16x16\) are upsampled to it: their light",
    ):
        FrameSequenceSource.from_transforms(small / "transforms_train.json", 32, 32, 3)
    first = json.loads((small / "transforms_train.json").read_text())["frames"][0]["file_path"]
    write_image(small / f"{first}.exr", train[0][::2, ::2])  # the first small too (a review)
    with pytest.warns(UserWarning, match=r"2 frame\(s\) smaller than its largest, 32x32, and"):
        FrameSequenceSource.from_transforms(small / "transforms_train.json", 32, 32, 3)
    with warnings.catch_warnings():  # at its size, not upsampled (the others downsampled)
        warnings.simplefilter("error")
        FrameSequenceSource.from_transforms(small / "transforms_train.json", 16, 16, 3)

    # two frames naming one image: said (the light at both poses was that one view's, unsaid)
    shared = tmp_path / "shared"
    shared.mkdir()
    write_transforms(shared / "transforms.json", "train", train, train_poses, truth.K, ".exr")
    doc = json.loads((shared / "transforms.json").read_text())
    doc["frames"][4]["file_path"] = doc["frames"][2]["file_path"]
    (shared / "transforms.json").write_text(json.dumps(doc))
    with pytest.warns(UserWarning, match=r"transforms.json: frames 2 and 4 name one image \("):
        FrameSequenceSource.from_transforms(shared / "transforms.json", 32, 32, 3)

    # one frame: said to need two (its axes were said not to converge, then, with a scene sphere
    # given, a stack of [1, H, W, C] refused naming no file)
    single = tmp_path / "single"
    single.mkdir()
    write_transforms(
        single / "transforms.json", "train", train[:1], train_poses[:1], truth.K, ".exr"
    )
    with pytest.raises(ValueError, match=r"transforms.json: 1 frame; a frame sequence needs 2"):
        FrameSequenceSource.from_transforms(single / "transforms.json", 32, 32, 3)
    # two, at the recording's ends, and no test file: no test view, said with the ways to one
    pair = train[[0, 5]], train_poses[[0, 5]]
    write_transforms(single / "transforms.json", "train", *pair, truth.K, ".exr")
    with pytest.raises(
        ValueError, match=r"readouts of the recording's ends hold no on-path view: "
    ):
        simulate_dataset(single / "transforms.json", tmp_path / "two", height=32, width=32)
    # none asked: the plain refusal, not the frames blamed (the scene-sources trial)
    none = {"test_on_path": 0, "test_off_path": 0, "height": 32, "width": 32}
    with pytest.raises(ValueError, match=r"source0': no held-out test view; evaluation and train"):
        simulate_dataset(tmp_path / "transforms_train.json", tmp_path / "none", **none)
    # of a sequence without test frames, none on the path asked: not the frames blamed, and test
    # frames offered only where off-path views are asked (the reviews)
    for off, said in (
        (None, r"\(no on-path view asked, and no test frames: a transforms_test.json beside"),
        (3, r"\(no on-path view asked, and no test frames: a transforms_test.json beside"),
    ):
        with pytest.raises(ValueError, match=said):
            options = {**none, "test_off_path": off}
            simulate_dataset(single / "transforms.json", tmp_path / "none", **options)
    options = {**none, "test_on_path": None}  # the default on-path views, none off it
    with pytest.raises(ValueError, match=r"hold no on-path view: more frames or readouts\)"):
        simulate_dataset(single / "transforms.json", tmp_path / "none", **options)

    # a frame of another aspect ratio than the first is another crop of the view
    cropped = tmp_path / "cropped"
    cropped.mkdir()
    write_transforms(cropped / "transforms.json", "train", train, train_poses, truth.K, ".exr")
    write_image(cropped / "train" / "r_3.exr", train[3][:, :20])
    with pytest.raises(
        ValueError,
        match=r"r_3: image 20x32 .*the camera \(sized as its first frame\) is for 32x32 images",
    ):
        FrameSequenceSource.from_transforms(cropped / "transforms.json", 32, 32, 3)

    # a float frame's round-off below 0 (-1e-7 in one channel: colour was refused, by index into
    # the resized stack, after the output folder was made; mono passed, its luma positive) is
    # set to 0 with one warning naming the file
    for value, file in ((-1e-7, "r_5"), (-0.02, "r_2")):
        write_transforms(cropped / "transforms.json", "train", train, train_poses, truth.K, ".exr")
        frame = train[int(file[-1])].copy()
        frame[10, 20, 0] = value
        frame[0, 0] = 0.0  # black, not below 0: not counted
        write_image(cropped / "train" / f"{file}.exr", frame)
        with pytest.warns(UserWarning, match=rf"1 frame\(s\) hold 1 values below 0 .*{file}"):
            low = FrameSequenceSource.from_transforms(cropped / "transforms.json", 32, 32, 3)
        assert low.frames.min() >= 0 and low.frames[int(file[-1]), 10, 20, 0] == 0
    write_transforms(cropped / "transforms.json", "train", train, train_poses, truth.K, ".exr")
    write_image(cropped / "train" / "r_5.exr", np.where(train[5] < 0.3, 0.0, train[5]))  # black
    with warnings.catch_warnings():  # black, not below 0: nothing to warn of
        warnings.simplefilter("error")
        FrameSequenceSource.from_transforms(cropped / "transforms.json", 32, 32, 3)

    # half resolution, mono: intrinsics scale, luma of the frames
    half = FrameSequenceSource.from_transforms(tmp_path / "transforms_train.json", 16, 16)
    np.testing.assert_allclose(half.K[:2], truth.K[:2] / 2, rtol=1e-6)
    assert half.frames.shape == (6, 16, 16, 1)

    # a dataset from the directory: on-path held-out views are exact frames (the frames are 100
    # readouts apart, ~1 degree a readout, 33 px between frames: flagged twice)
    with pytest.warns(UserWarning) as caught:
        ds = simulate_dataset(
            tmp_path,
            tmp_path / "ds",
            height=32,
            width=32,
            readouts=501,
            test_on_path=2,
            test_off_path=2,
            progress=False,
        )
    _said(caught, *MOTION)
    rate = ds.meta["sim"]["rate_at_one"]
    for view in ds.test_views:
        if view.readout is not None:
            i = int(np.argmin(np.abs(traj.readouts - view.readout)))
            assert view.readout == traj.readouts[i]
            np.testing.assert_allclose(view.image[..., 0], train[i] @ LUMA_709 * rate, atol=1e-6)
    assert [v.readout for v in ds.test_views][2:] == [None, None]
    # more test views than the sequence holds: said; 3 of its 4 frames inside (picks between the
    # ends gave 2 distinct)
    with pytest.warns(UserWarning) as caught:
        simulate_dataset(
            tmp_path, tmp_path / "few", height=32, width=32, readouts=501, test_on_path=3,
            test_off_path=3, progress=False,
        )  # fmt: skip
    _said(caught, "gives 3 on-path and 2 off-path test views of the 3 and 3", *MOTION)
    # the orbit's settings, which a frame sequence's frames and poses set: said to be ignored
    with pytest.warns(UserWarning) as caught:
        again = simulate_dataset(
            tmp_path, tmp_path / "ds2", height=32, width=32, readouts=501, test_on_path=2,
            test_off_path=2, progress=False, speed=0.5, up=[0, 1, 0], spp=4,
        )  # fmt: skip
    _said(caught, r"is a frame sequence, .*: speed, up \(a built-in or Mi", *MOTION)
    _said(caught, r"frame sequence, whose frames are the light: spp \(--spp, .*\) ignored")
    assert again.meta["up"] is None and again.meta["degrees_per_readout"] is None
    assert again.meta["spp"] is None


def test_frame_sequence_frames_are_stored_one_at_a_time(tmp_path, monkeypatch, alive_arrays):
    """Each frame of a sequence goes into the float32 frames as it is resized: the resized frames
    were listed in float64 and stacked, 4 times the frames' memory at once (`spikegs simulate
    --scene DIR`, 200 frames of 800x800 to 400x400 colour: 2.2 GB peak against 1.1). Six colour
    frames halved; at most two resized frames alive at once, and the frames as before."""
    from spikegs.data import transforms_file

    truth = ProceduralSource("solids", SCENES["solids"](), 32, 32, channels=3)
    poses = truth.trajectory(1001, 0.5).pose_at(np.linspace(0, 1000, 6))  # [6, 4, 4]
    frames = np.stack([truth.render(v) for v in poses])  # [6, 32, 32, 3]
    write_transforms(tmp_path / "transforms.json", "train", frames, poses, truth.K, ".exr")
    fitted = transforms_file.fitted

    def counted(*args):
        return alive_arrays.track(fitted(*args))

    monkeypatch.setattr(transforms_file, "fitted", counted)
    source = FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 16, 16, 3)
    assert 1 <= alive_arrays.most <= 2, alive_arrays.most  # (0: frames resized elsewhere)
    assert source.frames.dtype == np.float32 and source.frames.shape == (6, 16, 16, 3)
    monkeypatch.setattr(transforms_file, "fitted", fitted)
    halved = [fitted(f.astype(np.float64), (32, 32), (16, 16), "f") for f in frames]
    np.testing.assert_array_equal(source.frames, np.stack(halved).astype(np.float32))


def test_frame_sequence_missing_image(tmp_path):
    path = tmp_path / "transforms.json"
    path.write_text(
        json.dumps(
            {
                "camera_angle_x": 0.7,
                "frames": [{"file_path": "./train/r_0", "transform_matrix": np.eye(4).tolist()}],
            }
        )
    )
    with pytest.raises(FileNotFoundError, match="r_0"):
        FrameSequenceSource.from_transforms(path, 8, 8)
    with pytest.raises(FileNotFoundError, match="transforms file not found: .*nope.json"):
        make_source(tmp_path / "nope.json", 8, 8, 1)  # was "unknown scene", a .xml "not found"
    # each was "unknown scene 'PATH': expected a built-in scene ..."
    with pytest.raises(FileNotFoundError, match="scene .*nope not found; expected a built-in"):
        make_source(tmp_path / "nope", 8, 8, 1)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="scene folder .*empty holds no transforms_train.json"):
        make_source(tmp_path / "empty", 8, 8, 1)
    (tmp_path / "r_0.png").touch()
    with pytest.raises(ValueError, match=r"scene file .*r_0\.png is neither \.xml nor \.json"):
        make_source(tmp_path / "r_0.png", 8, 8, 1)
    with pytest.raises(ValueError, match="unknown scene 'teapot': expected a built-in"):
        make_source("teapot", 8, 8, 1)
    for empty in ("", " "):  # "" searched the current folder ("scene folder . holds no ...")
        with pytest.raises(ValueError, match=r"^scene \(--scene\): empty; expected a built-in"):
            make_source(empty, 8, 8, 1)
    with pytest.raises(FileNotFoundError, match="transforms file not found: .*T.JSON"):
        make_source(tmp_path / "T.JSON", 8, 8, 1)  # an upper-case suffix: was "unknown scene"
    train_dir = tmp_path / "train"
    train_dir.mkdir()
    write_image(train_dir / "r_0.png", np.zeros((8, 8, 3), np.float32))
    doc = json.loads(path.read_text())
    for key, value in (("camera_angle_x", "wide"), ("fl_x", [1, 2]), ("cx", None)):
        path.write_text(json.dumps({**doc, key: value}))
        with pytest.raises(ValueError, match=f"transforms.json: {key} expected a finite number"):
            FrameSequenceSource.from_transforms(path, 8, 8)


def test_frame_sequence_rounded_poses_made_rigid_and_malformed_files_named(tmp_path):
    """Poses rounded to 3 decimals (as some exporters write them) become exactly rigid, so a
    dataset simulated from them loads; a file that is not an object, or frames that are not
    objects with a path and a matrix, are named."""
    truth = ProceduralSource("solids", SCENES["solids"](), 8, 8)
    poses = truth.trajectory(101, 0.5).pose_at(np.array([0.0, 50.0, 100.0]))  # [3, 4, 4]
    frames = np.stack([truth.render(v) for v in poses])
    path = tmp_path / "transforms.json"
    write_transforms(path, "train", frames, poses, truth.K, ".exr")
    doc = json.loads(path.read_text())
    for f in doc["frames"]:
        f["transform_matrix"] = np.round(f["transform_matrix"], 3).tolist()
    path.write_text(json.dumps(doc))
    source = FrameSequenceSource.from_transforms(path, 8, 8)
    check_rigid(source.viewmats, "rounded")  # within 1e-5 of rigid: loadable test views
    np.testing.assert_allclose(source.viewmats, poses, atol=5e-3)
    bool_pose = [[True, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]
    for text, message in (
        ("[]", "expected a JSON object"),
        (json.dumps({**doc, "frames": ["train/r_0"]}), "frame 0 needs a file_path"),
        (json.dumps({**doc, "frames": [{**doc["frames"][0], "file_path": 3}]}), r"\(text\)"),
        (
            json.dumps({**doc, "frames": [{**doc["frames"][0], "transform_matrix": "I"}]}),
            "frame 0 .*transform_matrix expected 4 rows of 4 numbers",
        ),
        (  # numpy reads a true among numbers as 1
            json.dumps({**doc, "frames": [{**doc["frames"][0], "transform_matrix": bool_pose}]}),
            "frame 0 .*transform_matrix expected 4 rows of 4 numbers",
        ),
    ):
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            FrameSequenceSource.from_transforms(path, 8, 8)


def test_mitsuba_missing_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # import mitsuba -> ImportError
    with pytest.raises(
        MissingDependencyError,
        match=r"pip install mitsuba \(or, in a checkout of spikegs, pip install '\.\[mitsuba\]'\)",
    ):
        import_mitsuba()
    # a mistyped scene file is said to be missing, not Mitsuba (which asked to install it)
    with pytest.raises(FileNotFoundError, match="Mitsuba scene file not found: typo.xml"):
        MitsubaSource("typo.xml", 16, 16)


def test_every_command_reports_a_missing_extra(monkeypatch, tmp_path, capsys):
    """Each command caught it itself (simulate and poses did; a third would have shown a
    traceback): `spikegs` reports it as an error with the install hint."""
    from spikegs.cli import main

    def missing(*args, **kwargs):
        raise MissingDependencyError("pycolmap is needed: pip install 'spikegs[sfm]'")

    monkeypatch.setattr("spikegs.poses_cli.estimate_poses", missing)
    monkeypatch.setattr("spikegs.train_cli.config_from_args", missing)
    for argv in (["poses", str(tmp_path)], ["train", str(tmp_path), "--out", str(tmp_path / "r")]):
        assert main(argv) == 2
        assert "error: pycolmap is needed: pip install 'spikegs[sfm]'" in capsys.readouterr().err


def glowing_ball(center, radius: float, rgb=(1.0, 1.0, 1.0)) -> dict:
    """A Mitsuba scene of one emitting sphere."""
    emitter = {"type": "area", "radiance": {"type": "rgb", "value": list(rgb)}}
    return {
        "type": "scene",
        "integrator": {"type": "path"},
        "ball": {"type": "sphere", "center": list(center), "radius": radius, "emitter": emitter},
    }


def assert_drawn_where_projected(source, viewmat, mask, point) -> np.ndarray:
    """The centroid of `mask` [H, W] is where the source's K projects `point` (pixel centres at
    +0.5), within a pixel; returns `point` in camera coordinates."""
    cam = viewmat[:3, :3] @ point + viewmat[:3, 3]
    expected = (source.K @ cam)[:2] / cam[2]
    rows, cols = np.nonzero(mask)
    np.testing.assert_allclose([cols.mean() + 0.5, rows.mean() + 0.5], expected, atol=1.0)
    return cam


@pytest.fixture
def mitsuba(tmp_path, monkeypatch):
    """mitsuba, with Dr.Jit's kernel cache in a temporary folder: its first import, which reads
    DRJIT_CACHE_DIR, made ~/.drjit (a stamp of its sweep there, and any kernels)."""
    monkeypatch.setenv("DRJIT_CACHE_DIR", str(tmp_path / "drjit"))
    return pytest.importorskip("mitsuba")


def test_mitsuba_source_convention_and_dataset(tmp_path, mitsuba):
    target = np.array([0.3, -0.2, 0.1])
    scene = glowing_ball(target, 0.25, (1.0, 0.5, 0.25))
    source = MitsubaSource(scene, 16, 16, channels=3, spp=1, center=[0, 0, 0], radius=1.0)
    traj = source.trajectory(101, 1.0)
    viewmat = traj.pose_at(60.0)
    with warnings.catch_warnings():  # black, not below 0: nothing to warn of (black warned)
        warnings.simplefilter("error", UserWarning)
        image = source.render(viewmat)  # [16, 16, 3]
    assert image.shape == (16, 16, 3) and (image == 0).any()
    mask = image[..., 0] > 0.5
    assert mask.sum() > 3
    np.testing.assert_allclose(image[mask], [[1.0, 0.5, 0.25]] * mask.sum(), atol=1e-5)
    assert_drawn_where_projected(source, viewmat, mask, target)  # the OpenCV camera model

    ds = simulate_dataset(
        scene,
        tmp_path / "mi",
        height=16,
        width=16,
        readouts=330,
        spp=1,
        test_on_path=2,
        test_off_path=1,
        frame_every=40,
        progress=False,
    )
    assert ds.meta["source"] == "mitsuba" and len(ds.test_views) == 3


def test_mitsuba_draws_a_point_far_off_the_image_centre_where_k_projects_it(mitsuba):
    """A ball 24 and 20 pixels off a 64² image's centre, right and up, lies where K projects it:
    the axes' flip that turns OpenCV's camera into Mitsuba's is exactly -1 (-1.1, which moves a
    point 2.4 pixels there, passed: the other tests' balls lay 2 pixels off the centre)."""
    source = MitsubaSource(
        glowing_ball([0, 0, 0], 0.1), 64, 64, spp=1, center=[0, 0, 0], radius=1.0
    )
    viewmat = source.trajectory(2, 1.0).pose_at(0.0)  # [4, 4] world-to-camera
    depth, pixel = 2.0, np.array([32.0 + 24, 32.0 - 20, 1.0])
    point = viewmat[:3, :3].T @ (depth * np.linalg.solve(source.K, pixel) - viewmat[:3, 3])
    source = MitsubaSource(glowing_ball(point, 0.08), 64, 64, spp=1, center=[0, 0, 0], radius=1.0)
    mask = source.render(viewmat)[..., 0] > 0.5  # [64, 64]
    assert mask.sum() > 3
    assert_drawn_where_projected(source, viewmat, mask, point)


def test_a_mitsuba_scene_is_orbited_about_its_bounding_box(mitsuba):
    """Without a centre and radius given, a Mitsuba scene's sphere is its bounding box's: the
    centre midway (a third of the way passed every test: each gave its centre) and the radius
    half the diagonal."""
    source = MitsubaSource(glowing_ball([1.0, 2.0, -3.0], 0.5), 8, 8, spp=1)
    np.testing.assert_allclose(source.scene_center, [1.0, 2.0, -3.0], atol=1e-5)
    assert source.scene_radius == pytest.approx(0.5 * np.sqrt(3), rel=1e-4)


def test_a_mitsuba_scene_in_any_units_is_drawn(mitsuba):
    """A scene in millimetres or of a radius of 10⁻³ draws as one of radius 1: Mitsuba's own clip
    planes (0.01 and 10⁴) drew them as their background alone, unsaid."""
    images = []
    for scale in (1.0, 2e4, 1e-3):
        source = MitsubaSource(glowing_ball([scale, 0.0, 0.0], scale), 16, 16, spp=1)
        images.append(source.render(source.trajectory(2, 1.0).pose_at(0.0)))  # [16, 16, 1]
    assert (images[0] > 0.5).sum() > 20
    np.testing.assert_allclose(images[1], images[0], atol=1e-3)
    np.testing.assert_allclose(images[2], images[0], atol=1e-3)


def test_up_rotation_turns_z_into_up():
    """The identity, exactly, for +z (the built-in scenes' datasets stay bit for bit), a proper
    rotation taking +z to any other unit vector, -z a half turn."""
    from spikegs.data.trajectory import WORLD_UP, up_rotation

    assert (up_rotation(WORLD_UP) == np.eye(3)).all()
    near = [np.sin(1.5e-6), 0.0, -np.cos(1.5e-6)]  # 1 + cos cancelled to 2e-5 there
    for up in ([0, 1, 0], [0, 0, -1], [-1, 0, 0], np.array([1.0, -2.0, 0.5]) / np.sqrt(5.25), near):
        rot = up_rotation(np.asarray(up, np.float64))
        np.testing.assert_allclose(rot @ WORLD_UP, up, atol=1e-12)
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rot) == pytest.approx(1.0)


def test_mitsuba_orbit_ascends_along_the_scenes_up(tmp_path, mitsuba):
    """A y-up Mitsuba scene (its Cornell box's convention) orbited about +z showed its floor as a
    wall, every view sideways; `up` turns the spiral: the ball above the other (along +y) is
    above it in every view, which it is not about +z."""
    emitter = lambda value: {"type": "area", "radiance": {"type": "rgb", "value": value}}  # noqa: E731
    scene = {
        "type": "scene",
        "integrator": {"type": "path"},
        "top": {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.3, "emitter": emitter(1.0)},
        "low": {"type": "sphere", "center": [0, -0.6, 0], "radius": 0.3, "emitter": emitter(0.3)},
    }

    def heights(up) -> list[float]:
        """The top ball's centroid row minus the low one's, in 6 views along the spiral."""
        source = MitsubaSource(scene, 24, 24, spp=1, center=[0, 0, 0], radius=1.0, up=up)
        trajectory = source.trajectory(100, 3.0)
        rows = np.arange(24)[:, None]
        out = []
        for t in np.linspace(0, 99, 6):
            image = source.render(trajectory.pose_at(t))[..., 0]
            top, low = image > 0.6, (image > 0.1) & (image < 0.6)
            out.append(float((rows * top).sum() / top.sum() - (rows * low).sum() / low.sum()))
        return out

    assert max(heights([0, 1, 0])) < -4  # above, in every view
    assert max(heights([0, 0, 1])) > 0  # about +z: beside it, or below, in some
    ds = simulate_dataset(
        scene, tmp_path / "yup", height=8, width=8, readouts=330, spp=1, test_on_path=1,
        test_off_path=1, frame_every=60, up=[0, 2, 0], progress=False,
    )  # fmt: skip
    assert ds.meta["up"] == [0.0, 1.0, 0.0]
    assert ds.meta["spp"] == 1 and make_source(scene, 8, 8, 1).spp == 16  # given; the default
    with pytest.raises(ValueError, match=r"up: expected a non-zero direction \[x, y, z\]"):
        simulate_dataset(scene, tmp_path / "bad", up=[0, 0, 0], progress=False)
    source = MitsubaSource(scene, 8, 8, spp=1, up=[0, 3, 0])  # a direction: made a unit one
    np.testing.assert_array_equal(source.up, [0, 1, 0])
    with pytest.raises(ValueError, match="up: the source 'mitsuba-dict' given sets its own"):
        simulate_dataset(source, tmp_path / "bad", height=8, width=8, up=[0, 1, 0])
    with pytest.raises(ValueError, match="spp: the source 'mitsuba-dict' given sets its own"):
        simulate_dataset(source, tmp_path / "bad", height=8, width=8, spp=4)


def test_mitsuba_fov_sets_intrinsics_and_the_rendered_view(mitsuba):
    """MitsubaSource's fov_deg (no caller passes it) sets K and the sensor alike."""
    target, ball = np.array([0.15, -0.1, 0.05]), 0.3
    areas = {}
    for fov in (30.0, 60.0):
        source = MitsubaSource(
            glowing_ball(target, ball), 32, 32, spp=1, fov_deg=fov, center=[0, 0, 0], radius=1.0
        )
        focal = 16.0 / np.tan(np.radians(fov / 2))
        assert source.K[0, 0] == pytest.approx(focal) and source.K[1, 1] == pytest.approx(focal)
        viewmat = source.trajectory(2, 1.0).pose_at(0.0)
        mask = source.render(viewmat)[..., 0] > 0.5  # [32, 32]
        cam = assert_drawn_where_projected(source, viewmat, mask, target)
        areas[fov] = mask.sum()
        assert areas[fov] == pytest.approx(np.pi * (focal * ball / cam[2]) ** 2, rel=0.3)
    focal_ratio = np.tan(np.radians(30.0)) / np.tan(np.radians(15.0))
    assert areas[30.0] / areas[60.0] == pytest.approx(focal_ratio**2, rel=0.25)
    for height, width in ((24, 40), (40, 24)):  # the field of view spans the shorter side
        source = MitsubaSource(
            glowing_ball(target, ball), width, height, spp=1, center=[0, 0, 0], radius=1.0
        )
        focal = 12.0 / np.tan(np.radians(20.0))
        assert source.K[0, 0] == pytest.approx(focal)
        viewmat = source.trajectory(2, 1.0).pose_at(0.0)
        mask = source.render(viewmat)[..., 0] > 0.5
        cam = assert_drawn_where_projected(source, viewmat, mask, target)
        assert mask.sum() == pytest.approx(np.pi * (focal * ball / cam[2]) ** 2, rel=0.3)


def test_mitsuba_negative_light_is_set_to_0_with_one_warning(mitsuba):
    """A negative emitter's radiance was set to 0 without a word of ours (as frame files warn)."""
    source = MitsubaSource(glowing_ball([0, 0, 0], 0.5, (-1.0, 0.5, 0.5)), 8, 8, spp=1)
    viewmat = source.trajectory(2, 1.0).pose_at(0.0)
    with pytest.warns(UserWarning, match=r"renders \d+ values below 0 .* lowest -1;.* set to 0"):
        image = source.render(viewmat)
    assert image.min() == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        source.render(viewmat)  # said once


def test_mitsuba_scenes_that_cannot_render_are_named(tmp_path, mitsuba):
    """No integrator: Mitsuba's raw Exception at the first frame; no shapes: a NaN scene centre,
    reported as non-rigid poses; a parse error: a traceback."""
    ball = {"type": "sphere", "radius": 0.5}
    cases = [
        ({"type": "scene", "ball": ball}, "has no integrator"),
        ({"type": "scene", "integrator": {"type": "path"}}, "has no shapes"),
        ({"type": "scene", "ball": {**ball, "type": "no-such-shape"}}, "does not load"),
    ]
    for scene, message in cases:
        with pytest.raises(ValueError, match=message):
            MitsubaSource(scene, 16, 16)
    # a flat scene (one rectangle: no thickness along z) has shapes: accepted
    light = {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
    flat = {"type": "scene", "integrator": {"type": "path"}}
    MitsubaSource({**flat, "card": {"type": "rectangle", "emitter": light}}, 16, 16)
    (tmp_path / "bad.xml").write_text("<scene version='3.0.0'><shape")
    with pytest.raises(ValueError, match="Mitsuba scene 'bad' does not load"):
        MitsubaSource(tmp_path / "bad.xml", 16, 16)
    with pytest.raises(FileNotFoundError, match="Mitsuba scene file not found: .*gone.xml"):
        make_source(tmp_path / "gone.xml", 16, 16, 1)  # `spikegs simulate --scene` mistyped


def test_read_frame_composites_alpha_once_in_linear_light(tmp_path):
    from PIL import Image

    rgba = np.zeros((4, 4, 4), np.uint8)
    rgba[..., :3], rgba[..., 3] = 255, 128  # white at 50 % alpha (colour unassociated in PNG)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "rgba.png")
    np.testing.assert_allclose(read_frame(tmp_path / "rgba", 1.0), 1.0, atol=1e-6)
    np.testing.assert_allclose(read_frame(tmp_path / "rgba", 0.0), 128 / 255, atol=1e-6)
    Image.fromarray(np.zeros((4, 4, 2), np.uint8), "LA").save(tmp_path / "la.png")  # transparent
    np.testing.assert_allclose(read_frame(tmp_path / "la", 0.7), 0.7, atol=1e-6)
    grey = np.full((4, 4, 2), 0.5, np.float32)  # EXR: linear, colour premultiplied by alpha
    write_image(tmp_path / "premultiplied.exr", np.concatenate([grey, grey], axis=2))
    np.testing.assert_allclose(read_frame(tmp_path / "premultiplied", 1.0), 0.5 + 0.5, atol=1e-6)
    Image.fromarray(np.full((4, 4, 3), 255, np.uint8)).save(tmp_path / "photo.jpeg")
    np.testing.assert_allclose(read_frame(tmp_path / "photo", 0.0), 1.0, atol=1e-6)


def _write_tiff(path, pixels, fmt, unassociated, alpha=True):
    """A 2x2 RGBA TIFF of `pixels` [2, 2, 4], alpha (un)associated as its ExtraSamples says
    (`alpha` False: the fourth channel an unspecified extra sample, not alpha)."""
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(2, 2, 4, fmt)
    spec.attribute("oiio:UnassociatedAlpha", int(unassociated))
    if not alpha:
        spec.channelnames, spec.alpha_channel = ("R", "G", "B", "X"), -1
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    out.write_image(np.ascontiguousarray(pixels, np.float32))
    out.close()


def test_read_frame_takes_alpha_association_and_encoding_from_metadata(tmp_path):
    """The same pixel - 60 % grey at 50 % alpha over black - stored three ways in TIFF files:
    16-bit sRGB with alpha unassociated or associated (the encoded value times alpha), float
    linear with alpha associated. Each reads as the same linear colour; a fourth channel that
    the file does not call alpha is left out."""
    import OpenImageIO as oiio

    linear = float(srgb_to_linear(np.array(0.6)))
    rgba = lambda c: np.concatenate(  # noqa: E731
        [np.full((2, 2, 3), c), np.full((2, 2, 1), 0.5)], axis=2
    )
    _write_tiff(tmp_path / "unassociated.tif", rgba(0.6), oiio.UINT16, unassociated=True)
    _write_tiff(tmp_path / "associated.tif", rgba(0.3), oiio.UINT16, unassociated=False)
    _write_tiff(tmp_path / "linear.tif", rgba(0.5 * linear), oiio.FLOAT, unassociated=False)
    for name in ("unassociated", "associated", "linear"):
        np.testing.assert_allclose(
            read_frame(tmp_path / name, 0.0), 0.5 * linear, atol=1e-4, err_msg=name
        )
        np.testing.assert_allclose(
            read_frame(tmp_path / name, 1.0), 0.5 * linear + 0.5, atol=1e-4, err_msg=name
        )
    clear = rgba(0.3)
    clear[1, 1] = 0.0  # associated sRGB, wholly transparent: the background (not 0 / 0)
    _write_tiff(tmp_path / "clear.tif", clear, oiio.UINT16, unassociated=False)
    np.testing.assert_allclose(read_frame(tmp_path / "clear", 1.0)[1, 1], 1.0)
    _write_tiff(tmp_path / "extra.tif", rgba(0.6), oiio.UINT16, unassociated=False, alpha=False)
    np.testing.assert_allclose(read_frame(tmp_path / "extra", 1.0), linear, atol=1e-4)  # no alpha
    # a non-finite value in a channel left out (a renderer's depth: inf in the background) is
    # not the image's; in its colour it is refused, naming the pixel
    depth = np.concatenate([np.full((2, 2, 3), 0.5 * linear), np.full((2, 2, 1), np.inf)], 2)
    _write_tiff(tmp_path / "depth.tif", depth, oiio.FLOAT, unassociated=False, alpha=False)
    np.testing.assert_allclose(read_frame(tmp_path / "depth", 1.0), 0.5 * linear, atol=1e-6)
    depth[1, 0, 2] = np.nan
    _write_tiff(tmp_path / "nan.tif", depth, oiio.FLOAT, unassociated=False, alpha=False)
    with pytest.raises(ValueError, match="nan.tif: 1 pixel.* of colour not finite, .* row 1, col"):
        read_frame(tmp_path / "nan", 1.0)


# -- camera checks shared by `spikegs simulate --scene FILE` and the NeRF layout ------------------
def arc_viewmats(n: int = 9) -> np.ndarray:
    """Viewmats [n, 4, 4] on a quarter circle of radius 4, 1 above the origin, looking at it."""
    angles = np.linspace(0, np.pi / 2, n)
    return np.stack([look_at([4 * np.cos(a), 4 * np.sin(a), 1.0], [0, 0, 0]) for a in angles])


def forward_viewmats(n: int = 9, seed: int = 0) -> np.ndarray:
    """Viewmats [n, 4, 4] of a forward-facing sweep: cameras 1/8 apart on the x axis, looking
    along +z with 1° of jitter (the point nearest to their axes lies behind them for seed 0, far
    ahead for seed 1)."""
    c2w = np.tile(np.eye(4), (n, 1, 1))
    jitter = np.radians(1.0) * np.random.default_rng(seed).normal(size=(n, 3))
    c2w[:, :3, :3] = Rotation.from_rotvec(jitter).as_matrix()
    c2w[:, 0, 3] = np.arange(n) / 8 - 0.5
    return np.linalg.inv(c2w)


def write_nerf(root, camera, viewmats, *, size=(23, 37), images=None, frame_camera=None):
    """A NeRF-layout directory: transforms.json (OpenCV poses, the file's `camera` keys and each
    frame's `frame_camera`), spike_data/f_i.dat of 70 random readouts of `size` (h, w) and
    images/f_i.png from `images` {i: linear RGB [h, w, 3]}."""
    rng = np.random.default_rng(0)
    (root / "spike_data").mkdir(parents=True)
    for i in range(len(viewmats)):
        save_dat(root / "spike_data" / f"f_{i}.dat", rng.random((70, *size)) < 0.2)
    for i, image in (images or {}).items():
        write_image(root / "images" / f"f_{i}.png", image)
    frames = [
        {"file_path": f"./images/f_{i}", "transform_matrix": np.linalg.inv(v).tolist()}
        | (frame_camera or {})
        for i, v in enumerate(viewmats)
    ]
    doc = {"convention": "opencv", **camera, "frames": frames}
    (root / "transforms.json").write_text(json.dumps(doc))
    return root


def test_forward_facing_views_need_a_scene_sphere(tmp_path):
    """The optical axes of a forward-facing sweep meet behind the cameras: refused (the random
    initial Gaussians would be out of view) unless the scene sphere is given."""
    forward = forward_viewmats()
    eyes = np.linalg.inv(forward)[:, :3, 3]
    assert (centre_of_view(forward)[0][2] < eyes[:, 2]).all()  # behind every camera
    camera = {"fl_x": 50.8, "cx": 18.5, "cy": 11.5, "w": 37, "h": 23}
    root = write_nerf(tmp_path / "forward", camera, forward)
    with pytest.raises(
        ValueError,
        match=r"forward.transforms.json: the cameras' optical axes do not converge in front of "
        r"them .*set scene_center and scene_radius in .*spikegs.json, or, where its matrices are "
        r"in the other convention .*mean viewing direction",
    ):
        load_dataset(root)
    (root / "spikegs.json").write_text(json.dumps({"scene_center": [0, 0, 3], "scene_radius": 1}))
    ds = load_dataset(root)
    assert ds.meta["scene_center"] == [0, 0, 3] and ds.meta["scene_radius"] == 1
    assert converging_centre(forward_viewmats(seed=1)) is None  # the nearest point far ahead
    assert converging_centre(forward_viewmats(seed=1), AXES_SPREAD_MIN) is None
    assert converging_centre(arc_viewmats()) is not None
    frames = np.zeros((len(forward), 4, 4, 1))
    with pytest.raises(ValueError, match="frame sequence 'fw': .* do not converge.*center and"):
        FrameSequenceSource("fw", frames, forward, np.eye(3))
    source = FrameSequenceSource("fw", frames, forward, np.eye(3), center=[0, 0, 3], radius=1)
    assert source.scene_center.tolist() == [0, 0, 3] and source.scene_radius == 1


def test_a_frame_sequences_held_out_readouts_keep_the_margin_and_spread_inside_it():
    """11 frames over readouts 0..100 (one every 10), a margin of 10: the held-out views may lie
    on readouts 10..90, both ends included (90 = 100 - 10 left out passed); 3 of them lie
    between the ends (30, 50, 70; the ends taken passed), and 8 of the 9, whose picks between
    the ends would repeat, spread over all."""
    frames = np.zeros((11, 4, 4, 1), np.float32)
    viewmats = [look_at([3.0 * np.cos(a), 3.0 * np.sin(a), 0], [0, 0, 0]) for a in range(11)]
    source = FrameSequenceSource("seq", frames, viewmats, np.eye(3), center=[0, 0, 0], radius=1)
    assert source.on_path_times(101, 20, 10).tolist() == list(range(10, 91, 10))
    assert source.on_path_times(101, 3, 10).tolist() == [30, 50, 70]
    assert source.on_path_times(101, 8, 10).tolist() == [10, 20, 30, 40, 60, 70, 80, 90]


def test_simulate_takes_a_forward_sweeps_scene_sphere_from_its_transforms_file(tmp_path):
    """`spikegs simulate --scene transforms.json` of a forward-facing sweep was refused with a fix
    (pass center and radius to FrameSequenceSource) that the command line cannot apply."""
    forward = forward_viewmats(4)
    frames = np.random.default_rng(0).random((4, 16, 24, 3))
    path = tmp_path / "transforms.json"
    K = np.array([[30.0, 0, 12], [0, 30, 8], [0, 0, 1]])
    write_transforms(path, "train", frames, forward, K, ".exr")
    with pytest.raises(  # (OpenCV matrices unlabelled, the other cause, got only the sphere)
        ValueError,
        match=r"add scene_center .x, y, z. and scene_radius to transforms.json, or, where its "
        r'matrices are in the other convention than transforms.json states, state theirs ."conv',
    ):
        FrameSequenceSource.from_transforms(path, 24, 16)
    doc = json.loads(path.read_text())
    path.write_text(json.dumps({**doc, "scene_center": [0, 0, 3], "scene_radius": "1"}))
    with pytest.raises(ValueError, match="scene_radius expected a finite number > 0"):
        FrameSequenceSource.from_transforms(path, 24, 16)
    path.write_text(json.dumps({**doc, "scene_center": [0, 0, 3]}))  # a radius about another centre
    with pytest.raises(ValueError, match="a scene centre needs its radius"):
        FrameSequenceSource.from_transforms(path, 24, 16)
    path.write_text(json.dumps({**doc, "scene_center": [0, 0, 3], "scene_radius": 1}))
    source = FrameSequenceSource.from_transforms(path, 24, 16)
    assert source.scene_center.tolist() == [0, 0, 3] and source.scene_radius == 1


def test_simulate_from_a_folder_names_the_transforms_file_it_leaves_unread(tmp_path):
    """A folder with transforms_train.json and transforms.json simulated from the first silently."""
    forward = forward_viewmats(4)
    frames = np.random.default_rng(0).random((4, 16, 24, 3))
    K = np.array([[30.0, 0, 12], [0, 30, 8], [0, 0, 1]])
    for name in ("transforms_train.json", "transforms.json"):
        write_transforms(tmp_path / name, "train", frames, forward, K, ".exr")
        edit = json.loads((tmp_path / name).read_text())
        (tmp_path / name).write_text(
            json.dumps({**edit, "scene_center": [0, 0, 3], "scene_radius": 1})
        )
    with pytest.warns(UserWarning, match="reading transforms_train.json; transforms.json not read"):
        make_source(tmp_path, 24, 16, 1)


def test_narrow_inward_captures_give_their_scene_sphere():
    """A 30° arc and a ring seen from 82° elevation, aimed at the origin, were refused when the
    NeRF layout took LLFF's ±20° spread test (LLFF has depth bounds to fall back on); a 12° arc
    spreads its directions 0.005, over the 1e-3 (±2°) below which views are forward-facing."""
    arc = np.radians(np.linspace(-15, 15, 7))
    narrow = np.radians(np.linspace(-6, 6, 7))  # directions spread 0.005: over the 1e-3 (±2°)
    ring = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    up = np.radians(82)
    captures = {
        "arc 30°": [look_at([4 * np.sin(a), 4 * np.cos(a), 0.5], [0, 0, 0]) for a in arc],
        "arc 12°": [look_at([4 * np.sin(a), 4 * np.cos(a), 0.5], [0, 0, 0]) for a in narrow],
        "ring at 82°": [
            look_at(4 * np.array([np.cos(up) * np.cos(a), np.cos(up) * np.sin(a), np.sin(up)]),
                    [0, 0, 0], up=(1, 0, 0))
            for a in ring
        ],
    }  # fmt: skip
    for name, viewmats in captures.items():
        center, radius = view_sphere(np.stack(viewmats), name, "")
        assert np.abs(center).max() < 1e-6 and radius > 0, name


@pytest.mark.parametrize(
    "camera, frame_camera",
    [
        ({"fl_x": 60.0, "cx": 24.0, "cy": 16.0, "w": 48, "h": 32}, None),  # for 48x32 originals
        ({}, {"fl_x": 30.0, "fl_y": 30.0, "cx": 12.0, "cy": 8.0, "w": 24, "h": 16}),  # nerfstudio
    ],
)
def test_simulated_frames_read_the_camera_as_the_nerf_layout(tmp_path, camera, frame_camera):
    """`spikegs simulate --scene transforms.json`: intrinsics scaled from the file's w, h to the
    images' size, per-frame intrinsics read."""
    viewmats = arc_viewmats(3)
    frames = np.random.default_rng(0).random((3, 16, 24, 3))
    write_transforms(tmp_path / "transforms.json", "train", frames, viewmats, np.eye(3), ".exr")
    doc = json.loads((tmp_path / "transforms.json").read_text())
    del doc["camera_angle_x"]
    for frame in doc["frames"]:
        frame.update(frame_camera or {})
    (tmp_path / "transforms.json").write_text(json.dumps({**doc, **camera}))
    source = FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 24, 16)
    np.testing.assert_allclose(source.K, [[30, 0, 12], [0, 30, 8], [0, 0, 1]])
    half = FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 12, 8)
    np.testing.assert_allclose(half.K, [[15, 0, 6], [0, 15, 4], [0, 0, 1]])


def test_simulated_frames_cameras_checked_before_the_frames_are_read(tmp_path):
    """Frames of one file stating other keys for one camera (the last at half the size) read as
    one camera; a frame of another focal is refused before a later frame is read (a missing image
    was reported instead of the cameras)."""
    viewmats = arc_viewmats(3)
    frames = np.random.default_rng(0).random((3, 16, 24, 3))
    write_transforms(tmp_path / "transforms.json", "train", frames, viewmats, np.eye(3), ".exr")
    doc = json.loads((tmp_path / "transforms.json").read_text())
    del doc["camera_angle_x"]
    cameras = [{"fl_x": 30.0}, {"fl_x": 30.0, "cx": 12.0}, {"fl_x": 15.0, "w": 12, "h": 8}]
    for frame, camera in zip(doc["frames"], cameras):
        frame.update(camera)
    (tmp_path / "transforms.json").write_text(json.dumps(doc))
    source = FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 24, 16)
    np.testing.assert_allclose(source.K, [[30, 0, 12], [0, 30, 8], [0, 0, 1]])
    doc["frames"][2].update(fl_x=16.0, file_path="missing")
    (tmp_path / "transforms.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="their fx, fy, cx, cy differ; one camera expected"):
        FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 24, 16)


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("camera_angle_x", 40, r"in \(0, pi\) radians, found 40 \(40 degrees would be 0.698"),
        ("camera_angle_x", -0.7, r"in \(0, pi\) radians, found -0.7$"),
        # the ranges' open ends, each key's: π (a focal of 0, read as degrees) and 0
        (
            "camera_angle_x",
            np.pi,
            r"in \(0, pi\) radians, found 3.14159\d+ \(3.14159 degrees would",
        ),
        ("camera_angle_x", 0, r"in \(0, pi\) radians, found 0$"),
        ("camera_angle_y", 0, r"in \(0, pi\) radians, found 0$"),
        ("camera_angle_y", np.pi, r"in \(0, pi\) radians, found 3.14159\d+ \(3.14159 degrees"),
        ("fl_x", -50.8, r"> 0 \(pixels\), found -50.8"),
        ("fl_x", 0, r"> 0 \(pixels\), found 0"),
        ("fl_y", 0, r"> 0 \(pixels\), found 0"),
        ("fl_y", -30, r"> 0 \(pixels\), found -30"),
        ("w", 0, "a positive integer"),
        ("h", 0, "a positive integer"),
        ("h", 23.5, "a positive integer"),
        ("w", 36.5, "a positive integer"),
    ],
)
def test_intrinsics_out_of_range_named(tmp_path, key, value, expected):
    """Checked for both readers: the NeRF layout, `spikegs simulate --scene transforms.json`."""
    camera = {"fl_x": 50.8, "cx": 18.5, "cy": 11.5, "w": 37, "h": 23}
    camera = {"camera_angle_x": value} if key == "camera_angle_x" else {**camera, key: value}
    root = write_nerf(tmp_path, camera, arc_viewmats(2), images={0: np.ones((23, 37, 3))})
    match = f"transforms.json: {key} expected {expected}"
    with pytest.raises(ValueError, match=match):
        load_dataset(root)
    with pytest.raises(ValueError, match=match):
        FrameSequenceSource.from_transforms(root / "transforms.json", 37, 23)


@pytest.mark.filterwarnings("ignore:.*sharp images are put in firing-rate units")
@pytest.mark.filterwarnings("ignore:.*hardly match")  # random spikes, a held-out image
def test_aspect_ratio_of_the_camera_and_the_spikes_must_agree(tmp_path):
    """Intrinsics for images of another aspect ratio than the spikes would give non-square
    pixels: refused. A raw-row crop (raw_width, col_offset) keeps the focal, moves cx and crops
    the sharp images."""
    ramp = np.tile(np.linspace(0.1, 0.9, 52)[None, :, None], (25, 1, 3))  # [25, 52, 3]
    write_nerf(
        tmp_path / "square", {"camera_angle_x": 0.8}, arc_viewmats(), images={0: ramp[:23, :23]}
    )
    (tmp_path / "square" / "spikegs.json").write_text(json.dumps({"height": 23, "width": 37}))
    with pytest.raises(
        ValueError,
        match=r"transforms.json: the camera \(sized as its first sharp image, \./images/f_0\) is "
        r"for 23x23 images \(height x width\), of another aspect ratio than the 23x37 spikes.*set "
        r"height and width",
    ):
        load_dataset(tmp_path / "square")
    camera = {"fl_x": 60.0, "cx": 26.0, "cy": 12.5, "w": 52, "h": 25}
    root = write_nerf(tmp_path / "raw", camera, arc_viewmats(), size=(25, 52), images={0: ramp})
    (root / "spikegs.json").write_text(json.dumps({"width": 50}))
    with pytest.raises(ValueError, match=r"\(its w, h\) is for 25x52 images .*25x50 spikes"):
        load_dataset(root)
    (root / "spikegs.json").write_text(json.dumps({"width": 50, "raw_width": 52, "col_offset": 1}))
    ds = load_dataset(root)
    np.testing.assert_allclose(ds.K, [[60, 0, 25], [0, 60, 12.5], [0, 0, 1]], rtol=1e-6)
    sharp = ds.test_views[0].image[..., 0] / ds.meta["image_scale"]  # [25, 50]
    np.testing.assert_allclose(sharp, ramp[:, 1:51, 0], atol=0.005)  # 8-bit sRGB, decoded
    frames = np.random.default_rng(0).random((3, 16, 24, 3))  # simulate: 24x16 frames
    K = np.array([[30.0, 0, 12], [0, 30, 8], [0, 0, 1]])
    write_transforms(tmp_path / "sim.json", "sim", frames, arc_viewmats(3), K, ".exr")
    with pytest.raises(ValueError, match=r"sim.json: the camera \(sized as its first frame\) is "):
        FrameSequenceSource.from_transforms(tmp_path / "sim.json", 16, 16)


def test_nerf_orientation_check_reads_the_first_eight_training_images(tmp_path, monkeypatch):
    """With rate_at_one given, only the first ORIENTATION_VIEWS (8) training frames' sharp images
    are read, for the flip check: 12 frames, every 8th (0, 8) held out, all with images, give
    training frames 1-7 and 9 to the check, then the held-out 0 and 8 (10). Guards against one
    fewer (< for <=), frames counted with the test ones (1-7) and every training image read (12,
    the cost the limit avoids)."""
    seen = []
    monkeypatch.setattr(real, "check_orientation", lambda views, *_: seen.append(len(list(views))))
    image = np.full((23, 37, 3), 0.5)
    camera = {"fl_x": 50.8, "cx": 18.5, "cy": 11.5, "w": 37, "h": 23}
    root = write_nerf(tmp_path, camera, arc_viewmats(12), images=dict.fromkeys(range(12), image))
    (root / "spikegs.json").write_text(json.dumps({"rate_at_one": 0.25}))
    ds = load_dataset(root)
    assert [v.name for v in ds.test_views] == ["images_f_0", "images_f_8"]
    assert seen == [real.ORIENTATION_VIEWS + 2] == [10]


def test_nerf_training_views_tfps_are_computed_one_at_a_time(tmp_path, monkeypatch, alive_arrays):
    """The training views' TFPs, which calibrate the intensity scale and check the orientation
    against their sharp images, are computed a view at a time: a list of them all held as much
    as the images again (0.4 MB a view at 250x400; 160 views: peak RSS +295 MB over the load's
    start, +241 now). 12 frames with images, 10 of them training views, no rate_at_one: at most
    two TFPs alive at once (10 before), and the same scale."""
    from spikegs.spikes.stream import SpikeStream

    tfp = SpikeStream.tfp

    def counted(self, *args):
        return alive_arrays.track(tfp(self, *args))

    image = np.full((23, 37, 3), 0.5)
    camera = {"fl_x": 50.8, "cx": 18.5, "cy": 11.5, "w": 37, "h": 23}
    root = write_nerf(tmp_path, camera, arc_viewmats(12), images=dict.fromkeys(range(12), image))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        expected = load_dataset(root).meta["rate_at_one"]  # (random spikes)
        monkeypatch.setattr(SpikeStream, "tfp", counted)
        assert load_dataset(root).meta["rate_at_one"] == expected
    assert 0 < alive_arrays.most <= 2, alive_arrays.most
    # flat images show no orientation: not said to 'hardly match' their (random) spikes
    assert not [w for w in caught if "hardly match" in str(w.message)]


@pytest.mark.filterwarnings("ignore:.*hardly match")  # random spikes, a held-out image
def test_nerf_test_image_sizes_pixel_intrinsics_and_its_alpha_is_over_white(tmp_path):
    """Intrinsics in pixels without w, h are for the first sharp test image's size (here 46x74,
    twice the spikes'): K halved, no training image needed (guards against the training images
    sought first: none found, the camera read as for the spikes' 23x37, K not halved). Its
    transparent pixels are white, as NeRF synthetic's renders are meant (guards against a black
    background)."""
    image = np.concatenate([np.zeros((46, 37, 4)), np.ones((46, 37, 4))], axis=1)
    image[..., :3] = 0.2  # left half transparent
    camera = {"fl_x": 101.6, "cx": 37.0, "cy": 23.0}
    root = write_nerf(tmp_path, camera, arc_viewmats(), images={0: image})
    options = {"rate_at_one": 0.25, "height": 23, "width": 37}  # the spikes' size
    (root / "spikegs.json").write_text(json.dumps(options))
    ds = load_dataset(root)
    np.testing.assert_allclose(ds.K, [[50.8, 0, 18.5], [0, 50.8, 11.5], [0, 0, 1]], rtol=1e-6)
    sharp = ds.test_views[0].image[..., 0] / 0.25  # [23, 37] intensity
    np.testing.assert_allclose(sharp[:, :16], 1.0, atol=1e-3)  # (the resize filter's reach)
    np.testing.assert_allclose(sharp[:, 21:], 0.2, atol=0.005)  # 8-bit sRGB, decoded
    # spikes at twice the test image's size: it is upsampled into ground truth, said (it scored
    # a blurred truth unsaid; the frame sequence's test frames were warned of, these were not)
    (root / "spikegs.json").write_text(json.dumps({**options, "height": 92, "width": 148}))
    rng = np.random.default_rng(0)
    for i in range(9):
        save_dat(root / "spike_data" / f"f_{i}.dat", rng.random((70, 92, 148)) < 0.2)
    with pytest.warns(
        UserWarning, match=r"transforms.json: 1 test image\(s\) smaller than the data"
    ):
        load_dataset(root)


def test_nerf_per_frame_cameras_one_to_1e6_and_w_h_together(tmp_path):
    """Frames' own intrinsics must give one camera to within 1e-6: a frame whose fl_x is 1e-4
    off (another calibration) is refused, one 1e-8 off (rounding) is not; guards against a
    looser comparison passing the first. A frame's key overrides its file's (guards against the
    reverse). w or h alone is refused by name (guards against w alone failing as a bare KeyError
    and h alone ignored)."""
    camera = {"fl_x": 50.8, "cx": 18.5, "cy": 11.5, "w": 37, "h": 23}
    root = write_nerf(tmp_path / "own", camera, arc_viewmats())
    doc = json.loads((root / "transforms.json").read_text())
    for off, refused in ((1e-8, False), (1e-4, True)):
        doc["frames"][3]["fl_x"] = 50.8 * (1 + off)
        (root / "transforms.json").write_text(json.dumps(doc))
        if refused:
            with pytest.raises(ValueError, match=r"frame './images/f_3' has intrinsics .*differ"):
                load_dataset(root)
        else:
            np.testing.assert_allclose(load_dataset(root).K[0, 0], 50.8, rtol=1e-6)
    # a frame's keys override its file's (nerfstudio)
    root = write_nerf(
        tmp_path / "both", {**camera, "fl_x": 40.0}, arc_viewmats(), frame_camera={"fl_x": 50.8}
    )
    np.testing.assert_allclose(load_dataset(root).K[0, 0], 50.8, rtol=1e-6)
    for key in ("w", "h"):
        alone = {k: v for k, v in camera.items() if k != key}
        root = write_nerf(tmp_path / f"no_{key}", alone, arc_viewmats())
        with pytest.raises(ValueError, match="transforms.json: w and h expected together"):
            load_dataset(root)


def test_simulated_frames_without_intrinsics_are_refused(tmp_path):
    """A transforms file with no camera_angle_x nor fl_x, in the file or its frames: refused
    naming the keys it needs, not guessed."""
    viewmats = arc_viewmats(3)
    frames = np.random.default_rng(0).random((3, 16, 24, 3))
    write_transforms(tmp_path / "transforms.json", "train", frames, viewmats, np.eye(3), ".exr")
    doc = json.loads((tmp_path / "transforms.json").read_text())
    del doc["camera_angle_x"]
    (tmp_path / "transforms.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"transforms.json: intrinsics expected \(camera_angle_x"):
        FrameSequenceSource.from_transforms(tmp_path / "transforms.json", 24, 16)


def test_transforms_frames_must_be_a_list_of_4x4_matrices(tmp_path):
    """A transforms file whose frames is not a list (one frame object unwrapped, a number) is
    refused by name; guards against the check dropped: the object's keys read as frames ("frame
    0 needs a file_path", misleading) and a number failing as a bare TypeError. So is a frame
    without a transform_matrix (else a bare KeyError) and one of 4 rows of 3 (a check of the
    row count alone let it through)."""
    frame = {"file_path": "f_0", "transform_matrix": np.eye(4).tolist()}
    path = tmp_path / "transforms.json"
    for frames in (frame, 5, "f_0"):
        path.write_text(json.dumps({"frames": frames}))
        with pytest.raises(ValueError, match="transforms.json: expected a JSON object with a list"):
            read_transforms_doc(path)
    for doc in ({"frames": []}, {"camera_angle_x": 0.7}):  # no frame: said so, not read as none
        path.write_text(json.dumps(doc))
        with pytest.raises(ValueError, match="transforms.json: no frames"):
            read_transforms_doc(path)
    path.write_text(json.dumps({"frames": [frame]}))
    assert read_transforms_doc(path)["frames"] == [frame]
    path.write_text(json.dumps({"frames": [frame, {"file_path": "f_1"}]}))
    with pytest.raises(ValueError, match="frame 1 needs a file_path .text. and a transform_matr"):
        read_transforms_doc(path)  # (not a bare KeyError when its matrix is read)
    doc = {"frames": [frame, {**frame, "transform_matrix": np.eye(4)[:, :3].tolist()}]}
    with pytest.raises(
        ValueError, match=r"frame 1 \('f_0'\): transform_matrix expected 4 rows of 4"
    ):
        transforms_viewmats(path, doc)  # 4 rows of 3


def test_a_raw_row_crop_is_read_only_within_a_pixel_of_the_stored_rows():
    """frame_columns takes the images for whole stored rows (a crop: raw_width, col_offset) only
    when their width at the spikes' height is within a pixel of raw_width. Images already of the
    kept columns (50 of 56 stored) are no crop: a looser tolerance (10 px) read them as one, and
    refused a good camera as of another aspect ratio (or, nearer, shifted cx by col_offset). Both
    tolerances are a pixel either way of the images' width scaled to the spikes' height."""

    def columns(src, raw_width, col_offset=3):
        return frame_columns("t.json", "the camera", src, (25, 50), "FIX", raw_width, col_offset)

    assert columns((25, 56), 56) == (56, 3)  # whole rows: a crop, cx moved 3 left
    assert columns((50, 113), 56) == (56, 3)  # 56.5 px at height 25: within a pixel
    assert columns((25, 50), 56) == (50, 0)  # images of the kept columns: no crop
    assert columns((25, 50), 53) == (50, 0)
    for width in (49, 50, 51):  # a pixel either way: the same aspect ratio (the width rounded)
        assert columns((25, width), None) == (50, 0)
    assert columns((25, 57), 56) == (56, 3)
    refused = r"t.json: the camera is for 25x5\d images .* 25x50 spikes"
    for src in ((25, 54), (25, 58)):  # 2 px from either: another aspect ratio
        with pytest.raises(ValueError, match=refused + r" \(or the 56 stored pixels of a row, "):
            columns(src, 56)
    with pytest.raises(ValueError, match=refused + ": .*FIX"):  # no stored rows to name
        columns((25, 54), None)


@pytest.mark.parametrize("radius, warned", [(1.0, False), (5.0, False), (1.0, True)])
def test_cross_fade_warning_sees_only_points_in_front(radius, warned):
    """Frames 0.2° apart on an orbit of radius 4 move the scene by a pixel or so; a scene sphere
    of radius 5 (a user's, enclosing the cameras) put points behind them, whose projection (z
    clamped to 1e-9) moved 3e8 pixels: a cross-fade warning for still frames. Frames 20° apart
    are warned of (last case: 23 px)."""
    from spikegs.data.simulate import warn_about_frames

    step = 20.0 if warned else 0.2
    angles = np.radians(step * np.arange(10))
    eyes = np.stack([4 * np.cos(angles), 4 * np.sin(angles), np.zeros(10)], -1)
    viewmats = np.stack([look_at(eye, np.zeros(3), up=(0.0, 0.0, 1.0)) for eye in eyes])
    K = np.array([[200.0, 0, 16], [0, 200.0, 16], [0, 0, 1]])
    frames = np.zeros((10, 32, 32, 1), np.float32)
    source = FrameSequenceSource("orbit", frames, viewmats, K, center=np.zeros(3), radius=radius)
    trajectory = source.trajectory(901, 0.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_about_frames(source, trajectory, trajectory.readouts)
    assert [str(w.message)[:30] for w in caught] == (
        ["the scene moves up to 23.0 pix"] if warned else []
    ), [str(w.message) for w in caught]
    if warned:  # two frames, the first and the last: a frame sequence's remedy, not frame_every
        with pytest.warns(UserWarning, match=r"two frames of the sequence: .*a denser frame"):
            warn_about_frames(source, trajectory, trajectory.readouts[[0, -1]])
