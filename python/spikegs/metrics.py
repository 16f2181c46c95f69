"""PSNR and SSIM (scikit-image's, and 3DGS's) against ground truth, on [H, W] or [H, W, C] float
images (numpy arrays or torch tensors) in [0, 1]: intensities, as renders are (a dataset's images
are in firing-rate units: divide by `targets.intensity_scale`)."""

from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from .number_checks import non_finite_pixels


def image_pair(pred, gt) -> tuple[np.ndarray, np.ndarray]:
    """`pred` and `gt` (arrays or tensors) as float64 [H, W] or [H, W, C] images; ValueError for
    integer codes (data range 1: 8-bit 200 against 100 scored -40 dB), a channels-first image
    (a [3, H, W] tensor's layout was scored as 3 rows of W pixels with H channels), an empty
    image (scored NaN) or values that are not finite (a NaN scored NaN, unsaid)."""
    pred, gt = _image(pred), _image(gt)
    if pred.shape != gt.shape or pred.ndim not in (2, 3) or pred.size == 0:
        sizes = [image.shape[:2] for image in (pred, gt)]  # (a colour model on a mono dataset)
        channels = [image.shape[2] if image.ndim == 3 else 1 for image in (pred, gt)]
        other = sizes[0] == sizes[1] and channels[0] != channels[1] and min(pred.ndim, gt.ndim) > 1
        raise ValueError(
            f"expected two [H, W] or [H, W, C] images of one shape, not empty, got {pred.shape} "
            f"and {gt.shape}"
            + (f": {channels[0]} channel(s) against {channels[1]}" if other else "")
        )
    if pred.ndim == 3 and pred.shape[0] <= 4 < pred.shape[2]:
        raise ValueError(
            f"expected [H, W, C] images, got {list(pred.shape)}: channels first? "
            f"np.moveaxis(image, 0, -1)"
        )
    _check_finite(pred, "pred (the render)")
    _check_finite(gt, "gt (the ground truth)")
    return np.asarray(pred, np.float64), np.asarray(gt, np.float64)  # (no copy of float64)


def _check_finite(image: np.ndarray, name: str) -> None:
    """ValueError naming `name`, how many of its pixels hold a NaN or inf and where the first is."""
    found = non_finite_pixels(image)
    if found is not None:
        count, (y, x, *_) = found
        raise ValueError(
            f"{name}: {count} of {image.shape[0] * image.shape[1]} pixels not finite (NaN or "
            f"inf), the first at row {y}, column {x}: expected finite images (a NaN scores NaN)"
        )


def _image(x) -> np.ndarray:
    """`x` (an array or a tensor) as a float numpy array; ValueError for integer or bool values."""
    if hasattr(x, "detach"):  # a torch tensor, perhaps requiring grad, perhaps bfloat16
        x = x.detach().cpu()
        x = (x.double() if x.is_floating_point() else x).numpy()
    x = np.asarray(x)
    if x.dtype.kind != "f":
        raise ValueError(
            f"expected float images in [0, 1] (data range 1), found {x.dtype.name} values "
            f"(8-bit codes: image / 255)"
        )
    return x


def psnr(pred, gt) -> float:
    """PSNR in dB with data range 1 (inf for identical images, without numpy's warning)."""
    pred, gt = image_pair(pred, gt)
    with np.errstate(divide="ignore"):
        return float(peak_signal_noise_ratio(gt, pred, data_range=1.0))


def ssim(pred, gt) -> float:
    """SSIM with data range 1 (scikit-image's 7×7 uniform window, where 3DGS's evaluation takes an
    11×11 Gaussian one, `ssim_3dgs`; colour channels averaged). A side shorter than 7
    pixels takes the largest odd window that fits, a side of one pixel is dropped (a line image:
    1-D SSIM); a side of 2 pixels, or a single pixel, is a ValueError."""
    pred, gt = image_pair(pred, gt)
    shape = list(pred.shape[:2])
    keep = tuple(n for n in shape if n > 1) or (1,)
    pred, gt = pred.reshape(*keep, -1), gt.reshape(*keep, -1)  # [H', W', C] or [L, C] (C ≥ 1)
    side = min(min(keep), 7)
    win = side if side % 2 else side - 1
    if win < 3:
        raise ValueError(f"SSIM needs sides of 1 or at least 3 pixels (not all 1), got {shape}")
    value = structural_similarity(gt, pred, data_range=1.0, channel_axis=-1, win_size=win)
    return float(value)


def ssim_3dgs(pred, gt) -> float:
    """SSIM as 3DGS's evaluation computes it (its `ssim`, which most 3DGS papers report): an 11×11
    Gaussian window (σ = 1.5) with zero padding, the mean over every pixel and channel; data
    range 1, images [H, W] or [H, W, C]. Not scikit-image's `ssim` above: compare with papers."""
    import torch

    from .losses import dssim  # (1 - SSIM) / 2 with this window

    pred, gt = image_pair(pred, gt)
    if pred.ndim == 2:
        pred, gt = pred[..., None], gt[..., None]
    return float(1 - 2 * dssim(torch.from_numpy(pred), torch.from_numpy(gt)))
