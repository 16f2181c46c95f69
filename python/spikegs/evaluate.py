"""Evaluation of a trained scene on the dataset's held-out test views: PSNR, SSIM, images."""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import warnings
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from . import strict_json
from .atomic_save import STEM_MAX, short_name, sweep_temporaries, write_text_atomically
from .box_filter import block_means
from .data.dataset import check_dataset, check_edited_dataset, is_view_name, scale_guessed
from .data.real import PSEUDO_PREFIX
from .data_fingerprint import same_data
from .file_lock import exclusive_lock
from .gaussians import GaussianModel, frame_origin, near_plane
from .image_io import srgb_to_linear, stage_image
from .image_labels import column_titles, title_scale
from .metrics import image_pair, psnr, ssim, ssim_3dgs
from .number_checks import as_flag
from .output_paths import check_file_output, check_folder_output, writable_folder
from .ply import declares_channels
from .pose_align import MAX_STEPS, aligned_pose
from .pose_refine import pose_errors
from .provenance import environment
from .regular_file import read_text
from .run_summary import CONFIG, EVAL, LOCK, SCENE, read_summary, trained_model, trained_scene
from .shell_words import shell_path
from .targets import intensity_scale


def render_view(model: GaussianModel, viewmat: np.ndarray, dataset) -> np.ndarray:
    """The model's image [H, W, C] (intensity units) from world-to-camera `viewmat` [4, 4] in the
    dataset's camera (its intrinsics, size and scene's near plane), rendered about the origin
    that training uses for the dataset (`frame_origin`)."""
    model = model.centred_at(frame_origin(dataset.scene_center, dataset.scene_radius))
    with torch.no_grad():
        return model.render(
            model.view_of(viewmat),
            torch.as_tensor(dataset.K, dtype=model.dtype),
            dataset.width,
            dataset.height,
            near_plane(dataset.scene_radius),
        ).image.numpy()


SSIMS = {"ssim": ssim, "ssim_3dgs": ssim_3dgs}  # scikit-image's, 3DGS's evaluation's
SCORES = ("psnr", *SSIMS)  # what eval.json means over the views


def view_metrics(
    pred: np.ndarray, gt: np.ndarray, ssims: tuple[str, ...] = tuple(SSIMS)
) -> dict[str, float]:
    """PSNR and the SSIMS named in `ssims` (none: PSNR alone; one name alone as a string) of
    `pred` against `gt`, both [H, W, C] intensities (arrays or tensors, as `metrics` takes
    them), clipped to [0, 1]. ValueError for a name not in SSIMS."""
    ssims = (ssims,) if isinstance(ssims, str) else tuple(ssims)
    unknown = [name for name in ssims if name not in SSIMS]
    if unknown:
        raise ValueError(f"ssims: unknown {unknown}; known: {', '.join(SSIMS)}")
    pred, gt = image_pair(pred, gt)  # (a tensor requiring grad, or bfloat16, failed in np.clip)
    pred, gt = np.clip(pred, 0, 1), np.clip(gt, 0, 1)
    return {"psnr": psnr(pred, gt), **{name: SSIMS[name](pred, gt) for name in ssims}}


def score_view(model, view, dataset, scale: float, ssims: tuple[str, ...] = tuple(SSIMS)) -> dict:
    """`view_metrics` of the model's render of test `view` against its image over `scale` (a
    dataset's firing rates into the render's units), as training's evaluations score it."""
    pred = render_view(model, view.viewmat, dataset)
    return view_metrics(pred, np.asarray(view.image, np.float32) / scale, ssims)


