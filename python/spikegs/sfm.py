"""Camera poses from spikes: spike images (TFP or SIM) at chosen readouts, structure from motion
with pycolmap (`pip install pycolmap`, or the checkout's `pip install '.[sfm]'`), poses as
OpenCV world-to-camera viewmats.

SfM recovers poses and points up to a similarity (rotation, translation and scale of the world);
`align` maps them onto a known trajectory by the similarity that fits the camera centres and
orientations (`similarity`). COLMAP's camera is OpenCV's (x right, y down, z forward; pixel
centres at +0.5), so its `cam_from_world` is our viewmat as it is.
"""

from __future__ import annotations

import dataclasses
import shutil
import signal
import threading
from pathlib import Path

import numpy as np
from PIL import Image

from .data.dataset import field_of_view_deg
from .data.trajectory import Trajectory
from .missing_dependency import MissingDependencyError
from .pixel_defects import repaired

GAMMA = 2.2  # images are gamma-encoded for SIFT (contrast in the darks), points linearised back
MIN_FEATURES = 100  # fewer SIFT features per image than this: the images are the likely problem
MIN_PAIR_INLIERS = 15  # verified matches that make two images a matched pair


@dataclasses.dataclass
class Reconstruction:
    """Registered images of one SfM run and its sparse points, in one world frame."""

    readouts: np.ndarray  # [R] readouts of the registered images, increasing
    viewmats: np.ndarray  # [R, 4, 4] world-to-camera, OpenCV
    K: np.ndarray  # [3, 3] intrinsics (given, or estimated by SfM)
    points: np.ndarray  # [P, 3]
    colors: np.ndarray  # [P, 3] uint8, linear intensity
    num_images: int  # images given to SfM
    image_errors: np.ndarray  # [R] mean reprojection error (px) of each image's observed points
    reprojection_error: float  # px, the mean over every observation of a point
    # (image pairs matched, those of them COLMAP's verification found parallax in)
    pair_counts: tuple[int, int] = (0, 0)

    def transformed(self, scale: float, rotation: np.ndarray, shift: np.ndarray) -> Reconstruction:
        """The same reconstruction in the world X' = scale · rotation @ X + shift."""
        world = np.eye(4)
        world[:3, :3], world[:3, 3] = rotation, shift / scale  # X'/scale = world @ X
        viewmats = self.viewmats @ np.linalg.inv(world)  # [R, 4, 4], camera frame scaled by 1/s
        viewmats[:, :3, 3] *= scale
        points = scale * self.points @ rotation.T + shift
        return dataclasses.replace(self, viewmats=viewmats, points=points)

    def trajectory(self, num_readouts: int) -> Trajectory:
        """The registered poses as a trajectory over [0, num_readouts - 1]: unregistered readouts
        in between are interpolated, the first and last poses are held constant to the ends."""
        readouts, viewmats = self.readouts, self.viewmats
        if readouts[0] > 0:
            readouts, viewmats = np.append(0, readouts), np.concatenate([viewmats[:1], viewmats])
        if readouts[-1] < num_readouts - 1:
            readouts = np.append(readouts, num_readouts - 1)
            viewmats = np.concatenate([viewmats, viewmats[-1:]])
        return Trajectory(readouts, viewmats, source="sfm")


def spike_images(
    streams, readouts: np.ndarray, window: int, sim=None, defects: list | np.ndarray | None = None
) -> np.ndarray:
    """Grey images [N, H, W] in [0, 1] at `readouts` [N]: TFP(`window`) or, given a SIM, its
    images, each channel's `defects` [H, W] (bool; the sensor's hot, stuck and dead pixels) given
    the median of their 8 neighbours; the mean of a colour camera's channels, divided by the
    99.5th percentile."""
    from .sim_train import infer_sim

    def image(stream, defects) -> np.ndarray:  # [N, H, W]
        if sim is None:
            images = np.asarray(stream.tfp(readouts, window), np.float32)
        else:
            images = infer_sim(sim, stream, readouts)[..., 0]
        if defects is not None and defects.any():  # one at a time, in place
            for i, one in enumerate(images):
                images[i] = repaired(one, defects)
        return images

    # summed, scaled and clipped in place, a channel's images at a time: the channels' images,
    # their stack, the mean, its quotient and the clipped copy held 7 times the images at once
    # for a colour camera, 3 times for a mono one (1200 images of 250x400: 3.2 and 1.4 GB over
    # the 0.46 GB of the images), now twice (np.percentile's copy)
    defects = [None] * len(streams) if defects is None else defects
    if len(defects) != len(streams):
        raise ValueError(f"spike_images: {len(defects)} defect maps for {len(streams)} channels")
    grey = np.array(image(streams[0], defects[0]), np.float32)  # [N, H, W], its own
    for stream, found in zip(streams[1:], defects[1:]):
        grey += image(stream, found)
    grey /= len(streams)  # (np.mean's sum and division, in float32 as it)
    grey /= max(float(np.percentile(grey, 99.5)), 1e-12)
    return np.clip(grey, 0.0, 1.0, out=grey)


