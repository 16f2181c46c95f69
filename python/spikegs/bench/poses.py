"""`spikegs bench poses`: training from perturbed poses, with and without pose refinement.

A synthetic dataset's trajectory is replaced by a noisy one: its pose every KEYFRAME_EVERY
readouts (the training views' spacing) is moved by a random rotation of NOISE_DEG about a random
axis and a translation of NOISE_TRANSLATION scene radii, and the poses in between are interpolated.
The same method is trained three times: on the true poses, on the noisy poses held fixed, and on
the noisy poses with `pose_refine` on. All three are evaluated on the test views with their true
poses (PSNR, SSIM); the refined run also reports the pose error of its training views before and
after refinement. Repeated over noise seeds, medians reported. Writes OUT/poses.json, poses.png.
"""

from __future__ import annotations

import copy
import math
import statistics
from pathlib import Path

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from ..atomic_save import save_figure
from ..config import load_config
from ..data import simulate_dataset
from ..data.trajectory import Trajectory
from ..evaluate import evaluate_run
from ..method_titles import method_title
from ..pose_refine import pose_errors
from ..pyplot_agg import pyplot
from ..text_table import print_table
from ..train import Trainer
from .common import scratch_folder, write_results
from .train import schedule

NOISE_DEG = 1.0  # rotation of each perturbed pose
NOISE_TRANSLATION = 0.01  # translation of each perturbed pose, in scene radii
KEYFRAME_EVERY = 8  # readouts between perturbed poses, = the training views' spacing
FULL = {"size": 128, "readouts": 1600, "iterations": 1200, "method": "tfp33", "repeats": 3}
QUICK = {"size": 64, "readouts": 800, "iterations": 400, "method": "tfp33", "repeats": 1}
CONDITIONS = ("true poses", "noisy poses", "noisy + refinement")
COLUMNS = [
    "condition",
    "psnr",
    "ssim",
    "seconds",
    "gaussians",
    "rotation_deg_before",
    "rotation_deg_after",
    "centre_before",
    "centre_after",
    "views_improved",
]