def _eval_name(run_dir: Path, train: dict, dataset, progress: bool = False) -> str:
    """'eval' for the dataset the run was trained on (`train`: its train.json; or moved: its
    folder gone, the data fingerprint the run's), else 'eval-DATASETNAME' (RUN/NAME.json and
    RUN/NAME/*.png), so that scoring another dataset keeps the run's own scores;
    'eval-DATASETNAME-2', -3, ... where an evaluation of another dataset of the same directory
    name holds the name. The run's folder with other data in it (simulated again, new poses) is
    another dataset, warned of; a new intensity scale is not (evaluate_run converts the renders
    to the scale the dataset states now). `progress`: as `_holds_run_data`'s."""
    own = train.get("dataset")
    root = Path(dataset.root).resolve()
    # another tool's scene.ply (no train.json): eval.json is the first dataset's scored, the
    # others' eval-NAME (a second dataset's scores replaced the first's, unsaid)
    if own is None and _scored_dataset(run_dir / f"{EVAL}.json") in (None, str(root)):
        return EVAL
    known = "data" in train  # runs from before fingerprints: their own folder is trusted
    scale = _run_scale(train, dataset)
    same = not known or same_data(train["data"], dataset, scale)
    if own is not None and Path(own).resolve() == root:
        if same:
            return EVAL
        warnings.warn(
            f"{root} holds other data than {run_dir} was trained on ({OTHER_DATA}): scored as "
            f"another dataset, the run's own eval.json kept",
            stacklevel=3,
        )
    elif known and same and not _holds_run_data(Path(own), train["data"], scale, progress):
        return EVAL  # moved
    for i in itertools.count(1):
        # (a long dataset name shortened: eval-NAME.json past NAME_MAX failed after the scoring)
        name = f"{EVAL}-{short_name(root.name, STEM_MAX)}" + (f"-{i}" if i > 1 else "")
        if _scored_dataset(run_dir / f"{name}.json") in (None, str(root)):
            return name


OTHER_DATA = (
    "its spikes, poses, intrinsics or training timestamps differ: simulated again, or new poses"
)


def _run_scale(train: dict, dataset) -> float:
    """The intensity scale the run trained in (train.json's), else the dataset's."""
    scale = train.get("intensity_scale")
    return intensity_scale(dataset) if scale is None else float(scale)


def _other_scene(run_dir: Path, train: dict, dataset, use: str) -> str | None:
    """'RUN was trained on scene A and `use` DATASET, scene B' where train.json's scene and the
    dataset's differ; None where they agree, either is unnamed, or the dataset holds the run's
    data (a real layout's scene is its folder's name: moved or copied, it was called another)."""
    trained_on, holds = train.get("scene"), dataset.meta.get("scene")
    if trained_on and holds and trained_on != holds:
        if "data" in train and same_data(train["data"], dataset, _run_scale(train, dataset)):
            return None
        return (
            f"{run_dir} was trained on scene '{trained_on}' and {use} {dataset.root}, scene "
            f"'{holds}'"
        )
    return None


# test pixels coarser than the run's training pixels by more than this (the focal lengths'
# geometric mean, over the training camera's) are warned of: drawn at that size as 3DGS draws,
# they alias where the images are a camera's (0.75: −1.9 dB, 0.25: −13 against the mean of a
# render at the training size; BENCHMARKS.md, "Renders at another size")
COARSER_PIXELS = 0.8


def _coarser_pixels(run_dir: Path, train: dict, dataset, antialiased: bool) -> str | None:
    """What says that `dataset`'s pixels are coarser than those the run trained on (by
    COARSER_PIXELS; train.json's `camera`, absent from runs before it); None where they are not.
    `antialiased`: the run's scene is drawn with the antialiased filter (`train.antialiased`),
    which aliases less."""
    trained = train.get("camera")
    if trained is None:
        return None
    ratio = math.sqrt(dataset.meta["fx"] * dataset.meta["fy"] / (trained["fl_x"] * trained["fl_y"]))
    if ratio >= COARSER_PIXELS:
        return None
    # TFP(33)+3DGS on `textured` (BENCHMARKS.md, "The antialiased 2D filter")
    drawn = "25.5 dB drawn so (its antialiased filter)" if antialiased else "20.0 dB drawn so"
    return (
        f"{dataset.root}'s pixels are {1 / ratio:.3g} times as wide as those {run_dir} was "
        f"trained on: scored drawn at their size, as 3DGS draws, which aliases where the images "
        f"are a camera's (each pixel the light over its area): against such a truth at a quarter "
        f"of the size, {drawn} and 33.2 as the mean of a render at the training size "
        f"(`spikegs render --scale` draws so: docs/outputs.md)"
        + ("" if antialiased else "; a run trained with `train.antialiased: true` aliases less")
    )


