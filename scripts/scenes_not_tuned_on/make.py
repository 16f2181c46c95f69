"""Scenes that no default of SpikeGS was tuned on, for `spikegs simulate --scene` (BENCHMARKS.md,
section "Scenes not tuned on"); Mitsuba 3 (`pip install ".[mitsuba]"`):

  OUT/cbox_one_sided.xml  Mitsuba's Cornell box as published: one-sided walls, y up
  OUT/cbox.xml            the same, viewable from an orbit: two-sided walls, a constant
                          environment of 0.6 and the ceiling light 3x brighter
  OUT/textured.xml        a floor of rings, a sphere of multi-scale colour noise, a checkered
                          cube, a striped cylinder and a text panel (textures made here, none of
                          the scikit-image samples the built-in scenes use), z up, colour
  OUT/*.png               its textures: rings, noise, stripes, text
  OUT/frames/             160 frames of textured.xml on a 360° orbit ascending 20° -> 40°
                          (transforms.json, NeRF layout, sRGB PNGs at 32 spp) and 8 off-path
                          views above it (55°, 1.15x as far: transforms_test.json)

usage: python scripts/scenes_not_tuned_on/make.py OUT   (~30 s on 2 cores, most of it the frames)
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

HERE = Path(__file__).parent  # the scenes' XML files, copied to OUT
SIDE = 256  # texture size, pixels
FRAMES, TEST_VIEWS, FOV_DEG, FRAME_SIZE, SPP = 160, 8, 40.0, 128, 32


def _save(image: np.ndarray, path: Path) -> None:
    """An image [H, W, 3] in [0, 1] as an 8-bit PNG."""
    Image.fromarray((image * 255).astype(np.uint8)).save(path)


def write_textures(out: Path) -> None:
    """textured.xml's four textures (seeded: the same files every run)."""
    rng = np.random.default_rng(7)
    noise = np.zeros((SIDE, SIDE, 3))  # [S, S, 3] value noise at three scales
    for cells in (4, 16, 64):
        small = Image.fromarray((rng.random((cells, cells, 3)) * 255).astype(np.uint8))
        noise += np.asarray(small.resize((SIDE, SIDE), Image.BICUBIC)) / 255.0 / 3
    _save((noise - noise.min()) / (noise.max() - noise.min()), out / "noise.png")
    y, x = np.mgrid[0:SIDE, 0:SIDE]
    phase = ((x + 0.5 * y) / 16.0) % 3  # diagonal red, green and blue stripes
    stripes = np.stack([phase < 1, (phase >= 1) & (phase < 2), phase >= 2], -1) * 0.8 + 0.1
    _save(stripes, out / "stripes.png")
    rings = 0.25 + 0.5 * (np.sin(np.hypot(x - SIDE / 2, y - SIDE / 2) / 5.0) > 0)
    _save(np.stack([rings, rings * 0.9, rings * 0.7], -1), out / "rings.png")
    panel = Image.new("RGB", (SIDE, SIDE), (235, 225, 200))
    try:
        font = ImageFont.truetype("DejaVuSans-Bold.ttf", 34)
    except OSError:  # no DejaVu fonts installed: Pillow's own
        font = ImageFont.load_default()
    colours = [(20, 20, 120), (140, 20, 20), (10, 90, 10), (0, 0, 0)]
    for i, (word, colour) in enumerate(zip(["SPIKE", "AUDIT", "33a", "XYZW"], colours)):
        ImageDraw.Draw(panel).text((18, 10 + i * 60), word, fill=colour, font=font)
    panel.save(out / "text.png")


def write_frames(scene_file: Path, out: Path) -> None:
    """Frames of `scene_file` on an ascending orbit, and off-path views above it, as NeRF-style
    transforms files (OpenGL camera-to-world) with sRGB PNGs."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    scene = mi.load_file(str(scene_file))
    box = scene.bbox()
    low, high = np.array(box.min), np.array(box.max)
    # float32, as Mitsuba gives them: the cameras of the measured datasets to the last bit
    centre, radius = (low + high) / 2, np.linalg.norm(high - low) / 2

    def render(azimuth: float, elevation: float, distance: float, name: str) -> dict:
        a, e = np.radians(azimuth), np.radians(elevation)
        eye = centre + distance * np.array(
            [np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]
        )
        to_world = mi.ScalarTransform4f().look_at(
            origin=eye.tolist(), target=centre.tolist(), up=[0, 0, 1]
        )
        sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": FOV_DEG,
                "fov_axis": "x",
                "to_world": to_world,
                "film": {
                    "type": "hdrfilm",
                    "width": FRAME_SIZE,
                    "height": FRAME_SIZE,
                    "rfilter": {"type": "box"},
                },
                "sampler": {"type": "independent", "sample_count": SPP, "seed": 0},
            }
        )
        linear = np.clip(np.array(mi.render(scene, sensor=sensor)), 0, 1)  # [H, W, 3]
        srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray((srgb * 255 + 0.5).astype(np.uint8)).save(out / f"{name}.png")
        # Mitsuba's camera (x left, y up, z forward) to OpenGL's (x right, y up, z back)
        c2w = np.array(to_world.matrix, np.float64) @ np.diag([-1.0, 1.0, -1.0, 1.0])
        return {"file_path": name, "transform_matrix": c2w.tolist()}

    for file, views in (
        (
            "transforms.json",
            [
                render(
                    360.0 * i / FRAMES, 20 + 20 * i / (FRAMES - 1), 2.5 * radius, f"train/{i:03d}"
                )
                for i in range(FRAMES)
            ],
        ),
        (
            "transforms_test.json",
            [
                render(22.5 + 45.0 * i, 55, 1.15 * 2.5 * radius, f"test/{i:03d}")
                for i in range(TEST_VIEWS)
            ],
        ),
    ):
        doc = {"camera_angle_x": float(np.radians(FOV_DEG)), "frames": views}
        (out / file).write_text(json.dumps(doc, indent=1))


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name in ("cbox_one_sided.xml", "cbox.xml", "textured.xml"):
        shutil.copy(HERE / name, out / name)
    write_textures(out)
    write_frames(out / "textured.xml", out / "frames")
    print(f"scenes in {out}: cbox_one_sided.xml, cbox.xml, textured.xml, frames/")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("out", type=Path, help="the folder the scenes are written to")
    main(parser.parse_args().out)
