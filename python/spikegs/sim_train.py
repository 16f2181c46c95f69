"""Per-scene self-supervised SIM training (against TFP of the window centre), its cache, save/load,
inference.

A stream is anything with `len(stream)`, `.height`, `.width`, `.window(k, w)` -> uint8 0/1
[w, H, W] ([B, w, H, W] for an array of k), `.tfp(k, w)` and `.tfi(k)` -> float32 [H, W]
([B, H, W]).
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from .atomic_save import save_atomically, sweep_killed_writes
from .cache_home import cache_home
from .config import SimConfig
from .data_fingerprint import spikes_fingerprint
from .file_lock import exclusive_lock
from .grad_mode import refuse_inference_mode
from .interrupt import deferred_interrupt, interruption, progress_lost, quiet_close
from .losses import SIM_LOSSES
from .machine_memory import machine_memory
from .number_checks import is_int, is_number
from .output_paths import record_beside, writable_folder
from .sim import SIM, START
from .spikes.stream import as_readouts, centred_range

CHECKPOINT_S = 30.0  # SIM's training state saved at least this often (seconds)
SAVED_EVERY = f"saved every {CHECKPOINT_S:g} s and as it stops"  # what a stop's message says


@functools.lru_cache(maxsize=1)
def bf16_is_fast() -> bool:
    """Whether the CPU has native bfloat16 arithmetic (AVX-512 BF16 or AMX), not an emulation."""
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return False
    return "avx512_bf16" in flags or "amx_bf16" in flags


def _fast_dtype(dtype: torch.dtype | None) -> torch.dtype:
    """`dtype`, or bfloat16 where it is native (it holds SIM's error), else float32."""
    return dtype or (torch.bfloat16 if bf16_is_fast() else torch.float32)


def training_layout(bf16: bool) -> torch.memory_format:
    """The memory layout SIM trains in: channels-last under bfloat16 autocast (oneDNN's bf16
    kernels), channels-first in float32, where a step of 64² crops is 1.20× (batch 8) to 1.35×
    (batch 2) faster than channels-last on an AVX2 CPU (BENCHMARKS.md, "Training"). Inference
    keeps channels-last."""
    return torch.channels_last if bf16 else torch.contiguous_format


def _to_input(
    windows: np.ndarray, dtype: torch.dtype, layout: torch.memory_format = torch.channels_last
) -> torch.Tensor:
    """uint8 windows [B, w, H, W] -> network input in `dtype` and `layout`."""
    x = torch.from_numpy(np.ascontiguousarray(windows)).to(dtype)
    return x.contiguous(memory_format=layout)


# bytes a training step holds per crop pixel and feature map (the window's, and width or
# head_width per shift or head layer): measured 10.7 under bfloat16 autocast and 22.7 in float32
# (64² crops, batch 36 to 100, 2026-12-07); the lower, so that only a batch that cannot fit in
# memory is refused (5000 crops of 64² were killed by the kernel at 24 GB, with no word)
STEP_BYTES_PER_MAP = 10
FINAL_LOSS_STEPS = 50  # a SIM's final_loss: the mean loss of its last steps (saved, and bench's)


@torch.enable_grad()  # (a notebook's torch.no_grad() left around it: torch's error at a step)
def train_sim(
    stream,
    timestamps: Sequence[int],
    window: int = SimConfig.window,
    *,
    steps: int = SimConfig.iterations,
    batch_size: int = SimConfig.batch,
    crop: int = SimConfig.crop,
    lr: float = 2e-3,
    loss: str = SimConfig.loss,
    target_window: int | None = None,
    seed: int = 0,
    bf16: bool | None = None,
    progress: bool = True,
    checkpoint: Path | None = None,
    checkpoint_key: dict | None = None,
    resume: dict | None = None,
    **sim_kwargs,
) -> tuple[SIM, list[float]]:
    """Train a fresh SIM on random `crop`² crops (the whole frame along a side shorter than `crop`)
    of windows at random training `timestamps`. The window, steps, batch, crop and loss default
    to `SimConfig`'s, what `spikegs train` trains.

    `stream` may be a list of streams (a colour camera's channels): each crop then comes from a
    random one of them, and the one network serves every channel.

    The target is TFP of the centre `target_window` readouts of the input window (default: the
    whole window, the paper's eq. 15). The blind spot keeps the pixel's own spikes out of the
    input, so the optimum is the mean light over the target window given the neighbours' spikes
    over the whole window: a shorter target keeps the input's context for denoising but less of
    the window's motion blur (noisier targets cost training variance, not bias). `loss` "l2"
    (default) makes the optimum the conditional mean, the Noise2Void argument the paper states;
    "l1" (the paper's eq. 15) makes it the conditional median, biased where a window holds few
    spikes (a short window or a dim scene: 33.6 dB against 41.2 dB with l2 for a 17-readout
    window on `solids`).
    `bf16`: convolutions under bfloat16 autocast (float32 weights and loss), 2-3× faster; by
    default where native. Steps run the rotate-the-data network (`SIM.forward_rotated`, the same
    function as `forward`, which infers): on 64² crops in float32 a step takes as long as through
    `forward` (`spikegs bench sim`), and the SIMs trained so far are reproduced bit for bit.
    Deterministic for a given `seed` and thread count. Returns the model (eval mode) and the loss
    of every step.
    `checkpoint`: a file that holds the training state, tagged with `checkpoint_key` (what the
    caller's result depends on), at least every CHECKPOINT_S seconds; `resume`: such a state
    (`_resumable`) to continue from, to the same result as a run never interrupted.
    """
    refuse_inference_mode("train_sim")
    timestamps, _ = as_readouts(timestamps)  # (2-D ones: numpy's error at the first step)
    if timestamps.size == 0:
        raise ValueError("no training timestamps")
    for name, value in {"steps": steps, "batch_size": batch_size, "crop": crop}.items():
        if not is_int(value) or value < 1:  # (torch's errors, or numpy's, at the first step)
            raise ValueError(f"SIM {name} expected a positive int, found {value!r}")
    if loss not in SIM_LOSSES:
        raise ValueError(f"SIM loss '{loss}': expected one of {', '.join(SIM_LOSSES)}")
    rng = np.random.default_rng(seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        model = SIM(window=window, target_window=target_window, **sim_kwargs)
    bf16 = bf16_is_fast() if bf16 is None else bf16
    layout = training_layout(bf16)
    model = model.to(memory_format=layout).train()
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=steps)
    streams = _streams(stream)
    _check_windows(streams, timestamps, window)
    height, width = streams[0].height, streams[0].width
    ch, cw = min(crop, height), min(crop, width)
    _check_step_memory(model, batch_size, ch, cw)
    if crop < min(model.field(), max(height, width)):
        warnings.warn(
            f"SIM crop {crop}: under the {model.field()}-pixel square an output sees, so training "
            f"sees the zero border where inference sees the frame; crop {model.field()} or more "
            f"(sim-train --crop, a method config's sim.crop)",
            stacklevel=2,
        )
    spanning = model.spanning_layers(height, width)
    if len(model.shift) > spanning:
        warnings.warn(
            f"SIM's shift_layers {len(model.shift)} on {height}×{width} frames: {spanning} reach "
            f"every pixel from every other, the others add the zero border only and cost time; "
            f"sim.shift_layers {spanning} or fewer (a method config's; sim-train trains the "
            f"default, {SimConfig.shift_layers})",
            stacklevel=2,
        )
    losses, first, earlier = [], 0, 0.0  # earlier: seconds of the steps in a resumed state
    if resume is not None:
        model.load_state_dict(resume["model"])
        opt.load_state_dict(resume["opt"])
        sched.load_state_dict(resume["sched"])
        rng.bit_generator.state = resume["rng"]
        losses, first, earlier = resume["losses"], resume["step"], resume.get("seconds", 0.0)
        print(f"{checkpoint}: SIM's training resumes at step {first} of {steps}", file=sys.stderr)
    began = saved = time.monotonic()
    bar = tqdm(
        initial=first,
        total=steps,
        desc="SIM",
        disable=not progress,
        dynamic_ncols=True,
    )

    def save_state(done: int) -> None:  # after `done` steps
        state = {
            "model": model.state_dict(),
            "opt": opt.state_dict(),
            "sched": sched.state_dict(),
            "rng": rng.bit_generator.state,
            "losses": losses,
            "step": done,
            "seconds": earlier + time.monotonic() - began,  # training time of those steps
            "key": checkpoint_key,
        }
        save_atomically(state, checkpoint)

    kept = ", its state saved" if checkpoint is not None else ""  # (bench sim's keeps none)
    message = "\n{signal}: SIM's training stops after this step" + kept
    # (the bar's output gone at its close: the steps are done, the caller's output says so)
    with deferred_interrupt(message, " (again: at once)") as interrupted, quiet_close(bar):
        for step in range(first, steps):
            ks = rng.choice(timestamps, batch_size)
            channel = (
                rng.integers(len(streams), size=batch_size) if len(streams) > 1 else [0] * len(ks)
            )
            windows = [streams[c].window(k, window) for c, k in zip(channel, ks)]  # B x [w, H, W]
            ys = rng.integers(0, height - ch + 1, batch_size)
            xs = rng.integers(0, width - cw + 1, batch_size)
            crops = np.stack([s[:, y : y + ch, x : x + cw] for s, y, x in zip(windows, ys, xs)])
            x = _to_input(crops, torch.float32, layout)  # [B, w, ch, cw]
            target = x[:, model.target].mean(dim=1, keepdim=True)  # [B, 1, ch, cw]
            with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
                pred = model.forward_rotated(x)  # [B, 1, ch, cw]
            step_loss = SIM_LOSSES[loss](pred.float(), target)
            opt.zero_grad(set_to_none=True)
            step_loss.backward()
            opt.step()
            sched.step()
            losses.append(step_loss.item())
            gone = progress_lost(lambda: _show_step(bar, losses), bar)
            due = time.monotonic() - saved >= CHECKPOINT_S
            if checkpoint is not None and (due or interrupted() or gone is not None):
                save_state(step + 1)
                saved = time.monotonic()
            if interrupted():  # the last step too: the caller would go on to minutes of work
                raise interruption(interrupted())
            if gone is not None:  # nothing to show the rest to: stopped, as `| head` stops it
                raise gone
    return model.eval(), losses


def _show_step(bar, losses: list[float]) -> None:
    """A step done on the bar, with the mean loss of the last 50 every 50 steps."""
    if len(losses) % 50 == 0:
        bar.set_postfix(loss=f"{np.mean(losses[-50:]):.4f}")
    bar.update(1)


def _streams(stream) -> list:
    """`stream` as a list of streams: a colour camera's channels, or the one; ValueError where
    they differ in frame size (crops of the larger came from the first one's rows alone)."""
    streams = list(stream) if isinstance(stream, (list, tuple)) else [stream]
    sizes = [f"{s.height}x{s.width}" for s in streams]
    if len(set(sizes)) > 1:
        raise ValueError(f"SIM's streams (a camera's channels) differ in frame size: {sizes}")
    return streams


def _resumable(checkpoint: Path | None, key: dict | None) -> dict | None:
    """The training state saved at `checkpoint` for `key`, or None (no file, another key, or a
    file that cannot be read: training starts afresh)."""
    if checkpoint is None or not Path(checkpoint).exists():
        return None
    try:
        state = torch.load(checkpoint, map_location="cpu", weights_only=True)
    except Exception as err:  # a torn file: start afresh, as without one (torch's own message
        print(  # advised loading it with weights_only=False, which runs a file's code)
            f"{checkpoint}: unreadable ({type(err).__name__}: torn, or not a SIM training's "
            f"state); training SIM from the start",
            file=sys.stderr,
        )
        return None
    if isinstance(state, dict) and state.get("key") == key:
        return state
    print(  # (an earlier version's, or other settings': its steps cannot be continued)
        f"{checkpoint}: an interrupted SIM training of other settings or spikes, or of an "
        f"earlier spikegs; training SIM from the start",
        file=sys.stderr,
    )
    return None


def save_sim(model: SIM, path: Path, **meta) -> None:
    """Save weights, architecture and `meta` (seed, steps, ...) to `path`."""
    path = Path(path)
    save_atomically({"config": model.config, "state_dict": model.state_dict(), "meta": meta}, path)


def weights_digest(model: SIM) -> str:
    """SHA-256 of a SIM's weights, in their order (one SIM's identity: SIM trained at another
    thread count or precision is another, every weight)."""
    digest = hashlib.sha256()
    for name, tensor in model.state_dict().items():
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def _read_saved(path: Path) -> dict:
    """What `save_sim` wrote at `path`; ValueError saying why the file is not that."""
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises RuntimeError, EOFError, pickle errors, ...
        raise ValueError(f"unreadable ({type(err).__name__})") from None
    parts = ("config", "state_dict", "meta")
    if not (isinstance(payload, dict) and all(isinstance(payload.get(k), dict) for k in parts)):
        raise ValueError("not a saved SIM")
    return payload


def recorded_meta(path: Path) -> dict:
    """The meta that the SIM saved at `path` recorded ({} where it is no saved SIM)."""
    try:
        return _read_saved(path)["meta"]
    except ValueError:
        return {}


def recorded_seconds(path: Path) -> float:
    """The training seconds that the SIM saved at `path` recorded (0 where it records none or
    is no saved SIM)."""
    return meta_seconds(recorded_meta(path))


def meta_seconds(meta: dict) -> float:
    """The training seconds a saved SIM's `meta` records (0 where it records none)."""
    seconds = meta.get("seconds", 0.0)
    return float(seconds) if is_number(seconds) and seconds > 0 else 0.0


def is_sim_file(path: Path) -> bool:
    """Whether `path` holds a SIM saved by `save_sim` (weights, architecture and meta)."""
    try:
        _read_saved(path)
    except ValueError:
        return False
    return True


def _model_of(payload: dict) -> SIM:
    """The SIM of a saved payload (`_read_saved`'s), in eval mode; ValueError where its
    architecture or weights are no SIM's (an edited or another program's file: torch's
    TypeError or RuntimeError ended `spikegs train` where it reads its cache)."""
    try:  # SIM's default init, replaced by the state, drew from torch's global generator (CPU's)
        with torch.random.fork_rng(devices=[]):
            model = SIM(**payload["config"])
        model.load_state_dict(payload["state_dict"])
    except (TypeError, RuntimeError, ValueError) as err:
        detail = (str(err).strip().splitlines() or [""])[0][:200]  # (torch's run to pages)
        raise ValueError(f"not a saved SIM's architecture or weights ({detail})") from None
    return model.eval()


def load_sim(path: Path) -> SIM:
    """The SIM saved at `path`, in eval mode; FileNotFoundError where there is no such file,
    ValueError naming the file where it is not a saved SIM."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such file (a SIM saved by spikegs sim-train)")
    try:
        return _model_of(_read_saved(Path(path)))
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None


def _crop_taken(settings: dict, side: int) -> dict:
    """SIM training `settings` with their crop as training takes it: at most `side`."""
    crop = settings.get("crop")
    return {**settings, "crop": min(crop, side)} if is_int(crop) else dict(settings)


def _cached(
    path: Path,
    window: int,
    data: tuple[str, ...],
    settings: dict,
    side: int,
    say: bool = True,
    keep: bool = False,
) -> SIM | None:
    """The SIM saved at `path` if it was trained for `window` on spikes of a fingerprint in
    `data` from this package's start with training `settings` (train_sim's keywords) on frames
    whose larger side is `side`; None (saying why where a file is there, if `say`) otherwise;
    FileExistsError saying why where a file is there and `keep` (a file the user named)."""
    if not path.exists():
        return None
    try:
        payload = _read_saved(path)
        model = _model_of(payload)
    except ValueError as err:
        why = str(err)
    else:
        # crops as trained, at most the larger side (SIMs saved before 2026-11-25 recorded the
        # crop asked for: a SIM of 32² frames saved as crop 64 was retrained, bit for bit)
        meta, now = (_crop_taken(m, side) for m in (payload["meta"], settings))
        same = (model.window, meta.get("start")) == (window, START)
        same = same and meta.get("data") in data
        other = {k: (meta.get(k), v) for k, v in now.items() if meta.get(k) != v}
        if same and not other:
            return model
        why = (
            "a SIM trained with other settings ("
            + ", ".join(f"{k} {was!r}, now {now!r}" for k, (was, now) in other.items())
            + ")"
            if same
            else "a SIM trained on other spikes, for another window or from another start"
        )
    if keep:  # (why: "a SIM trained ..." or "not a saved SIM's architecture or weights (...)")
        raise FileExistsError(
            f"{path}: {why}, which training would replace; --force trains afresh over it, or "
            f"give another --out"
        )
    if say:
        print(f"{path}: {why}; training SIM afresh", file=sys.stderr)
    return None


def user_cache(name: str, data: str) -> Path | None:
    """Where a SIM for spikes of fingerprint `data` is cached when its dataset's folder cannot be
    written: $XDG_CACHE_HOME (an absolute path, as the XDG spec has it), else ~/.cache, then
    spikegs/sim/<fingerprint>/name; None where neither is known (no home directory)."""
    home = cache_home()
    return None if home is None else home / "sim" / data[:16] / name


def train_or_load(
    path: Path,
    stream,
    timestamps,
    window: int = SimConfig.window,
    force: bool = False,
    keep: bool = False,
    alternates: Sequence[Path] = (),
    **kwargs,
):
    """Load the SIM at `path` if it was trained for this window on these spikes (the same
    `spikes_fingerprint`) with these settings (`kwargs`), unless `force`, or else such a SIM at
    one of `alternates` or in the user cache in place of either (read, never replaced); else
    train one and save it at `path` (a SIM there trained otherwise refused where `keep`: a file
    the user named). Where `path`'s folder cannot be written (a read-only dataset), `user_cache`
    stands in for it.

    Returns (model, seconds spent training, 0 when loaded; a resumed training's earlier steps
    included, the path it was loaded from or saved at).
    """
    path = Path(path)
    data = spikes_fingerprint(stream, timestamps)
    known = (data, spikes_fingerprint(stream, timestamps, sampled=True))  # a SIM's of today, before
    settings = {k: v for k, v in kwargs.items() if k != "progress"}
    first = _streams(stream)[0]
    side = max(first.height, first.width)
    model = None if force else _cached(path, window, known, settings, side, say=False, keep=keep)
    # where `path` and `alternates` are cached while their folder cannot be written (None: no
    # home directory); read where it can be too, a SIM stranded there (trained again once the
    # dataset could be written), but for a file the user named, which is that file alone
    in_cache = [user_cache(Path(p).name, data) for p in (path, *alternates)]
    # (os.path.exists: a cache that cannot be read is none; Path.exists raised PermissionError)
    stranded = [] if keep else [p for p in in_cache if p is not None and os.path.exists(p)]
    for other in [*alternates, *stranded] if model is None and not force else ():
        model = _cached(Path(other), window, known, settings, side, say=False)
        if model is not None:
            return model, 0.0, Path(other)
    if model is None and not writable_folder(path.parent):
        fallback, *others = in_cache  # (the alternates' read alone)
        if fallback is None or not writable_folder(fallback.parent):
            raise OSError(
                f"SIM cannot be cached: {path.parent} cannot be written, nor the user cache "
                f"{fallback.parent if fallback else '(no home directory)'}; set XDG_CACHE_HOME "
                f"to a writable folder"
            )
        print(f"{path.parent} cannot be written: SIM is cached in {fallback}", file=sys.stderr)
        # a SIM cached there before 2026-11-28 lies under the sampled fingerprint's folder
        legacy = user_cache(path.name, known[1])
        path, keep = fallback, False  # (a cache, not the file the user named)
        # (those `stranded` were read above)
        for cached in (fallback, legacy, *others) if not force else ():
            if cached in stranded:
                continue
            model = _cached(cached, window, known, settings, side, say=False)
            if model is not None:
                path = cached
                break
    if model is not None:
        return model, 0.0, path
    for saved in (path, record_beside(path)):  # (they were found folders once SIM had trained)
        if saved.is_dir():
            raise IsADirectoryError(
                f"{saved}: a folder where SIM's {'weights' if saved == path else 'scores'} are "
                f"saved, which SIM's training would end at; move or delete it"
            )
    # one process trains each SIM: another (a second method on the same dataset) waits for it and
    # loads what it saved
    path.parent.mkdir(parents=True, exist_ok=True)
    with exclusive_lock(path.with_name(f"{path.name}.lock"), busy=None):
        # (`keep`: a SIM another process saved at a file the user named, while this one waited,
        # was trained over as a stale cache's)
        model = None if force else _cached(path, window, known, settings, side, keep=keep)
        if model is not None:
            return model, 0.0, path
        partial = path.with_name(f"{path.name}.partial")  # SIM's training state, if interrupted
        for written in (path, partial):  # only the lock's holder writes them: what another
            sweep_killed_writes(written)  # process left is a killed one's
        key = {"data": data, "start": START, "window": window, **settings}
        if force:
            partial.unlink(missing_ok=True)
        state = _resumable(partial, key)
        quiet = not kwargs.get("progress", True)  # no bar: a line at each end instead (for logs)
        if quiet:
            print(f"SIM: training -> {path}", file=sys.stderr, flush=True)
        start = time.perf_counter()
        model, losses = train_sim(
            stream,
            timestamps,
            window,
            checkpoint=partial,
            checkpoint_key=key,
            resume=state,
            **kwargs,
        )
        seconds = (state or {}).get("seconds", 0.0) + time.perf_counter() - start
        final_loss = float(np.mean(losses[-FINAL_LOSS_STEPS:]))
        # sim-train's scores of the SIM replaced, removed first: a kill between the two leaves
        # the old weights without their record, never the new ones with the old one's
        record_beside(path).unlink(missing_ok=True)
        # the thread count and bfloat16 autocast (a CPU's native support): SIM's training
        # differs with each, every weight
        machine = {"threads": torch.get_num_threads(), "bf16": bf16_is_fast()}
        save_sim(
            model,
            path,
            final_loss=final_loss,
            seconds=seconds,
            data=data,
            start=START,
            **{**machine, **settings},
        )
        partial.unlink(missing_ok=True)
        if quiet:
            print(
                f"SIM: trained {len(losses):,} step{'s' if len(losses) != 1 else ''} in "
                f"{seconds:.0f} s, final loss {final_loss:.4g}",
                file=sys.stderr,
                flush=True,
            )
    return model, seconds, path


def inference_model(model: SIM, dtype: torch.dtype = torch.float32) -> SIM:
    """A frozen copy of `model` for fast CPU inference: `dtype` weights, channels-last layout."""
    with torch.random.fork_rng(devices=[]):  # (its default init, overwritten: as `_model_of`)
        fast = SIM(**model.config)
    fast.load_state_dict(model.state_dict())
    return fast.to(dtype=dtype, memory_format=torch.channels_last).eval().requires_grad_(False)


def fast_inference_model(model: SIM, dtype: torch.dtype | None = None) -> SIM:
    """`inference_model` in `dtype`, by default the fastest this CPU has (`_fast_dtype`)."""
    return inference_model(model, _fast_dtype(dtype))


def predict(model: SIM, windows: np.ndarray) -> np.ndarray:
    """Spike windows uint8 [B, w, H, W] -> float32 images [B, H, W, C], in `model`'s dtype."""
    dtype = next(model.parameters()).dtype
    with torch.inference_mode():
        y = model(_to_input(windows, dtype))  # [B, C, H, W]
    return y.float().permute(0, 2, 3, 1).numpy()


