"""``pdsmc identify``."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..arguments import positive_float
from ..errors import ConfigError


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``identify`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser(
        "identify", help="identify the arm's dynamics from a bag's joint states and efforts (an excitation run): "
        "base parameters, friction, motor inertia, payload; writes a corrected URDF and its options file")
    p.add_argument("bag", help="the run's bag (a directory of .mcap files or one file) with /joint_states efforts")
    p.add_argument("--robot", required=True,
                   help="the arm: an arm of example-robot-data (ur5, ...), a .urdf file, or serial_3r; its URDF and "
                   "options are the model identification starts from")
    p.add_argument("--out", required=True,
                   help="directory for identified.urdf, identified.yaml (its options), identification.yaml and "
                   "torques.png (created; these files are replaced)")
    p.add_argument("--validate", default=None, metavar="BAG",
                   help="a second, held-out run: the identified model's effort error on it (NRMSE per joint)")
    p.add_argument("--cutoff", type=positive_float, default=None, metavar="HZ",
                   help="the filter's cut-off (default: 5 x the motion's bandwidth, from its spectrum)")
    p.add_argument("--window", default=None, metavar="START:END",
                   help="fit only the states from START to END s after the bag's first state (a recording holds "
                   "more than the excitation: the arm at rest, braked, the goal's lead)")
    p.add_argument("--validate-window", default=None, metavar="START:END",
                   help="the same for the held-out bag")
    p.add_argument("--topic", default="/joint_states", help="the JointState topic (default /joint_states)")
    commands["identify"] = run


def run(args: argparse.Namespace) -> int:
    import yaml

    from ..identification.arm_files import (
        OPTIONS_NAME,
        URDF_NAME,
        corrected_urdf,
        identified_options,
        options_text,
    )
    from ..identification.identify import identify, validate
    from ..identification.model import ArmDynamics, arm_of
    from ..identification.recording import parse_window, read_joint_states
    from ..identification.report import report_data, report_lines, torque_figure

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a file: give a directory")
    window = parse_window(args.window, "--window") if args.window else None
    held_out_window = parse_window(args.validate_window, "--validate-window") if args.validate_window else None
    dynamics = ArmDynamics(arm_of(args.robot))
    recording = read_joint_states(args.bag, dynamics.layout.joint_names, topic=args.topic)
    if window:
        recording = recording.window(*window, f"bag {args.bag!r}")
    held_out = None
    if args.validate:
        held_out = read_joint_states(args.validate, dynamics.layout.joint_names, topic=args.topic)
        if held_out_window:
            held_out = held_out.window(*held_out_window, f"bag {args.validate!r}")
    result = identify(dynamics, recording.t, recording.q, recording.tau, cutoff=args.cutoff)
    validation = None
    if held_out is not None:
        fitted, nominal, moving, static = validate(result, held_out.t, held_out.q, held_out.tau)
        validation = (str(args.validate), fitted, nominal, moving, static)
    data = report_data(result, robot=args.robot, bag=str(args.bag), validation=validation)
    source = f"Identified from {args.bag} (pdsmc identify), starting from {args.robot}."
    urdf = corrected_urdf(dynamics, result.fit.values, note=source)
    options = options_text(identified_options(dynamics, result.fit.values),
                           f"{source}\nThe options of {URDF_NAME} beside this file: --robot {out / URDF_NAME}, "
                           f"or --model {out / OPTIONS_NAME}.")
    try:  # everything computed: now write
        out.mkdir(parents=True, exist_ok=True)
        (out / URDF_NAME).write_text(urdf)
        (out / OPTIONS_NAME).write_text(options)
        (out / "identification.yaml").write_text(yaml.safe_dump(data, sort_keys=False, width=120))
        torque_figure(result, out / "torques.png")
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot write it ({exc.strerror})") from None
    print(f"{args.bag}: {len(recording.t)} joint states over {recording.duration:.3g} s")
    for line in report_lines(data):
        print(line)
    print("seconds: " + ", ".join(f"{k} {v:.3g}" for k, v in result.seconds.items()))
    print(f"wrote {out / URDF_NAME}, {out / OPTIONS_NAME}, {out / 'identification.yaml'}, {out / 'torques.png'}")
    return 0