def reconstruct(
    images: np.ndarray,
    readouts: np.ndarray,
    work_dir: str | Path,
    K: np.ndarray | None = None,
    min_registered: float = 0.5,
    seed: int = 0,
    from_sim: bool = False,
    can_sim: bool = True,
) -> Reconstruction:
    """Incremental SfM on grey images [N, H, W] taken at `readouts` [N], in `work_dir` (replaced:
    images/, database.db, sparse/). Known intrinsics `K` are held fixed, else a pinhole camera is
    estimated. ValueError, with the numbers and the likely cause, when fewer than `min_registered`
    of the images are registered (`from_sim`: the images are SIM's, which its hints then know;
    `can_sim`: a SIM can be trained for them, else --sim is not suggested: a raw recording's
    needs poses first)."""
    pycolmap = import_pycolmap()
    work = Path(work_dir)
    shutil.rmtree(work, ignore_errors=True)
    (work / "images").mkdir(parents=True)
    names = [f"{int(k):08d}.png" for k in readouts]
    for name, image in zip(names, images):
        encoded = np.round(255 * image ** (1 / GAMMA)).astype(np.uint8)
        Image.fromarray(encoded).save(work / "images" / name)
    database = work / "database.db"
    reader = pycolmap.ImageReaderOptions()
    if K is None:
        reader.camera_model = "SIMPLE_PINHOLE"
    else:
        reader.camera_model = "PINHOLE"
        reader.camera_params = ",".join(
            str(float(K[i, j])) for i, j in ((0, 0), (1, 1), (0, 2), (1, 2))
        )
    level = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 2  # COLMAP's progress log is long: errors only
    try:
        # one extraction thread: images enter the database, and get their ids, in `names`' order
        # (threads insert them as they finish, and the ids' order steers matching and mapping)
        extraction = pycolmap.FeatureExtractionOptions()
        extraction.num_threads = 1
        pycolmap.extract_features(
            database, work / "images", names, pycolmap.CameraMode.SINGLE, reader, extraction
        )
        verification = pycolmap.TwoViewGeometryOptions()
        verification.ransac.random_seed = seed  # -1 (COLMAP's default) seeds from the clock
        matching = pycolmap.FeatureMatchingOptions()
        matching.num_threads = 1  # threaded matching once gave other poses in a CI run
        pycolmap.match_exhaustive(
            database, matching_options=matching, verification_options=verification
        )
        stats = _match_stats(database, len(names))
        failure = {"images": work / "images", "from_sim": from_sim, "can_sim": can_sim, "K": K}
        failure["width"] = images.shape[2]
        # the mapper judges parallax: most pairs of small images, even of an orbit it
        # reconstructs, are ones COLMAP labels PLANAR_OR_PANORAMIC, which a check before it
        # refused (17 of 20 images of a 64x96 orbit registered, 2.4 degrees off, once let
        # through); as are a still camera's, whose poses it fits to noise: said by poses
        if stats["pairs"] == 0:
            raise ValueError(_failure(stats, None, min_registered, **failure))
        models = pycolmap.incremental_mapping(
            database, work / "images", work / "sparse", _mapper_options(K is None, seed)
        )
    finally:
        pycolmap.logging.minloglevel = level
    model = max(models.values(), key=lambda m: m.num_reg_images(), default=None)
    registered = 0 if model is None else model.num_reg_images()
    if registered < max(3, min_registered * len(names)):
        raise ValueError(_failure(stats, registered, min_registered, **failure))
    recon = _read_model(model, names, readouts)
    return dataclasses.replace(recon, pair_counts=(stats["pairs"], stats["parallax_pairs"]))


