"""What a caller's torch grad mode leaves a training to do: a `torch.no_grad()` left around the
call (a notebook's) is lifted by the trainers; inference mode, whose tensors take no gradient, is
refused by name (torch's errors named internal arguments, or none)."""

from __future__ import annotations

import torch


def refuse_inference_mode(name: str) -> None:
    """RuntimeError naming `name` (the function called) where torch's inference mode is on."""
    if torch.is_inference_mode_enabled():
        raise RuntimeError(
            f"{name}: called under torch.inference_mode(), where no tensor takes a gradient; "
            f"call it outside"
        )
