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

from pdsmc_ros.control import ControlLaw, LawEntry, law, register_law  # noqa: E402
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
EQUAL = {"pd_pos": "pd", "pdsmc_pos": "pdsmc"}
"""Each position domain law runs a second time (``<law>@eq``) with its ``kp``, ``kd`` and ``ks`` (every
joint) times one factor that puts its real-time margin (:func:`realtime_margin`) on its time-domain law's."""
SCALED = ("kp", "kd", "ks")
MATCH = 1.002
"""The factor's bisection stops when its bracket is this narrow (the margins then agree to 0.2 %)."""
EQ_PAIRS = (("pd_pos@eq", "pd"), ("pdsmc_pos@eq", "pdsmc"))
EQUAL_LABELS = tuple(f"{name}@eq" for name in EQUAL)
LABELS = (*LAWS, *EQUAL_LABELS)
SWITCH_WINDOW = 0.05
"""Seconds either side of a master switch counted as its transient (the decomposition's switch shares)."""


def realtime_margin(spec: Any) -> float:
    """``pdsmc check-gains``'s real-time margin: rate over the lowest stable rate with two periods of delay
    (:func:`~pdsmc_ros.control.stability.rate_margin`, its sampled configurations)."""
    return float(rate_margin(spec, spec.reference(), mode="realtime").margin)


def scaled_spec(robot: str, contour: str, controller: str, scenario: str, factor: float) -> Any:
    """The run with the law's ``kp``, ``kd`` and ``ks`` (every joint) times ``factor``; the rest of its gains
    (``lam``, ``phi``, ``v_rest``) as given."""
    base = make_run(robot, contour, controller, scenario=scenario)
    names = [name for name in SCALED if name in law(controller).gain_names]
    return make_run(robot, contour, controller, scenario=scenario,
                    overrides={name: [factor * x for x in base.gains[name]] for name in names})


def equal_margin_factor(robot: str, contour: str, controller: str, scenario: str, target: float) -> float:
    """The factor of :func:`scaled_spec` whose real-time margin is ``target`` (bisection in the factor's log:
    the margin falls as the gains grow, from about 1/8 up: far below, the plant's own damping dominates and
    the margin falls again); nan if none in [1/8, 16] gives it."""
    lo, hi = 1.0 / 8.0, 16.0

    def margin(k: float) -> float:
        return realtime_margin(scaled_spec(robot, contour, controller, scenario, k))

    if not margin(lo) >= target >= margin(hi):
        return math.nan
    while hi / lo > MATCH:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if margin(mid) >= target else (lo, mid)
    return math.sqrt(lo * hi)


def master_sequence(spec: Any, t: np.ndarray) -> np.ndarray:
    """The master (0-based) the per-segment law picks along ``spec``'s reference at the instants ``t``: the
    compiled law itself, stepped along the reference (its choice depends on the reference only)."""
    control = ControlLaw.from_spec(spec)
    ref = spec.reference().sample(t)
    out = np.empty(len(t), dtype=int)
    for k in range(len(t)):
        control.torque(ref.q[k], ref.qd[k], ref.q[k], ref.qd[k], ref.qdd[k])
        out[k] = int(control.state[0, 0]) - 1
    return out


