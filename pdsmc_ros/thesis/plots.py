"""PNG figures of the thesis's kinds (analysis layer; matplotlib is imported lazily).

Not part of the numeric core: nothing here computes a statistic, it only draws
what :mod:`pdsmc_ros.metrics` and :mod:`pdsmc_ros.bag.reader` produced.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..metrics import Samples

MAGNIFY = {"serial_3r": 100.0, "parallel_5r": 20.0}
"""Error magnification of the thesis's contour plots (footnotes of Figs. 4.40 ff.)."""


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_run(samples: Samples, robot: str, label: str, out: Path) -> list[Path]:
    """Contour (error magnified), axial, task-space and contour errors, torques against time."""
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    factor = MAGNIFY.get(robot, 1.0)
    fig, ax = plt.subplots(figsize=(6, 6))
    shown = samples.xy_ref + factor * (samples.xy - samples.xy_ref)
    ax.plot(samples.xy_ref[:, 0], samples.xy_ref[:, 1], "k--", lw=1, label="desired")
    ax.plot(shown[:, 0], shown[:, 1], lw=1, label=f"actual (error x{factor:g})")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend()
    ax.set_title(f"{label}: contour")
    paths.append(_save(fig, out / f"{label}_contour.png"))
    series = [
        ("axial", "axial error (rad)", samples.q_ref - samples.q, [f"axis {i + 1}" for i in range(samples.q.shape[1])]),
        ("task", "task-space error (m)", samples.xy_ref - samples.xy, ["x", "y"]),
        ("contour_error", "contour error (m)", samples.contour_error[:, None], ["contour error"]),
        ("torque", "torque (N m)", samples.tau, [f"tau {i + 1}" for i in range(samples.tau.shape[1])]),
    ]
    for name, ylabel, values, labels in series:
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for j, lab in enumerate(labels):
            ax.plot(samples.t, values[:, j], lw=0.8, label=lab)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title(f"{label}: {ylabel}")
        paths.append(_save(fig, out / f"{label}_{name}.png"))
    return paths


def plot_comparison(labels: Sequence[str], means: Sequence[float], out: Path, title: str) -> Path:
    """Mean contour error bars (Figs. 4.90 / 4.91)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(max(4, 1.5 * len(labels)), 3.5))
    ax.bar(range(len(labels)), means)
    ax.set_xticks(range(len(labels)), labels, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("mean contour error (m)")
    ax.set_title(title)
    return _save(fig, out)


def plot_sweep(param: str, values: np.ndarray, mean: np.ndarray, sd: np.ndarray, peak: np.ndarray,
               out: Path, title: str) -> Path:
    """Mean contour error and its bounds against a control parameter (Figs. 4.29-4.36)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(values, mean, "o-", ms=3, label="mean contour error")
    ax.fill_between(values, np.maximum(mean - sd, 0), mean + sd, alpha=0.25, label="mean +- S.D.")
    ax.plot(values, peak, "--", lw=1, label="max contour error")
    ax.set_xscale("symlog", linthresh=10)
    ax.set_yscale("log")
    ax.set_xlabel(param)
    ax.set_ylabel("contour error (m)")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, out)


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path
