"""Benchmark: the identification checked against the truth on the MuJoCo stand-in with the bench nuisances.

``python bench/identification_stand_in.py [--robot ur5|serial_3r] [--payload KG] [--out DIR]
[--excitation DIR] [--periods N] [--cutoff HZ] [--sensitivity] [--realtime BAG --realtime-held-out BAG]``

1. ``pdsmc excite --robot ARM`` (or the excitation of ``--excitation DIR``, an earlier ``excite``'s);
2. the excitation on the stand-in in lockstep, in-process (``excite_stand_in`` of
   :mod:`pdsmc_ros.identification.simulated`):
   ``--realism bench`` (Coulomb and viscous friction, an 18-bit encoder with noise, the velocity
   differenced and filtered, a 2-tick delay, the torque's lag and its torque-speed line) with an
   unknown ``--payload`` (2 kg on the UR5, 0.2 kg on the serial 3R), under computed torque with
   the URDF's model (``--omega-n``, 60 rad/s: at 30 the wrists stick against their friction); the
   joint states the drive publishes and the torque MuJoCo applied written to a training bag
   (``--periods``) and a held-out one (2 periods, another phase), as the recorder would;
3. ``pdsmc identify`` on them, the result against what MuJoCo's model holds: the payload's mass,
   each joint's Coulomb and viscous friction, the held-out NRMSE per joint, the links' physical
   consistency, each against its target (5 %, 10 %, 10 %, 5 %);
4. fed back (``--feedback``): smc, ctc, pdg and ismc on the circle, on the same stand-in (``pdsmc
   simulate --plant mujoco --realism bench --payload-mass KG``, ``--smc-reading exact``, each
   law's preset gains) with the URDF's model, the identified one and the true one (``--model``:
   the URDF with the payload and the frictions MuJoCo's model holds, written beside the bags):
   the contour error, the RMS joint error and the largest torque;
5. with ``--realtime BAG [--realtime-window START:END] [--realtime-held-out BAG]`` the same check
   on bags recorded in real time (``scripts/run_experiment.sh --stand-in ARM --realism bench
   --driver-param payload_mass:=KG`` and ``pdsmc send-goal``: docs/tutorials/identify-ur5.md),
   against the same truth.

The last line: ``verdict=PASS|FAIL payload_error=E worst_coulomb_error=E worst_viscous_error=E
worst_heldout_nrmse_static_friction_set=E worst_heldout_nrmse_point=E worst_heldout_nrmse_outside_dead_zone=E
true_worst_heldout_nrmse_static_friction_set=E true_worst_heldout_nrmse_point=E consistent=yes|no condition=C``.
The held-out NRMSE is at every sample, dead zones included. ``static_friction_set``: Coulomb
friction the set-valued law it is, any torque within ``+/- fc`` where a joint is at rest, carried
through the efforts' filters (pdsmc_ros.identification.identify.prediction_nrmse's ``static``) --
the verdict's; ``point``: each sample's prediction a value, ``fc sign(qd)`` at rest too, which no
parameters can meet while a joint sticks; ``true_``: MuJoCo's own parameters scored on the same
held-out run, what the right model scores by each.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from identification import run  # noqa: E402  (bench/identification.py: a command's exit, output and time)

from pdsmc_ros.identification.arm_files import (  # noqa: E402
    OPTIONS_NAME,
    URDF_NAME,
    corrected_urdf,
    identified_options,
    options_text,
)
from pdsmc_ros.identification.consistent import is_consistent  # noqa: E402
from pdsmc_ros.identification.excitation import FourierExcitation  # noqa: E402
from pdsmc_ros.identification.identify import filtered_regressor, prediction_nrmse  # noqa: E402
from pdsmc_ros.identification.model import ArmDynamics, arm_of  # noqa: E402
from pdsmc_ros.identification.recording import parse_window, read_joint_states  # noqa: E402
from pdsmc_ros.identification.signals import prepare  # noqa: E402
from pdsmc_ros.identification.simulated import StandInTruth, excite_stand_in, write_joint_states  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402
from pdsmc_ros.sim.mujoco_lockstep import StandIn  # noqa: E402

TARGETS = {"payload": 0.05, "coulomb": 0.10, "viscous": 0.10, "nrmse": 0.05}
"""Issue 51's targets: payload mass within 5 %, each joint's frictions within 10 %, held-out NRMSE at most 5 %."""
PAYLOADS = {"ur5": 2.0, "serial_3r": 0.2}
LAWS = ("smc", "ctc", "pdg", "ismc")
"""The model-based laws."""


def truth_values(dynamics: ArmDynamics, truth: StandInTruth) -> np.ndarray:
    """The standard parameters MuJoCo's model holds: the URDF's links (the stand-in's bodies), the
    payload, the motor inertias and the frictions."""
    import pinocchio as pin

    layout = dynamics.layout
    values = dynamics.nominal.copy()
    values[layout.payload] = pin.Inertia(truth.payload_mass, truth.payload_com, np.zeros((3, 3))).toDynamicParameters()
    values[layout.joint_field("armature")] = truth.armature
    values[layout.joint_field("friction_coulomb")] = truth.friction_coulomb
    values[layout.joint_field("friction_viscous")] = truth.friction_viscous
    return values


def oracle(robot: str, report: dict, held_out: str,
           window: str | None) -> Callable[[StandInTruth], tuple[np.ndarray, np.ndarray]]:
    """A scorer of true parameters on the held-out run: its NRMSE per joint, ``(point, set)``. The
    held-out bag is read and filtered once, as ``pdsmc identify --validate`` filtered it (the
    identification's cut-off and Coulomb band); each call scores one truth, each sample's prediction
    a value and static friction a set at rest (prediction_nrmse's ``static``): what the right model
    scores by each on this run."""
    dynamics = ArmDynamics(arm_of(robot))
    recording = read_joint_states(held_out, dynamics.layout.joint_names)
    if window:
        recording = recording.window(*parse_window(window, "--realtime-held-out-window"), held_out)
    band = np.array(list(report["filter"]["coulomb_band"].values()), dtype=float)
    prepared = prepare(recording.t, recording.q, recording.tau, cutoff=report["filter"]["cutoff_hz"], stick_band=band)
    regressor = filtered_regressor(dynamics, prepared)

    def score(truth: StandInTruth) -> tuple[np.ndarray, np.ndarray]:
        values = truth_values(dynamics, truth)
        return (prediction_nrmse(regressor, values, prepared),
                prediction_nrmse(regressor, values, prepared, static=dynamics.layout.joint_field("friction_coulomb")))

    return score


CHANGES = (
    ("as they are", {}),
    ("every Coulomb friction 1.5 times", {"friction_coulomb": 1.5}),
    ("every Coulomb friction halved", {"friction_coulomb": 0.5}),
    ("viscous friction 1.1 times", {"friction_viscous": 1.1}),
    ("no payload", {"payload_mass": 0.0}),
)
"""``--sensitivity``: the true parameters with one thing changed (each field by its factor)."""


def sensitivity(robot: str, truth: StandInTruth, report: dict, held_out: str) -> None:
    """Whether the held-out check sees a wrong model: the true parameters with one thing changed
    (:data:`CHANGES`), scored on the held-out run as :func:`oracle` scores the truth, per joint."""
    print("the true parameters with one change, on the held-out run: NRMSE per joint, static friction a set "
          "| each prediction a value")
    score = oracle(robot, report, held_out, None)
    for label, change in CHANGES:
        changed = dataclasses.replace(truth, **{key: getattr(truth, key) * factor for key, factor in change.items()})
        point, static = score(changed)
        print(f"{label:34s} {', '.join(f'{v:.2%}' for v in static)} | {', '.join(f'{v:.2%}' for v in point)}")


def write_truth(where: Path, robot: str, truth: StandInTruth) -> Path:
    """The true arm as a model (``--model``): the robot's URDF with the payload, the frictions and
    the motor inertias MuJoCo's model holds, written by ``pdsmc identify``'s own writers; the
    options file's path."""
    dynamics = ArmDynamics(arm_of(robot))
    values = truth_values(dynamics, truth)
    (where / "truth").mkdir(exist_ok=True)
    note = f"The MuJoCo stand-in's truth: {truth.summary}"
    (where / "truth" / URDF_NAME).write_text(corrected_urdf(dynamics, values, note=note))
    (where / "truth" / OPTIONS_NAME).write_text(options_text(identified_options(dynamics, values), note))
    return where / "truth" / OPTIONS_NAME


def feedback_table(robot: str, payload: float, seed: int, models: dict[str, str]) -> None:
    """Each model-based law on the stand-in with each model: the table of docs/how-to/identify.md."""
    print(f"fed back: the circle on the stand-in (--plant mujoco --realism bench --payload-mass {payload:g} --seed "
          f"{seed}, --smc-reading exact, each law's preset gains)")
    print("law    model            contour error mean (m)   RMS joint error (rad)   largest |torque| (N m)   seconds")
    for law in LAWS:
        for label, model in models.items():
            code, printed, seconds = run(["simulate", "--robot", robot, "--contour", "circle", "--controller", law,
                                          "--smc-reading", "exact", "--model", model, "--plant", "mujoco",
                                          "--realism", "bench", "--payload-mass", f"{payload:g}", "--seed",
                                          str(seed), "--json"])
            if code != 0:
                print(f"{law:6s} {label:16s} failed (exit {code}): {printed.strip()[-200:]}")
                continue
            metrics = yaml.safe_load(printed)
            rms = metrics.get("run_scores", {}).get("error_rms", float("nan"))
            print(f"{law:6s} {label:16s} {metrics['contour_mean']:22.4e} {rms:23.4e} "
                  f"{max(metrics['max_torque']):24.4g} {seconds:9.1f}")


def check(identified_dir: Path, robot: str, truth: StandInTruth, label: str, held_out_bag: str,
          held_out_window: str | None = None) -> bool:
    """Print the identified model against the truth; whether every target is met."""
    identified = yaml.safe_load((identified_dir / "identified.yaml").read_text())
    report = yaml.safe_load((identified_dir / "identification.yaml").read_text())
    payload_error = identified["payload_mass"] / truth.payload_mass - 1.0
    coulomb = np.asarray(identified["friction_coulomb"], dtype=float)
    viscous = np.asarray(identified["friction_viscous"], dtype=float)
    coulomb_error = coulomb / truth.friction_coulomb - 1.0
    viscous_error = viscous / truth.friction_viscous - 1.0
    held_out = np.array(list(report["nrmse"]["validation"].values()), dtype=float)
    moving = np.array(list(report["nrmse"]["validation_outside_dead_zone"].values()), dtype=float)
    static = np.array(list(report["nrmse"]["validation_static_friction_set"].values()), dtype=float)
    true_point, true_static = oracle(robot, report, held_out_bag, held_out_window)(truth)
    dynamics = ArmDynamics(arm_of(robot))
    standard = np.array([entry["value"] for entry in report["standard_parameters"]], dtype=float)
    consistent = bool(np.all(is_consistent(standard, dynamics)))
    print(f"--- {label}: {truth.summary}")
    print(f"payload mass {identified['payload_mass']:.4f} kg (true {truth.payload_mass:g}, {payload_error:+.2%}); com "
          f"{np.round(identified['payload_com'], 4).tolist()} m (true {np.round(truth.payload_com, 4).tolist()})")
    names = dynamics.layout.joint_names
    print("joint                  Coulomb true  identified  error    viscous true  identified  error    "
          "held-out NRMSE: point, outside the dead zone, static friction a set (URDF's) | true parameters: point, set")
    nominal_out = report["nrmse"].get("nominal_on_validation", {})
    for j, name in enumerate(names):
        print(f"{name:22s} {truth.friction_coulomb[j]:12.4g} {coulomb[j]:11.4g} {coulomb_error[j]:+7.2%} "
              f"{truth.friction_viscous[j]:13.4g} {viscous[j]:11.4g} {viscous_error[j]:+7.2%}    "
              f"{held_out[j]:.2%}, {moving[j]:.2%}, {static[j]:.2%}"
              + (f" ({nominal_out[name]:.1%})" if name in nominal_out else "")
              + f" | {true_point[j]:.2%}, {true_static[j]:.2%}")
    print(f"identified model physically consistent (every link's pseudo-inertia, payload, frictions): "
          f"{'yes' if consistent else 'NO'}")
    met = (abs(payload_error) <= TARGETS["payload"] and np.all(np.abs(coulomb_error) <= TARGETS["coulomb"])
           and np.all(np.abs(viscous_error) <= TARGETS["viscous"]) and np.all(static <= TARGETS["nrmse"])
           and consistent)
    print(f"verdict={'PASS' if met else 'FAIL'} payload_error={payload_error:+.4f} "
          f"worst_coulomb_error={np.max(np.abs(coulomb_error)):.4f} "
          f"worst_viscous_error={np.max(np.abs(viscous_error)):.4f} "
          f"worst_heldout_nrmse_static_friction_set={static.max():.4f} worst_heldout_nrmse_point={held_out.max():.4f} "
          f"worst_heldout_nrmse_outside_dead_zone={moving.max():.4f} "
          f"true_worst_heldout_nrmse_static_friction_set={true_static.max():.4f} "
          f"true_worst_heldout_nrmse_point={true_point.max():.4f} "
          f"consistent={'yes' if consistent else 'no'} condition={report['condition_number']:.4g}")
    return bool(met)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="ur5", choices=sorted(PAYLOADS))
    parser.add_argument("--payload", type=float, default=None, help="kg (default: 2 on the UR5, 0.2 on the serial 3R)")
    parser.add_argument("--out", default=None, help="keep the files here (default: a temporary directory)")
    parser.add_argument("--excitation", default=None, help="an earlier `pdsmc excite --out` directory to reuse")
    parser.add_argument("--starts", default="3")
    parser.add_argument("--iterations", default="40")
    parser.add_argument("--periods", type=float, default=4.0, help="periods of the training run (default 4)")
    parser.add_argument("--cutoff", default=None, help="the identification's filter cut-off (Hz; default its own)")
    parser.add_argument("--seed", type=int, default=0, help="the nuisances' seed")
    parser.add_argument("--omega-n", type=float, default=60.0,
                        help="computed torque's natural frequency in the excitation runs (rad/s, default 60)")
    parser.add_argument("--feedback", action="store_true", help="also the table of the model-based laws")
    parser.add_argument("--sensitivity", action="store_true",
                        help="also the true parameters with one thing changed, scored on the held-out run")
    parser.add_argument("--realtime", default=None, help="a bag recorded in real time to check as well")
    parser.add_argument("--realtime-held-out", default=None,
                        help="its held-out bag (default: the in-process held-out bag, the same arm)")
    parser.add_argument("--realtime-window", default=None, metavar="START:END",
                        help="identify's --window for the real-time bag (the goal's excitation: pdsmc analyze "
                        "gives the goal's start)")
    parser.add_argument("--realtime-held-out-window", default=None, metavar="START:END",
                        help="identify's --validate-window for the real-time held-out bag")
    options = parser.parse_args()
    robot = options.robot
    payload = PAYLOADS[robot] if options.payload is None else options.payload
    where = Path(options.out or tempfile.mkdtemp(prefix="bench-identification-stand-in-"))
    if where.exists() and options.out:
        shutil.rmtree(where)
    where.mkdir(parents=True, exist_ok=True)

    if options.excitation:
        excite_dir = Path(options.excitation)
    else:
        excite_dir = where / "excite"
        code, printed, excite_s = run(["excite", "--robot", robot, "--out", str(excite_dir), "--starts",
                                       options.starts, "--iterations", options.iterations])
        assert code == 0, printed
        print(printed, end="")
        print(f"excite: {excite_s:.1f} s")
    description = yaml.safe_load((excite_dir / "excitation.yaml").read_text())
    excitation = FourierExcitation(np.array(description["home"]), np.array(description["a"]),
                                   np.array(description["b"]), description["period_s"])
    print(f"excitation: period {excitation.period:g} s, condition number {description['condition_number']:.4g}")

    model = make_robot(resolve_robot(robot))
    rate = float(arm_of(robot).settings.get("control_rate", 1000.0))
    stand_in = StandIn(preset="bench", given={"payload_mass": payload}, seed=options.seed)
    began = time.perf_counter()
    truth = None
    for name, periods, start in (("train", options.periods, 0.0), ("held_out", 2.0, 0.37 * excitation.period)):
        sim, truth = excite_stand_in(robot, model, model, excitation, stand_in, periods=periods, rate=rate, start=start,
                                     gains={"omega_n": [options.omega_n] * model.n, "zeta": [1.0] * model.n})
        write_joint_states(where / name, model.joint_names, sim.t, sim.q, sim.qd, sim.tau)
        error = np.max(np.abs(sim.reference - sim.q))
        print(f"{name}: {periods:g} periods at {rate:g} Hz on the stand-in, largest tracking error {error:.3g} rad")
    assert truth is not None
    print(f"simulated and recorded in {time.perf_counter() - began:.1f} s")

    args = ["identify", str(where / "train"), "--robot", robot, "--out", str(where / "identified"), "--validate",
            str(where / "held_out")]
    if options.cutoff:
        args += ["--cutoff", options.cutoff]
    code, printed, identify_s = run(args)
    assert code == 0, printed
    print(printed, end="")
    print(f"identify: {identify_s:.2f} s")
    met = check(where / "identified", robot, truth, "in-process lockstep", str(where / "held_out"))
    if options.sensitivity:
        report = yaml.safe_load((where / "identified" / "identification.yaml").read_text())
        sensitivity(robot, truth, report, str(where / "held_out"))
    if options.feedback:
        models = {"URDF's": robot, "identified": str(where / "identified" / "identified.yaml"),
                  "true": str(write_truth(where, robot, truth))}
        feedback_table(robot, payload, options.seed, models)
    if options.realtime:
        args = ["identify", options.realtime, "--robot", robot, "--out", str(where / "identified_realtime"),
                "--validate", options.realtime_held_out or str(where / "held_out")]
        if options.realtime_window:
            args += ["--window", options.realtime_window]
        if options.realtime_held_out and options.realtime_held_out_window:
            args += ["--validate-window", options.realtime_held_out_window]
        if options.cutoff:
            args += ["--cutoff", options.cutoff]
        code, printed, identify_s = run(args)
        assert code == 0, printed
        print(printed, end="")
        met = check(where / "identified_realtime", robot, truth, "real time (run_experiment.sh --stand-in)",
                    options.realtime_held_out or str(where / "held_out"),
                    options.realtime_held_out_window if options.realtime_held_out else None) and met
    print(f"files in {where}")
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