def other_data(run_dir: Path, dataset) -> str | None:
    """What tells `dataset` from the data the finished run RUN was trained on (another scene,
    or other data than train.json's fingerprint); None where nothing does."""
    train = read_summary(run_dir)
    scene = _other_scene(run_dir, train, dataset, "renders along")
    if scene:
        return scene
    if "data" in train and not same_data(train["data"], dataset, _run_scale(train, dataset)):
        return f"{dataset.root} holds other data than {run_dir} was trained on ({OTHER_DATA})"
    return None


def _holds_run_data(folder: Path, data: str, scale: float, progress: bool = False) -> bool:
    """Whether `folder`, the run's dataset folder, still holds the data of fingerprint `data`
    (False where it is gone, or holds another dataset or none: the run's data moved).
    `progress`: `load_dataset`'s bar over its flicker search."""
    from .data import load_dataset

    if not folder.exists():
        return False
    try:
        with warnings.catch_warnings():  # of a dataset not scored: not the user's concern here
            warnings.simplefilter("ignore")
            return same_data(data, load_dataset(folder, progress), scale)
    except (OSError, ValueError, KeyError):
        return False


def _aligned_name(run_dir: Path, own: str, root: Path, foreign: bool = False) -> str:
    """OWN-aligned, the name of an aligned scoring (`own`: `_eval_name`'s, of dataset `root`), or
    OWN-aligned-2, -3, ... where that name holds another scoring: the plain one of a dataset
    whose folder is named 'aligned' (eval-aligned) or 'NAME-aligned', which it replaced unsaid,
    or, in a `foreign` folder (another tool's scene.ply, no dataset of its own), another
    dataset's aligned scoring (a second dataset's replaced the first's)."""
    for i in itertools.count(1):
        name = f"{own}-aligned" + (f"-{i}" if i > 1 else "")
        doc = _scoring(run_dir / f"{name}.json")
        if doc is None:
            return name
        mine = (own == EVAL and not foreign) or doc.get("dataset") == str(Path(root).resolve())
        if "aligned_poses" in doc and mine:  # (an unreadable one's name is not reused)
            return name


def _scoring(path: Path) -> dict | None:
    """An evaluation file's object; None where there is no such file ({} where it is unreadable
    or holds no object: its name is not reused)."""
    if not path.exists():
        return None
    try:
        doc = json.loads(read_text(path))
    except ValueError:
        return {}
    return doc if isinstance(doc, dict) else {}


def _scored_dataset(path: Path) -> str | None:
    """The dataset an evaluation file scored; None where there is no such file ('' where it is
    unreadable: its name is not reused)."""
    doc = _scoring(path)
    return None if doc is None else str(doc.get("dataset", ""))


def _scored_views(path: Path) -> dict:
    """The views an evaluation file scored, with their scores {name: {"psnr", "ssim"}} (none
    where there is no such file, or it is unreadable; a name that is no view's, e.g. a path, is
    left out)."""
    try:
        views = json.loads(read_text(path))["views"]
        return {v: views[v] for v in views if is_view_name(v)}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _means(views: list[dict]) -> dict:
    """{"psnr", "ssim", "ssim_3dgs"}: the means of `views`' scores (none where there are none)."""
    return {k: float(np.mean([v[k] for v in views])) for k in SCORES} if views else {}


def _group(views: list[dict]) -> dict:
    """The means of `views`' scores and their number ("views")."""
    return {**_means(views), "views": len(views)}


def _changed(old, new: dict) -> bool:
    """Whether a view's scores `new` differ from an earlier scoring's `old` (a score that scoring
    did not record, ssim_3dgs before 2026-11-29, is no change; a non-finite one is the null
    eval.json holds for it: NaN != NaN deleted a flat image's side-by-side at every scoring)."""
    if not isinstance(old, dict):
        return True

    def same(was, now) -> bool:
        if isinstance(now, float) and not math.isfinite(now):
            return was is None or was == now or (isinstance(was, float) and math.isnan(was))
        return was == now

    return not all(same(old.get(key, value), value) for key, value in new.items())


def _configured_method(run_dir: Path) -> str | None:
    """The method of RUN/config.yaml (a run without train.json: stopped, or another tool's scene
    in a run folder), None where it has none or cannot be read."""
    import yaml

    from .yaml_files import read_yaml

    try:
        method = read_yaml(run_dir / CONFIG).get("method")
    except (OSError, UnicodeDecodeError, yaml.YAMLError, AttributeError):
        return None
    return method if isinstance(method, str) else None


