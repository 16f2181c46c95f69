"""SIM scored against the other spike decoders (TFP(33), TFP(65), TFI) on a dataset's held-out
views on the camera path: PSNR and SSIM against their clean images."""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from .flicker import Flicker
from .metrics import psnr, ssim
from .sim import SIM
from .sim_train import infer_sim
from .targets import TFI_TIME, readouts_beside

TFP_WINDOWS = (33, 65)  # the TFP decoders' windows scored beside SIM, in readouts


def compare_methods(
    model: SIM,
    streams: Sequence,
    timestamps: Sequence[int],
    gt: np.ndarray,
    dtype=None,
    own: Sequence[str | None] | None = None,
    flicker: Flicker | None = None,
) -> dict[str, dict[str, float]]:
    """Mean PSNR/SSIM over views of SIM, TFP(33), TFP(65) and TFI at `timestamps` against `gt`
    [N, H, W, C], one SpikeStream of `streams` a channel; a colour view is scored as `spikegs
    eval` scores one, its channels pooled in the PSNR and averaged in the SSIM. A view whose
    ground truth is a method's own image (`own` [N], the method's name or None: a pseudo ground
    truth, TFP of the view's spikes, whatever was repaired or divided out of it since; or equal
    to it: a dataset that kept no name) is left out of that method's mean, and a method left no
    view is left out. Each image is divided by a `flicker` of the light over the readouts it
    shows, as training's targets are.
    TFI(t) spans readouts t and t + 1 (training compares it with the render at t + 0.5); it is
    scored here against the image at t, half a readout apart (at the default speed 0.075° of
    orbit, a fraction of a pixel), small beside its noise."""
    timestamps = np.asarray(timestamps)
    own = [None] * len(timestamps) if own is None else own
    decoded = [_decoded(model, s, timestamps, dtype) for s in streams]  # C x {name: [N, H, W]}
    light = {  # the readouts of the light each image shows: span, time offset
        "SIM": (model.target.stop - model.target.start, 0.0),
        **{f"TFP({w})": (w, 0.0) for w in TFP_WINDOWS},
        "TFI": (1, TFI_TIME),
    }
    gt = np.asarray(gt, dtype=np.float32)
    scores = {}
    for name, (span, offset) in light.items():
        raw = np.stack([channel[name] for channel in decoded], -1)  # [N, H, W, C]
        pred = raw if flicker is None else flicker.divided(raw, timestamps, span, offset)
        # (a dataset that kept no name: its pseudo ground truth equal to the image, divided or
        # not: one made before the flicker was divided out of it)
        pairs = [
            (p, g)
            for p, r, g, o in zip(pred, raw, gt, own)
            if o != name and not np.array_equal(p, g) and not np.array_equal(r, g)
        ]
        if pairs:
            scores[name] = {
                "psnr": float(np.mean([psnr(p, g) for p, g in pairs])),
                "ssim": float(np.mean([ssim(p, g) for p, g in pairs])),
            }
    return scores


def _decoded(model: SIM, stream, timestamps: np.ndarray, dtype) -> dict[str, np.ndarray]:
    """SIM's, TFP(33)'s, TFP(65)'s and TFI's images [N, H, W] of one stream at `timestamps`."""
    return {
        "SIM": infer_sim(model, stream, timestamps, dtype=dtype)[..., 0],
        **{f"TFP({w})": stream.tfp(timestamps, w) for w in TFP_WINDOWS},
        "TFI": stream.tfi(timestamps),
    }


def on_path_views(dataset, sim_window: int) -> list:
    """The dataset's held-out views on the camera path (those SIM can be scored on) around which
    every decoder's window fits, SIM's of `sim_window` readouts too, warning of the others (a
    real recording's view near its start ended sim-train, once SIM had trained, with the window's
    error); ValueError when there is none."""
    views = [v for v in dataset.test_views if v.readout is not None]
    if not views:
        raise ValueError(f"{dataset.root}: no held-out view on the camera path to compare on")
    reach = max(*TFP_WINDOWS, sim_window) // 2
    room = readouts_beside(dataset.streams[0], np.array([round(v.readout) for v in views]))
    near = [f"{v.name} (readout {v.readout:g})" for v, r in zip(views, room) if r < reach]
    if len(near) == len(views):
        raise ValueError(
            f"{dataset.root}: every held-out view on the camera path lies within {reach} readouts "
            f"of its stream's ends, where a {2 * reach + 1}-readout window does not fit: "
            f"{', '.join(near)}; none to compare on"
        )
    if near:
        warnings.warn(
            f"{dataset.root}: held-out views within {reach} readouts of their stream's ends, "
            f"where a {2 * reach + 1}-readout window does not fit, are left out of the scores: "
            f"{', '.join(near)}",
            stacklevel=2,
        )
    return [v for v, r in zip(views, room) if r >= reach]


def evaluate_dataset(
    model: SIM,
    dataset,
    dtype=None,
    streams: list | None = None,
    flicker: Flicker | None = None,
    views: list | None = None,
) -> dict[str, dict[str, float]]:
    """`compare_methods` on a dataset's held-out on-path `views` (default `on_path_views`'),
    against their clean images (a pseudo ground truth's own TFP left out), reading `streams`
    (default the dataset's; one a channel), divided by a `flicker` of the light."""
    views = on_path_views(dataset, model.window) if views is None else views
    timestamps = np.array([round(v.readout) for v in views])
    own = [None if v.window is None else f"TFP({v.window})" for v in views]
    gt = np.stack([v.image for v in views])  # [N, H, W, C] firing rates
    return compare_methods(model, streams or dataset.streams, timestamps, gt, dtype, own, flicker)
