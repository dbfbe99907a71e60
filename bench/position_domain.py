"""The position domain laws against the time domain's: the tables and the figure of docs/POSITION_DOMAIN.md.

    .venv/bin/python bench/position_domain.py                  # everything: docs/POSITION_DOMAIN.md
    .venv/bin/python bench/position_domain.py --quick --out /tmp/pdc   # nominal only, one scenario

Every thesis contour of the serial 3R and the five-bar, nominal, high speed (Section 4.5.1) and
payload (Section 4.5.2), and the UR5's contours, nominal: the time-domain PD and PD-SMC (Eqs. 3.4,
3.44), their position-domain forms ``pd_pos`` and ``pdsmc_pos`` (the master per segment,
:mod:`pdsmc_ros.control.position_domain`) and the alternative master, the virtual one
(``pdsmc_vm``, registered here only), each with the same gains (the time-domain law's presets,
``v0`` besides), at the arm's own rate, lockstep (the in-process plant), the torque clamped to the
arm's effort limits. Per run: mean and max contour error, RMS tracking error, the chattering
(torque total variation per second), the control energy, the peak torque as a share of the effort
limit, and the real-time stability margin of ``pdsmc check-gains`` (two periods of delay). Where
the position/time ratio of the mean contour error is within 15 % of 1, a Monte Carlo over drawn
plants (``config/uncertainty.yaml``, common random numbers) gives the paired ratio's mean with a
bootstrap 95 % interval (the thesis arms: the Monte Carlo draws their plants only).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pdsmc_ros.control import LawEntry, register_law  # noqa: E402
from pdsmc_ros.control.position_domain import (  # noqa: E402
    PDSMC_VIRTUAL,
    POSITION_ROWS,
    law_error_map,
    pdsmc_pos_linear_gains,
    v_rest_preset,
)
from pdsmc_ros.control.stability import rate_margin  # noqa: E402
from pdsmc_ros.experiments.bootstrap import bootstrap_mean  # noqa: E402
from pdsmc_ros.experiments.compare import run_values  # noqa: E402
from pdsmc_ros.experiments.compare_mc import compare_plant  # noqa: E402
from pdsmc_ros.experiments.montecarlo import load_uncertainty  # noqa: E402
from pdsmc_ros.runs.builder import make_run  # noqa: E402
from pdsmc_ros.sim import simulate  # noqa: E402

VIRTUAL = LawEntry("pdsmc_vm", "PD-SMC (virtual master)", POSITION_ROWS,
                   equation="Eq. (3.44), every joint in the virtual master's position domain", code=PDSMC_VIRTUAL,
                   linear_gains=pdsmc_pos_linear_gains, rows=POSITION_ROWS, state_size=1, presets_from="pdsmc",
                   derive_presets=v_rest_preset, error_map=law_error_map)
"""The alternative master (the reference's own time, estimated from every joint); its linearisation is
the per-segment master's map, an approximation for it (it is checked as one, not proven)."""

ARMS = {"serial_3r": ("zigzag", "diamond", "circle", "ellipse"),
        "parallel_5r": ("zigzag", "diamond", "circle", "ellipse_horizontal", "ellipse_vertical"),
        "ur5": ("zigzag", "diamond", "circle", "ellipse")}
SCENARIOS = ("nominal", "high_speed", "payload")
LAWS = ("pd", "pd_pos", "pdsmc", "pdsmc_pos", "pdsmc_vm")
PAIRS = (("pd_pos", "pd"), ("pdsmc_pos", "pdsmc"), ("pdsmc_vm", "pdsmc"))
MC_ARMS = ("serial_3r", "parallel_5r")
"""The arms whose plants the Monte Carlo draws (``config/uncertainty.yaml`` spreads the thesis arms'
parameters; a URDF arm's are not drawn)."""
CLOSE = 0.15
"""A ratio within this of 1 gets its Monte Carlo."""


def one_run(robot: str, contour: str, controller: str, scenario: str) -> dict[str, Any]:
    spec = make_run(robot, contour, controller, scenario=scenario)
    result = simulate(spec, check_stability=False)
    values = run_values(result)
    limits = np.asarray(spec.robot_model().effort_limits, dtype=float)
    row: dict[str, Any] = {"robot": robot, "contour": contour, "law": controller, "scenario": scenario,
                           "diverged": result.diverged or ("" if values is not None else "non-finite statistics")}
    if values is not None:
        peak = np.max(np.abs(result.samples.tau), axis=0)
        row.update(values)
        row["effort_share"] = float(np.max(peak / limits)) if np.all(np.isfinite(limits)) else math.nan
    if values is not None and controller == "pdsmc":
        row["static_ratio"] = static_ratio(spec, result)
    check = rate_margin(spec, spec.reference(), mode="realtime")
    row["margin_realtime"] = float(check.margin)
    return row


def static_ratio(spec: Any, result: Any) -> float:
    """What the master's error adds to a time-domain run's contour error, linearised: the mean of
    ``|(I - t t^T) J (e - c e_m)|`` over the mean of ``|(I - t t^T) J e|`` (``e = q_d - q`` sampled,
    ``J`` the task Jacobian, ``t`` the unit tangent ``J qd_d``, ``c`` the master's axis: the fastest joint
    of ``qd_d``). In the position domain's equilibrium the slaves follow the master, so its error leaves
    the contour (docs/explanation/position-domain.md); this ratio is that effect alone."""
    samples = result.samples
    ref = spec.reference().sample(samples.t)
    model = spec.robot_model()
    jac = model.jacobian(samples.q)
    e = ref.q - samples.q
    master = np.argmax(np.abs(ref.qd), axis=1)
    e_slaves = e.copy()
    e_slaves[np.arange(len(e)), master] = 0.0
    tangent = np.einsum("kij,kj->ki", jac, ref.qd)
    norm = np.linalg.norm(tangent, axis=1)
    moving = norm > 1e-3 * np.max(norm)
    t = tangent[moving] / norm[moving, None]

    def normal(x: np.ndarray) -> np.ndarray:
        v = np.einsum("kij,kj->ki", jac[moving], x[moving])
        return np.linalg.norm(v - t * np.sum(v * t, axis=1)[:, None], axis=1)

    return float(np.mean(normal(e_slaves)) / np.mean(normal(e)))


def monte_carlo(robot: str, contour: str, laws: tuple[str, str], runs: int, seed: int) -> dict[str, Any]:
    """The paired ratio ``law0 / law1`` of the mean contour error over ``runs`` drawn plants."""
    specs = [make_run(robot, contour, name) for name in laws]
    spreads = load_uncertainty()
    ratios = []
    for i in range(runs):
        rows = {r["law"]: r for r in compare_plant(i, seed, specs, spreads)}
        if all(rows[name]["status"] == "ok" for name in laws):
            ratios.append(rows[laws[0]]["contour_mean"] / rows[laws[1]]["contour_mean"])
    interval = bootstrap_mean(np.array(ratios))
    return {"robot": robot, "contour": contour, "laws": list(laws), "runs": runs, "ok": len(ratios),
            "mean": interval.mean, "low": interval.low, "high": interval.high}


def ratio(rows: list[dict[str, Any]], robot: str, contour: str, scenario: str, num: str, den: str) -> float:
    pick = {r["law"]: r for r in rows if (r["robot"], r["contour"], r["scenario"]) == (robot, contour, scenario)}
    a, b = pick.get(num, {}), pick.get(den, {})
    if "contour_mean" not in a or "contour_mean" not in b:
        return math.nan
    return float(a["contour_mean"] / b["contour_mean"])


def cell(x: float, fmt: str = ".3g") -> str:
    return "-" if not math.isfinite(x) else format(x, fmt)


def markdown(rows: list[dict[str, Any]], mc: list[dict[str, Any]], command: str, seconds: float) -> str:
    cases = sorted({(r["robot"], r["contour"], r["scenario"]) for r in rows},
                   key=lambda c: (list(ARMS).index(c[0]), ARMS[c[0]].index(c[1]), SCENARIOS.index(c[2])))
    out = ["# Position domain control: the comparison", "",
           f"Written by `{command}` ({seconds:.0f} s on 2 shared cores); the laws and their equations:",
           ("[Position domain PD-SMC](explanation/position-domain.md). Every run: the arm's own rate, lockstep "
            "(the in-process plant), every law with the time-domain law's preset gains (`v0` = 0.05 rad/s "
            "besides), the torque clamped to the effort limits."), "",
           "## The contour error ratio, position / time domain", "",
           ("Mean contour error of the position-domain law over its time-domain law's (below 1: the position "
            "domain is better; the issue's goal for PD-SMC is 0.5). `pdsmc_vm`: the virtual master, the "
            "alternative. *static*: the ratio the linearised equilibrium predicts from the time-domain PD-SMC's own "
            "run (its contour error with the master's error taken out, over its contour error; "
            "[why](explanation/position-domain.md#what-the-master-removes))."),
           "", "| arm | contour | scenario | PD pos/time | PD-SMC pos/time | PD-SMC virtual/time | static |",
           "| --- | --- | --- | --- | --- | --- | --- |"]
    for robot, contour, scenario in cases:
        values = [cell(ratio(rows, robot, contour, scenario, a, b)) for a, b in PAIRS]
        static = [r.get("static_ratio", math.nan) for r in rows
                  if (r["robot"], r["contour"], r["scenario"], r["law"]) == (robot, contour, scenario, "pdsmc")]
        values.append(cell(static[0] if static else math.nan))
        out.append(f"| {robot} | {contour} | {scenario} | " + " | ".join(values) + " |")
    out += ["", "## Every run", "",
            ("contour mean and max (um), RMS |e| (mrad), chattering: torque total variation per second (N m/s), "
             "energy: integral of |tau|^2 (N^2 m^2 s), peak |tau| as a share of the effort limit, and the "
             "real-time stability margin (`pdsmc check-gains`: rate over the lowest stable rate with two periods "
             "of delay; 2 is required of a real-time loop)."), "",
            ("| arm | contour | scenario | law | contour mean | contour max | RMS e | TV/s | energy | "
             "peak/limit | RT margin |"), "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in sorted(rows, key=lambda r: (cases.index((r["robot"], r["contour"], r["scenario"])),
                                         LAWS.index(r["law"]))):
        if r["diverged"]:
            out.append(f"| {r['robot']} | {r['contour']} | {r['scenario']} | {r['law']} | DIVERGED: "
                       f"{r['diverged']} | | | | | | {cell(r['margin_realtime'], '.2f')} |")
            continue
        out.append(f"| {r['robot']} | {r['contour']} | {r['scenario']} | {r['law']} | "
                   f"{cell(1e6 * r['contour_mean'])} | {cell(1e6 * r['contour_max'])} | "
                   f"{cell(1e3 * r['error_rms'])} | {cell(r['torque_tv_rate'])} | {cell(r['control_energy'])} | "
                   f"{cell(r['effort_share'], '.2f')} | {cell(r['margin_realtime'], '.2f')} |")
    if mc:
        out += ["", "## Monte Carlo where the ratio is within 15 % of 1", "",
                ("The paired ratio of the mean contour error over drawn plants (`config/uncertainty.yaml`, "
                 "the same plants for both laws), its mean and percentile-bootstrap 95 % interval."), "",
                "| arm | contour | ratio | runs (ok) | mean | 95 % interval |", "| --- | --- | --- | --- | --- | --- |"]
        for m in mc:
            out.append(f"| {m['robot']} | {m['contour']} | {m['laws'][0]} / {m['laws'][1]} | {m['runs']} ({m['ok']}) | "
                       f"{m['mean']:.3f} | [{m['low']:.3f}, {m['high']:.3f}] |")
    out += ["", "![position/time contour error ratios](figures/position_domain_ratios.png)", ""]
    return "\n".join(out)


