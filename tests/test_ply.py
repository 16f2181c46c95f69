"""load_ply (ply.py): files it must refuse by name, rather than load wrongly or fail in torch,
and the comments it reads (only spikegs's own)."""

import numpy as np
import pytest
import torch
from plyfile import PlyData, PlyElement
from spikegs.gaussians import GaussianModel
from spikegs.ply import load_ply, save_ply

BASE = [
    "x",
    "y",
    "z",
    "opacity",
    *(f"scale_{i}" for i in range(3)),
    *(f"rot_{i}" for i in range(4)),
]


def _write(path, dc: int, rest: int, comments=()):
    """A 2-Gaussian PLY with `dc` f_dc_* and `rest` f_rest_* properties (rotation (1, 0, 0, 0))
    and `comments`."""
    names = BASE + [f"f_dc_{i}" for i in range(dc)] + [f"f_rest_{i}" for i in range(rest)]
    vertex = np.zeros(2, dtype=[(n, "f4") for n in names])
    vertex["rot_0"] = 1.0
    PlyData([PlyElement.describe(vertex, "vertex")], comments=list(comments)).write(str(path))
    return path


OURS = ["spikegs background 0 0 0"]  # no warning about the background


@pytest.mark.parametrize(
    "dc, rest, comments, message",
    [
        # 46 = 3 x 15 + 1: not whole coefficients per channel (46 // 3 = 15 would pass as degree 3)
        (3, 46, OURS, "o.ply: expected a multiple of 3 f_rest_\\* properties"),
        # 2 coefficients a channel past the DC one: no degree has 3 (1, 4, 9, 16); not read as 0
        (3, 6, OURS, "o.ply: 3 SH coefficients per channel, which no SH degree has"),
        # one f_dc: a grey file cannot declare 3 channels
        (1, 0, ["spikegs background 0", "spikegs channels 3"], "expected 1..1"),
        # a background of 1 value for 3 channels, of 4 for 3
        (3, 0, ["spikegs background 0.5"], "'spikegs background 0.5': expected 3 finite numbers"),
        (3, 0, ["spikegs background 0 0 0 0"], "expected 3 finite numbers"),
        # an origin of 2 coordinates, of 4
        (3, 0, [*OURS, "spikegs origin 1 2"], "'spikegs origin 1 2': expected 3 finite numbers"),
        (3, 0, [*OURS, "spikegs origin 1 2 3 4"], "expected 3 finite numbers"),
        # words where numbers go: named, not a float()'s ValueError
        (3, 0, ["spikegs background a b c"], "'spikegs background a b c': expected 3 finite"),
        (3, 0, [*OURS, "spikegs origin x y z"], "'spikegs origin x y z': expected 3 finite"),
        # f_dc_2 missing: it said "expected a multiple of 2 f_rest_* properties"
        (2, 45, OURS, r"f_dc_\* properties \['f_dc_0', 'f_dc_1'\]: expected f_dc_0 \(grey\) or"),
    ],
)
def test_load_ply_refuses_by_name(tmp_path, dc, rest, comments, message):
    path = _write(tmp_path / "o.ply", dc, rest, comments)
    with pytest.raises(ValueError, match=message):
        load_ply(path)


def test_a_point_cloud_is_no_splat_file(tmp_path):
    """A point cloud (points3d.ply of `spikegs poses`, another tool's scan) given as a scene:
    refused with the properties a 3DGS file has and it lacks."""
    from spikegs.point_cloud import write_points

    write_points(tmp_path / "points3d.ply", np.zeros((4, 3)), np.zeros((4, 3), np.uint8))
    lacking = r"\['opacity', 'scale_0', 'scale_1', 'scale_2', 'rot_0', 'rot_1', 'rot_2', 'rot_3'\]"
    with pytest.raises(ValueError, match=f"points3d.ply: vertex properties {lacking} missing: not"):
        load_ply(tmp_path / "points3d.ply")


def test_a_compressed_ply_is_named(tmp_path):
    """SuperSplat's compressed .ply (a chunk element, uint32 packed_* vertex properties): refused
    as such, not as a file that is no splat file."""
    chunk = np.zeros(1, [(f"{e}_{a}", "f4") for e in ("min", "max") for a in "xyz"])
    packed = np.zeros(256, [(f"packed_{k}", "u4") for k in ("position", "rotation", "scale")])
    elements = [PlyElement.describe(chunk, "chunk"), PlyElement.describe(packed, "vertex")]
    PlyData(elements).write(str(tmp_path / "scene.compressed.ply"))
    with pytest.raises(ValueError, match="scene.compressed.ply: a compressed .ply .*SuperSplat"):
        load_ply(tmp_path / "scene.compressed.ply")


