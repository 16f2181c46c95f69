"""Keyword arguments that make a tensor float32 whatever torch's default dtype a caller set (a
script's float64 failed training with pose refinement; float16 changed the run)."""

from __future__ import annotations

import torch

F32 = {"dtype": torch.float32}  # torch.zeros(n, **F32)
