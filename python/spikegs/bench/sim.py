"""`spikegs bench sim`: SIM inference FPS at 250×400, training step and time, PSNR over TFP(33).

Quality: SIM is trained on each built-in scene (simulated at 250×400 with the project's spike
simulator) and compared with TFP(33), TFP(65) and TFI on the held-out on-path views. Speed: the
straightforward SIM (square padding, four rotations stacked on the batch, channels first,
autograd on) is the named alternative that the fast path (each branch's rotated kernels on the
unrotated window, channels-last, inference mode, float32 or bfloat16) is timed against, in the
same run; a float32 training step (batch 8, 64² crops) of the literal rotate-the-data network
channels-first (how SIM trains without native bfloat16) against the per-branch network.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from ..config import SimConfig
from ..data import simulate_dataset
from ..data.scenes import SCENES
from ..sim import SIM
from ..sim_scores import evaluate_dataset
from ..sim_train import FINAL_LOSS_STEPS, inference_model, train_sim, training_layout
from ..text_table import print_table
from .common import median_seconds, scratch_folder, write_results

TRAINING = SimConfig()  # SIM trains as `spikegs train` trains it: steps, batch


def _fps_rows(model, height: int, width: int, repeats: int) -> list[dict]:
    """Time SIM variants on one random spike window; error = max |Δ| against float32 fast path."""
    rng = np.random.default_rng(1)
    spikes = torch.from_numpy(rng.random((1, model.window, height, width)) < 0.15).float()
    plain = SIM(**model.config)  # channels-first float32 copy, gradients on
    plain.load_state_dict(model.state_dict())
    variants = {
        "straightforward f32 (square, NCHW, autograd)": (
            plain,
            spikes,
            lambda m, x: m.forward_rotated(x, square=True),
        ),
        "rotated pairs f32 (channels-last, inference)": (
            inference_model(model, torch.float32),
            spikes.contiguous(memory_format=torch.channels_last),
            lambda m, x: m.forward_rotated(x),
        ),
    }
    for dtype in (torch.float32, torch.bfloat16):
        name = f"per-branch {str(dtype)[6:]} (channels-last, inference)"
        fast = inference_model(model, dtype)
        x = spikes.to(dtype).contiguous(memory_format=torch.channels_last)
        variants[name] = (fast, x, lambda m, x: m(x))
    with torch.inference_mode():
        reference = model(spikes)
    rows = []
    for name, (m, x, fn) in variants.items():
        grad = "autograd" in name
        with torch.inference_mode(mode=not grad):
            seconds = median_seconds(lambda m=m, x=x, fn=fn: fn(m, x), repeats=repeats)
            error = (fn(m, x).detach().float() - reference).abs().max().item()
        rows.append({"variant": name, "seconds": seconds, "fps": 1 / seconds, "max_abs_err": error})
    base = rows[0]["seconds"]
    for row in rows:
        row["speedup"] = base / row["seconds"]
    return rows


def _train_step_rows(model, batch: int, crop: int, repeats: int) -> list[dict]:
    """Time one float32 training step (forward, L2 loss, backward) of the literal rotate-the-data
    network channels-first (SIM's training without native bfloat16) against the per-branch
    network (the inference path) channels-first and channels-last, on the same crops; error =
    max |Δ weight gradient| / max |grad|."""
    rng = np.random.default_rng(2)
    spikes = torch.from_numpy(rng.random((batch, model.window, crop, crop)) < 0.15).float()
    target = spikes.mean(dim=1, keepdim=True)  # [B, 1, crop, crop]
    variants = (
        ("rotated pairs (literal), channels-first", "forward_rotated", training_layout(False)),
        ("per-branch, channels-first", "forward", training_layout(False)),
        ("per-branch, channels-last", "forward", torch.channels_last),
    )
    grads, rows = [], []
    for name, forward, layout in variants:
        net = SIM(**model.config).to(memory_format=layout).train()
        net.load_state_dict(model.state_dict())
        x = spikes.contiguous(memory_format=layout)

        def step(net=net, x=x, forward=forward):
            net.zero_grad(set_to_none=True)
            ((getattr(net, forward)(x) - target) ** 2).mean().backward()

        seconds = median_seconds(step, repeats=repeats)
        grads.append(torch.cat([p.grad.flatten() for p in net.parameters()]))
        rows.append(
            {"variant": f"train step {name}", "batch": batch, "crop": crop, "seconds": seconds}
        )
    scale = grads[0].abs().max().item() or 1.0
    for row, grad in zip(rows, grads):
        row["speedup"] = rows[0]["seconds"] / row["seconds"]
        row["grad_err"] = (grad - grads[0]).abs().max().item() / scale
    return rows


def _scene(scene: str, quick: bool, root: Path, progress: bool) -> tuple[list[dict], dict, SIM]:
    """Simulate `scene`, train SIM on it (a progress bar where `progress`), score every method:
    (quality rows, training, model)."""
    height, width, readouts, views = (64, 96, 400, 2) if quick else (250, 400, 1200, 4)
    steps = 30 if quick else TRAINING.iterations
    dataset = simulate_dataset(
        scene,
        root / scene,
        height=height,
        width=width,
        readouts=readouts,
        test_on_path=views,
        test_off_path=0,
        progress=False,
    )
    start = time.perf_counter()
    model, losses = train_sim(
        dataset.stream,
        dataset.train_timestamps,
        steps=steps,
        batch_size=TRAINING.batch,
        seed=0,
        progress=progress,
    )
    seconds = time.perf_counter() - start
    rows = []
    for dtype in (torch.float32, torch.bfloat16):
        for name, scores in evaluate_dataset(model, dataset, dtype).items():
            if name == "SIM" or dtype == torch.float32:
                label = f"SIM {str(dtype)[6:]}" if name == "SIM" else name
                rows.append({"scene": scene, "method": label, **scores})
    train = {
        "scene": scene,
        "height": height,  # (a "size" of "HxW" read as the rasterizer's "WxH")
        "width": width,
        "steps": steps,
        "batch": TRAINING.batch,
        "seconds": seconds,
        "s_per_step": seconds / steps,
        "final_loss": float(np.mean(losses[-FINAL_LOSS_STEPS:])),
    }
    return rows, train, model


def run(quick: bool, out: Path, progress: bool = False) -> dict:
    """Quality on the built-in scenes, training time, inference FPS at 250×400; writes sim.json.
    SIM's training draws a progress bar where `progress`."""
    quality, training = [], []
    with scratch_folder("sim") as tmp:
        for scene in SCENES if not quick else list(SCENES)[:1]:
            rows, train, model = _scene(scene, quick, Path(tmp), progress)
            quality += rows
            training.append(train)
    psnr = {(r["scene"], r["method"]): r["psnr"] for r in quality}
    scenes = [t["scene"] for t in training]
    gains = {s: psnr[s, "SIM bfloat16"] - psnr[s, "TFP(33)"] for s in scenes}
    size = (64, 96) if quick else (250, 400)
    fps_rows = _fps_rows(model, *size, repeats=1 if quick else 5)  # the last scene's SIM
    step_rows = _train_step_rows(model, 8, 32 if quick else 64, repeats=1 if quick else 7)

    print(f"SIM: {model.num_parameters()} parameters")
    print_table(training)
    print_table(quality)
    print(f"inference at {size[0]}x{size[1]} (height x width):")
    print_table(fps_rows)
    print_table(step_rows)
    for scene, gain in gains.items():
        print(f"{scene}: SIM PSNR gain over TFP(33) {gain:+.2f} dB")
    if quick:
        print(
            "(--quick: SIM trained a few steps on a small scene; these scores check the run only)"
        )
    results = {
        "parameters": model.num_parameters(),
        "training": training,
        "quality": quality,
        "psnr_gain_over_tfp33_db": gains,
        "inference": {"height": size[0], "width": size[1], "rows": fps_rows},
        "train_step": step_rows,
    }
    write_results(out, "sim", results, quick)
    return results
