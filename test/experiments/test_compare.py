"""``pdsmc compare`` (pdsmc_ros/experiments): the table and its best marks, the report, the Monte
Carlo's intervals, laws a test registers (one that diverges), and bad input.

Fast runs: the five-bar's circle at its high_speed scenario (2.5 s at 5 kHz, compiled thesis
laws), and the serial arm's zigzag at 500 Hz (high_speed, 2 s) for the laws declared here (numpy
path), with PD gains stable at that rate (``pdsmc tune``'s starting point) from params files.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from pdsmc_ros import cli
from pdsmc_ros.control import GainSpec, LawEntry, LawSetup, register_law, unregister_law
from pdsmc_ros.experiments.compare import Column, LawRow, best_marks, law_specs, text_table
from pdsmc_ros.robots.base import FloatArray
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate

FIVE_BAR = ["--robot", "parallel_5r", "--contour", "circle", "--scenario", "high_speed"]
SERIAL = ["--robot", "serial_3r", "--contour", "zigzag", "--scenario", "high_speed", "--rate", "500"]
THESIS = ("pd", "smc", "pdsmc")

KAPPA = GainSpec("kappa", "share of the PD's torque applied", "1", per_joint=False, lower=0.0, lower_open=True,
                 upper=2.0, neutral=1.0)
PUSH = GainSpec("push", "a constant torque on every joint", "N m", per_joint=False)


def scaled_pd(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
              qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """``kappa (Kp e + Kd edot)`` (rows kp, kd, kappa): a law no config file knows."""
    g = setup.gains
    return g[2] * (g[0] * (q_ref - q) + g[1] * (qd_ref - qd))


def scaled_pd_linear(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:  # noqa: ARG001
    return np.diag(g[0] * g[2]), np.diag(g[1] * g[2])


def push(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
         qdd_ref: FloatArray) -> FloatArray:  # noqa: ARG001
    """A constant torque, no feedback: the arm runs away (no linear part, so no rate check)."""
    return setup.gains[0] * np.ones_like(q)


@pytest.fixture
def laws() -> Iterator[None]:
    register_law(LawEntry("pd_scaled", "PD x kappa", ("kp", "kd", KAPPA), scaled_pd, "a test's own law",
                          linear_gains=scaled_pd_linear))
    register_law(LawEntry("runaway", "Runaway", (PUSH,), push, "a test's diverging law"))
    yield
    unregister_law("pd_scaled")
    unregister_law("runaway")


def params_file(folder: Path, law: str, **gains: object) -> str:
    path = folder / f"{law}.yaml"
    path.write_text(yaml.safe_dump({"controller": {"ros__parameters": {"type": law, **gains}}}))
    return str(path)


def serial_pd_gains() -> dict[str, list[float]]:
    from pdsmc_ros.experiments.tuning import starting_gains

    start = starting_gains(make_run("serial_3r", "zigzag", "pd", rate=500.0))
    return {"kp": list(start["kp"]), "kd": list(start["kd"])}


def compare(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    try:
        code = cli.main(["compare", *args])
    except SystemExit as exc:  # argparse's own errors (one line too: OneLineParser)
        code = int(exc.code or 0)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


COLS = (Column("a", "a", "m"), Column("b", "b", "N m"), Column("c", "c", "1"))


def test_the_best_of_each_column_is_its_lowest_and_a_diverged_row_never_competes() -> None:
    rows = [LawRow("x", "X", {"a": 2e-4, "b": 3.0, "c": math.nan}),
            LawRow("y", "Y", {"a": 1e-4, "b": 3.00001, "c": 0.5}),  # b equal to the printed digits: a tie
            LawRow("z", "Z", None, "diverged at t = 0.1 s")]
    assert best_marks(rows, COLS) == {"a": ["y"], "b": ["x", "y"], "c": ["y"]}
    assert best_marks([LawRow("z", "Z", None, "why")], COLS) == {}
    text = text_table(rows, COLS).splitlines()
    assert text[1].split() == ["X", "2.000e-04", "3*", "n/a"] and text[2].split() == ["Y", "1.000e-04*", "3*", "0.5*"]
    assert text[3].split() == ["Z", "DIVERGED", "-", "-"]  # no number from a diverged run
    assert "lower is better in every column" in text[4] and text[5] == "Z: DIVERGED: diverged at t = 0.1 s"


def test_the_thesis_laws_table_report_and_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "report"
    code, stdout, err = compare(capsys, *FIVE_BAR, "--laws", ",".join(THESIS), "--out", str(out), "--format",
                                "html", "--json")
    assert code == 0, err
    data = json.loads(stdout)
    assert [r["law"] for r in data["rows"]] == list(THESIS) and data["lower_is_better"] is True
    keys = [c["key"] for c in data["columns"]]
    assert keys[:4] == ["contour_mean", "contour_max", "axial_mean_1", "axial_mean_2"] and keys[-1] == "peak_torque"
    # each row is that law's own run, as pdsmc simulate runs it
    for row in data["rows"]:
        result = simulate(make_run("parallel_5r", "circle", row["law"], scenario="high_speed"))
        assert row["values"]["contour_mean"] == pytest.approx(result.metrics.contour_mean, rel=1e-12)
        assert row["values"]["control_energy"] == pytest.approx(result.metrics.run_scores["control_energy"], rel=1e-12)
        assert row["values"]["contour_max"] == pytest.approx(np.max(result.samples.contour_error), rel=1e-12)
    for key in keys:  # the marked law holds the lowest value of the column
        lowest = min(r["values"][key] for r in data["rows"])
        assert all(r["values"][key] <= lowest * (1 + 1e-3) for r in data["rows"] if key in r["best"])
        assert any(key in r["best"] for r in data["rows"])
    assert {p.name for p in out.iterdir()} == {
        "compare.md", "compare.html", "compare.json", "compare_parallel_5r_circle_contour_error.png",
        "compare_parallel_5r_circle_axial_torque.png", "compare_parallel_5r_circle_contours.png"}
    md = (out / "compare.md").read_text()
    page = (out / "compare.html").read_text()
    for label in ("PD", "SMC", "PD-SMC"):
        assert f"| {label} |" in md and f"<td>{label}</td>" in page
    assert "kp = 230, 260; kd = 24, 36" in md and "presets of config/gains.yaml for parallel_5r/circle" in md
    assert "![compare parallel 5r circle contours](compare_parallel_5r_circle_contours.png)" in md
    assert "\\|e1\\| mean (rad)" in md and "**" in md  # a | in a cell is escaped; the best in bold
    assert page.count('src="data:image/png;base64,') == 3 and not re.search(r'src="(?!data:)', page)
    assert json.loads((out / "compare.json").read_text()) == data


def test_registered_laws_params_files_and_a_diverging_law(laws: None, tmp_path: Path,  # noqa: ARG001
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    pd = serial_pd_gains()
    files = [params_file(tmp_path, "pd", **pd), params_file(tmp_path, "pd_scaled", **pd, kappa=0.8),
             params_file(tmp_path, "runaway", push=1000.0)]
    out = tmp_path / "report"
    code, stdout, err = compare(capsys, *SERIAL, "--laws", "pd,pd_scaled,runaway", "--out", str(out),
                                *(arg for f in files for arg in ("--params-file", f)))
    assert code == 1  # a law diverged: the command says so
    assert "pdsmc compare: error: Runaway diverged (diverged at t = " in err
    lines = stdout.splitlines()
    runaway = next(line for line in lines if line.startswith("Runaway "))
    assert runaway.split()[1] == "DIVERGED" and not re.search(r"\d", runaway)  # no number in its row
    scaled = next(line for line in lines if line.startswith("PD x kappa "))
    assert len(re.findall(r"\d\.\d+e-\d\d", scaled)) >= 5
    md = (out / "compare.md").read_text()
    assert "| Runaway | **DIVERGED** (diverged at t = " in md and "| PD x kappa |" in md and "| PD |" in md
    assert f"params file {files[1]}" in md and "kappa = 0.8" in md
    data = json.loads((out / "compare.json").read_text())
    rows = {r["law"]: r for r in data["rows"]}
    assert rows["runaway"]["values"] is None and rows["runaway"]["best"] == [] and rows["pd"]["diverged"] == ""
    # the comparison's figures leave the diverged run out (its NaN samples would set their scales)
    assert len(list(out.glob("*.png"))) == 3
    # a law outside the thesis's three is drawn with its label and a colour none of the three has
    from pdsmc_ros.experiments.plots import CONTROLLER_STYLE, controller_style

    label, colour, line = controller_style("pd_scaled")
    assert label == "PD x kappa" and line == "-." and colour not in {c for _, c, _ in CONTROLLER_STYLE.values()}
    assert controller_style("runaway")[1] not in {colour, None} and controller_style("pd") == CONTROLLER_STYLE["pd"]


def test_bad_input_is_one_line_exit_2_and_writes_nothing(laws: None, tmp_path: Path,  # noqa: ARG001
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "never"
    laws_ = ["--laws", "pd,smc"]
    uncertainty = tmp_path / "u.yaml"
    uncertainty.write_text("link_mass: {distribution: triangular, relative: 0.1}\n")
    cases = [
        ([*FIVE_BAR, "--laws", "pd,pidd"], "unknown controller 'pidd'"),
        (["--robot", "parallel_7r", "--contour", "circle", *laws_], "parallel_7r"),
        (["--robot", "parallel_5r", "--contour", "square", *laws_], "square"),
        ([*FIVE_BAR, "--laws", "pd,pd_scaled"],
         "law pd_scaled has no gains for parallel_5r/circle (pd_scaled needs gains kp, kd, kappa"),
        ([*FIVE_BAR, *laws_, "--uncertainty", str(uncertainty)], "--uncertainty is for the Monte Carlo: give --runs"),
        ([*FIVE_BAR, *laws_, "--runs", "2", "--uncertainty", str(uncertainty)], "distribution must be one of"),
        ([*FIVE_BAR, *laws_, "--format", "html"], "--format html writes a report: give --out DIR"),
        (["--robot", "serial_3r", "--contour", "circle", *laws_, "--rate", "1000"],
         "pd gains for serial_3r/circle at 1000 Hz: joint"),
        ([*FIVE_BAR, "--laws", "pd,pd"], "expected distinct comma-separated names"),
    ]
    for args, message in cases:
        code, stdout, err = compare(capsys, *args, "--out", str(out)) if "--format" not in args else \
            compare(capsys, *args)
        lines = err.strip().splitlines()
        assert code == cli.EXIT_USAGE and len(lines) == 1 and message in lines[0], (args, err)
        assert stdout == "" and not out.exists(), args
    assert "--params-file FILE (`pdsmc tune --robot parallel_5r --contour circle --controller pd_scaled`" in \
        compare(capsys, *FIVE_BAR, "--laws", "pd,pd_scaled")[2]
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    code, _, err = compare(capsys, *FIVE_BAR, *laws_, "--out", str(a_file))
    assert code == cli.EXIT_USAGE and f"--out {str(a_file)!r} is a file" in err and a_file.read_text() == ""
    code, _, err = compare(capsys, *FIVE_BAR, *laws_, "--params-file", params_file(tmp_path, "pdsmc", kp=[1, 2]))
    assert code == cli.EXIT_USAGE and "holds gains for type 'pdsmc'; --laws is pd,smc" in err


def test_the_montecarlo_runs_montecarlos_plants_and_gives_intervals(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    import dataclasses

    from pdsmc_ros.experiments.compare_mc import compare_plant
    from pdsmc_ros.experiments.montecarlo import load_uncertainty, run_sample

    # the plants of pdsmc montecarlo: run i of seed K is the same draw, every law on it
    specs = [dataclasses.replace(e.spec, duration_factor=0.05)
             for e in law_specs("parallel_5r", "circle", ["pd", "pdsmc"])]
    spreads = load_uncertainty()
    mine = compare_plant(3, 7, specs, spreads)
    theirs = run_sample(3, 7, specs, spreads)
    assert [r["law"] for r in mine] == ["pd", "pdsmc"]
    for a, b in zip(mine, theirs):
        assert a["status"] == b["status"] == "ok" and a["contour_mean"] == b["contour_mean"]
        assert a["torque_tv_rate"] == b["run_scores_torque_tv_rate"]

    out = tmp_path / "mc"
    code, stdout, err = compare(capsys, *FIVE_BAR, "--laws", "pd,pdsmc", "--runs", "3", "--seed", "7", "--workers", "1",
                                "--out", str(out), "--json")
    assert code == 0, err
    mc = json.loads(stdout)["montecarlo"]
    assert mc["runs"] == 3 and mc["seed"] == 7 and mc["uncertainty_source"] == "config/uncertainty.yaml"
    for name in ("pd", "pdsmc"):
        entry = mc["intervals"][name]
        assert entry["runs"] == 3 and entry["diverged"] == entry["failed"] == 0
        for key, ci in entry["columns"].items():
            assert ci["n"] == 3 and ci["low"] <= ci["mean"] <= ci["high"], key
    lines = (out / "compare_runs.csv").read_text().splitlines()
    assert lines[0].startswith("run,law,status,contour_mean,contour_max") and len(lines) == 1 + 3 * 2
    md = (out / "compare.md").read_text()
    assert "## Monte Carlo: 3 drawn plants" in md and "10,000 resamples" in md and "default_rng([7, i])" in md
    assert (out / "compare_montecarlo.png").stat().st_size > 0
