"""PSNR and SSIM (scikit-image) against ground truth, on [H, W] or [H, W, C] images in [0, 1]."""

from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity


def _pair(pred, gt) -> tuple[np.ndarray, np.ndarray]:
    pred, gt = np.asarray(pred, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    if pred.shape != gt.shape or pred.ndim not in (2, 3):
        raise ValueError(
            f"expected two [H, W] or [H, W, C] images, got {pred.shape} and {gt.shape}"
        )
    return pred, gt


def psnr(pred, gt) -> float:
    """PSNR in dB with data range 1 (inf for identical images)."""
    pred, gt = _pair(pred, gt)
    return float(peak_signal_noise_ratio(gt, pred, data_range=1.0))


def ssim(pred, gt) -> float:
    """SSIM with data range 1 (7×7 window; colour channels averaged)."""
    pred, gt = _pair(pred, gt)
    channel_axis = -1 if pred.ndim == 3 else None
    return float(structural_similarity(gt, pred, data_range=1.0, channel_axis=channel_axis))