def test_a_header_declaring_more_than_memory_holds_is_named(tmp_path):
    """An ASCII .ply whose header declares 1e15 vertices (a corrupt or crafted file): plyfile
    allocates them before reading, and numpy's MemoryError ("Unable to allocate 10.7 PiB", exit
    1) named no file. 10.7 PiB is past any 64-bit machine's address space, overcommit or not."""
    path = tmp_path / "huge.ply"
    header = "ply\nformat ascii 1.0\nelement vertex 1000000000000000\n"
    properties = "".join(f"property float {a}\n" for a in "xyz")
    path.write_text(header + properties + "end_header\n0 0 0\n")
    with pytest.raises(ValueError, match="huge.ply: not a readable PLY file: its header declares"):
        load_ply(path)


def test_only_spikegs_comments_are_read(tmp_path):
    """Another tool's `KEY VALUE` comments with spikegs's keys are not spikegs's: a file of 45
    f_rest is degree 3 whatever "viewer sh_degree 1" says, and its 3 channels stay 3."""
    path = _write(tmp_path / "o.ply", 3, 45, [*OURS, "viewer sh_degree 1", "viewer channels 1"])
    model = load_ply(path)
    assert model.sh_degree == 3 and model.channels == 3
    assert model.params["sh_rest"].shape == (2, 15, 3)


def test_a_grey_scene_round_trips_as_grey(tmp_path):
    """A mono model is written as 3 equal channels with `spikegs channels 1` and read back as one
    (the channel count comes from the comment, bounded by the f_dc count)."""
    gen = torch.Generator().manual_seed(0)
    model = GaussianModel.random(5, (0, 0, 0), 1.0, 1, 1, gen)
    save_ply(model, tmp_path / "g.ply")
    v = PlyData.read(str(tmp_path / "g.ply"))["vertex"].data
    np.testing.assert_array_equal(v["f_dc_0"], v["f_dc_2"])
    back = load_ply(tmp_path / "g.ply")
    assert back.channels == 1 and back.params["sh_dc"].shape == (5, 1, 1)
    # its colour changed by a tool that kept the comment: dropped, said (unsaid until 2026-12-06)
    v["f_dc_1"][3] += 0.25
    grey = ["spikegs channels 1", "spikegs background 0"]
    PlyData([PlyElement.describe(v, "vertex", comments=grey)]).write(str(tmp_path / "edited.ply"))
    with pytest.warns(
        UserWarning, match=r"'spikegs channels 1', but its f_dc_\* differ by up to 0.25"
    ):
        assert load_ply(tmp_path / "edited.ply").channels == 1


def test_a_scene_loads_as_float32_whatever_torchs_default_dtype(tmp_path, float64_default):
    """A script whose torch default dtype is float64 could load no scene.ply: its background and
    an empty f_rest were made in the default dtype, and the model refused the mixed dtypes."""
    gen = torch.Generator().manual_seed(0)
    model = GaussianModel.random(5, (0, 0, 0), 1.0, 1, 3, gen)
    save_ply(model, tmp_path / "s.ply")
    back = load_ply(tmp_path / "s.ply")
    assert back.dtype == back.background.dtype == back.params["sh_rest"].dtype == torch.float32
    assert all(torch.equal(back.params[k], model.params[k]) for k in model.params)


def test_a_model_of_a_dtype_the_rasterizer_does_not_render_is_refused_by_name():
    """A bfloat16 model failed on saving (numpy's "unsupported ScalarType"), a float16 one on
    rendering; a float64 one renders from float32 cameras (its viewmat's dtype was refused)."""
    model = GaussianModel.random(5, (0, 0, 3), 1.0, 1, 1, torch.Generator().manual_seed(0))
    state = model.state_dict()
    for dtype in (torch.bfloat16, torch.float16):
        params = {k: v.to(dtype) for k, v in state["params"].items()}
        with pytest.raises(
            ValueError,
            match=f"one floating dtype expected; means {str(dtype)[6:]}.*float32 or float64",
        ):
            GaussianModel(params, state["background"].to(dtype), 1)
    wide = GaussianModel(
        {k: v.double() for k, v in state["params"].items()}, state["background"].double(), 1
    )
    view = wide.view_of(torch.eye(4, dtype=torch.float32))
    K = torch.tensor([[8.0, 0, 4], [0, 8, 4], [0, 0, 1]], dtype=wide.dtype)
    image = wide.render(view, K, 8, 8, 0.01).image
    narrow = model.render(model.view_of(np.eye(4)), K.float(), 8, 8, 0.01).image
    assert view.dtype == image.dtype == torch.float64
    torch.testing.assert_close(image.float(), narrow, atol=1e-5, rtol=0)


def test_a_dilation_comment_that_is_not_a_number_is_named():
    """scene.ply's `spikegs dilation V` comment holding no number: refused naming the file and
    the comment, as one out of the rasterizer's range (not float()'s bare ValueError)."""
    from spikegs.ply import _tag_dilation

    with pytest.raises(ValueError, match="s.ply: comment 'spikegs dilation wide': expected pix"):
        _tag_dilation("s.ply", {"dilation": "wide"})
    assert _tag_dilation("s.ply", {"dilation": " 0.25"}) == 0.25 and _tag_dilation("s", {}) == 0.3
