"""Joint-space via points: stop-and-go motion through them (Eq. 4.5) and the end effector's path."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..config import read_yaml
from ..errors import ConfigError
from ..robots.base import FloatArray, Manipulator
from .polynomials import quintic
from .samples import JointSample, TaskSample
from .shapes import Contour, polyline_distance


def load_joint_waypoints(path: str | Path, n: int) -> tuple[FloatArray, FloatArray]:
    """``(times, points)`` of joint via points from a CSV (rows ``t, q1 .. qn``; a header line
    is allowed) or a YAML file (``points: [{t: 0.0, q: [...]}, ...]``).

    Raises
    ------
    ConfigError
        One line naming the file, the line or point, and what is wrong: a missing file, a wrong
        column count, a non-number, times not starting at 0 or not increasing, fewer than two points.
    """
    where = str(path)
    label = f"joint waypoints {where!r}"
    rows: list[tuple[float, list[float]]] = []
    if Path(path).suffix.lower() in (".yaml", ".yml"):
        data = read_yaml(path, label)
        points = data.get("points") if isinstance(data, dict) else None
        if not isinstance(points, list):
            raise ConfigError(f"joint waypoints {where!r}: expected 'points: [{{t: ..., q: [...]}}, ...]'")
        for i, point in enumerate(points):
            try:
                rows.append((float(point["t"]), [float(v) for v in point["q"]]))
            except (KeyError, TypeError, ValueError):
                raise ConfigError(f"joint waypoints {where!r}: point {i} needs t (s) and q ({n} numbers)") from None
            if len(rows[-1][1]) != n:
                raise ConfigError(f"joint waypoints {where!r}: point {i} has {len(rows[-1][1])} joint values, "
                                  f"the robot has {n} joints")
    else:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise ConfigError(f"{label}: {exc.strerror}") from None
        for lineno, line in enumerate(csv.reader(text.splitlines()), 1):
            if not line or not "".join(line).strip() or line[0].lstrip().startswith("#"):
                continue
            try:
                values = [float(v) for v in line]
            except ValueError:
                if not rows:
                    continue  # a header line
                raise ConfigError(f"{where}:{lineno}: expected numbers, got {line!r}") from None
            if len(values) != n + 1:
                raise ConfigError(f"{where}:{lineno}: expected {n + 1} columns (t, q1..q{n}), got {len(values)}")
            rows.append((values[0], values[1:]))
    if len(rows) < 2:
        raise ConfigError(f"joint waypoints {where!r}: need at least 2 points, got {len(rows)}")
    times = np.array([t for t, _ in rows])
    points = np.array([q for _, q in rows])
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(points))):
        raise ConfigError(f"joint waypoints {where!r}: values must be finite")
    if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
        raise ConfigError(f"joint waypoints {where!r}: times must start at 0 and increase, got {times.tolist()}")
    return times, points


class JointPath:
    """Stop-and-go motion through joint via points: each segment scaled by the quintic of
    Eq. (4.5), ``q(t) = q_i + (q_{i+1} - q_i) s_c(t)``, at rest at every via point."""

    def __init__(self, times: ArrayLike, points: ArrayLike) -> None:
        self.times = np.asarray(times, dtype=float)
        self.points = np.asarray(points, dtype=float)
        self.duration = float(self.times[-1])

    def sample(self, t: ArrayLike) -> JointSample:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        seg = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        s, sd, sdd = quintic(t - self.times[seg], self.times[seg + 1] - self.times[seg])
        delta = self.points[seg + 1] - self.points[seg]
        return JointSample(q=self.points[seg] + delta * s[:, None], qd=delta * sd[:, None],
                           qdd=delta * sdd[:, None])

    def scaled(self, factor: float) -> JointPath:
        return JointPath(self.times * factor, self.points)


class JointPathContour(Contour):
    """The end effector's path of a :class:`JointPath` (``robot.position`` of the joint motion):
    the contour error is the distance to that path, sampled every :attr:`GRID_S` seconds."""

    GRID_S = 0.002

    def __init__(self, name: str, robot: Manipulator, path: JointPath) -> None:
        self.name = name
        self.robot = robot
        self.path = path
        self.dim = 2
        self.duration = path.duration
        grid = np.linspace(0.0, path.duration, max(int(np.ceil(path.duration / self.GRID_S)), 2) + 1)
        self._vertices = robot.position(path.sample(grid).q)

    def task(self, t: ArrayLike) -> TaskSample:
        sample = self.path.sample(t)
        p = self.robot.position(sample.q)
        jac = self.robot.jacobian(sample.q)[..., :2, :]
        pd = np.einsum("...ij,...j->...i", jac, sample.qd)
        return TaskSample(p=p, pd=pd, pdd=np.full_like(p, np.nan))  # pdd: not used by the metrics

    def contour_error(self, t: FloatArray, xy: FloatArray) -> FloatArray:
        return polyline_distance(self._vertices, xy)

    def scaled(self, factor: float) -> JointPathContour:
        return JointPathContour(self.name, self.robot, self.path.scaled(factor))

    def extent(self) -> tuple[FloatArray, FloatArray]:
        return self._vertices.min(axis=0), self._vertices.max(axis=0)

    def describe(self) -> dict[str, object]:
        return {"type": "joints", "name": self.name, "times": self.path.times.tolist(),
                "points": self.path.points.tolist(), "contour_error": "nearest (end effector path)"}
