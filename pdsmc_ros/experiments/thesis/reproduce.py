"""Run the thesis matrix (Tables 4.17-4.61) in-process or over the ROS nodes and compare
every cell (``pdsmc reproduce``; the report is :mod:`pdsmc_ros.experiments.thesis.report`)."""

from __future__ import annotations

import dataclasses
import fnmatch
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ...bag.reader import read_run, run_samples
from ...config import choice, load_config
from ...errors import BagError, ConfigError
from ...metrics.statistics import compute_metrics
from ...resources import ros_environment, script_path
from ...runs.builder import PAYLOAD_READINGS, RunSpec, make_run, smc_reading
from ...sim import RunResult, simulate, simulate_many
from .cells import (
    CONTINUOUS_CASE,
    LABEL,
    Cell,
    Reproduction,
    compare,
    matrix_specs,
    needed_torque,
    run_key,
    summarize,
)
from .verdicts import continuous_check


def select(specs: list[RunSpec], only: str | None) -> list[RunSpec]:
    if not only:
        return specs
    chosen = [s for s in specs if fnmatch.fnmatch(run_key(s), only)]
    if not chosen:
        raise ConfigError(f"--only {only!r} matches no run; runs are named robot/contour/scenario/controller, "
                          "e.g. 'parallel_5r/ellipse_vertical/*/pdsmc'")
    return chosen


def run_reproduction(
    *,
    smc: str = "thesis_fit",
    workers: int | None = None,
    readings: bool = True,
    progress: Callable[[str], None] | None = None,
    only: str | None = None,
    ros_bags: Path | None = None,
    payload_reading: str = "tip",
    scheduler: str | None = None,
) -> Reproduction:
    """Simulate the whole matrix (and, optionally, every SMC reading on the nominal rows,
    the other payload readings on the payload rows and, for the whole matrix, the
    continuous-time check of :func:`continuous_check`).

    ``payload_reading`` places the payload scenario's load in the primary cells.

    With ``ros_bags``, every run is executed over DDS through
    ``scripts/run_experiment.sh`` (lockstep, composed intra-process), recorded into that
    directory and analysed from its bag; each bag is checked against the
    in-process simulation of the same run (1e-9).
    """
    start = time.perf_counter()
    choice(payload_reading, tuple(PAYLOAD_READINGS), "payload reading")
    specs = select(matrix_specs(smc, payload_reading=payload_reading), only)
    if ros_bags is not None and payload_reading != "tip" and any(s.payload > 0.0 for s in specs):
        raise ConfigError(f"--payload-reading {payload_reading} runs in-process only (the ROS plant carries "
                          "the load as a point mass at the tip); drop --ros or use --payload-reading tip")
    extra: dict[str, list[RunSpec]] = {}
    payload_extra: dict[str, list[RunSpec]] = {}
    if readings:
        for name in load_config("smc_readings"):
            if name == smc:
                continue
            model = smc_reading(name)
            extra[name] = [
                dataclasses.replace(s, smc_model=model)
                for s in specs
                if s.controller == "smc" and s.scenario == "nominal"
            ]
        for name in PAYLOAD_READINGS:
            if name != payload_reading:
                payload_extra[name] = [dataclasses.replace(s, payload_reading=name)
                                       for s in specs if s.payload > 0.0]
    # the runs a gain reading changed, once more with the gains as printed (run last)
    printed_specs = [p for p, s in zip(select(matrix_specs(smc, gain_readings=False), only), specs)
                     if p.gains != s.gains]
    everything = (specs + [s for group in extra.values() for s in group]
                  + [s for group in payload_extra.values() for s in group] + printed_specs)
    tables = load_config("thesis_tables")

    def report(done: int, total: int, res: RunResult) -> None:
        if progress is None:
            return
        s = res.spec
        thesis = tables[s.robot][s.contour][s.scenario][s.controller]["contour_mean"]
        ours = res.metrics.contour_mean
        progress(
            f"[{done:3d}/{total}] {s.robot:11s} {s.contour:18s} {s.scenario:10s} "
            f"{LABEL[s.controller]:6s} contour mean {ours:.4e} m (thesis {thesis:.4e}, "
            f"{100 * (ours - thesis) / thesis:+6.1f} %)  {res.wall_s:5.2f} s"
        )

    if ros_bags is not None:
        # each case is its own process group and DDS domain; one at a time unless asked: a composed
        # intra-process run keeps a core busy, and two at once took 30 s each against 9 s alone
        from concurrent.futures import ThreadPoolExecutor

        done = iter(range(1, len(specs) + 1))

        def one(spec: RunSpec) -> RunResult:
            return _ros_result(spec, ros_bags, lambda r: report(next(done), len(specs), r))

        order = sorted(range(len(specs)), key=lambda i: -specs[i].contour_model().duration)
        with ThreadPoolExecutor(max_workers=workers or 1) as pool:
            futures = {i: pool.submit(one, specs[i]) for i in order}
            results = [futures[i].result() for i in range(len(specs))]
        results += (simulate_many(everything[len(specs):], workers=workers, scheduler=scheduler)
                    if len(everything) > len(specs) else [])
    else:
        results = simulate_many(everything, workers=workers, progress=report, scheduler=scheduler)
    main = results[: len(specs)]
    printed = {run_key(r.spec): r for r in results[len(results) - len(printed_specs):]}
    cells = compare(main, printed)
    summary_by_reading = {smc: summarize(c for c in cells if c.controller == "smc" and c.scenario == "nominal")}
    offset = len(specs)
    for name, group in extra.items():
        chunk = results[offset : offset + len(group)]
        offset += len(group)
        summary_by_reading[name] = summarize(compare(chunk))
    payload_cells: dict[str, list[Cell]] = {}
    payload_results: dict[str, list[RunResult]] = {}
    for name, group in payload_extra.items():
        payload_results[name] = results[offset : offset + len(group)]
        offset += len(group)
        payload_cells[name] = compare(payload_results[name])
    needed: dict[str, list[float]] = {}
    for s in specs:
        key = f"{s.robot}/{s.contour}/{s.scenario}"
        if key not in needed and "torque" in tables[s.robot][s.contour][s.scenario]["tables"]:
            needed[key] = needed_torque(s).tolist()
    continuous: dict[str, dict[str, Any]] = {}
    if readings and not only:
        case = next(r for r in main if (r.spec.robot, r.spec.contour, r.spec.controller) == CONTINUOUS_CASE
                    and r.spec.scenario == "nominal")
        continuous = continuous_check(case)
    return Reproduction(cells, main, smc, time.perf_counter() - start, summary_by_reading,
                        payload_reading, payload_cells, payload_results, needed, continuous)