def perturb_trajectory(
    trajectory: Trajectory,
    readouts: np.ndarray,
    rotation_deg: float,
    translation: float,
    seed: int = 0,
) -> Trajectory:
    """The trajectory resampled at `readouts` [P], each pose moved by an independent random rigid
    motion (camera side): a rotation of `rotation_deg` about a random axis and a translation of
    length `translation` in a random direction (world units)."""
    rng = np.random.default_rng(seed)
    viewmats = trajectory.pose_at(np.asarray(readouts, np.float64))  # [P, 4, 4]
    axes = rng.normal(size=(len(viewmats), 2, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    noise = np.tile(np.eye(4), (len(viewmats), 1, 1))  # [P, 4, 4]
    noise[:, :3, :3] = Rotation.from_rotvec(axes[:, 0] * math.radians(rotation_deg)).as_matrix()
    noise[:, :3, 3] = axes[:, 1] * translation
    return Trajectory(readouts, noise @ viewmats, source="perturbed")


def noisy_dataset(dataset, seed: int):
    """A shallow copy of `dataset` whose trajectory is perturbed (test views keep their poses)."""
    last = dataset.num_readouts - 1
    keyframes = np.append(np.arange(0, last, KEYFRAME_EVERY), last).astype(np.float64)
    noisy = copy.copy(dataset)
    noisy.trajectory = perturb_trajectory(
        dataset.trajectory, keyframes, NOISE_DEG, NOISE_TRANSLATION * dataset.scene_radius, seed
    )
    return noisy


def refined_pose_errors(trainer: Trainer, truth: Trajectory) -> dict[str, np.ndarray]:
    """Rotation (degrees) and centre (scene radii) errors [M] of the training views' poses before
    and after `trainer`'s refinement, against the true trajectory."""
    ts = np.asarray(trainer.dataset.train_timestamps, np.float64)  # [M]
    given = trainer.dataset.trajectory.pose_at(ts)  # [M, 4, 4]
    with torch.no_grad():
        refined = np.stack(
            [
                trainer.poses(torch.from_numpy(v).float(), i).double().numpy()
                for i, v in enumerate(given)
            ]
        )
    radius = trainer.dataset.scene_radius
    out = {}
    for name, poses in (("before", given), ("after", refined)):
        rotation, centre = pose_errors(poses, truth.pose_at(ts))
        out[f"rotation_deg_{name}"], out[f"centre_{name}"] = rotation, centre / radius
    return out


def _run(dataset, setup: dict, quick: bool, refine: bool, run_dir: Path) -> tuple[dict, Trainer]:
    """Train `setup`'s method on `dataset` and score it on the test views (true poses)."""
    overrides = schedule(setup["iterations"], quick)
    overrides["pose_refine"] = {"enabled": refine}  # its default learning rate
    config = load_config(setup["method"], overrides)
    trainer = Trainer(dataset, config, run_dir, progress=False, resumable=False)
    summary = trainer.train()
    result = evaluate_run(run_dir, dataset, write_images=False)
    scores = {k: result[k] for k in ("psnr", "ssim", "gaussians")}
    return {**scores, "seconds": summary["train_seconds"]}, trainer


def _plot(rows: list[dict], errors: dict[str, np.ndarray], setup: dict, path: Path) -> None:
    """Test PSNR of the three conditions, and the training views' rotation and centre errors
    before and after refinement (the last noise seed's, sorted)."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    # points, not bars: an axis that does not start at 0 would exaggerate bars' lengths
    names, psnrs = [r["condition"] for r in rows], [r["psnr"] for r in rows]
    axes[0].plot(names, psnrs, "o", color="C0", markersize=8)
    for name, value in zip(names, psnrs):
        axes[0].annotate(f"{value:.2f}", (name, value), textcoords="offset points", xytext=(0, 8))
    axes[0].margins(x=0.2, y=0.3)
    axes[0].set_ylabel("test PSNR (dB), true test poses")
    seeds = setup["repeats"]
    axes[0].set_title(f"median of {seeds} noise seed{'s' * (seeds > 1)}", fontsize=9)
    for ax, key, label, scale in (
        (axes[1], "rotation_deg", "rotation error (degrees)", 1.0),
        (axes[2], "centre", "camera centre error (% of the scene radius)", 100.0),
    ):
        for name, style in (("before", ("C3", "--")), ("after", ("C0", "-"))):
            values = np.sort(errors[f"{key}_{name}"]) * scale
            ax.plot(values, color=style[0], linestyle=style[1], label=f"{name} refinement")
        ax.set_xlabel("training view (sorted by its error)")
        ax.set_ylabel(label)
        ax.set_title(f"the last noise seed's {len(values)} views", fontsize=9)
        ax.legend()
    fig.suptitle(
        f"Pose refinement: solids {setup['size']}², {method_title(setup['method'])} "
        f"({setup['iterations']} iterations), poses off by {NOISE_DEG}° and "
        f"{NOISE_TRANSLATION:.0%} of the radius every {KEYFRAME_EVERY} readouts"
    )
    fig.tight_layout()
    save_figure(fig, path)


def run(quick: bool, out: Path) -> dict:
    """The three conditions, repeated over noise seeds; writes poses.json and poses.png."""
    setup = QUICK if quick else FULL
    runs = {c: [] for c in CONDITIONS}
    with scratch_folder("poses") as tmp:
        tmp = Path(tmp)
        dataset = simulate_dataset(
            "solids",
            tmp / "data",
            height=setup["size"],
            width=setup["size"],
            readouts=setup["readouts"],
            test_on_path=2,
            test_off_path=4,
            train_every=KEYFRAME_EVERY,
            progress=False,
        )
        for seed in range(setup["repeats"]):
            noisy = noisy_dataset(dataset, seed)
            trainers = {}
            for condition, data, refine in zip(
                CONDITIONS, (dataset, noisy, noisy), (False, False, True)
            ):
                if condition == CONDITIONS[0] and seed > 0:
                    continue  # the true poses do not depend on the noise seed
                run_dir = tmp / f"{condition.replace(' ', '_')}_{seed}"
                scores, trainers[condition] = _run(data, setup, quick, refine, run_dir)
                runs[condition].append(scores)
            errors = refined_pose_errors(trainers[CONDITIONS[2]], dataset.trajectory)
            runs[CONDITIONS[2]][-1].update({k: float(np.median(v)) for k, v in errors.items()})
            runs[CONDITIONS[2]][-1]["views_improved"] = float(
                np.mean(errors["rotation_deg_after"] < errors["rotation_deg_before"])
            )
    rows = [
        {"condition": c, **{k: statistics.median(r[k] for r in runs[c]) for k in runs[c][0]}}
        for c in CONDITIONS
    ]
    psnr = [r["psnr"] for r in rows]
    recovered = (psnr[2] - psnr[1]) / (psnr[0] - psnr[1]) if psnr[0] != psnr[1] else float("nan")
    print(
        f"solids {setup['size']}x{setup['size']}, {len(dataset.train_timestamps)} training views, "
        f"{setup['method']}, {setup['iterations']} iterations, noise {NOISE_DEG} deg + "
        f"{NOISE_TRANSLATION:.0%} radius every {KEYFRAME_EVERY} readouts, median of "
        f"{setup['repeats']} noise seed{'s' * (setup['repeats'] > 1)}"
    )
    print_table(rows, COLUMNS)
    print(f"refinement recovers {recovered:.0%} of the PSNR lost to pose noise")
    results = {
        "setup": {
            **setup,
            "noise_deg": NOISE_DEG,
            "noise_translation_radius": NOISE_TRANSLATION,
            "keyframe_every": KEYFRAME_EVERY,
            "pose_lr": load_config(setup["method"]).pose_refine.lr,
        },
        "rows": rows,
        "runs": runs,
        "psnr_recovered_fraction": recovered,
    }
    write_results(out, "poses", results, quick)
    _plot(rows, errors, setup, out / "poses.png")
    return results