def switch_shares(spec: Any, result: Any) -> dict[str, float]:
    """Where the master switches (``pdsmc_pos``'s choice along the reference) and what falls within
    :data:`SWITCH_WINDOW` of a switch: the share of the time, of the contour error's integral and of the
    torque's total variation (summed over the samples: the statistics' rate, not the control rate); and
    the acceleration the master's error adds to the slaves' references in its position domain,
    ``|q_s' e_m''|`` (the run's master error differenced twice at the statistics' rate), summed over the
    slaves and the instants where the master moves, over their own ``|qdd_s,d|`` summed alike."""
    samples = result.samples
    t = np.asarray(samples.t, dtype=float)
    masters = master_sequence(make_run(spec.robot, spec.contour, "pdsmc_pos", scenario=spec.scenario), t)
    switches = t[1:][np.diff(masters) != 0]
    near = np.zeros(len(t), dtype=bool)
    for s in switches:
        near |= np.abs(t - s) <= SWITCH_WINDOW
    # the slaves' reference in the master's position moves with the master's error: delta = -e_m / v adds
    # q_s' (-e_m)'' to a slave's reference acceleration (to first order; q_s' = qd_s,d / v)
    ref = spec.reference().sample(t)
    e_dd = np.gradient(np.gradient(ref.q - samples.q, t, axis=0), t, axis=0)
    rows = np.arange(len(t))
    v = ref.qd[rows, masters]
    moving = np.abs(v) > 0.05 * np.max(np.abs(ref.qd))
    slave = np.ones_like(ref.qd, dtype=bool)
    slave[rows, masters] = False
    added = np.abs(ref.qd / v[:, None] * e_dd[rows, masters][:, None])[moving] * slave[moving]
    own = np.abs(ref.qdd)[moving] * slave[moving]
    contour = np.abs(np.asarray(samples.contour_error, dtype=float))
    tv = np.concatenate([[0.0], np.sum(np.abs(np.diff(samples.tau, axis=0)), axis=1)])
    return {"switches": float(len(switches)), "switch_time_share": float(np.mean(near)),
            "switch_contour_share": float(np.sum(contour[near]) / np.sum(contour)),
            "switch_tv_share": float(np.sum(tv[near]) / max(np.sum(tv), 1e-300)),
            "added_acceleration": float(np.sum(added) / np.sum(own))}


def one_run(spec: Any, label: str, factor: float = 1.0) -> dict[str, Any]:
    robot, contour, scenario, controller = spec.robot, spec.contour, spec.scenario, spec.controller
    result = simulate(spec, check_stability=False)
    values = run_values(result)
    limits = np.asarray(spec.robot_model().effort_limits, dtype=float)
    row: dict[str, Any] = {"robot": robot, "contour": contour, "law": label, "scenario": scenario,
                           "gain_factor": factor,
                           "diverged": result.diverged or ("" if values is not None else "non-finite statistics")}
    if values is not None:
        peak = np.max(np.abs(result.samples.tau), axis=0)
        row.update(values)
        row["effort_share"] = float(np.max(peak / limits)) if np.all(np.isfinite(limits)) else math.nan
    if values is not None and controller == "pdsmc":
        row["static_ratio"], row["master_share"] = static_ratio(spec, result)
    if values is not None and controller in ("pdsmc", "pdsmc_pos"):
        row.update(switch_shares(spec, result))
    row["margin_realtime"] = realtime_margin(spec)
    return row


def static_ratio(spec: Any, result: Any) -> tuple[float, float]:
    """What the master's error adds to a time-domain run's contour error, linearised: the mean of ``|(I - t
    t^T) J (e - c e_m)|`` over the mean of ``|(I - t t^T) J e|`` (``e = q_d - q`` sampled, ``J`` the task
    Jacobian's rows in the contour's plane, ``t`` the unit tangent ``J qd_d``, ``c`` the master's axis: the
    joint ``pdsmc_pos`` masters with, :func:`master_sequence`). In the position domain's equilibrium the
    slaves follow the master, so its error leaves the contour (docs/explanation/position-domain.md); this
    ratio is that effect alone. Returned with the master's own share, the mean of ``|(I - t t^T) J c e_m|``
    over the same: the two shares add to more than 1 where the master's and the slaves' errors cancel across
    the path."""
    samples = result.samples
    ref = spec.reference().sample(samples.t)
    model = spec.robot_model()
    jac = model.jacobian(samples.q)[:, :2, :]  # the contour's plane (x, y; a spatial arm's u, v): the rows the
    # contour error is measured in (a serial arm's and the UR5's third row is the pose angle, not on the path)
    e = ref.q - samples.q
    master = master_sequence(make_run(spec.robot, spec.contour, "pdsmc_pos", scenario=spec.scenario), samples.t)
    e_slaves = e.copy()
    e_slaves[np.arange(len(e)), master] = 0.0
    tangent = np.einsum("kij,kj->ki", jac, ref.qd)
    norm = np.linalg.norm(tangent, axis=1)
    moving = norm > 1e-3 * np.max(norm)
    t = tangent[moving] / norm[moving, None]

    def normal(x: np.ndarray) -> np.ndarray:
        v = np.einsum("kij,kj->ki", jac[moving], x[moving])
        return np.linalg.norm(v - t * np.sum(v * t, axis=1)[:, None], axis=1)

    total = np.mean(normal(e))
    return float(np.mean(normal(e_slaves)) / total), float(np.mean(normal(e - e_slaves)) / total)