def _ros_result(spec: RunSpec, bags: Path, report: Callable[[RunResult], None]) -> RunResult:
    """One run over DDS, analysed from its bag and checked against the in-process loop."""

    start = time.perf_counter()
    out = bags / run_key(spec).replace("/", "-")
    script = script_path()
    reading = "thesis_fit" if spec.smc_model == smc_reading("thesis_fit") else "literal"
    cmd = ["bash", str(script), "--robot", spec.robot, "--contour", spec.contour, "--controller",
           spec.controller, "--scenario", spec.scenario, "--smc-reading", reading, "--composed",
           "--intra-process", "--out", str(out), "--timeout", "3600"]
    printed = make_run(spec.robot, spec.contour, spec.controller, scenario=spec.scenario)
    if spec.gains != printed.gains:  # a gain reading: the controller gets the gains explicitly
        for name, values in spec.gains.as_dict().items():
            if values:
                cmd += ["--param", f"{name}:=[{', '.join(repr(float(v)) for v in values)}]"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=ros_environment())
    if proc.returncode != 0:
        raise BagError(f"{run_key(spec)} over DDS failed: {proc.stderr.strip().splitlines()[-1:]}")
    run = read_run(out)
    run = dataclasses.replace(run, spec=dataclasses.replace(run.spec, bound=spec.bound))
    samples = run_samples(run)
    reference = simulate(spec)
    gap = float(np.max(np.abs(samples.q - reference.samples.q)))
    if not run.complete or gap > 1e-9:
        raise BagError(f"{run_key(spec)}: the DDS run differs from the in-process one "
                       f"(max |dq| {gap:.3g}, complete={run.complete})")
    result = RunResult(spec, samples, compute_metrics(samples, spec.bound), run.steps,
                       time.perf_counter() - start)
    report(result)
    return result
