"""The held-out PSNR falling during a run: a fit that diverged (learning rates too high) or, with
few training views, one that overfits them, or, on faint light, one that fits its shot noise."""

from __future__ import annotations

import math

# a fall of the held-out PSNR below its best at an earlier evaluation of this many dB, or more, is
# said as the run ends. Measured (BENCHMARKS.md, "When a run goes wrong"): every lr x20 fell 5.06
# dB (128² solids, 750 iterations); the 459 logs on the audit's machine with two evaluations or
# more fell 1.94 dB at most (a 40-iteration test's), the 105 of 1000 iterations or more 0.81
FALL_DB = 3.0


def psnr_fall(curve: list[dict]) -> str | None:
    """What to say where a logged curve [{"iteration", "psnr", ...}] fell FALL_DB or more below
    its best at an earlier evaluation (its largest such fall), else None; a PSNR that is None
    (log.jsonl's null for inf or NaN) or not finite is passed over."""
    best, fall = None, None  # (iteration, psnr) of the best so far; (dB, best, at, psnr)
    for r in curve:
        psnr = r["psnr"]
        if psnr is None or not math.isfinite(psnr):  # inf, logged as null: no fall to measure
            continue
        if best is not None and best[1] - psnr > (fall[0] if fall else 0.0):
            fall = (best[1] - psnr, best, r["iteration"], psnr)
        if best is None or psnr > best[1]:
            best = (r["iteration"], psnr)
    if fall is None or fall[0] < FALL_DB:
        return None
    db, (then, peak), at, psnr = fall
    return (
        f"the held-out PSNR fell {db:.2f} dB, from {peak:.2f} at iteration {then} to {psnr:.2f} "
        f"at {at} (log.jsonl): a fit that diverged (learning rates too high: every lr x20 fell "
        f"5 dB) or, with few training views, one that overfits them, or on light too faint to "
        f"count a spike in a window, one that fits its shot noise (loading names such light: a "
        f"FaintLightWarning); check `lr:` against the method's (docs/training.md, 'When a run "
        f"goes wrong')"
    )
