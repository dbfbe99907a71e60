"""PNG figures of the thesis's kinds (analysis layer; matplotlib is imported lazily).

Not part of the numeric core: nothing here computes a statistic, it only draws
what :mod:`pdsmc_ros.metrics.statistics` and :mod:`pdsmc_ros.bag.reader` produced.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..metrics.statistics import Samples

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


CONTROLLER_STYLE = {"pd": ("PD", "tab:blue", "-"), "smc": ("SMC", "tab:orange", "--"),
                    "pdsmc": ("PD-SMC", "tab:green", "-")}
"""Label, colour and line of the thesis's controllers in the comparison figures."""

OTHER_COLOURS = ("tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")
"""Colours of the other registered laws, in registration order (none of the thesis's three)."""


def controller_style(controller: str) -> tuple[str, str | None, str]:
    """Label, colour and line of ``controller``: the thesis's own, or for another registered law its
    label and a colour of :data:`OTHER_COLOURS` by registration order, dash-dotted (an unregistered
    name: its name and the next colour of matplotlib's cycle)."""
    if controller in CONTROLLER_STYLE:
        return CONTROLLER_STYLE[controller]
    from ..control import law_label, law_names

    others = [name for name in law_names() if name not in CONTROLLER_STYLE]
    if controller not in others:
        return controller, None, "-"
    i = others.index(controller)
    return law_label(controller), OTHER_COLOURS[i % len(OTHER_COLOURS)], ("-.", ":")[i // len(OTHER_COLOURS) % 2]


def plot_controllers(runs: Sequence[tuple[str, Samples]], robot: str, name: str, bound: float,
                     out: Path) -> list[Path]:
    """The thesis's comparison figures (Figs. 4.37-4.91) for one robot and contour, every
    controller on the same axes: contour error against time with the bound drawn; axial errors
    and torques side by side, a row per joint; the contours with the error magnified.

    ``runs``: ``(controller, samples)`` pairs; ``name`` prefixes the files.
    """
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    order = list(CONTROLLER_STYLE)
    runs = sorted(runs, key=lambda run: order.index(run[0]) if run[0] in order else len(order))

    def style(controller: str) -> dict[str, Any]:
        label, colour, line = controller_style(controller)
        return {"label": label, "color": colour, "linestyle": line, "lw": 0.9}

    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    for controller, samples in runs:
        ax.plot(samples.t, samples.contour_error, **style(controller))
    if bound > 0.0:
        ax.axhline(bound, color="k", lw=0.8, linestyle=":", label=f"bound {bound:g} m")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("contour error (m)")
    ax.set_title(f"{name}: contour error")
    ax.legend(fontsize=8)
    paths.append(_save(fig, out / f"{name}_contour_error.png"))

    n = runs[0][1].q.shape[1]
    fig, axes = plt.subplots(n, 2, figsize=(10, 2.2 * n + 0.6), sharex=True, squeeze=False)
    for controller, samples in runs:
        for j in range(n):
            axes[j, 0].plot(samples.t, samples.q_ref[:, j] - samples.q[:, j], **style(controller))
            axes[j, 1].plot(samples.t, samples.tau[:, j], **style(controller))
    for j in range(n):
        axes[j, 0].set_ylabel(f"axis {j + 1} error (rad)")
        axes[j, 1].set_ylabel(f"tau {j + 1} (N m)")
    for column in (0, 1):
        axes[-1, column].set_xlabel("time (s)")
    axes[0, 0].set_title(f"{name}: axial errors")
    axes[0, 1].set_title(f"{name}: torques")
    axes[0, 1].legend(fontsize=8, loc="upper right")
    paths.append(_save(fig, out / f"{name}_axial_torque.png"))

    factor = MAGNIFY.get(robot, 1.0)
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    reference = runs[0][1].xy_ref
    ax.plot(reference[:, 0], reference[:, 1], "k", lw=1.4, label="desired")
    for controller, samples in runs:
        shown = samples.xy_ref + factor * (samples.xy - samples.xy_ref)
        ax.plot(shown[:, 0], shown[:, 1], **style(controller))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{name}: contours, error x{factor:g}")
    ax.legend(fontsize=8)
    paths.append(_save(fig, out / f"{name}_contours.png"))
    return paths