def import_pycolmap():
    """pycolmap, or MissingDependencyError saying how to install it."""
    handler = signal.getsignal(signal.SIGTERM)
    try:
        import pycolmap
    except ImportError as err:
        raise MissingDependencyError(
            "poses from spikes need pycolmap, which is not installed: "
            "pip install pycolmap (or, in a checkout of spikegs, pip install '.[sfm]')"
        ) from err
    # glog's failure handler took SIGTERM below Python (a stack dump, not 'terminated')
    if handler is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, handler)
    return pycolmap


def _mapper_options(estimate_focal: bool, seed: int):
    """Incremental mapping relaxed for small images (a few hundred features each)."""
    import pycolmap

    options = pycolmap.IncrementalPipelineOptions()
    options.ba_refine_focal_length = estimate_focal
    options.ba_refine_extra_params = False
    options.min_model_size = 3
    options.random_seed = seed
    # one thread: the mapper's threaded bundle adjustment and triangulation sum in the order the
    # threads finish, and two runs on 2 cores gave 272-275 points and 1.18-1.40° median error
    options.num_threads = 1
    options.mapper.init_min_num_inliers = 30
    options.mapper.abs_pose_min_num_inliers = 12
    options.mapper.abs_pose_min_inlier_ratio = 0.1
    options.mapper.abs_pose_refine_focal_length = estimate_focal
    return options


def _reprojection_errors(model, image) -> np.ndarray:
    """The distances (px) [O] between a registered image's observations and its projections of
    the points they observe."""
    observed = image.get_observation_points2D()
    xy = np.array([q.xy for q in observed]).reshape(-1, 2)  # [O, 2]
    xyz = np.array([model.points3D[q.point3D_id].xyz for q in observed]).reshape(-1, 3)
    cam_from_world = image.cam_from_world().matrix()  # [3, 4]
    in_camera = xyz @ cam_from_world[:, :3].T + cam_from_world[:, 3]  # [O, 3]
    projected = image.camera.img_from_cam(in_camera, check_cheirality=False)  # [O, 2]
    return np.linalg.norm(projected - xy, axis=1)


def _read_model(model, names: list[str], readouts: np.ndarray) -> Reconstruction:
    by_name = {image.name: image for image in model.images.values() if image.has_pose}
    order = [i for i, name in enumerate(names) if name in by_name]
    viewmats = np.tile(np.eye(4), (len(order), 1, 1))  # [R, 4, 4]
    errors = []  # [R] of [O_r]
    for row, i in enumerate(order):
        viewmats[row, :3] = by_name[names[i]].cam_from_world().matrix()
        errors.append(_reprojection_errors(model, by_name[names[i]]))
    camera = next(iter(model.cameras.values()))
    points = np.array([p.xyz for p in model.points3D.values()]).reshape(-1, 3)  # [P, 3]
    encoded = np.array([p.color for p in model.points3D.values()]).reshape(-1, 3) / 255.0
    colors = np.round(255 * encoded**GAMMA).astype(np.uint8)  # [P, 3]
    return Reconstruction(
        np.asarray(readouts, np.float64)[order],
        viewmats,
        np.asarray(camera.calibration_matrix(), np.float64),
        points,
        colors,
        len(names),
        np.array([e.mean() if len(e) else np.nan for e in errors]),
        float(np.concatenate(errors).mean()),
    )


def _match_stats(database: Path, num_images: int) -> dict:
    """Features per image, image pairs with >= MIN_PAIR_INLIERS verified matches, how many of
    those show parallax (their geometry is not a homography: neither pure rotation nor a plane
    seen from one place) and how many are of images not next to each other on the path (the
    images' ids are in their readouts' order)."""
    import pycolmap

    config = pycolmap.TwoViewGeometryConfiguration
    moving = (config.CALIBRATED, config.CALIBRATED_RIG, config.UNCALIBRATED, config.PLANAR)
    db = pycolmap.Database.open(database)
    try:
        ids, geometries = db.read_two_view_geometries()
        matched = [
            (pycolmap.pair_id_to_image_pair(i), g)
            for i, g in zip(ids, geometries)
            if len(g.inlier_matches) >= MIN_PAIR_INLIERS
        ]
        return {
            "images": num_images,
            "features": db.num_keypoints() / max(num_images, 1),
            "pairs": len(matched),
            "parallax_pairs": sum(g.config in moving for _, g in matched),
            "beyond_neighbours": sum(abs(a - b) > 1 for (a, b), _ in matched),
            "inliers": db.num_inlier_matches(),
        }
    finally:
        db.close()


