"""Every compiled function of the package names its numba runtime option (pdsmc_ros.kernels.options).

A function that names none is compiled with the option of the first compiled caller that calls it:
under the closed loop (compiled without numba's runtime) a law written in Python would hand its
callback the whole array a view was taken from instead of the view. These tests hold every kernel
to an explicit choice, and run the Python forms after the loop has compiled first.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys

from conftest import ROOT
from numba.core.registry import CPUDispatcher

from pdsmc_ros.kernels import cache as kernel_cache
from pdsmc_ros.kernels import options as kernel_options


def _module_name(path) -> str:  # noqa: ANN001
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def _dispatchers(value: object) -> list[CPUDispatcher]:
    if isinstance(value, CPUDispatcher):
        return [value]
    if isinstance(value, dict):
        return [v for v in value.values() if isinstance(v, CPUDispatcher)]
    return []


def test_every_kernel_compiled_on_its_own_names_its_runtime_option() -> None:
    unnamed = []
    count = 0
    for path in kernel_cache.kernel_sources():
        module = importlib.import_module(_module_name(path))
        for name, value in vars(module).items():
            for dispatcher in _dispatchers(value):
                if dispatcher.py_func.__module__ != module.__name__:
                    continue  # imported from where it is defined, checked there
                if dispatcher.targetoptions.get("inline") == "always":
                    continue  # compiled as part of its caller, with the caller's options
                count += 1
                if "_nrt" not in dispatcher.targetoptions:
                    unnamed.append(f"{module.__name__}.{name}")
    assert count >= 60, count  # the closed loops, the RK4 steps, the laws and robots' kernels
    assert unnamed == [], f"compiled without ALLOCATION_FREE or WITH_RUNTIME: {unnamed}"


def test_the_hot_path_is_compiled_without_the_runtime_and_the_python_bridges_with_it() -> None:
    from pdsmc_ros.control import python_form as law_bridge
    from pdsmc_ros.control.law import compiled_torque
    from pdsmc_ros.robots import python_form as robot_bridge
    from pdsmc_ros.sim import loop, rk4

    for kernel in (*loop._CLOSED_LOOPS.values(), *rk4._STEPS.values(), rk4.rk4_advance, compiled_torque):
        assert kernel.targetoptions["_nrt"] is kernel_options.ALLOCATION_FREE["_nrt"] is False
    for kernel in (law_bridge.torque, robot_bridge.accelerations, robot_bridge.outputs):
        assert kernel.targetoptions["_nrt"] is True


SCRIPT = """
import sys
import numpy as np
sys.path.insert(0, "test/control")
from law_readings import pdsmc_reading
from pdsmc_ros.control import ControlLaw, LawEntry, register_law
from pdsmc_ros.control.laws import pdsmc_linear_gains
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate

base = make_run("serial_3r", "circle", "pdsmc")
compiled = simulate(base)  # the compiled loop first: the Python law's bridge compiles inside its call tree
register_law(LawEntry("pdsmc_python", "PD-SMC (Python)", ("kp", "kd", "ks", "lam", "phi"), pdsmc_reading,
                      linear_gains=pdsmc_linear_gains))
python_run = simulate(make_run("serial_3r", "circle", "pdsmc_python", gains=base.gains))
assert ControlLaw.from_spec(python_run.spec).code >= 1000
print(np.max(np.abs(python_run.samples.q - compiled.samples.q)),
      np.max(np.abs(python_run.samples.tau - compiled.samples.tau)))
"""


def test_a_law_written_in_python_after_the_compiled_loop_gets_the_views_it_is_given(tmp_path) -> None:  # noqa: ANN001
    """The loop compiled first, in a fresh process with an empty kernel cache: the Python law's bridge,
    compiled inside the loop's call tree, still hands the law each joint vector, not the array of
    samples it is a row of (which is what it got when the bridge took the loop's option)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    proc = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    q_error, tau_error = (float(x) for x in proc.stdout.split())
    assert q_error < 1e-9
    assert tau_error < 1e-6