def monte_carlo(specs: list[Any], label: str, runs: int, seed: int) -> dict[str, Any]:
    """The paired ratio ``specs[0] / specs[1]`` of the mean contour error over ``runs`` drawn plants."""
    spreads = load_uncertainty()
    laws = [spec.controller for spec in specs]
    ratios = []
    for i in range(runs):
        rows = {r["law"]: r for r in compare_plant(i, seed, specs, spreads)}
        if all(rows[name]["status"] == "ok" for name in laws):
            ratios.append(rows[laws[0]]["contour_mean"] / rows[laws[1]]["contour_mean"])
    interval = bootstrap_mean(np.array(ratios))
    return {"robot": specs[0].robot, "contour": specs[0].contour, "laws": [label, laws[1]], "runs": runs,
            "ok": len(ratios), "mean": interval.mean, "low": interval.low, "high": interval.high}


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
            "besides; `@eq`: the position domain laws again at the time-domain law's real-time margin, "
            "[below](#at-an-equal-stability-margin)), the torque clamped to the effort limits."), "",
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
    out += equal_margin_table(rows, cases) + decomposition_table(rows, cases)
    out += ["", "## Every run", "",
            ("contour mean and max (um), RMS |e| (mrad), chattering: torque total variation per second (N m/s), "
             "energy: integral of |tau|^2 (N^2 m^2 s), peak |tau| as a share of the effort limit (1.00: the clamp "
             "took it), and the real-time stability margin (`pdsmc check-gains`: rate over the lowest stable rate "
             "with two periods of delay; 2 is required of a real-time loop). `@eq`: the law's `kp`, `kd`, `ks` "
             "times the factor in the law's cell."), "",
            ("| arm | contour | scenario | law | contour mean | contour max | RMS e | TV/s | energy | "
             "peak/limit | RT margin |"), "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in sorted(rows, key=lambda r: (cases.index((r["robot"], r["contour"], r["scenario"])),
                                         LABELS.index(r["law"]))):
        name = r["law"] + (f" x{r['gain_factor']:.3g}" if r["law"].endswith("@eq") else "")
        if r["diverged"]:
            out.append(f"| {r['robot']} | {r['contour']} | {r['scenario']} | {name} | DIVERGED: "
                       f"{r['diverged']} | | | | | | {cell(r['margin_realtime'], '.2f')} |")
            continue
        out.append(f"| {r['robot']} | {r['contour']} | {r['scenario']} | {name} | "
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


def pick(rows: list[dict[str, Any]], case: tuple[str, str, str], label: str) -> dict[str, Any]:
    """The row of ``label`` in ``case`` (arm, contour, scenario); {} if it did not run."""
    found = [r for r in rows if (r["robot"], r["contour"], r["scenario"], r["law"]) == (*case, label)]
    return found[0] if found else {}


def equal_margin_table(rows: list[dict[str, Any]], cases: list[tuple[str, str, str]]) -> list[str]:
    out = ["", "## At an equal stability margin", "",
           ("Each position domain law with its `kp`, `kd` and `ks` (every joint; `lam`, `phi`, `v0` kept) times the "
            "one factor that puts its real-time margin (`pdsmc check-gains`: the arm's rate over the lowest stable "
            "rate with two periods of delay, the check's sampled configurations) on its time-domain law's, to "
            "0.2 % (bisection); the time-domain laws keep their presets. The ratio is the mean contour error "
            "over the time-domain law's, as above; *presets* repeats the ratio with the presets' gains. Peak "
            "torque: the largest share of an effort limit among the four runs (1.00: the clamp took it)."), "",
           ("| arm | contour | scenario | margin PD, PD-SMC | PD pos/time | factor | presets | PD-SMC pos/time | "
            "factor | presets | peak torque |"),
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for case in cases:
        cells = [(f"x{pick(rows, case, 'pd').get('margin_realtime', math.nan):.2f}, "
                  f"x{pick(rows, case, 'pdsmc').get('margin_realtime', math.nan):.2f}")]
        for (num, den), (plain, _) in zip(EQ_PAIRS, PAIRS[:2], strict=True):
            cells += [cell(ratio(rows, *case, num, den)), cell(pick(rows, case, num).get("gain_factor", math.nan)),
                      cell(ratio(rows, *case, plain, den))]
        peaks = [pick(rows, case, x).get("effort_share", math.nan) for x in ("pd", "pdsmc", *EQUAL_LABELS)]
        cells.append(cell(max((x for x in peaks if math.isfinite(x)), default=math.nan), ".2f"))
        out.append(f"| {' | '.join(case)} | " + " | ".join(cells) + " |")
    return out


def decomposition_table(rows: list[dict[str, Any]], cases: list[tuple[str, str, str]]) -> list[str]:
    out = ["", "## Where the contour error goes (PD-SMC, presets)", "",
           ("*ratio*: `pdsmc_pos` / `pdsmc`, measured. *static*: the time-domain run's contour error with its "
            "master's error taken out (what the position domain's equilibrium removes), over its contour error; "
            "*master share*: the master's error alone across the path over the same (static + master share > 1: "
            "the two cancel in part). *loop*: ratio / static, what the position domain loop does to the "
            "slaves' errors beyond removing the master's (1: nothing). *switches*: master switches on the "
            "contour; *near*: the share of the time within 50 ms of one, and of `pdsmc_pos`'s contour error and "
            "torque total variation there. *TV*: the torque's total variation per second, pos / time. "
            "*added acc.*: the acceleration the master's error adds to the slaves' references in `pdsmc_pos`'s "
            "run, `|q_s' e_m''|`, over their own `|qdd_s,d|` (summed over slaves and instants)."), "",
           ("| arm | contour | scenario | ratio | static | master share | loop | switches | near: time | "
            "contour | TV | TV pos/time | added acc. |"),
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for case in cases:
        t, p = pick(rows, case, "pdsmc"), pick(rows, case, "pdsmc_pos")
        value = ratio(rows, *case, "pdsmc_pos", "pdsmc")
        static = t.get("static_ratio", math.nan)
        tv = p.get("torque_tv_rate", math.nan) / t.get("torque_tv_rate", math.nan) if t and p else math.nan
        out.append(f"| {' | '.join(case)} | {cell(value)} | {cell(static)} | {cell(t.get('master_share', math.nan))}"
                   f" | {cell(value / static)} | {cell(p.get('switches', math.nan), '.0f')} | "
                   f"{cell(p.get('switch_time_share', math.nan), '.2f')} | "
                   f"{cell(p.get('switch_contour_share', math.nan), '.2f')} | "
                   f"{cell(p.get('switch_tv_share', math.nan), '.2f')} | {cell(tv)} | "
                   f"{cell(p.get('added_acceleration', math.nan))} |")
    return out


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


V_REST_CASES = (("ur5", "circle", "nominal"), ("ur5", "ellipse", "nominal"),
                ("parallel_5r", "ellipse_horizontal", "nominal"), ("parallel_5r", "ellipse_horizontal", "high_speed"),
                ("serial_3r", "ellipse", "nominal"))
"""The cases of ``--v-rest``: where ``v0`` trades the contour error against the margin or the effort."""


def v_rest_table(values: list[float]) -> str:
    """``pdsmc_pos``'s ratio to ``pdsmc``, real-time margin and peak torque share for each ``v0`` of
    ``values`` (the presets' other gains), on :data:`V_REST_CASES`: a markdown table."""
    out = ["| case | " + " | ".join(f"v0 = {v:g}" for v in values) + " |", "| --- |" + " --- |" * len(values)]
    for robot, contour, scenario in V_REST_CASES:
        base = one_run(make_run(robot, contour, "pdsmc", scenario=scenario), "pdsmc")
        cells = []
        for v in values:
            row = one_run(make_run(robot, contour, "pdsmc_pos", scenario=scenario, overrides={"v_rest": [v]}),
                          "pdsmc_pos")
            cells.append(f"{row.get('contour_mean', math.nan) / base['contour_mean']:.3f}, "
                         f"x{row['margin_realtime']:.3f}, {row.get('effort_share', math.nan):.2f}")
        out.append(f"| {robot} {contour} {scenario} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def report(row: dict[str, Any]) -> None:
    print(f"{row['robot']} {row['contour']} {row['scenario']} {row['law']} x{row['gain_factor']:.3g}: "
          f"{row.get('contour_mean', math.nan):.3e} margin x{row['margin_realtime']:.2f} {row['diverged']}", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"), help="directory of POSITION_DOMAIN.md (figures/ beside)")
    parser.add_argument("--quick", action="store_true", help="nominal only, no Monte Carlo")
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo plants per close case")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--v-rest", default="",
                        help="comma-separated v0 values (rad/s): print pdsmc_pos's ratio, real-time margin and peak "
                             "torque share for each on a few cases, and stop")
    parser.add_argument("--arms", default=",".join(ARMS), help="comma-separated arms of " + ", ".join(ARMS))
    parser.add_argument("--replot", action="store_true",
                        help="only draw the figure again from the runs of figures/position_domain.json under --out")
    args = parser.parse_args()
    if args.replot:
        saved = json.loads((Path(args.out) / "figures" / "position_domain.json").read_text())
        figure(saved["runs"], Path(args.out) / "figures" / "position_domain_ratios.png")
        return 0
    if args.v_rest:
        try:
            values = [float(x) for x in args.v_rest.split(",")]
        except ValueError:
            parser.error(f"--v-rest: comma-separated numbers > 0 (rad/s), got {args.v_rest!r}")
        if not all(math.isfinite(v) and v > 0 for v in values):
            parser.error(f"--v-rest: comma-separated numbers > 0 (rad/s), got {args.v_rest!r}")
        print(v_rest_table(values))
        return 0
    arms = [a for a in args.arms.split(",") if a]
    if not arms or any(a not in ARMS for a in arms):
        parser.error(f"--arms: comma-separated names of {', '.join(ARMS)}, got {args.arms!r}")
    register_law(VIRTUAL)
    start = time.time()
    rows = []
    for robot in arms:
        for contour in ARMS[robot]:
            for scenario in (("nominal",) if args.quick or robot == "ur5" else SCENARIOS):
                for name in LAWS:
                    rows.append(one_run(make_run(robot, contour, name, scenario=scenario), name))
                    report(rows[-1])
                for name, time_law in EQUAL.items():
                    target = next(r["margin_realtime"] for r in rows[-len(LAWS):] if r["law"] == time_law)
                    factor = equal_margin_factor(robot, contour, name, scenario, target)
                    if math.isfinite(factor):
                        rows.append(one_run(scaled_spec(robot, contour, name, scenario, factor), f"{name}@eq", factor))
                        report(rows[-1])
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "figures" / "position_domain.json").write_text(json.dumps({"runs": rows}, indent=1))
    mc = []
    if not args.quick:
        for robot in arms:
            if robot not in MC_ARMS:
                continue
            for contour in ARMS[robot]:
                value = ratio(rows, robot, contour, "nominal", "pdsmc_pos", "pdsmc")
                if math.isfinite(value) and abs(value - 1.0) <= CLOSE:
                    specs = [make_run(robot, contour, "pdsmc_pos"), make_run(robot, contour, "pdsmc")]
                    mc.append(monte_carlo(specs, "pdsmc_pos", args.runs, args.seed))
                    print(mc[-1], flush=True)
                value = ratio(rows, robot, contour, "nominal", "pdsmc_pos@eq", "pdsmc")
                factor = [r["gain_factor"] for r in rows if (r["robot"], r["contour"], r["scenario"], r["law"])
                          == (robot, contour, "nominal", "pdsmc_pos@eq")]
                if factor and math.isfinite(value) and abs(value - 1.0) <= CLOSE:
                    specs = [scaled_spec(robot, contour, "pdsmc_pos", "nominal", factor[0]),
                             make_run(robot, contour, "pdsmc")]
                    mc.append(monte_carlo(specs, "pdsmc_pos@eq", args.runs, args.seed))
                    print(mc[-1], flush=True)
    command = ("python bench/position_domain.py" + (" --quick" if args.quick else "")
               + (f" --arms {','.join(arms)}" if arms != list(ARMS) else ""))
    (out / "POSITION_DOMAIN.md").write_text(markdown(rows, mc, command, time.time() - start))
    (out / "figures" / "position_domain.json").write_text(json.dumps({"runs": rows, "monte_carlo": mc}, indent=1))
    figure(rows, out / "figures" / "position_domain_ratios.png")
    print(f"wrote {out / 'POSITION_DOMAIN.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