def _failure(
    stats: dict,
    registered: int | None,
    min_registered: float,
    images: Path,
    from_sim: bool,
    can_sim: bool = True,
    K: np.ndarray | None = None,
    width: int | None = None,
) -> str:
    """The failure message: what SfM managed (`registered` None: no pair matched, mapping not
    tried), in numbers, the likely reasons, and where its `images` (SIM's where `from_sim`;
    `can_sim`: SIM's could be made) are to look at. `K` [3, 3]: the stated intrinsics SfM held
    fixed, for images `width` px wide (a focal in mm failed as "no parallax", unnamed)."""
    n = stats["images"]
    need = max(3, int(np.ceil(min_registered * n)))
    if registered is not None:
        outcome = f"{registered} of {n} images registered (needed {need})"
    else:  # (noise: "no pair shows parallax" sent to more readouts)
        outcome = "no image pair matched, so nothing can be triangulated"
    reasons = []
    if n < 10:
        reasons.append(f"too few images ({n}): raise --count or lower --every")
    if stats["features"] < MIN_FEATURES:
        cleaner = (  # (--window with --sim is refused: SIM reads its own)
            "a SIM of a longer window, `spikegs sim-train --window N`, gives cleaner images"
            if from_sim
            else "a longer --window" + (", or --sim," if can_sim else "") + " gives cleaner images"
        )
        reasons.append(f"few features: textureless or noisy images ({cleaner})")
    # few pairs but of neighbours on the path, most of them matched and with parallax: each
    # image overlaps the next only (a long path, or a fast camera, for the images: 40 over 600°
    # of an orbit matched 34 such pairs, 8 more). Not where no pair matched, nor where the pairs
    # show no parallax (a still or turning camera: more images, closer, would show less)
    near = stats["pairs"] - stats["beyond_neighbours"]
    far = (
        stats["features"] >= MIN_FEATURES
        and stats["beyond_neighbours"] < n / 2
        and near >= (n - 1) / 2
        and stats["parallax_pairs"] >= stats["pairs"] / 2
    )
    if far:
        reasons.append(
            f"images far apart on the path: {near} of the {stats['pairs']} matched pairs are of "
            "neighbouring images (each image overlaps the next only): raise --count or lower "
            "--every"
        )
    elif stats["pairs"] < n:
        reasons.append(
            "few matching pairs: too little overlap between images, or repetitive texture"
        )
    if 0 < stats["pairs"] and stats["parallax_pairs"] < n and not far:
        reasons.append(
            "too little parallax (a short stream, or a camera that barely moves or only turns): "
            "spread the images over more readouts"
        )
    if K is not None:  # a focal in mm, or ×10, registers none
        reasons.append(
            f"the intrinsics stated in meta.json are held fixed (fx = {K[0, 0]:.4g} px, a "
            f"{field_of_view_deg(width, K[0, 0]):.0f}° horizontal field of view): wrong ones "
            "(another lens's, or in mm, not pixels) register few or no images; check them, or "
            "remove fx, fy, cx, cy for SfM to estimate them"
        )
    return (
        f"structure from motion failed: {outcome}; {n} images, {stats['features']:.0f} SIFT "
        f"features per image, {stats['pairs']} image pairs with >= {MIN_PAIR_INLIERS} verified "
        f"matches ({stats['parallax_pairs']} of them with parallax, {stats['inliers']} inlier "
        "matches in all). Likely: "
        + "; ".join(reasons or ["a hard scene for SIFT at this resolution"])
        + f". Look at the images in {images}: scrambled or sheared ones mean a wrong height, "
        "width or raw_width in meta.json."
    )


