"""SIM: the Spike Instant Mapping network, a self-supervised blind-spot net (SpikeGS §3.3, SSML).

Each of four branches sees the spike window rotated by 0/90/180/270°, runs `m` shift-based 3×3
convolutions (receptive field only at or above the pixel) and a final one-row shift (the pixel
itself excluded in every time channel); the un-rotated branches are merged by `n` 1×1 convolutions.

`SIM.forward` computes the same function without rotating any data: a convolution of a rotated
input equals the rotation of a convolution with the rotated kernel, so each branch runs dense
convolutions with its rotated kernels on the unrotated window (padded within the convolution, on
both sides: the margin on the far side is computed and never read). Any H×W works, with no
square padding and no transposes. (One grouped convolution of the four branches on a shared
zero-framed canvas, the form before, ran 1.2-1.4× slower on an AVX2 CPU: oneDNN's grouped
kernels reach less of the FMA units than its dense ones, BENCHMARKS.md, "SIM".)
`SIM.forward_rotated` is the literal rotate-the-data formulation, the reference the fast path is
tested against.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .float32 import F32
from .number_checks import is_int

# The side each branch looks towards, as a (row, col) step in the unrotated frame: k = 0 up,
# 1 right, 2 down, 3 left (torch.rot90 by k = 1 puts the original right side on top).
_DIRS = ((-1, 0), (0, 1), (1, 0), (0, -1))
_SLOPE = 0.1  # leaky ReLU slope
START = "zero-output"  # how a fresh SIM starts (a SIM cached from another start is retrained)


def _into_blind_spot(out: torch.Tensor, y: torch.Tensor, k: int) -> None:
    """Write branch k's output into `out` [B, width, H, W]: from `y`, its last convolution's
    output with a margin of rows (columns) on the far side of k's axis (`SIM.forward`), each pixel
    takes its neighbour's value on k's side (zeros past the image), the blind spot, in the
    unrotated frame."""
    h, w = out.shape[-2:]
    dr, dc = _DIRS[k]
    # where the image lies in y: after the margin, for a branch that looks down (right)
    r0, c0 = (y.shape[-2] - h) * int(dr > 0), (y.shape[-1] - w) * int(dc > 0)
    if dr < 0:
        out[..., 1:, :].copy_(y[..., r0 : r0 + h - 1, :])
        out[..., 0, :].zero_()
    elif dr > 0:
        out[..., :-1, :].copy_(y[..., r0 + 1 : r0 + h, :])
        out[..., -1, :].zero_()
    elif dc < 0:
        out[..., 1:].copy_(y[..., :, c0 : c0 + w - 1])
        out[..., 0].zero_()
    else:
        out[..., :-1].copy_(y[..., :, c0 + 1 : c0 + w])
        out[..., -1].zero_()


class SIM(nn.Module):
    """Blind-spot map from a spike window [B, window, H, W] (0/1) to an image [B, C, H, W].

    The output at a pixel never depends on that pixel's own spikes; each branch sees a block
    2m+1 wide and 2m+1 deep on its side of the pixel, m = `shift_layers`. It learns the TFP of
    the `target_window` readouts at the window's centre (default: all).
    """

    def __init__(
        self,
        window: int = 33,
        out_channels: int = 1,
        width: int = 32,
        head_width: int = 32,
        shift_layers: int = 3,
        head_layers: int = 3,
        target_window: int | None = None,
    ):
        super().__init__()
        sizes = {"window": window, "out_channels": out_channels, "width": width}
        sizes.update(head_width=head_width, shift_layers=shift_layers, head_layers=head_layers)
        for name, value in sizes.items():  # (numpy's integers too, as Python ints)
            if not is_int(value) or value < 1:
                raise ValueError(f"SIM {name} expected a positive int, found {value!r}")
        window, out_channels, width, head_width, shift_layers, head_layers = map(
            int, sizes.values()
        )
        target_window = window if target_window is None else target_window
        if not is_int(target_window):
            raise ValueError(f"SIM target window expected an int, found {target_window!r}")
        target_window = int(target_window)
        if not (1 <= target_window <= window and (window - target_window) % 2 == 0):
            raise ValueError(
                f"SIM target window {target_window}: expected 1..{window} and centred in the "
                f"{window}-readout input window (same parity)"
            )
        self.config = {
            "window": window,
            "out_channels": out_channels,
            "width": width,
            "head_width": head_width,
            "shift_layers": shift_layers,
            "head_layers": head_layers,
            "target_window": target_window,
        }
        self.window = window
        first = (window - target_window) // 2
        self.target = slice(first, first + target_window)  # the readouts whose TFP SIM learns
        self.out_channels = out_channels
        # (float32 layers whatever torch's default dtype, as its spike windows)
        self.shift = nn.ModuleList(
            nn.Conv2d(window if i == 0 else width, width, 3, **F32) for i in range(shift_layers)
        )
        head_in = [4 * width] + [head_width] * (head_layers - 1)
        head_out = [head_width] * (head_layers - 1) + [out_channels]
        self.head = nn.ModuleList(nn.Conv2d(i, o, 1, **F32) for i, o in zip(head_in, head_out))
        # The output layer starts at zero: the network's first output is 0 and the features grow
        # from there. With PyTorch's default start, 300 training steps ended wherever the random
        # output layer had set them (SIM's bias 30.8 / 32.9 / 34.0 dB for seeds 0 / 1 / 2; 33.1 /
        # 33.1 / 33.9 from zero: BENCHMARKS.md, "What decides a 300-step SIM")
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)

    def field(self) -> int:
        """Side in pixels of the square an output pixel depends on: 2(2m + 1) + 1, as each
        branch's m shift convolutions and the blind spot's shift reach 2m + 1 rows out."""
        return 4 * len(self.shift) + 3

    @staticmethod
    def spanning_layers(height: int, width: int) -> int:
        """The fewest shift layers whose every output on `height`×`width` frames sees every
        other pixel: a branch's m layers reach 2m + 1 pixels along its axis and m across, so
        from a corner the far pixel lies in the field of the branch along the longer side from
        this many layers on."""
        return max(1, -(-(max(height, width) - 2) // 2), min(height, width) - 1)

    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())

    def _merge(self, y: torch.Tensor) -> torch.Tensor:
        """The 1×1 head on the concatenated branches [B, 4·width, H, W] -> [B, C, H, W].

        The output is clamped to [0, 1] outside training only: a saturating activation (sigmoid)
        can die under the L1 loss when the targets are low firing rates.
        """
        for conv in self.head[:-1]:
            y = F.leaky_relu(conv(y), _SLOPE, inplace=True)
        y = self.head[-1](y)
        return y if self.training else y.clamp(0.0, 1.0)

    def check_input(self, x: torch.Tensor) -> None:
        """ValueError unless x is a spike window [B, window, H, W] in the weights' dtype."""
        dtype = self.head[-1].weight.dtype
        if (
            not isinstance(x, torch.Tensor)
            or x.dim() != 4
            or x.shape[1] != self.window
            or min(x.shape[2:]) < 1
        ):
            found = list(x.shape) if isinstance(x, torch.Tensor) else type(x).__name__
            raise ValueError(
                f"SIM input expected [B, {self.window}, H, W], H, W ≥ 1, found {found}"
            )
        if x.dtype != dtype:
            raise ValueError(f"SIM input expected dtype {dtype} (the weights'), found {x.dtype}")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Spike window [B, window, H, W] -> image [B, C, H, W] in x's dtype (autocast's under
        autocast, as torch's convolutions) and memory format.

        Each shift convolution pads 2 on both sides along its branch's axis (1 across) within
        the convolution, not as a copy: a branch that sees the pixel's row and those above it
        (k = 0) reads its output from rows [0, H), the rows past them hold values that no output
        pixel reads, and each layer adds two (k = 2 reads rows [2m, 2m + H)). The branches are
        written into one tensor, not concatenated. (The padding copies and the concatenation
        were 29 % of a 256² frame's time, BENCHMARKS.md, "SIM".)
        """
        self.check_input(x)
        b, _, h, w = x.shape
        width = self.shift[0].out_channels
        layout = (
            torch.channels_last
            if x.is_contiguous(memory_format=torch.channels_last)
            else torch.contiguous_format
        )
        shape = (b, 4 * width, h, w)  # the branches side by side
        merged = torch.empty(shape, dtype=x.dtype, device=x.device, memory_format=layout)
        for k, (dr, _) in enumerate(_DIRS):
            y = x
            for conv in self.shift:  # sees the pixel's row (column) and those on side k only
                kernel = torch.rot90(conv.weight, -k, dims=(2, 3))  # seen from the unrotated frame
                y = F.conv2d(y, kernel, conv.bias, padding=(2, 1) if dr else (1, 2))
                y = F.leaky_relu(y, _SLOPE, inplace=True)
            _into_blind_spot(merged[:, k * width : (k + 1) * width], y, k)
        return self._merge(merged)

    def forward_rotated(self, x: torch.Tensor, square: bool = False) -> torch.Tensor:
        """The literal formulation: rotate the data, shift-convolve, un-rotate, merge.

        The 0/180° and 90/270° pairs share a shape and run as two batches; `square=True` instead
        zero-pads H×W to a square and runs all four rotations as one batch, the straightforward
        version (its bottom/right border differs where the padding leaks in).
        """
        self.check_input(x)
        h, w = x.shape[-2:]
        if square:
            s = max(h, w)
            x = F.pad(x, (0, s - w, 0, s - h))
        turns = [(0, 2), (1, 3)] if not square else [(0, 1, 2, 3)]
        branches = {}
        for group in turns:
            y = torch.cat([torch.rot90(x, k, dims=(2, 3)) for k in group])  # [len·B, T, H', W']
            for conv in self.shift:
                y = F.leaky_relu(conv(F.pad(y, (1, 1, 2, 0))), _SLOPE)  # rows at or above only
            y = F.pad(y, (0, 0, 1, 0))[..., :-1, :]  # the blind spot: down one row
            for k, part in zip(group, y.chunk(len(group))):
                branches[k] = torch.rot90(part, -k, dims=(2, 3))[..., :h, :w]
        return self._merge(torch.cat([branches[k] for k in range(4)], dim=1))
