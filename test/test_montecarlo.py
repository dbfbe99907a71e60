"""Robustness Monte Carlo on Dask (issue 18): draws, determinism across engines, faults, bad input."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.errors import ConfigError
from pdsmc_ros.experiments.montecarlo import base_specs, load_uncertainty, run_sample, sample_plant

pytest.importorskip("distributed")

BIN = Path(sys.executable).parent
ARGS = ["--robot", "parallel_5r", "--contour", "circle", "--controllers", "pd,pdsmc", "--seed", "7"]


def montecarlo(*args: str, timeout: float = 600, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "montecarlo", *args], capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, **env})


def table(out: Path) -> list[dict[str, str]]:
    with (out / "montecarlo.csv").open() as handle:
        return list(csv.DictReader(handle))


def test_draws_depend_on_the_seed_and_the_run_alone_and_every_controller_shares_them() -> None:
    spreads = load_uncertainty()
    a = sample_plant("serial_3r", spreads, np.random.default_rng([3, 11]))
    b = sample_plant("serial_3r", spreads, np.random.default_rng([3, 11]))
    c = sample_plant("serial_3r", spreads, np.random.default_rng([3, 12]))
    assert a[3] == b[3] and a[3] != c[3]
    assert 0.8 <= a[3]["link1_mass"] / 1.0 <= 1.2 and 0.0 <= a[3]["payload"] <= 1.5  # the default spreads
    specs = base_specs("serial_3r", "circle", ["pd", "pdsmc"])
    rows = run_sample(0, 3, [dataclasses.replace(s, duration_factor=0.05) for s in specs], spreads)
    drawn = [{k: v for k, v in row.items() if k.startswith(("link", "motor", "payload", "initial"))} for row in rows]
    assert drawn[0] == drawn[1] and [r["controller"] for r in rows] == ["pd", "pdsmc"]
    assert all(r["status"] == "ok" and r["contour_mean"] > 0 for r in rows)


def test_a_drawn_thesis_arm_runs_against_the_stand_in_and_a_urdf_arm_draws_its_start_alone() -> None:
    """The stand-in builds MuJoCo from the drawn plant's URDF: its numbers must read as numbers."""
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    spreads = load_uncertainty()
    specs = [dataclasses.replace(s, duration_factor=0.05) for s in base_specs("parallel_5r", "circle", ["pd"])]
    rows = run_sample(2, 3, specs, spreads, stand_in=StandIn())
    assert rows[0]["status"] == "ok" and rows[0]["contour_mean"] > 0
    from pdsmc_ros.robots.catalog import resolve_robot

    resolve_robot("ur5")  # registers the arm of example-robot-data
    params, payload, initial, drawn = sample_plant("ur5", {"initial_error": spreads["initial_error"]},
                                                   np.random.default_rng([3, 11]))
    assert params is None and payload == 0.0 and initial.shape == (6,) and np.any(initial != 0.0)
    assert sorted(drawn) == [f"initial_error_{j}" for j in range(1, 7)]
    with pytest.raises(ConfigError, match="'ur5' is a URDF arm: only initial_error can be drawn"):
        sample_plant("ur5", spreads, np.random.default_rng(0))


def test_every_csv_cell_is_a_plain_number_or_word(tmp_path: Path) -> None:
    """numpy 2's ``repr`` of a numpy scalar (``np.float64(0.75...)``) is not a number to a CSV reader."""
    from pdsmc_ros.experiments.montecarlo import summarize, write_outputs

    spreads = load_uncertainty()
    specs = [dataclasses.replace(s, duration_factor=0.02) for s in base_specs("serial_3r", "circle", ["pd", "smc"])]
    rows = run_sample(0, 5, specs, spreads) + run_sample(1, 5, specs, spreads)
    # the drawn values are plain floats now (the stand-in writes them into a URDF); a numpy scalar in a row is
    # what the table used to repr
    rows[0]["link1_mass"] = np.float64(rows[0]["link1_mass"])
    assert any(isinstance(v, np.floating) for v in rows[0].values())
    meta = {"controllers": ["pd", "smc"]}
    write_outputs(rows, summarize(rows, ["pd", "smc"], specs[0].bound), meta, tmp_path)
    read = table(tmp_path)
    assert len(read) == 4 and [r["controller"] for r in read] == ["pd", "smc", "pd", "smc"]
    for row, original in zip(read, rows, strict=True):
        assert row["status"] == "ok"
        for column, cell in row.items():
            if column in ("controller", "status"):
                continue
            assert float(cell) == float(original[column]), (column, cell)  # every digit, not text
        assert row["run"] in ("0", "1") and "np." not in "".join(row.values())