def similarity(
    centres: np.ndarray,
    rotations: np.ndarray,
    known_centres: np.ndarray,
    known_rotations: np.ndarray,
) -> tuple[float, np.ndarray, np.ndarray]:
    """The similarity (scale, rotation [3, 3], shift [3]) taking cameras with centres [N, 3] and
    camera-to-world rotations [N, 3, 3] onto `known_*`: X' = scale · rotation @ X + shift.

    The rotation maximises, in one SVD (Kabsch), the agreement of both the centres (as Umeyama's
    fit, scaled) and the camera orientations, weighted alike (each term in squared distances of
    the known world): centres alone leave the turn about a short arc's chord free (a 40° arc:
    12° off); the scale and shift then fit the centres. ValueError where the fit would mirror
    the world (a scale <= 0: centres that do not correlate) or the centres coincide.
    """
    mu_src, mu_dst = centres.mean(axis=0), known_centres.mean(axis=0)
    src, dst = centres - mu_src, known_centres - mu_dst  # [N, 3] centred
    spread_src, spread_dst = (src * src).sum(axis=1).mean(), (dst * dst).sum(axis=1).mean()
    if not spread_src > 0:  # (its scale 0/0: numpy's RuntimeWarning before the error)
        raise ValueError(
            "align: the registered cameras' centres coincide: no similarity maps them onto the "
            "trajectory's"
        )
    cross = dst.T @ src / len(src)  # [3, 3]; the centres' term: maximise tr(R^T cross)
    orient = np.einsum("nij,nkj->ik", known_rotations, rotations) / len(src)  # sum R_t R_s^T / N
    # tr(R^T cross) ~ spread of the centres; tr(R^T orient) <= 3: weighted to the same scale
    u, _, vt = np.linalg.svd(cross + orient * np.sqrt(spread_src * spread_dst) / 3.0)
    rotation = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    scale = float(np.einsum("ni,ni->", dst, src @ rotation.T) / len(src) / spread_src)
    if not scale > 0:
        raise ValueError(
            f"align: the registered cameras' centres do not follow the trajectory's (scale "
            f"{scale:.3g}): no similarity maps them onto it"
        )
    return scale, rotation, mu_dst - scale * rotation @ mu_src


ROW_FLIP = np.diag([1.0, -1.0, 1.0])  # a camera's y axis reversed: its image upside down
MIRROR = np.diag([1.0, 1.0, -1.0])  # a world mirrored (in z: any mirror, up to a similarity)


def unmirrored(recon: Reconstruction) -> Reconstruction:
    """The cameras that took `recon`'s images were they read upside down (a wrong `flip`): SfM's
    world is then the true one mirrored, X' = M X, its rotations F R M (F: ROW_FLIP, M: MIRROR),
    which no similarity undoes; returned: rotations F R' M, centres M C', points M X'."""
    rotations = ROW_FLIP @ recon.viewmats[:, :3, :3] @ MIRROR  # [R, 3, 3] world-to-camera
    centres = np.linalg.inv(recon.viewmats)[:, :3, 3] @ MIRROR  # [R, 3]
    viewmats = np.tile(np.eye(4), (len(rotations), 1, 1))  # [R, 4, 4]
    viewmats[:, :3, :3] = rotations
    viewmats[:, :3, 3] = -np.einsum("nij,nj->ni", rotations, centres)
    return dataclasses.replace(recon, viewmats=viewmats, points=recon.points @ MIRROR)


def compared(readouts: np.ndarray, trajectory: Trajectory) -> np.ndarray:
    """Which registered `readouts` [R] to compare with `trajectory`'s poses (bool [R]): those
    within its recorded span (`Trajectory.recorded_span`: an earlier run's SfM holds its ends'
    poses constant, which a re-run registering a wider span fitted, 4.5 deg off, and reported
    16.9 deg from), all where fewer than 3 are."""
    first, last = trajectory.recorded_span()
    inside = (readouts >= first) & (readouts <= last)  # [R]
    return inside if inside.sum() >= 3 else np.ones(len(readouts), bool)


def align(recon: Reconstruction, trajectory: Trajectory) -> Reconstruction:
    """`recon` moved into `trajectory`'s world by the similarity that best maps its cameras (their
    centres and orientations: `similarity`) onto the trajectory's at the same readouts (those
    `compared`)."""
    if len(recon.readouts) < 3:
        raise ValueError(f"align: needs >= 3 registered images, found {len(recon.readouts)}")
    inside = compared(recon.readouts, trajectory)  # [R]
    c2w = np.linalg.inv(recon.viewmats[inside])  # [R', 4, 4]
    known = np.linalg.inv(trajectory.pose_at(recon.readouts[inside]))  # [R', 4, 4]
    fit = similarity(c2w[:, :3, 3], c2w[:, :3, :3], known[:, :3, 3], known[:, :3, :3])
    return recon.transformed(*fit)