def side_by_side(
    gt: np.ndarray, pred: np.ndarray, pseudo: bool, psnr: float | None = None
) -> np.ndarray:
    """RUN/eval/VIEW.png's image [TITLES + H, 3 W, C] (linear): ground truth | render | 4 x the
    absolute error that was scored, shown as it is (sRGB encoding would show an error of 0.02 as
    a 31 % grey), under titles that say which is which and the error's scale (the panels alone
    said neither); a `pseudo` ground truth (TFP of the view's own spikes) titled so, the render
    with the view's `psnr` (dB) where given (the image alone did not say how it scored)."""
    error = srgb_to_linear(np.clip(4 * np.abs(pred - gt), 0, 1))
    (h, w, c), truth = gt.shape, "TFP pseudo truth" if pseudo else "ground truth"
    render = "render" if psnr is None else f"render, {psnr:.2f} dB"
    titles = column_titles([truth, render, "4 x |error|"], w, title_scale(h))
    header = np.broadcast_to(titles, (*titles.shape[:2], c))
    return np.concatenate([header, np.concatenate([gt, pred, error], axis=1)], axis=0)


# a view whose aligned render leaves over this many times the median view's share of its image's
# coarse structure unexplained (`Alignment.unexplained`) is suspect: settled off its pose. Views
# back to their pose left 0.2-9 % on 128² `solids` and `fine-texture`, 20-54 % on `wires` (as at
# their true poses), those lost at 128² 27-165 %; of 17 lost from 10° and 20° off, 7 named, 5 more
# unsettled, none of 39 back named (BENCHMARKS.md, "eval --align-poses: Levenberg-Marquardt"); it
# needs most views right (with 6 of 8 lost none stands out)
SUSPECT_RATIO = 2.0
# and leaves at least this: views that all match closely differ by noise, and an under-fit run's
# view at its exact pose left 0.15-0.18 where the others left 0.05-0.08 (64², 200 iterations: the
# eval trial), between what views back and views lost left above
SUSPECT_LEAST = 0.2
# test views moving a median over this many degrees once aligned are warned of: exact poses of
# 32² runs moved 9-12° (under-fit or coarse scenes drift to where the render matches better, all
# alike, none suspect), a well-fit 64² one's 0.67°, SfM's poses lie 1-3° off (the eval trial)
DRIFT_DEG = 5.0
# an aligned render whose correlation with its image is under this bears no likeness to it: the
# scene is out of its view, suspect whatever the others leave (a run in SfM's own frame scored on
# poses of another, every view's render blank, "settled" leaving 1.22 each, none suspect: the
# poses trial). The correlation, not the share left: a render of the right picture 1.66 times
# too bright leaves 1.62 (a review), and correlates as a right one does
NO_LIKENESS = 0.2


def _varies(values: np.ndarray) -> bool:
    """Whether `values` vary by more than their means' rounding (a flat image's blocks differ
    in the last bits)."""
    return bool(values.std() > 1e-9 * np.abs(values).max())


def _first_three(names: list[str]) -> str:
    """`names` as a warning lists them: the first three, and "..." for any more."""
    return ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")


def _finite_median(values) -> float:
    """The median of the finite `values` (an unexplained share is NaN for an image without
    coarse structure, a pose for a view whose alignment failed); NaN where none is."""
    finite = [value for value in values if math.isfinite(value)]
    return float(np.median(finite)) if finite else math.nan


def _suspect(views: dict) -> list[str]:
    """The views (names) of `views` {name: scores} whose aligned render leaves over SUSPECT_RATIO
    times the median view's share of its image's coarse structure unexplained, and at least
    SUSPECT_LEAST; or whose render bears no likeness to its image (`_unlike`)."""
    shares = {name: v["aligned_unexplained"] for name, v in views.items()}
    median = _finite_median(shares.values())
    bound = max(SUSPECT_RATIO * median, SUSPECT_LEAST) if math.isfinite(median) else math.inf
    unlike = _unlike(views)
    return [name for name, share in shares.items() if share > bound or name in unlike]


