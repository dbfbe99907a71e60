"""A gain's way from ``-p kp:=`` to the torque, measured: the package files whose code holds the value.

A child process gives a controller's run a marker gain on the command line (``kp`` of one joint
:data:`MARK`), declares the run on a real rclpy node (:func:`declare_controller_run`, the
controller node's first step), builds the controller's core from the run it gives and asks it for
one torque, as the node does, with every compiled function of the package swapped for its Python
source (numba's ``py_func``: the law's formulas run as frames like any other; the torque is checked
equal to the compiled one's) under :func:`sys.setprofile`. Every call and return whose frame holds
the marker -- as a number, in an array, a sequence, a mapping, an rclpy ``Parameter`` or an object
of the package (a ``Gains``, a ``RunSpec``, a ``ControlLaw``), reached in at most :data:`DEPTH`
steps -- names a file on the gain's way. The files are printed with their functions
(``pytest -s``).

The list is the architecture page's (its section on a gain's way, one file per list item): the
test fails if a file outside it holds the value, or if a file of it no longer does. The page also
lists the controller node (:data:`CALLER`), whose lines the child plays itself.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap

import pytest
from conftest import ROOT, next_domain

pytest.importorskip("rclpy")

MARK = 123.456
"""The marker gain (N m/rad): ``kp`` of the arm's second joint, a value no preset, default or
intermediate result holds (the nominal scenario scales no gain)."""
DEPTH = 6
"""How many containers deep a frame's locals are searched (a RunSpec's gains: spec -> Gains -> rows
-> (name, values) -> values -> the float)."""
PAGE = ROOT / "docs" / "explanation" / "architecture.md"
SECTION = "## A gain's way from the command line to the torque"
CALLER = "pdsmc_ros/controller/node.py"
"""The node: it calls :func:`declare_controller_run` and hands the run to its core (the child does both)."""


def documented() -> set[str]:
    """The files the architecture page lists on a gain's way: every list item of its section that
    opens with a package file."""
    text = PAGE.read_text()
    assert SECTION in text, f"{PAGE.name} has no section {SECTION!r}"
    section = text.split(SECTION, 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"^(?:\d+\.|-) `(pdsmc_ros/[\w/]+\.py)`", section, flags=re.MULTILINE))


CHILD = textwrap.dedent("""
    import json, sys
    import numpy as np
    import rclpy
    from numba.core.dispatcher import Dispatcher
    from pdsmc_ros.controller.commanding import TorqueGuard
    from pdsmc_ros.controller.core import ControllerCore
    from pdsmc_ros.controller.joints import JointSelector
    from pdsmc_ros.controller.limits import JointLimits
    from pdsmc_ros.controller.parameters import declare_controller_run

    MARK, DEPTH, ROOT = float(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    PACKAGE = ROOT + "/pdsmc_ros/"

    def holds(obj, depth, seen):
        if isinstance(obj, (float, np.floating)):
            return float(obj) == MARK
        if isinstance(obj, (str, bytes, int, type)) or obj is None or depth == 0 or id(obj) in seen:
            return False
        seen.add(id(obj))
        if isinstance(obj, np.ndarray):
            return obj.dtype.kind == "f" and bool(np.any(obj == MARK))
        if isinstance(obj, (list, tuple, set, frozenset)):
            return any(holds(x, depth - 1, seen) for x in obj)
        if isinstance(obj, dict):
            return any(holds(x, depth - 1, seen) for x in obj.values())
        if isinstance(obj, rclpy.parameter.Parameter):
            return holds(obj.value, depth - 1, seen)
        if type(obj).__module__.startswith("pdsmc_ros."):
            names = getattr(type(obj), "__slots__", ()) or ()
            fields = [getattr(obj, n, None) for n in names]
            fields += list(getattr(obj, "__dict__", {}).values())
            return any(holds(x, depth - 1, seen) for x in fields)
        return False

    found = {}

    def profile(frame, event, arg):
        if event not in ("call", "return"):
            return
        path = frame.f_code.co_filename
        if not path.startswith(PACKAGE):
            return
        values = list(frame.f_locals.values()) + ([arg] if event == "return" else [])
        if any(holds(v, DEPTH, set()) for v in values):
            found.setdefault(path[len(ROOT) + 1:], set()).add(frame.f_code.co_qualname)

    def torque():
        node = rclpy.create_node("controller")
        run = declare_controller_run(node)
        spec = run.spec
        robot = spec.robot_model()
        names = tuple(robot.joint_names)
        core = ControllerCore(spec, JointSelector(names), run.joint_map, JointLimits.of(robot, names),
                              TorqueGuard(None), 0.1, True, lambda why: None)
        core.configure()
        start = core.reference.sample([0.0])
        zeros = np.zeros(len(names))
        tau = core.command(0.0, start.q[0] + 0.01, zeros, (start.q[0], zeros, zeros))
        node.destroy_node()
        assert spec.gains["kp"][1] == MARK and tau is not None
        return tau

    rclpy.init(args=["controller", "--ros-args", "-p", "robot:=serial_3r", "-p", "type:=pdsmc",
                     "-p", "contour:=circle", "-p", f"kp:=[400.0, {MARK!r}, 1900.0]"])
    compiled = torque()  # every module the way imports, imported
    for module in [m for name, m in sys.modules.items() if name.startswith("pdsmc_ros")]:
        for name, value in list(vars(module).items()):
            if isinstance(value, Dispatcher):
                setattr(module, name, value.py_func)  # the compiled code as Python: its frames seen
    sys.setprofile(profile)
    tau = torque()
    sys.setprofile(None)
    assert np.array_equal(tau, compiled), (tau, compiled)
    rclpy.shutdown()
    print(json.dumps({k: sorted(v) for k, v in sorted(found.items())}))
""")


@pytest.mark.timeout(300)
def test_a_gain_crosses_the_files_the_architecture_page_lists() -> None:
    env = {**os.environ, "ROS_DOMAIN_ID": str(next_domain()),
           "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    done = subprocess.run([sys.executable, "-c", CHILD, repr(MARK), str(DEPTH), str(ROOT)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=280, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"{len(found)} files hold kp = {MARK} (and {CALLER}, whose part the test plays):")
    for path, functions in found.items():
        print(f"  {path}: {', '.join(functions)}")
    listed = documented()
    assert CALLER in listed, f"{PAGE.name} does not list {CALLER}, which hands the run to the core"
    assert set(found) - listed == set(), f"a file entered the gain's way: list it in {PAGE.name} or take it out"
    assert listed - {CALLER} - set(found) == set(), f"a file left the gain's way: take it out of {PAGE.name}"


def test_the_page_lists_what_the_measure_can_see() -> None:
    """The section is found and read: a parse that found nothing would let every file in."""
    listed = documented()
    assert {"pdsmc_ros/controller/parameters.py", "pdsmc_ros/control/laws.py", CALLER} <= listed
    assert all((ROOT / path).is_file() for path in listed), sorted(p for p in listed if not (ROOT / p).is_file())
