"""``pdsmc ladder`` (pdsmc_ros/experiments/ladder.py): the rungs' nuisances, the verdicts' rules,
the command end to end on a short run, and bad input.

Fast runs: the five-bar's circle at its high_speed scenario (2.5 s at 5 kHz) against the stand-in.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pdsmc_ros import cli
from pdsmc_ros.experiments.bootstrap import Interval
from pdsmc_ros.experiments.ladder import (
    CLAIMS,
    FAILS,
    HOLDS,
    LAWS,
    NOT_APPLICABLE,
    RUNG_NAMES,
    RUNGS,
    UNDECIDED,
    compare_intervals,
    degradation,
    rung_stand_ins,
    verdict,
)
from pdsmc_ros.sim.realism import NUISANCES


def test_each_rung_turns_on_its_nuisances_at_the_bench_values_and_nothing_else() -> None:
    stand_ins = rung_stand_ins("ur5", 1000.0, RUNGS)
    assert list(stand_ins) == list(RUNG_NAMES)
    _, bench, _ = stand_ins["bench"].resolve("ur5", 1000.0)
    _, ideal, _ = stand_ins["ideal"].resolve("ur5", 1000.0)
    assert bench.preset == "bench" and ideal.is_ideal
    for rung in RUNGS[1:-1]:
        _, realism, _ = stand_ins[rung.name].resolve("ur5", 1000.0)
        assert rung.nuisances, rung.name
        for name in NUISANCES:
            expected = bench if name in rung.nuisances else ideal
            if name == "no_load_speed":  # unused without the torque-speed line (bench only)
                continue
            assert np.array_equal(np.asarray(realism.value(name)), np.asarray(expected.value(name))), (rung.name, name)
        assert not realism.is_ideal and realism.summary() != bench.summary()
    # every nuisance of bench is in some rung but the torque-speed line, in bench alone
    covered = {name for rung in RUNGS if rung.nuisances for name in rung.nuisances}
    assert set(NUISANCES) - covered == {"torque_speed", "no_load_speed"}


def interval(mean: float, half: float) -> Interval:
    return Interval(mean, mean - half, mean + half, 30)


def test_intervals_apart_decide_a_claim_and_overlapping_ones_do_not() -> None:
    assert compare_intervals(interval(1.0, 0.1), interval(2.0, 0.1), "lower") == HOLDS
    assert compare_intervals(interval(2.0, 0.1), interval(1.0, 0.1), "lower") == FAILS
    assert compare_intervals(interval(1.0, 0.6), interval(2.0, 0.6), "lower") == UNDECIDED
    # comparable: not above; overlapping counts as comparable, wholly above does not
    assert compare_intervals(interval(1.0, 0.6), interval(2.0, 0.6), "comparable") == HOLDS
    assert compare_intervals(interval(3.0, 0.1), interval(2.0, 0.1), "comparable") == FAILS


def rows_of(values: dict[tuple[str, str], list[float]]) -> list[dict[str, Any]]:
    """Rows as compare_plant gives them (NaN: a diverged draw) for (rung, law)."""
    out = []
    for (rung, law), series in values.items():
        for i, v in enumerate(series):
            ok = np.isfinite(v)
            out.append({"rung": rung, "run": i, "law": law, "status": "ok" if ok else "diverged",
                        **({"contour_mean": v, "error_rms": v} if ok else {})})
    return out


def summary_of(rows: list[dict[str, Any]], rungs: list[str], laws: list[str]) -> dict[str, Any]:
    from pdsmc_ros.experiments.compare import Column
    from pdsmc_ros.experiments.ladder import summarize

    cols = [Column("contour_mean", "contour mean", "m"), Column("error_rms", "RMS |e|", "rad")]
    return summarize(rows, rungs, laws, cols)


def test_the_verdicts_of_each_claim_from_draws() -> None:
    rng = np.random.default_rng(0)
    base = 1.0 + 0.01 * rng.standard_normal(30)
    values = {("ideal", "pd"): list(2.0 * base), ("ideal", "pdsmc"): list(1.0 * base),
              ("ideal", "smc"): list(1.0 * base),
              # friction: SMC's error triples, PD-SMC's grows by a tenth; PD diverges in every draw
              ("friction", "pd"): [np.nan] * 30, ("friction", "pdsmc"): list(1.1 * base),
              ("friction", "smc"): list(3.0 * base)}
    rows = rows_of(values)
    summary = summary_of(rows, ["ideal", "friction"], ["pd", "smc", "pdsmc"])
    by_name = {c.name: c for c in CLAIMS}
    assert verdict(by_name["contour"], "ideal", summary, rows).verdict == HOLDS
    v = verdict(by_name["contour"], "friction", summary, rows)
    assert v.verdict == HOLDS and "pd diverged in every draw" in v.why
    assert verdict(by_name["robust"], "ideal", summary, rows).verdict == NOT_APPLICABLE
    robust = verdict(by_name["robust"], "friction", summary, rows)
    assert robust.verdict == HOLDS and robust.law is not None and robust.other is not None
    assert abs(robust.law.mean - 1.1) < 1e-9 and abs(robust.other.mean - 3.0) < 1e-9
    assert verdict(by_name["tracking"], "ideal", summary, rows).verdict == HOLDS  # equal: comparable
    assert verdict(by_name["tracking"], "friction", summary, rows).verdict == HOLDS  # lower
    # the degradation pairs each draw with the same draw at the ideal rung
    ratio = degradation(rows, "friction", "smc", "contour_mean")
    assert ratio is not None and ratio.n == 30 and abs(ratio.mean - 3.0) < 1e-9
    # without the ideal rung there is nothing to measure the growth against
    alone = [r for r in rows if r["rung"] == "friction"]
    v = verdict(by_name["robust"], "friction", summary_of(alone, ["friction"], ["pd", "smc", "pdsmc"]), alone)
    assert v.verdict == NOT_APPLICABLE and "ideal rung" in v.why
    # a law that lost more draws does not win a claim on the draws it kept
    values[("friction", "pd")] = [5.0] * 30
    values[("friction", "pdsmc")] = [1.1] * 20 + [np.nan] * 10
    rows = rows_of(values)
    summary = summary_of(rows, ["ideal", "friction"], ["pd", "smc", "pdsmc"])
    v = verdict(by_name["contour"], "friction", summary, rows)
    assert v.verdict == UNDECIDED and "pdsmc lost more draws" in v.why


def ladder(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = cli.main(["ladder", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_command_writes_the_report_of_compare_plants_draws(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    from pdsmc_ros.experiments.compare import law_specs
    from pdsmc_ros.experiments.ladder import ladder_task
    from pdsmc_ros.experiments.montecarlo import load_uncertainty

    out = tmp_path / "ladder"
    code, stdout, err = ladder(capsys, "--robot", "parallel_5r", "--contour", "circle", "--scenario", "high_speed",
                               "--laws", "pd,smc,pdsmc", "--rungs", "ideal,delay", "--draws", "3", "--seed", "5",
                               "--workers", "1", "--out", str(out))
    assert code == 0, err
    data = json.loads((out / "ladder.json").read_text())
    assert data["rungs"] == ["ideal", "delay"] and data["draws"] == 3 and data["laws"] == ["pd", "smc", "pdsmc"]
    assert "command_delay" in data["plants"]["delay"] and "every nuisance off" in data["plants"]["ideal"]
    assert data["command"].startswith("pdsmc ladder --robot parallel_5r --contour circle --scenario high_speed")
    assert len(data["verdicts"]) == len(CLAIMS) * 2
    for rung in ("ideal", "delay"):
        for law in ("pd", "smc", "pdsmc"):
            entry = data["rungs_summary"][rung][law]
            assert entry["runs"] == 3
    # the rows are compare_plant's for the same draw and rung
    specs = [e.spec for e in law_specs("parallel_5r", "circle", ["pd", "smc", "pdsmc"], scenario="high_speed")]
    stand_in = rung_stand_ins(specs[0].robot, specs[0].rate, [RUNGS[RUNG_NAMES.index("delay")]])["delay"]
    mine = ladder_task("delay", 2, 5, specs, load_uncertainty(None, default="ladder_uncertainty"), stand_in)
    lines = (out / "ladder.csv").read_text().splitlines()
    assert lines[0].startswith("rung,run,law,status,contour_mean") and len(lines) == 1 + 2 * 3 * 3
    header = lines[0].split(",")
    row = dict(zip(header, lines[1 + 3 * 3 + 2 * 3].split(",")))  # delay, draw 2, pd
    assert row["rung"] == "delay" and row["run"] == "2" and row["law"] == "pd"
    assert float(row["contour_mean"]) == mine[0]["contour_mean"]
    md = (out / "ladder.md").read_text()
    assert "## Verdicts" in md and "+ delay and torque lag" in md and data["command"] in md
    assert (out / "ladder.png").stat().st_size > 0
    for claim in ("contour", "robust", "tracking"):
        assert any(line.startswith(claim) for line in stdout.splitlines())


def test_bad_input_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = ladder(capsys, "--robot", "parallel_5r", "--rungs", "ideal,wind", "--draws", "2",
                          "--out", str(tmp_path / "x"))
    assert code == cli.EXIT_USAGE and "unknown rung 'wind'" in err and len(err.strip().splitlines()) == 1
    a_file = tmp_path / "f"
    a_file.write_text("")
    code, _, err = ladder(capsys, "--robot", "parallel_5r", "--draws", "2", "--out", str(a_file))
    assert code == cli.EXIT_USAGE and "is a file" in err
    code, _, err = ladder(capsys, "--robot", "parallel_5r", "--laws", "pd,nope", "--draws", "2",
                          "--out", str(tmp_path / "x"))
    assert code == cli.EXIT_USAGE and "nope" in err
    assert not (tmp_path / "x").exists()


def test_the_help_names_the_defaults_the_module_declares(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        cli.main(["ladder", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert ",".join(LAWS) in text and ",".join(RUNG_NAMES) in text


def test_more_draws_go_where_a_claim_is_undecided_and_to_the_ideal_rung_a_robust_claim_pairs_with() -> None:
    from pdsmc_ros.experiments.ladder import FAILS, HOLDS, UNDECIDED, Verdict, undecided_rungs

    def v(claim: str, rung: str, verdict: str) -> Verdict:
        return Verdict(claim, rung, verdict, None, None, "")

    assert undecided_rungs([v("contour", "bench", UNDECIDED), v("tracking", "delay", HOLDS)]) == ["bench"]
    # the robust claim compares each draw with the same draw on the ideal rung: both get the new draws
    assert undecided_rungs([v("contour", "ideal", HOLDS), v("robust", "payload", UNDECIDED),
                            v("contour", "bench", UNDECIDED), v("robust", "bench", FAILS)]) == ["payload", "ideal",
                                                                                                  "bench"]