def test_the_summary_takes_the_runs_in_their_order_whatever_order_they_finish_in() -> None:
    """The engine hands rows back as tasks finish; a mean's last digit depends on its order of summation."""
    from pdsmc_ros.experiments.montecarlo import summarize

    # in run order the small means add up before the large one; reversed, each is lost against it
    values = [1e-16] * 10 + [1.0]
    rows = [{"run": i, "controller": "pd", "contour_mean": v} for i, v in enumerate(values)]
    assert sum(values) != sum(reversed(values))
    ordered = summarize(rows, ["pd"], 0.5)
    assert summarize(rows[::-1], ["pd"], 0.5) == ordered
    assert ordered["pd"]["contour_mean_mean"] == float(np.mean(values))


def test_bad_uncertainty_files_are_one_line(tmp_path: Path) -> None:
    cases = {
        "link_mas: {distribution: uniform, relative: 0.1}\n": "unknown parameter 'link_mas'",
        "link_mass: {distribution: uniform, relative: -0.1}\n": r"link_mass.relative must be >= 0 \(a spread\)",
        "link_mass: {distribution: cauchy, relative: 0.1}\n": "distribution must be one of uniform, normal",
        "payload: {distribution: uniform, low: 2, high: 1}\n": "low 2 > high 1",
    }
    path = tmp_path / "u.yaml"
    for text, message in cases.items():
        path.write_text(text)
        with pytest.raises(ConfigError, match=message) as info:
            load_uncertainty(path)
        assert "\n" not in str(info.value)
    path.write_text("link_mass: {distribution: uniform, relative: -0.1}\n")
    proc = montecarlo(*ARGS, "--runs", "2", "--uncertainty", str(path), "--out", str(tmp_path / "x"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "must be >= 0" in proc.stderr
    proc = montecarlo(*ARGS, "--runs", "2", "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "y"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "--scheduler 'tcp://127.0.0.1:9': cannot reach it" in proc.stderr
    proc = montecarlo(*ARGS, "--runs", "2", "--scheduler", "localhost:8786", "--out", str(tmp_path / "z"))
    assert proc.returncode == 2 and "expected an address like tcp://HOST:PORT" in proc.stderr


def free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@contextlib.contextmanager
def dask_cluster(workers: int) -> Iterator[tuple[str, list[subprocess.Popen]]]:
    """``dask scheduler`` and ``workers`` ``dask worker`` processes from the venv; stopped by PID."""
    port = free_port()
    started: list[subprocess.Popen] = []
    try:
        started.append(subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                         "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                        start_new_session=True))
        for _ in range(workers):
            started.append(subprocess.Popen([str(BIN / "dask"), "worker", f"tcp://127.0.0.1:{port}", "--nthreads",
                                             "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                            stderr=subprocess.DEVNULL, start_new_session=True))
        yield f"tcp://127.0.0.1:{port}", started
    finally:
        for proc in started:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in started:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)


@pytest.mark.timeout(900)
def test_the_table_is_the_same_on_a_local_cluster_and_on_a_scheduler_with_a_worker_killed(tmp_path: Path) -> None:
    local = montecarlo(*ARGS, "--runs", "24", "--workers", "2", "--out", str(tmp_path / "local"))
    assert local.returncode == 0, local.stderr
    one = montecarlo(*ARGS, "--runs", "24", "--workers", "1", "--out", str(tmp_path / "one"))
    assert one.returncode == 0, one.stderr
    assert (tmp_path / "local" / "montecarlo.csv").read_bytes() == (tmp_path / "one" / "montecarlo.csv").read_bytes()
    rows = table(tmp_path / "local")
    assert len(rows) == 48 and {r["status"] for r in rows} == {"ok"}
    assert [r["run"] for r in rows] == [str(i // 2) for i in range(48)]

    with dask_cluster(2) as (address, started):
        out = tmp_path / "cluster"
        run = subprocess.Popen([sys.executable, "-m", "pdsmc_ros.cli", "montecarlo", *ARGS, "--runs", "24",
                                "--scheduler", address, "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # kill one worker once the first run is in (the rest still to do): its tasks are redone
        first = run.stderr.readline()  # type: ignore[union-attr]
        assert first.startswith("montecarlo: 1/24 runs"), first
        os.killpg(started[1].pid, signal.SIGKILL)
        _, err = run.communicate(timeout=600)
        assert run.returncode == 0, first + err
        assert "montecarlo: 24/24 runs" in err
        assert (out / "montecarlo.csv").read_bytes() == (tmp_path / "local" / "montecarlo.csv").read_bytes()


def pdsmc(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.timeout(600)
def test_sweep_tune_and_reproduce_on_a_scheduler_equal_their_local_runs(tmp_path: Path) -> None:
    """The other commands with ``--scheduler``: the same files as without it, byte for byte."""
    commands = {
        "sweep_kp.csv": ["sweep", "--param", "kp", "--robot", "parallel_5r", "--contour", "circle",
                         "--values", "100,1000"],
        "gains.yaml": ["tune", "--robot", "parallel_5r", "--contour", "circle", "--controller", "pd",
                       "--rounds", "1", "--quiet"],
        "reproduction.csv": ["reproduce", "--only", "parallel_5r/circle/*/pd*", "--no-readings", "--quiet"],
    }

    def run(name: str, where: str, *engine: str) -> None:
        command = commands[name]
        out = tmp_path / where / name if name.endswith(".yaml") else tmp_path / where
        proc = pdsmc(*command, *engine, "--out", str(out))
        assert proc.returncode == 0, f"{command[0]} {engine}: {proc.stderr}"

    def tasks_run(dask_scheduler) -> dict[str, int]:  # noqa: ANN001
        return {name: sum(prefix.state_counts.values()) for name, prefix in dask_scheduler.task_prefixes.items()}

    for name in commands:
        run(name, "local")
    from distributed import Client

    with dask_cluster(1) as (address, _), Client(address, timeout="20s") as client:
        counts = [client.run_on_scheduler(tasks_run)]
        for name in commands:
            run(name, "cluster", "--scheduler", address)
            counts.append(client.run_on_scheduler(tasks_run))
    # each command's runs were tasks of the cluster: 2 sweep values, tune's candidates, 2 reproduction cells
    simulated = [c.get("pdsmc_simulate", 0) for c in counts]
    assert simulated[1] - simulated[0] >= 2 and simulated[3] - simulated[2] >= 2, counts
    assert counts[2].get("pdsmc_evaluate", 0) > counts[1].get("pdsmc_evaluate", 0), counts
    for name in commands:
        local = (tmp_path / "local" / name).read_bytes()
        assert local and (tmp_path / "cluster" / name).read_bytes() == local, name


@pytest.mark.timeout(600)
def test_ctrl_c_writes_the_runs_finished_so_far(tmp_path: Path) -> None:
    out = tmp_path / "partial"
    # as from a shell: SIGINT at its default (a test before this one in the same pytest process may
    # leave it ignored, and an ignored signal is inherited: the run then went on to the end)
    run = subprocess.Popen([sys.executable, "-m", "pdsmc_ros.cli", "montecarlo", *ARGS, "--runs", "500", "--workers",
                            "1", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    first = run.stderr.readline()  # type: ignore[union-attr]
    assert first.startswith("montecarlo: 1/500 runs"), first
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=300)
    assert run.returncode == 130, err
    done = int(err.split("the table is partial (")[1].split(" of 500 runs")[0])
    assert 1 <= done < 500 and "Traceback" not in err
    rows = table(out)
    runs = [int(r["run"]) for r in rows]
    assert len(rows) == 2 * done and len(set(runs)) == done and runs == sorted(runs)  # whole runs, in order
    assert {r["controller"] for r in rows} == {"pd", "pdsmc"}
