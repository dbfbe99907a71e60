"""What an identification reports: plain data for ``identification.yaml`` and the lines it prints,
its figure (efforts measured and predicted), and an excitation's figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..robots.base import FloatArray
from .arm_files import payload_point
from .consistent import MARGIN
from .excitation import ExcitationLimits, FourierExcitation
from .identify import Identification
from .model import JOINT_FIELDS, ArmDynamics

__all__ = ["CONSISTENCY_METHOD", "excitation_figure", "report_data", "report_lines", "torque_figure"]

CONSISTENCY_METHOD = (
    "LMI (semidefinite program, Clarabel): each link's pseudo-inertia positive definite (margin "
    f"{MARGIN:g} of its scale; positive mass, inertia and the triangle inequalities), the payload's "
    "semidefinite, motor inertias and frictions >= 0; the least-squares base parameters kept exactly, "
    "the URDF's links where the data do not decide (pdsmc_ros.identification.consistent)")


def _per_joint(names: tuple[str, ...], values: FloatArray) -> dict[str, float]:
    return {name: float(v) for name, v in zip(names, values, strict=True)}


def report_data(result: Identification, *, robot: str, bag: str,
                validation: tuple[str, FloatArray, FloatArray, FloatArray, FloatArray] | None = None) -> dict[str, Any]:
    """Everything the identification found, as plain data (``identification.yaml``)."""
    dynamics = result.dynamics
    layout = dynamics.layout
    fit = result.fit
    names = layout.joint_names
    mass, com = payload_point(dynamics, fit.values)
    k_mass = layout.payload.start
    prepared = result.prepared
    data: dict[str, Any] = {
        "robot": robot,
        "bag": bag,
        "filter": {
            "description": prepared.describe(),
            "cutoff_hz": prepared.cutoff,
            "motion_bandwidth_hz": prepared.bandwidth,
            "recording_rate_hz": prepared.rate,
            "kept_rate_hz": prepared.kept_rate,
            "samples": int(len(prepared.keep)),
            "equations": int(result.equations),
            "coulomb_band": _per_joint(names, prepared.stick_band),
        },
        "condition_number": result.condition,
        "consistency": {"method": CONSISTENCY_METHOD, "projected": fit.projected, "shift": fit.shift},
        "payload": {"mass_kg": mass, "mass_standard_error": float(fit.standard_errors[k_mass]),
                    "com_m": com.tolist(), "frame": dynamics.arm.ee_frame},
        "joints": {
            field: {"value": _per_joint(names, fit.values[layout.joint_field(field)]),
                    "standard_error": _per_joint(names, fit.standard_errors[layout.joint_field(field)]),
                    "nominal": _per_joint(names, dynamics.nominal[layout.joint_field(field)])}
            for field in JOINT_FIELDS},
        "residual_sigma": _per_joint(names, result.estimate.sigma),
        "nrmse": {"fit": _per_joint(names, result.nrmse), "nominal_on_fit": _per_joint(names, result.nominal_nrmse)},
        "base_parameters": [
            {"name": name, "value": float(v), "standard_error": float(se), "nominal": float(nom)}
            for name, v, se, nom in zip(result.base.names, result.estimate.values, result.estimate.standard_errors,
                                        result.base.of(dynamics.nominal), strict=True)],
        "standard_parameters": [
            {"name": name, "value": float(v), "standard_error": float(se), "nominal": float(nom)}
            for name, v, se, nom in zip(layout.names, fit.values, fit.standard_errors, dynamics.nominal, strict=True)],
        "seconds": {k: float(v) for k, v in result.seconds.items()},
    }
    if validation is not None:
        held_out, fitted, nominal, moving, static = validation
        data["nrmse"]["validation_bag"] = held_out
        data["nrmse"]["validation"] = _per_joint(names, fitted)
        data["nrmse"]["nominal_on_validation"] = _per_joint(names, nominal)
        data["nrmse"]["validation_outside_dead_zone"] = _per_joint(names, moving)
        data["nrmse"]["validation_static_friction_set"] = _per_joint(names, static)
    return data


def report_lines(data: dict[str, Any]) -> list[str]:
    """The summary ``pdsmc identify`` prints."""
    filt = data["filter"]
    payload = data["payload"]
    joints = data["joints"]
    names = list(joints["armature"]["value"])
    lines = [
        f"filter: {filt['description']}",
        f"{filt['equations']} torque equations, base regressor condition number {data['condition_number']:.4g}",
        (f"payload: {payload['mass_kg']:.4g} +/- {payload['mass_standard_error']:.2g} kg at "
         f"[{', '.join(f'{c:.4g}' for c in payload['com_m'])}] m in {payload['frame']}"),
        "consistency: " + (("the least-squares estimate was not physically consistent: moved to the nearest "
                            f"consistent one ({data['consistency']['shift']:.3g} in the weighted residual's units)")
                           if data["consistency"]["projected"] else ("the least-squares estimate, made consistent "
                                                                     "with the URDF where the data do not decide")),
        (f"{'joint':24s} {'armature (kg m^2)':>22s} {'coulomb (N m)':>20s} {'viscous (N m s)':>20s} "
         f"{'NRMSE fit':>10s}") + (" held-out (moving) [friction a set]" if "validation" in data["nrmse"] else "")
        + "  (URDF)",
    ]
    for name in names:
        cells = [f"{joints[f]['value'][name]:9.4g} +/- {joints[f]['standard_error'][name]:<8.2g}" for f in JOINT_FIELDS]
        nrmse = data["nrmse"]
        line = f"{name:24s} {cells[0]:>22s} {cells[1]:>20s} {cells[2]:>20s} {nrmse['fit'][name]:9.2%}"
        if "validation" in nrmse:
            line += (f" {nrmse['validation'][name]:8.2%} ({nrmse['validation_outside_dead_zone'][name]:6.2%}) "
                     f"[{nrmse['validation_static_friction_set'][name]:6.2%}]  "
                     f"({nrmse['nominal_on_validation'][name]:.1%})")
        else:
            line += f"  ({nrmse['nominal_on_fit'][name]:.1%})"
        lines.append(line)
    return lines


def torque_figure(result: Identification, path: str | Path) -> None:
    """Each joint's filtered effort, the identified model's and the URDF's prediction, over the run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dynamics = result.dynamics
    prepared = result.prepared
    t = prepared.t
    fitted = (result.regressor @ result.fit.values).reshape(prepared.tau.shape)
    nominal = (result.regressor @ dynamics.nominal).reshape(prepared.tau.shape)
    measured = prepared.tau
    n = dynamics.n
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.8 * n + 0.6), sharex=True, squeeze=False)
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(t, measured[:, j], color="black", lw=1.2, label="measured (filtered)")
        ax.plot(t, fitted[:, j], color="tab:blue", lw=1.0, ls="--", label="identified")
        ax.plot(t, nominal[:, j], color="tab:red", lw=0.8, alpha=0.7, label="URDF")
        ax.set_ylabel(f"{dynamics.layout.joint_names[j]}\n(N m)", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right", ncol=3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"{dynamics.arm.name}: efforts measured and predicted", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def excitation_figure(dynamics: ArmDynamics, excitation: FourierExcitation, limits: ExcitationLimits,
                      path: str | Path) -> None:
    """One period of an excitation: each joint's excursion from home, and its velocity, acceleration
    and effort (the arm's own model) as shares of their limits."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    t = np.linspace(0.0, excitation.period, 1001)
    q, qd, qdd = excitation.sample(t)
    tau = dynamics.torque(dynamics.nominal, q[::5], qd[::5], qdd[::5])
    panels = [
        (t, q - excitation.home, "position - home (rad)"),
        (t, qd / limits.velocity, "velocity / limit used"),
        (t, qdd / limits.acceleration, "acceleration / limit used"),
        (t[::5], tau / limits.effort, "effort (URDF model) / limit used"),
    ]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 9), sharex=True)
    for ax, (x, y, label) in zip(axes, panels, strict=True):
        for j in range(dynamics.n):
            ax.plot(x, y[:, j], lw=1.0, label=dynamics.layout.joint_names[j])
        if "/" in label:
            ax.axhline(1.0, color="black", lw=0.6, ls=":")
            ax.axhline(-1.0, color="black", lw=0.6, ls=":")
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=3, loc="upper right")
    axes[-1].set_xlabel(f"time (s), one period of {excitation.period:g} s ({excitation.harmonics} harmonics)")
    fig.suptitle(f"{dynamics.arm.name}: excitation (Fourier series, at rest at home at both ends)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
