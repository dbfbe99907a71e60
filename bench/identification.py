"""Benchmark: the identification path on a simulated UR5, each step timed, the result against the truth.

``python bench/identification.py [--out DIR] [--starts N] [--iterations N]``:

1. ``pdsmc excite --robot ur5`` (the default search: 3 starts of 40 L-BFGS iterations): the
   condition number reached and the seconds it took;
2. the excitation run on a "true" UR5 -- its URDF with a 2 kg tool at [0, 0.02, 0.06] m in
   tool0, motor inertias and viscous friction in its options -- in the project's simulator
   under computed torque with the URDF's model (the in-process path: no Coulomb friction, no
   encoder, no delay), written to a training bag (4 periods) and a held-out one (2 periods,
   another phase), as the recorder would;
3. ``pdsmc identify`` on them: payload, motor inertias and frictions against the truth, the
   held-out NRMSE per joint, and the seconds of each step;
4. computed torque on the true arm with the URDF's model and with the identified one (``--model``).

The last line: ``condition=C excite_s=S identify_s=S payload_error=E worst_viscous_error=E
worst_armature_error=E worst_heldout_nrmse=E``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pdsmc_ros.cli import main as pdsmc  # noqa: E402
from pdsmc_ros.identification.excitation import FourierExcitation  # noqa: E402
from pdsmc_ros.identification.simulated import simulate_excitation, write_joint_states  # noqa: E402
from pdsmc_ros.robots.catalog import example_robot_data_dir, resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402

TRUTH = {"payload_mass": 2.0, "payload_com": [0.0, 0.02, 0.06], "armature": [0.4, 0.4, 0.3, 0.05, 0.05, 0.05],
         "friction_viscous": [2.0, 3.0, 1.5, 0.4, 0.35, 0.25]}


def run(args: list[str]) -> tuple[int, str, float]:
    out = io.StringIO()
    began = time.perf_counter()
    with contextlib.redirect_stdout(out):
        code = pdsmc(args)
    return code, out.getvalue(), time.perf_counter() - began


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="keep the files here (default: a temporary directory)")
    parser.add_argument("--starts", default="3")
    parser.add_argument("--iterations", default="40")
    options = parser.parse_args()
    where = Path(options.out or tempfile.mkdtemp(prefix="bench-identification-"))
    if where.exists() and options.out:
        shutil.rmtree(where)
    where.mkdir(parents=True, exist_ok=True)

    code, printed, excite_s = run(["excite", "--robot", "ur5", "--out", str(where / "excite"),
                                   "--starts", options.starts, "--iterations", options.iterations])
    assert code == 0, printed
    print(printed, end="")
    description = yaml.safe_load((where / "excite" / "excitation.yaml").read_text())
    condition = description["condition_number"]
    excitation = FourierExcitation(np.array(description["home"]), np.array(description["a"]),
                                   np.array(description["b"]), description["period_s"])

    shutil.copy(example_robot_data_dir() / "ur_description/urdf/ur5_robot.urdf", where / "truth.urdf")
    arm = yaml.safe_load((ROOT / "config" / "urdf_arms.yaml").read_text())["ur5"]
    arm.pop("urdf")
    (where / "truth.yaml").write_text(yaml.safe_dump({**arm, **TRUTH}))
    plant = make_robot(resolve_robot(str(where / "truth.urdf")))
    model = make_robot(resolve_robot("ur5"))
    began = time.perf_counter()
    for name, periods, start in (("train", 4, 0.0), ("held_out", 2, 0.37 * excitation.period)):
        sim = simulate_excitation(plant, model, excitation, periods=periods, start=start)
        write_joint_states(where / name, plant.joint_names, sim.t, sim.q, sim.qd, sim.tau)
    simulate_s = time.perf_counter() - began
    print(f"simulated and recorded 6 periods at 1 kHz in {simulate_s:.1f} s")

    code, printed, identify_s = run(["identify", str(where / "train"), "--robot", "ur5", "--out",
                                     str(where / "identified"), "--validate", str(where / "held_out")])
    assert code == 0, printed
    print(printed, end="")
    identified = yaml.safe_load((where / "identified" / "identified.yaml").read_text())
    report = yaml.safe_load((where / "identified" / "identification.yaml").read_text())
    payload_error = identified["payload_mass"] / TRUTH["payload_mass"] - 1.0
    viscous = np.array(identified["friction_viscous"]) / TRUTH["friction_viscous"] - 1.0
    armature = np.array(identified["armature"]) / TRUTH["armature"] - 1.0
    held_out = max(report["nrmse"]["validation"].values())
    print(f"payload {identified['payload_mass']:.4f} kg (true 2, {payload_error:+.2%}), com "
          f"{np.round(identified['payload_com'], 4).tolist()} (true {TRUTH['payload_com']})")
    print("viscous friction error per joint: " + " ".join(f"{v:+.2%}" for v in viscous))
    print("motor inertia error per joint:    " + " ".join(f"{v:+.2%}" for v in armature))

    for label, chosen in (("URDF model", "ur5"), ("identified model", str(where / "identified" / "identified.yaml")),
                          ("true model", str(where / "truth.urdf"))):
        code, printed, _ = run(["simulate", "--robot", str(where / "truth.urdf"), "--contour", "circle",
                                "--controller", "ctc", "--gain", "omega_n=30", "--gain", "zeta=1", "--smc-reading",
                                "exact", "--model", chosen, "--json"])
        assert code == 0, printed
        print(f"computed torque on the true arm, circle, {label:16s}: contour error mean "
              f"{yaml.safe_load(printed)['contour_mean']:.3e} m")
    print(f"files in {where}")
    print(f"condition={condition:.4g} excite_s={excite_s:.1f} identify_s={identify_s:.2f} "
          f"payload_error={payload_error:+.4f} worst_viscous_error={np.max(np.abs(viscous)):.4f} "
          f"worst_armature_error={np.max(np.abs(armature)):.4f} worst_heldout_nrmse={held_out:.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