def _unlike(views: dict) -> list[str]:
    """The views (names) of `views` whose aligned render correlates with its image under
    NO_LIKENESS (a NaN correlation, of an image with no structure, judges nothing)."""
    return [name for name, v in views.items() if v["aligned_correlation"] < NO_LIKENESS]


LIKENESS_BLOCKS = 16  # the correlation's blocks a side (at least): a pixel's noise averaged


def _correlation(pred: np.ndarray, gt: np.ndarray) -> float:
    """The Pearson correlation of a render and its image [H, W, C] as scored, over blocks of
    1/LIKENESS_BLOCKS of the shorter side (a pseudo ground truth's noise, TFP of few spikes,
    pulled a right render's pixels under NO_LIKENESS: the second review): 0 for a flat render
    (it shows nothing of the image), NaN for a flat image (nothing to show)."""
    side = max(1, min(gt.shape[:2]) // LIKENESS_BLOCKS)
    h, w = gt.shape[0] // side * side, gt.shape[1] // side * side  # whole blocks
    pred, gt = (block_means(x[:h, :w], side).astype(np.float64).ravel() for x in (pred, gt))
    if not _varies(gt):
        return math.nan
    if not _varies(pred):
        return 0.0
    return float(np.corrcoef(pred, gt)[0, 1])


def evaluate_run(
    run_dir: str | Path,
    dataset,
    write_images: bool = True,
    progress: bool = False,
    align_poses: bool = False,
) -> dict:
    """Evaluate RUN/scene.ply on every test view; writes RUN/eval.json and RUN/eval/*.png
    (`_eval_name`: eval-DATASETNAME for a dataset other than the run's own). `progress`: a bar
    where the run's own dataset folder is loaded to tell whether it still holds the run's data
    (its flicker search), and over the views aligned. `align_poses`: each view scored from its
    pose aligned to its image (`pose_align`), into NAME-aligned.json and NAME-aligned/."""
    check_dataset(dataset, "evaluate_run")
    flags = {"write_images": write_images, "progress": progress, "align_poses": align_poses}
    write_images, progress, align_poses = (  # ("no" wrote the images)
        as_flag(f"evaluate_run: {name}", flag) for name, flag in flags.items()
    )
    run_dir = Path(run_dir)
    trained_scene(run_dir)  # a run unfinished, being trained, not there: said before the lock
    # (none: eval.json was replaced by one without scores, and every side-by-side deleted)
    check_edited_dataset(dataset, "evaluate_run")
    # refused before any view is rendered, not after the images are written
    if not writable_folder(run_dir):
        raise ValueError(
            f"{run_dir}: not writable, where eval writes its scores and images (a colleague's "
            f"run, a read-only mount: copy it, cp -r {shell_path(run_dir)} COPY, and score the "
            f"copy)"
        )
    # one process in the run at a time: two scorings of datasets of one folder name took one
    # eval-NAME.json, one's scores lost though both said they were written
    busy = f"{run_dir} is being scored or trained by another process; try again once it has ended"
    # (a scene in its dataset's own folder: one .lock, which `spikegs eval` holds shared as it
    # reads the dataset, shutting out training there; taken again it refused eval itself)
    in_dataset = run_dir.resolve() == Path(dataset.root).resolve()
    locked = contextlib.nullcontext() if in_dataset else exclusive_lock(run_dir / LOCK, busy)
    with locked:
        return _evaluate_locked(run_dir, dataset, write_images, progress, align_poses)


def _evaluate_locked(
    run_dir: Path, dataset, write_images: bool, progress: bool, align_poses: bool
) -> dict:
    """`evaluate_run` with RUN locked."""
    train = read_summary(run_dir)
    own = _eval_name(run_dir, train, dataset, progress)
    foreign = train.get("dataset") is None  # another tool's scene.ply: no dataset of its own
    name = _aligned_name(run_dir, own, dataset.root, foreign) if align_poses else own
    scene = _other_scene(run_dir, train, dataset, "is scored on")
    model = trained_model(run_dir)
    ply = run_dir / SCENE  # (`trained_model`'s)
    for said in (scene, _coarser_pixels(run_dir, train, dataset, model.antialiased)):
        if said:
            warnings.warn(said, stacklevel=2)
    if model.channels != dataset.channels:
        resaved = model.channels == 3 and dataset.channels == 1 and not declares_channels(ply)
        raise ValueError(
            f"{ply} renders {model.channels} channel(s), the dataset {dataset.root} has "
            f"{dataset.channels}: "
            + (
                "a mono scene.ply re-saved by another tool loses spikegs's 'channels' comment "
                "and reads as RGB: add the header line 'comment spikegs channels 1' after "
                "'element vertex N' (SIBR reads the count from the third line) to read it as "
                "mono again; a colour scene is scored on a colour dataset"
                if resaved
                else "score a run on a dataset with as many channels as it was trained on"
            )
        )
    if model.channels == 3 and not declares_channels(ply) and _grey(model):
        warnings.warn(
            f"{ply}: every Gaussian is grey (R = G = B) and the file states no channel count: a "
            f"mono scene re-saved by another tool (which drops spikegs's 'comment spikegs "
            f"channels 1') reads as RGB, and is scored on the colour dataset {dataset.root} as "
            f"grey; add that line after 'element vertex N' where it is mono",
            stacklevel=2,
        )
    scale = intensity_scale(dataset)
    run_scale = _run_scale(train, dataset)  # the units the run renders in
    # the render's intensity 1 in the sharp images' units: on the run's own data whose scale
    # changed since (a rate_at_one set where it trained in a guessed one), the scale it trained
    # in over the one stated now; on another dataset the render's intensity is the truth's; the
    # same to 6 digits (as the data's fingerprint: a guess's last bits differ between machines)
    changed = f"{run_scale:.6g}" != f"{scale:.6g}"
    run_guessed = train.get("intensity_scale_guessed")  # None: a run trained before the key
    data_guessed = scale_guessed(dataset.meta)
    units = run_scale / scale if own == EVAL and changed else 1.0
    if units != 1 and any(not v.name.startswith(PSEUDO_PREFIX) for v in dataset.test_views):
        warnings.warn(
            f"{run_dir} trained in an intensity scale of {run_scale:.4g} spikes a readout for "
            f"intensity 1, and {dataset.root} now states {scale:.4g}: its renders' firing rates "
            f"are scored in the scale stated now (x {units:.4g})",
            stacklevel=2,
        )
    elif changed and own != EVAL and (run_guessed is not False or data_guessed):
        # (an LLFF stream's guessed 0.18 on its simulation's 0.25: 20.35 dB where its renders in
        # that scale scored 25.62, unsaid; two stated scales are the same light, calibrated, and
        # their advice, "give both the same rate_at_one", scored 12 dB low where followed)
        run_how = {True: "guessed", False: "stated"}.get(run_guessed, "stated or guessed")
        data_how = "guesses" if data_guessed else "states"
        fixes = [f"state rate_at_one in {dataset.root}"] if data_guessed else []
        if run_guessed is not False:  # (a run keeps the scale it trained in)
            fixes.append("train the run again with its dataset's rate_at_one stated")
        warnings.warn(
            f"{run_dir} trained in an intensity scale of {run_scale:.4g} spikes a readout for "
            f"intensity 1 ({run_how}), {dataset.root} {data_how} {scale:.4g}: its renders' "
            f"intensity is scored as the dataset's, the same light only where both scales are "
            f"the cameras' calibration ({' and '.join(fixes)}: docs/datasets.md)",
            stacklevel=2,
        )
    folder, scores_file = run_dir / name, run_dir / f"{name}.json"
    check_file_output(scores_file, "eval's scores")
    made = write_images and not folder.exists()  # a stopped first scoring leaves none behind
    if write_images:
        check_folder_output(folder, "eval's images", images=True)
    for written in (run_dir, folder):  # what a killed scoring (or training) half-wrote there
        sweep_temporaries(written)
    # an earlier scoring's side-by-sides of views this dataset no longer has (not a user's files)
    earlier = _scored_views(scores_file)  # {view: its scores then}
    now = [v.name for v in dataset.test_views]
    gone, added = sorted(set(earlier) - set(now)), sorted(set(now) - set(earlier))
    for view in gone:
        (folder / f"{view}.png").unlink(missing_ok=True)
    if earlier and (gone or added):  # (its means replaced by another set's, unsaid)
        changes = [
            f"{what} {_first_three(views)}"
            for what, views in (("without", gone), ("with", added))
            if views
        ]
        warnings.warn(
            f"{scores_file} scored {len(earlier)} test view{'s' * (len(earlier) != 1)}; "
            f"{dataset.root} holds {len(now)} now ({', '.join(changes)}): its scores and means "
            f"are replaced by theirs, which the earlier ones (and the training log's) do not "
            f"compare with",
            stacklevel=2,
        )
    # the side-by-sides are written beside theirs and renamed onto them once the scores are: a
    # scoring stopped on the way left the earlier scores beside some of the new images
    staged = []  # [(temporary file, the image it becomes)]
    images = folder if write_images else None
    try:  # (the temporaries left, where the scoring stops or the scores are not written)
        views = _score_views(
            model, dataset, (scale, run_scale, units), align_poses, progress, images, staged
        )
        if not write_images:  # side-by-sides of an earlier scoring these scores no longer match
            for view in (v for v, s in views.items() if v in earlier and _changed(earlier[v], s)):
                (folder / f"{view}.png").unlink(missing_ok=True)
        exact = [view for view, scores in views.items() if scores["psnr"] == math.inf]
        if exact:  # the mean is inf (null in eval.json) and hides the other views' scores
            listed = _first_three(exact)
            warnings.warn(
                f"{len(exact)} test view(s) ({listed}) match the render exactly once both "
                f"are clipped to [0, 1] (saturated or empty views?): PSNR inf, and so is the "
                f"mean; each view's score is in {name}.json",
                stacklevel=2,
            )
        result = {
            "method": train.get("method") or _configured_method(run_dir),
            "dataset": str(Path(dataset.root).resolve()),
            "scene": dataset.meta.get("scene"),
            **_means(list(views.values())),  # psnr, ssim, ssim_3dgs over every test view
            # the views on the camera's path (at a readout of the stream) and off it (novel views)
            "on_path": _group([v for v in views.values() if v["readout"] is not None]),
            "off_path": _group([v for v in views.values() if v["readout"] is None]),
            "iterations": train.get("iterations"),
            "seed": train.get("seed"),
            "train_seconds": train.get("train_seconds"),
            "sim_seconds": train.get("sim_seconds"),
            "gaussians": len(model),
            # real data without sharp images: scored against a TFP pseudo ground truth (pseudo_*)
            "ground_truth": dataset.meta.get("test_ground_truth", "sharp images (synthetic)"),
            "views": views,
            "environment": environment(),  # of this scoring; train.json's names what trained it
        }
        if align_poses:
            unsettled = [name for name, v in views.items() if not v["aligned_settled"]]
            result["aligned_poses"] = {
                "steps": max(v["aligned_steps"] for v in views.values()),  # the most a view took
                "max_steps": MAX_STEPS,
                **{
                    f"{key}_median": _finite_median(v[f"aligned_{key}"] for v in views.values())
                    for key in ("steps", "rotation_deg", "centre", "unexplained")
                },
                "unsettled": unsettled,
                "suspect": _suspect(views),
            }
            if unsettled:
                listed = _first_three(unsettled)
                warnings.warn(
                    f"{len(unsettled)} test view(s) ({listed}) were still moving when their "
                    f"alignment stopped at {max(views[v]['aligned_steps'] for v in unsettled)} "
                    "steps: their given poses lie too far from what their images show, and "
                    "their aligned scores are not the scene's (the reach depends on the scene: on "
                    "128² solids, fine-texture and wires 7 or 8 of 8 views turned 10° came back, "
                    "2 to 5 of 8 turned 20°: docs/outputs.md)",
                    stacklevel=2,
                )
            blank = _unlike(views)
            if blank:
                warnings.warn(
                    f"{len(blank)} test view(s) ({_first_three(blank)}) bear no likeness to their "
                    "images once aligned (their renders' correlation with them at most "
                    f"{max(views[v]['aligned_correlation'] for v in blank):.2f}, under "
                    f"{NO_LIKENESS:g}): the scene is not in their view, their aligned scores not "
                    "the scene's (a run trained in another frame than these poses, SfM's own "
                    "say, or on another scene)",
                    stacklevel=2,
                )
            suspect = [v for v in result["aligned_poses"]["suspect"] if v not in blank]
            if suspect:
                listed = _first_three(suspect)
                warnings.warn(
                    f"{len(suspect)} test view(s) ({listed}) leave over {SUSPECT_RATIO:g} times "
                    "the median view's share of their images' coarse structure unexplained once "
                    f"aligned (up to {max(views[v]['aligned_unexplained'] for v in suspect):.2f}): "
                    "likely settled off their poses, their aligned scores not the scene's "
                    "(docs/outputs.md)",
                    stacklevel=2,
                )
            drift = result["aligned_poses"]["rotation_deg_median"]
            if drift > DRIFT_DEG:
                warnings.warn(
                    f"the test views moved a median {drift:.2f}° once aligned (over "
                    f"{DRIFT_DEG:g}°; a well-fit scene moves them under 1° from their true poses, "
                    "SfM's poses lie 1-3° off): an under-fit or coarse scene lets them drift to "
                    "where its render matches better, and their aligned scores flatter it "
                    "(docs/outputs.md)",
                    stacklevel=2,
                )
        result["file"] = str(scores_file.resolve())  # not as typed: where it lies
        write_text_atomically(scores_file, strict_json.dumps(result, indent=2))
        for tmp, image in staged:
            tmp.replace(image)
    finally:
        _discard(staged)
        if made:  # (rmdir removes only an empty folder: the images written stay)
            with contextlib.suppress(OSError):
                folder.rmdir()
    return result


def _grey(model: GaussianModel) -> bool:
    """Whether every colour coefficient of `model` is the same in its three channels (a mono
    scene as 3DGS's files hold it: R = G = B)."""
    sh = model.sh.detach()  # [N, K, 3]
    return bool(torch.equal(sh[..., 0], sh[..., 1]) and torch.equal(sh[..., 0], sh[..., 2]))


def _score_views(
    model: GaussianModel,
    dataset,
    scales: tuple[float, float, float],
    align_poses: bool,
    progress: bool,
    folder: Path | None,
    staged: list,
) -> dict:
    """`evaluate_run`'s scores of each test view {name: scores} (`scales`: the dataset's and
    the run's intensity scales, and the render's intensity 1 in the sharp images' units;
    `align_poses`, `progress` its), each view's side-by-side written to a temporary file beside
    FOLDER/VIEW.png and appended to `staged` (no images where `folder` is None)."""
    scale, run_scale, sharp_units = scales
    views, radius = {}, float(dataset.scene_radius)
    bar = tqdm(dataset.test_views, "aligning poses", disable=not (progress and align_poses))
    for view in bar:
        # a sharp image is intensity x the dataset's scale, and the render is scored in its
        # units (scored unconverted until 2026-12-06); a pseudo ground truth, TFP of the view's
        # own spikes, in the run's units
        pseudo = view.name.startswith(PSEUDO_PREFIX)
        units = 1.0 if pseudo else sharp_units
        gt = np.asarray(view.image, dtype=np.float32) / (run_scale if pseudo else scale)
        gt = np.clip(gt, 0, 1)  # what is scored, and shown
        aligned = aligned_pose(model, view.viewmat, gt / units, dataset) if align_poses else None
        viewmat = aligned.viewmat if aligned else view.viewmat
        pred = np.clip(units * render_view(model, viewmat, dataset), 0, 1)
        views[view.name] = {**view_metrics(pred, gt), "readout": view.readout}  # (None: off path)
        if aligned:  # how far the pose moved: degrees, and the centre in scene radii
            degrees, moved = (float(e[0]) for e in pose_errors(viewmat[None], view.viewmat[None]))
            views[view.name].update(
                aligned_rotation_deg=degrees,
                aligned_centre=moved / radius,
                aligned_steps=aligned.steps,
                aligned_settled=aligned.settled,
                aligned_unexplained=aligned.unexplained,
                aligned_correlation=_correlation(pred, gt),
            )
        if folder is not None:
            image = side_by_side(gt, pred, pseudo, views[view.name]["psnr"])
            staged.append(stage_image(folder / f"{view.name}.png", image))
    return views


def _discard(staged: list) -> None:
    """Remove the temporary files in `staged` ([(temporary, image)]) not renamed."""
    for tmp, _ in staged:
        tmp.unlink(missing_ok=True)
