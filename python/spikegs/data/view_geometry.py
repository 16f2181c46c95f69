"""The scene sphere that cameras look at: where their optical axes converge, and how far they
stand from it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..number_checks import is_number, number_array

CONVERGING = 0.03  # smallest eigenvalue of mean(I - d d^T) over view directions d: inward-facing
# the least spread whose nearest point of the axes a scene sphere is taken from where no depth
# bounds give another (NeRF layout, simulate): below it (directions within ~2°, forward-facing
# or parallel) that point is set by the poses' noise. A 30° inward arc, a ring seen from 82°
# elevation spread 0.02-0.07, forward-facing views jittered by 1° ~3e-4
AXES_SPREAD_MIN = 1e-3


def optical_axes(viewmats: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera centres [F, 3], view directions [F, 3] and the projections I - d d^T [F, 3, 3]
    across each optical axis, of world-to-camera viewmats [F, 4, 4]."""
    c2w = np.linalg.inv(viewmats)  # [F, 4, 4]
    eyes, dirs = c2w[:, :3, 3], c2w[:, :3, 2]  # [F, 3] each
    return eyes, dirs, np.eye(3) - dirs[:, :, None] * dirs[:, None, :]


def centre_of_view(viewmats: np.ndarray) -> tuple[np.ndarray, float]:
    """The point [3] nearest to all optical axes, and the mean camera distance to it / 2.5
    (the scene radius that the spiral sources see from their distance of 2.5 radii)."""
    eyes, _, proj = optical_axes(viewmats)
    center = np.linalg.lstsq(proj.sum(0), np.einsum("fij,fj->i", proj, eyes), rcond=None)[0]
    return center, float(np.linalg.norm(eyes - center, axis=1).mean() / 2.5)


class AxesMeeting(NamedTuple):
    """Where cameras' optical axes meet (`axes_meeting`)."""

    center: np.ndarray  # [3] `centre_of_view`'s point
    radius: float  # and its radius
    spread: float  # the view directions': the smallest eigenvalue of the mean of I - d d^T
    depth: np.ndarray  # [F] the point's depth along each camera's axis (< 0: behind it)
    distance: np.ndarray  # [F] each camera's distance to it


def axes_meeting(viewmats: np.ndarray) -> AxesMeeting:
    """Where the optical axes of world-to-camera viewmats [F, 4, 4] meet, and how the cameras
    stand to that point."""
    eyes, dirs, proj = optical_axes(viewmats)  # [F, 3], [F, 3], [F, 3, 3]
    center, radius = centre_of_view(viewmats)
    offsets = center - eyes  # [F, 3]
    spread = float(np.linalg.eigvalsh(proj.mean(0))[0])
    depth = np.einsum("fi,fi->f", offsets, dirs)
    return AxesMeeting(center, radius, spread, depth, np.linalg.norm(offsets, axis=1))


def converging_centre(
    viewmats: np.ndarray, min_spread: float = CONVERGING
) -> tuple[np.ndarray, float] | None:
    """`centre_of_view` of viewmats [F, 4, 4] when their optical axes converge in front of every
    camera: view directions spread (`min_spread`; CONVERGING, about ±20°, for LLFF, which has depth
    bounds to fall back on) and the point ahead of each; else None (forward-facing views: the
    nearest point is set by noise, often behind them)."""
    meeting = axes_meeting(viewmats)
    converged = meeting.spread >= min_spread and (meeting.depth > 0).all()
    return (meeting.center, meeting.radius) if converged else None


def view_sphere(
    viewmats: np.ndarray,
    source,
    fix: str,
    *,
    center=None,
    radius: float | None = None,
    axes_fix: str = "",
) -> tuple[np.ndarray, float]:
    """The scene sphere's centre [3] and radius: `center`, `radius` where given (a centre needs
    its radius; a radius alone keeps the computed centre), else `converging_centre`'s; ValueError
    naming `source` and how to `fix` it when one is needed and the optical axes of viewmats
    [F, 4, 4] do not converge in front of the cameras (then `axes_fix` too: a file's stated
    convention)."""
    if radius is not None and not (is_number(radius) and radius > 0):
        raise ValueError(f"{source}: scene radius expected a finite number > 0, found {radius!r}")
    if center is not None:
        try:
            given = number_array(center)
        except ValueError:  # text, booleans, ragged lists
            given = np.full(1, np.nan)
        if given.shape != (3,) or not np.isfinite(given).all():
            raise ValueError(f"{source}: scene centre expected 3 finite numbers, found {center!r}")
    if center is not None and radius is not None:
        return given, float(radius)
    if center is not None:
        raise ValueError(
            f"{source}: a scene centre needs its radius (the radius computed from the views is "
            f"about the centre computed with it); {fix}"
        )
    converged = converging_centre(viewmats, AXES_SPREAD_MIN)
    if converged is None:
        eyes, dirs, _ = optical_axes(viewmats)  # [F, 3], [F, 3]
        position, direction = (
            (np.round(v, 3) + 0.0).tolist()  # + 0.0: no -0.0
            for v in (eyes.mean(0), dirs.mean(0) / np.linalg.norm(dirs.mean(0)))
        )
        raise ValueError(
            f"{source}: the cameras' optical axes do not converge in front of them (forward-facing "
            f"or parallel views, directions within about ±2°, or axes whose nearest point lies "
            f"behind a camera, as poses in another convention than their file states give: "
            f"OpenCV matrices where OpenGL's are read, or world-to-camera ones), so the scene's "
            f"centre and size are unknown; {fix}{axes_fix} (the "
            f"cameras' mean position is {position}, their mean viewing direction {direction}: a "
            f"scene D ahead of them is centred at position + D * direction)"
        )
    return converged[0], converged[1] if radius is None else float(radius)