def _check_step_memory(model: SIM, batch_size: int, ch: int, cw: int) -> None:
    """ValueError, before the first step, where a step's `batch_size` crops of ch×cw pixels need
    more memory than this process may use (STEP_BYTES_PER_MAP, a lower bound)."""
    c = model.config
    maps = c["window"] + c["width"] * c["shift_layers"] + c["head_width"] * c["head_layers"]
    need, memory = STEP_BYTES_PER_MAP * maps * batch_size * ch * cw, machine_memory()
    if need > memory:
        raise ValueError(
            f"SIM batch {batch_size} of {ch}x{cw} crops: a training step needs over "
            f"{need / 2**30:.1f} GiB, more than the {memory / 2**30:.1f} GiB this process may "
            f"use; a smaller batch (sim-train --batch-size, a method config's sim.batch) or crop"
        )


def _check_windows(streams: list, timestamps: np.ndarray, window: int) -> None:
    """ValueError, before training, where a timestamp's window of `window` readouts runs past a
    stream's ends (the first step to draw it raised, minutes in)."""
    readouts = min(len(s) for s in streams)
    lo, hi = centred_range(readouts, window)
    outside = timestamps[(timestamps < lo) | (timestamps > hi)]  # ([lo, hi] fit)
    if outside.size:
        fit = f"centres {lo}..{hi} fit" if lo <= hi else "longer than the stream"
        raise ValueError(
            f"training timestamps {outside[:3].tolist()}{' ...' if outside.size > 3 else ''}: "
            f"their windows of {window} readouts run past the stream's {readouts} readouts "
            f"({fit})"
        )


def infer_sim(
    model: SIM, stream, timestamps: Sequence[int], batch_size: int = 4, dtype=None
) -> np.ndarray:
    """SIM images at `timestamps` [N] (readouts, as the stream's readers take them): float32
    [N, H, W, C], [H, W, C] at one readout given alone, computed in `dtype` (`_fast_dtype`),
    `batch_size` windows at a time."""
    if not is_int(batch_size) or batch_size < 1:  # (range() arg 3 must not be zero)
        raise ValueError(f"SIM batch_size expected a positive int, found {batch_size!r}")
    timestamps, single = as_readouts(timestamps)  # (a lone readout: len() of unsized object)
    if not timestamps.size:  # (np.concatenate of none)
        return np.zeros((0, stream.height, stream.width, model.out_channels), np.float32)
    fast = fast_inference_model(model, dtype)
    chunks = [
        predict(fast, stream.window(timestamps[i : i + batch_size], model.window))
        for i in range(0, len(timestamps), batch_size)
    ]
    images = np.concatenate(chunks)
    return images[0] if single else images
