"""The renders' brightness against their targets', per loss term, over a run's last steps.

A fit far darker (or brighter) than its targets is biased, or has not converged (a dim scene's
Gaussians start from the views' median intensity, 0). The known bias: an L1 norm fits the
median of TFP's whole spike counts, which is 0 wherever most windows hold no spike (under ln 2
spikes on average for Poisson counts, about 0.5 for an integrate-and-fire pixel's regular ones),
so on a dim recording it learns a darker scene, down to black (a 64² scene at 0.02 spikes a
readout at intensity 1: 1 Gaussian, the background's 13.5 dB, in silence; at 0.05: half as
bright). Measured over 100 steps: unbiased fits render 0.96-1.06 times their targets'
brightness on the built-in scenes; L1 on dim TFP(33) 0-0.49. Each colour channel is judged:
a colour scene's dim blue fitted at 39 % of its brightness pooled with red and green at 93 %.
"""

from __future__ import annotations

import math
from collections import deque

import torch

STEPS = 100  # the last steps compared
MIN_STEPS = 50  # a term observed on fewer steps is not judged
LOW, HIGH = 0.8, 1.25  # a ratio outside [LOW, HIGH] is a biased fit
# a colour channel whose targets hold under this fraction of the brightest channel's is not
# judged (a ratio of near-black means: noise)
DARK_CHANNEL = 0.1
CHANNEL_NAMES = ("red", "green", "blue")
# renders averaging below 0 by over a fifth of their targets' brightness diverged (every learning
# rate 1.0: a learnt background at -17); a hair under, a black recording's fit's round-off, not
DIVERGED = -0.2


class FitBrightness:
    """Mean intensities of each loss term's renders and targets, per channel, over its last
    STEPS steps."""

    def __init__(self):
        self._means: dict[str, deque] = {}  # term -> ([C] render means, [C] target means) a step

    def observe(self, term: str, renders: list[torch.Tensor], target: torch.Tensor) -> None:
        """One step's renders [H, W, C] of `term` (the exposure's K, or the instant one) and
        their target [H, W, C]."""
        render = torch.stack([r.detach() for r in renders]).mean(dim=(0, 1, 2))  # [C]
        means = self._means.setdefault(term, deque(maxlen=STEPS))
        means.append((render.tolist(), target.mean(dim=(0, 1)).tolist()))

    def channel_ratios(self) -> dict[str, tuple[dict[str | None, float], int]]:
        """{term: ({channel: its renders' mean brightness / its targets'}, steps)}, for the terms
        observed on MIN_STEPS steps or more whose targets are not black, over their channels
        not DARK_CHANNEL: a colour scene's named (CHANNEL_NAMES), a mono scene's None."""
        ratios = {}
        for term, means in self._means.items():
            renders = [sum(r[c] for r, _ in means) for c in range(len(means[0][0]))]  # [C]
            targets = [sum(t[c] for _, t in means) for c in range(len(renders))]
            names = CHANNEL_NAMES if len(renders) == 3 else [None]
            if len(means) >= MIN_STEPS and max(targets) > 0:
                lit = [c for c, t in enumerate(targets) if t >= DARK_CHANNEL * max(targets)]
                ratios[term] = ({names[c]: renders[c] / targets[c] for c in lit}, len(means))
        return ratios

    def ratios(self) -> dict[str, tuple[float, int, str | None]]:
        """{term: (ratio, steps, channel)} of `channel_ratios`' channel furthest from 1 (by the
        ratio's logarithm) in each term."""
        ratios = {}
        for term, (by_channel, steps) in self.channel_ratios().items():
            worst = max(by_channel, key=lambda c: abs(math.log(max(by_channel[c], 1e-30))))
            ratios[term] = (by_channel[worst], steps, worst)
        return ratios


def biased_fit(brightness: FitBrightness, supervision) -> str | None:
    """What is said of the terms whose ratio lies outside [LOW, HIGH] (None: none), naming an
    L1 norm on TFP's spike counts as the likely cause where the term has one."""
    said, by_channel = [], brightness.channel_ratios()
    for term, (ratio, steps, channel) in brightness.ratios().items():
        if LOW <= ratio <= HIGH:
            continue
        if ratio < DIVERGED:  # (it held "-627 %" of its targets' brightness: the stability trial)
            said.append(
                f"the {term} renders average below 0"
                + (f" in {channel}" if channel else "")
                + f" over the term's last {steps} steps: a diverging fit (nothing keeps the learnt "
                "background at or above 0; learning rates too high?)"
            )
            continue
        text = (
            f"the renders hold {round(100 * ratio)} % of their {term} targets' brightness"
            + (f" in {channel}" if channel else "")
            + f" over the term's last {steps} steps: a biased or unconverged fit"
        )
        fitted = [  # the other terms' ratios in that channel, where fitted
            (other, ratios[channel])
            for other, (ratios, _) in by_channel.items()
            if LOW <= ratios.get(channel, 0.0) <= HIGH
        ]
        counts = term == "exposure" or supervision.instant == "tfp"  # TFP's whole counts
        if getattr(supervision, f"{term}_norm") == "l1" and counts and ratio < LOW:
            window = getattr(supervision, f"{term}_window")
            text += (
                f" (supervision.{term}_norm l1 fits the median of the TFP's whole spike counts, "
                f"0 where most {window}-readout windows hold no spike, under 0.5-0.69 spikes on "
                f"average: dim data; smooth_l1 fits their mean, as the baseline tfp33_smooth_l1 "
                f"does)"
            )
        elif fitted:  # the same model fits the other term's targets: the targets disagree
            other, r = fitted[0]
            sim = term == "instant" and supervision.instant == "sim"
            text += (
                f" (its {other} renders hold {round(100 * r)} % of theirs: the {term} targets"
                + (", SIM's output," if sim else "")
                + f" differ in brightness from the {other} targets"
                + ("; a SIM trained too briefly? sim.iterations" if sim else "")
                + ")"
            )
        said.append(text)
    return "; ".join(said) or None