def figure(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nominal = [(r, c) for r in ARMS for c in ARMS[r]
               if any((x["robot"], x["contour"], x["scenario"]) == (r, c, "nominal") for x in rows)]
    fig, ax = plt.subplots(figsize=(9, 4.2))
    x = np.arange(len(nominal))
    for k, (num, den) in enumerate(PAIRS):
        ax.bar(x + (k - 1) * 0.27, [ratio(rows, r, c, "nominal", num, den) for r, c in nominal], 0.27,
               label=f"{num} / {den}")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(0.5, color="k", lw=0.8, ls="--")
    ax.set_xticks(x, [f"{r}\n{c.replace('ellipse_', 'ellipse ')}" for r, c in nominal], fontsize=7, rotation=30,
                  ha="right")
    ax.set_ylabel("mean contour error ratio")
    ax.set_title("position / time domain, nominal (dashed: the goal, 0.5)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"), help="directory of POSITION_DOMAIN.md (figures/ beside)")
    parser.add_argument("--quick", action="store_true", help="nominal only, no Monte Carlo")
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo plants per close case")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--replot", action="store_true",
                        help="only draw the figure again from the runs of figures/position_domain.json under --out")
    args = parser.parse_args()
    if args.replot:
        saved = json.loads((Path(args.out) / "figures" / "position_domain.json").read_text())
        figure(saved["runs"], Path(args.out) / "figures" / "position_domain_ratios.png")
        return 0
    register_law(VIRTUAL)
    start = time.time()
    rows = []
    for robot, contours in ARMS.items():
        for contour in contours:
            for scenario in (("nominal",) if args.quick or robot == "ur5" else SCENARIOS):
                for name in LAWS:
                    rows.append(one_run(robot, contour, name, scenario))
                    r = rows[-1]
                    print(f"{robot} {contour} {scenario} {name}: "
                          f"{r.get('contour_mean', math.nan):.3e} {r['diverged']}", flush=True)
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "figures" / "position_domain.json").write_text(json.dumps({"runs": rows}, indent=1))
    mc = []
    if not args.quick:
        for robot, contours in ARMS.items():
            if robot not in MC_ARMS:
                continue
            for contour in contours:
                value = ratio(rows, robot, contour, "nominal", "pdsmc_pos", "pdsmc")
                if math.isfinite(value) and abs(value - 1.0) <= CLOSE:
                    mc.append(monte_carlo(robot, contour, ("pdsmc_pos", "pdsmc"), args.runs, args.seed))
                    print(mc[-1], flush=True)
    command = "python bench/position_domain.py" + (" --quick" if args.quick else "")
    (out / "POSITION_DOMAIN.md").write_text(markdown(rows, mc, command, time.time() - start))
    (out / "figures" / "position_domain.json").write_text(json.dumps({"runs": rows, "monte_carlo": mc}, indent=1))
    figure(rows, out / "figures" / "position_domain_ratios.png")
    print(f"wrote {out / 'POSITION_DOMAIN.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
