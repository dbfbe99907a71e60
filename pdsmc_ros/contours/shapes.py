"""Task-space contours (Section 4.2): the desired end-effector point ``P_d(t)`` with its first
two derivatives, and the contour error of an actual point (Section 2.4.2)."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError, InvalidInputError
from ..robots.base import FloatArray, as_vector
from .polynomials import quintic
from .samples import TaskSample

ELLIPSE_ERRORS = ("nearest", "osculating")
"""The contour errors of a non-circular ellipse (:class:`EllipseContour`'s ``ellipse_error``, the run's
``ellipse_error``): the exact nearest point, or the local circle the thesis says it used."""


def _require_positive(label: str, value: float | FloatArray) -> None:
    """A contour's durations and radii: finite and > 0 (InvalidInputError naming them)."""
    if not np.all(np.isfinite(value)) or np.any(np.asarray(value) <= 0.0):
        raise InvalidInputError(f"{label} must be finite and > 0, got {value!r}")


def _require_choice(label: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise InvalidInputError(f"{label} must be one of {', '.join(map(repr, allowed))}, got {value!r}")


class Contour:
    """A timed task-space path. ``dim`` is 3 (x, y, pose) or 2 (x, y)."""

    name: str = "contour"
    dim: int = 2
    duration: float = 0.0

    def task(self, t: ArrayLike) -> TaskSample:
        """Desired point, rate and acceleration at times ``t`` (s)."""
        raise NotImplementedError

    def contour_error(self, t: FloatArray, xy: FloatArray) -> FloatArray:
        """Contour error (m, >= 0) of actual points ``xy`` ``(len(t), 2)`` at times ``t``."""
        raise NotImplementedError

    def scaled(self, factor: float) -> Contour:
        """The same path run in ``factor`` times the duration (Section 4.5.1)."""
        raise NotImplementedError

    def describe(self) -> dict[str, object]:
        """Plain-data description, stored with every run."""
        raise NotImplementedError

    def extent(self) -> tuple[FloatArray, FloatArray]:
        """Corners ``(low, high)`` of the box around the path's points ``(x, y)``."""
        raise NotImplementedError

    def placed(self, scale: float, shift: ArrayLike) -> Contour:
        """The same timed path with its points ``(x, y)`` mapped to ``scale * (x, y) + shift``
        (a contour sized and placed in an arm's workspace; the pose is unchanged)."""
        raise NotImplementedError

    def fitted(self, size: float) -> Contour:
        """Placed so its box is centred at ``(0, 0)`` with its longer side ``size`` (m)."""
        _require_positive("contour size", size)
        low, high = self.extent()
        scale = size / float(np.max(high - low))
        return self.placed(scale, -scale * (low + high) / 2.0)


class SegmentContour(Contour):
    """Stop-and-go straight segments through waypoints, Eq. (4.5).

    Each segment ``P_d(t) = P_i + (P_f - P_i) s_c(t)`` lasts ``segment_duration``
    seconds (2 s in the thesis). The contour error is Eq. (2.9) against the
    segment active at ``t`` (``metric="active_segment"``) or the distance to the
    nearest point of the whole polyline (``metric="nearest"``).
    """

    def __init__(
        self,
        name: str,
        waypoints: ArrayLike,
        segment_durations: float | Sequence[float],
        *,
        metric: str = "active_segment",
    ) -> None:
        pts = np.asarray(waypoints, dtype=float)
        if pts.ndim != 2 or pts.shape[0] < 2 or pts.shape[1] not in (2, 3):
            raise InvalidInputError(
                f"waypoints must be a (k >= 2, 2 or 3) array, got shape {pts.shape}"
            )
        if not np.all(np.isfinite(pts)):
            raise InvalidInputError("waypoints must be finite")
        durations = np.broadcast_to(
            np.asarray(segment_durations, dtype=float), (pts.shape[0] - 1,)
        ).copy()
        _require_positive("segment durations", durations)
        _require_choice("metric", metric, ("active_segment", "nearest"))
        self.name = name
        self.waypoints = pts
        self.dim = pts.shape[1]
        self.durations = durations
        self.starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
        self.duration = float(np.sum(durations))
        self.metric = metric

    def _segment(self, t: FloatArray) -> np.ndarray:
        idx = np.searchsorted(self.starts, t, side="right") - 1
        return np.clip(idx, 0, len(self.durations) - 1)

    def task(self, t: ArrayLike) -> TaskSample:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        seg = self._segment(t)
        local = t - self.starts[seg]
        s, sd, sdd = quintic(local, self.durations[seg])
        delta = self.waypoints[seg + 1] - self.waypoints[seg]
        return TaskSample(
            p=self.waypoints[seg] + delta * s[:, None],
            pd=delta * sd[:, None],
            pdd=delta * sdd[:, None],
        )

    def contour_error(self, t: FloatArray, xy: FloatArray) -> FloatArray:
        if self.metric == "nearest":
            return polyline_distance(self.waypoints[:, :2], xy)
        seg = self._segment(np.asarray(t, dtype=float))
        start = self.waypoints[seg, :2]
        delta = self.waypoints[seg + 1, :2] - start
        theta = np.arctan2(delta[:, 1], delta[:, 0])
        desired = self.task(t).p[:, :2]
        ex = xy[:, 0] - desired[:, 0]
        ey = xy[:, 1] - desired[:, 1]
        return np.abs(-ex * np.sin(theta) + ey * np.cos(theta))  # Eq. (2.9)

    def scaled(self, factor: float) -> SegmentContour:
        return SegmentContour(self.name, self.waypoints, self.durations * factor, metric=self.metric)

    def extent(self) -> tuple[FloatArray, FloatArray]:
        xy = self.waypoints[:, :2]
        return xy.min(axis=0), xy.max(axis=0)

    def placed(self, scale: float, shift: ArrayLike) -> SegmentContour:
        _require_positive("contour scale", scale)
        pts = self.waypoints.copy()
        pts[:, :2] = scale * pts[:, :2] + as_vector(shift, 2, "shift")
        return SegmentContour(self.name, pts, self.durations, metric=self.metric)

    def describe(self) -> dict[str, object]:
        return {
            "type": "segments",
            "name": self.name,
            "waypoints": self.waypoints.tolist(),
            "segment_durations": self.durations.tolist(),
            "contour_error": self.metric,
        }


class EllipseContour(Contour):
    """One revolution of an ellipse (circle if ``rx == ry``), Eqs. (4.6)-(4.8).

    ``theta_d(t) = 2 pi s_c(t)``; the serial arm's pose goes from
    ``pose_start`` to ``pose_end`` with the same scaling (Eq. 4.5).

    Contour error: Eq. (2.10) for a circle; for an ellipse either the exact
    distance to the nearest point of the ellipse (``"nearest"``) or Eq. (2.10)
    applied to the osculating circle at the desired point (``"osculating"``,
    the "local circle approximation" of Section 2.4.2).
    """

    def __init__(
        self,
        name: str,
        center: ArrayLike,
        rx: float,
        ry: float,
        duration: float,
        *,
        pose: tuple[float, float] | None = None,
        ellipse_error: str,
    ) -> None:
        c = as_vector(center, 2, "center")
        for label, value in (("rx", rx), ("ry", ry), ("duration", duration)):
            _require_positive(label, value)
        _require_choice("ellipse_error", ellipse_error, ELLIPSE_ERRORS)
        self.name = name
        self.center = c
        self.rx = float(rx)
        self.ry = float(ry)
        self.duration = float(duration)
        self.pose = pose
        self.dim = 3 if pose is not None else 2
        self.ellipse_error = ellipse_error

    @property
    def is_circle(self) -> bool:
        return self.rx == self.ry

    def _theta(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        s, sd, sdd = quintic(t, self.duration)
        return 2.0 * np.pi * s, 2.0 * np.pi * sd, 2.0 * np.pi * sdd

    def task(self, t: ArrayLike) -> TaskSample:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        th, thd, thdd = self._theta(t)
        c, s = np.cos(th), np.sin(th)
        x = self.center[0] + self.rx * c
        y = self.center[1] + self.ry * s
        xd = -self.rx * s * thd
        yd = self.ry * c * thd
        xdd = -self.rx * (c * thd**2 + s * thdd)
        ydd = self.ry * (-s * thd**2 + c * thdd)
        cols = [[x, xd, xdd], [y, yd, ydd]]
        if self.pose is not None:
            sc, scd, scdd = quintic(t, self.duration)
            span = self.pose[1] - self.pose[0]
            cols.append([self.pose[0] + span * sc, span * scd, span * scdd])
        return TaskSample(
            p=np.stack([col[0] for col in cols], axis=-1),
            pd=np.stack([col[1] for col in cols], axis=-1),
            pdd=np.stack([col[2] for col in cols], axis=-1),
        )

    def contour_error(self, t: FloatArray, xy: FloatArray) -> FloatArray:
        dx = xy[:, 0] - self.center[0]
        dy = xy[:, 1] - self.center[1]
        if self.is_circle:
            return np.abs(np.hypot(dx, dy) - self.rx)  # Eq. (2.10)
        if self.ellipse_error == "osculating":
            th, _, _ = self._theta(np.asarray(t, dtype=float))
            c, s = np.cos(th), np.sin(th)
            speed2 = (self.rx * s) ** 2 + (self.ry * c) ** 2
            radius = speed2**1.5 / (self.rx * self.ry)
            # inward unit normal of (rx cos, ry sin)
            norm = np.sqrt(speed2)
            nx = -self.ry * c / norm
            ny = -self.rx * s / norm
            cx = self.center[0] + self.rx * c + radius * nx
            cy = self.center[1] + self.ry * s + radius * ny
            return np.abs(np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) - radius)
        return ellipse_distance(self.rx, self.ry, dx, dy)

    def scaled(self, factor: float) -> EllipseContour:
        return EllipseContour(
            self.name,
            self.center,
            self.rx,
            self.ry,
            self.duration * factor,
            pose=self.pose,
            ellipse_error=self.ellipse_error,
        )

    def extent(self) -> tuple[FloatArray, FloatArray]:
        radii = np.array([self.rx, self.ry])
        return self.center - radii, self.center + radii

    def placed(self, scale: float, shift: ArrayLike) -> EllipseContour:
        _require_positive("contour scale", scale)
        return EllipseContour(self.name, scale * self.center + as_vector(shift, 2, "shift"), scale * self.rx,
                              scale * self.ry, self.duration, pose=self.pose, ellipse_error=self.ellipse_error)

    def describe(self) -> dict[str, object]:
        return {
            "type": "circle" if self.is_circle else "ellipse",
            "name": self.name,
            "center": self.center.tolist(),
            "rx": self.rx,
            "ry": self.ry,
            "duration": self.duration,
            "pose": list(self.pose) if self.pose is not None else None,
            "contour_error": "circle" if self.is_circle else self.ellipse_error,
        }


def ellipse_distance(rx: float, ry: float, dx: FloatArray, dy: FloatArray) -> FloatArray:
    """Distance from points ``(dx, dy)`` (relative to the centre) to an ellipse.

    Newton's method on the foot-point parameter, started from the point's
    eccentric angle; converges to machine precision for points near the curve.
    """
    th = np.arctan2(dy / ry, dx / rx)
    for _ in range(20):
        c, s = np.cos(th), np.sin(th)
        ex, ey = dx - rx * c, dy - ry * s
        f = ex * rx * s - ey * ry * c  # (P - E) . E'(th) with E' = (-rx s, ry c), negated
        fp = (rx * s) ** 2 + (ry * c) ** 2 + ex * rx * c + ey * ry * s
        step = f / fp
        th = th - step
        if np.max(np.abs(step)) < 1e-15:
            break
    return np.hypot(dx - rx * np.cos(th), dy - ry * np.sin(th))


def polyline_distance(vertices: FloatArray, xy: FloatArray) -> FloatArray:
    """Distance from each point of ``xy`` ``(m, 2)`` to the polyline ``vertices``."""
    a = vertices[:-1][None, :, :]
    d = (vertices[1:] - vertices[:-1])[None, :, :]
    rel = xy[:, None, :] - a
    length2 = np.maximum(np.sum(d * d, axis=-1), 1e-300)
    u = np.clip(np.sum(rel * d, axis=-1) / length2, 0.0, 1.0)
    foot = a + u[..., None] * d
    return np.min(np.linalg.norm(xy[:, None, :] - foot, axis=-1), axis=1)


def load_waypoints_csv(path: str | Path, *, dim: int) -> FloatArray:
    """Read task-space waypoints (columns x, y[, pose]) from a CSV file.

    A header row is allowed; blank lines and lines starting with ``#`` are skipped.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read waypoint file {str(path)!r}: {exc.strerror}") from exc
    rows: list[list[float]] = []
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        if not row or row[0].strip().startswith("#"):
            continue
        try:
            values = [float(cell) for cell in row if cell.strip() != ""]
        except ValueError:
            if not rows and lineno == 1:
                continue  # header
            raise ConfigError(f"{path}:{lineno}: not a number in {row!r}") from None
        if len(values) != dim:
            raise ConfigError(
                f"{path}:{lineno}: expected {dim} columns ({'x, y, pose' if dim == 3 else 'x, y'}),"
                f" got {len(values)}"
            )
        rows.append(values)
    if len(rows) < 2:
        raise ConfigError(f"{path}: need at least 2 waypoints, got {len(rows)}")
    pts = np.asarray(rows)
    if not np.all(np.isfinite(pts)):
        raise ConfigError(f"{path}: waypoints must be finite")
    return pts


