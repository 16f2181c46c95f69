"""The built-in scenes' pieces (data/scenes.py): textures in linear light, a cube's faces."""

import numpy as np
import pytest
import skimage.data
from spikegs.data.scenes import SCENES, cube, texture
from spikegs.image_io import srgb_to_linear


@pytest.mark.parametrize("name", ["camera", "coffee"])  # 8-bit grey and colour samples
def test_a_texture_is_its_sample_decoded_to_linear_light_and_exposed(name):
    """The 8-bit sRGB sample decoded (0-255 scaled to 0-1 first), grey made RGB, then scaled
    so its 99th percentile is `white` (clipped at 1)."""
    decoded = srgb_to_linear(np.atleast_3d(getattr(skimage.data, name)() / 255.0))
    decoded = np.broadcast_to(decoded, (*decoded.shape[:2], 3))
    tex = texture(name, white=0.8)
    assert np.percentile(tex, 99) == pytest.approx(0.8)
    unclipped = tex < 1
    ratios = tex[unclipped] / np.maximum(decoded[unclipped], 1e-12)
    np.testing.assert_allclose(ratios[decoded[unclipped] > 1e-3], 0.8 / np.percentile(decoded, 99))


def test_a_cubes_faces_are_textured_upright_and_unmirrored_from_outside():
    """Six faces of n² surfels each on the cube's surface; on the +z face (seen from +z, y up)
    and the +x face (seen from +x, z up) a texture's columns run to the viewer's right and its
    rows down."""
    h = w = 4
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    tex = np.stack([cols / w, rows / h, np.zeros((h, w))], axis=2)  # red: column, green: row
    scene = cube([0.0, 0.0, 0.0], 2.0, [tex], per_side=4, rng=np.random.default_rng(0))
    assert len(np.unique(scene.means.round(9), axis=0)) == 6 * 16
    assert np.allclose(np.abs(scene.means).max(axis=1), 1.0)
    for axis, right, up in ((2, 0, 1), (0, 1, 2)):  # +z: right x, up y; +x: right y, up z
        face = scene.means[:, axis] > 0.999
        means, colors = scene.means[face], scene.colors[face]
        assert len(means) == 16
        assert np.all(np.diff(colors[np.argsort(means[:, right]), 0].reshape(4, 4)[:, 0]) > 0)
        assert np.all(np.diff(colors[np.argsort(-means[:, up]), 1].reshape(4, 4)[:, 0]) > 0)


def test_the_wire_cubes_rods_are_its_twelve_edges():
    """Rods between corners one coordinate apart (±0.6): 12 of length 1.2 in 60 needles each,
    every needle with two coordinates at a corner's (a face's diagonal has one)."""
    means = SCENES["wires"]().means  # [N, 3]
    assert np.sum(np.sum(np.isclose(np.abs(means), 0.6), axis=1) >= 2) == 12 * 60
