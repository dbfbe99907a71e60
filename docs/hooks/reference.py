"""MkDocs hook: the reference pages generated from the code at every build.

* ``reference/cli.md``: every ``pdsmc`` subcommand and option, rendered from the argument
  parser itself (:func:`pdsmc_ros.cli.build_parser`): usage, description, each option's
  flags, value, default, choices and help.
* ``reference/nodes.md``: every node's parameters (name, default, range or allowed values,
  description), publishers, subscriptions (with QoS), services and actions, from
  :func:`node_interfaces`: the nodes built as their executables build them, their
  declarations noted (``docs/hooks/node_interfaces.py``).

Nothing here is written by hand, so the pages cannot drift from the code; a page that cannot be
generated fails the build.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
CLI_PAGE = "reference/cli.md"
NODES_PAGE = "reference/nodes.md"
MODES = ("lockstep", "realtime")


# --------------------------------------------------------------------------- #
# pdsmc: from the argument parser
# --------------------------------------------------------------------------- #
def _cell(text: Any) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _code(text: Any) -> str:
    text = str(text)
    tick = "``" if "`" in text else "`"
    pad = " " if tick == "``" else ""
    return f"{tick}{pad}{text}{pad}{tick}".replace("|", "\\|")


def _subparsers(parser: argparse.ArgumentParser) -> tuple[argparse._SubParsersAction, dict[str, str]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            return action, helps
    raise RuntimeError("pdsmc's parser has no subcommands")


def _option_row(action: argparse.Action) -> str:
    if action.option_strings:
        flags = ", ".join(_code(f) for f in action.option_strings)
        if action.nargs != 0:
            metavar = action.metavar or action.dest.upper()
            flags += f" {_code(metavar if isinstance(metavar, str) else ' '.join(metavar))}"
    else:
        flags = _code(action.metavar or action.dest)
    default = action.default
    if action.nargs == 0 or default in (None, argparse.SUPPRESS) or action.required:
        default_text = "required" if action.required or not action.option_strings else ""
    else:
        default_text = _code(default)
    choices = ", ".join(_code(c) for c in action.choices) if action.choices else ""
    help_text = (action.help or "").replace("%(default)s", str(default)).replace("%%", "%")
    return f"| {flags} | {default_text} | {choices} | {_cell(help_text)} |"


def cli_reference() -> str:
    """Markdown of every ``pdsmc`` subcommand, read from :func:`pdsmc_ros.cli.build_parser`."""
    from pdsmc_ros.cli import build_parser

    parser = build_parser()
    sub, helps = _subparsers(parser)
    lines = [
        "# `pdsmc` command reference",
        "",
        ("Generated at build time from the command's argument parser "
        "(`pdsmc_ros.cli.build_parser`): what is here is what `pdsmc COMMAND --help` accepts. "
        "Every error is one line on stderr naming the input and what is allowed, exit status 2 "
        "for bad input and 1 for a failure while running. How the options combine in practice: "
        "[common options](cli-options.md)."),
        "",
        "| command | what it does |",
        "| --- | --- |",
    ]
    lines += [f"| [`{name}`](#pdsmc-{name}) | {_cell(helps.get(name, ''))} |" for name in sub.choices]
    for name, command in sub.choices.items():
        usage = command.format_usage().strip().removeprefix("usage: ")
        lines += ["", f"## pdsmc {name} {{ #pdsmc-{name} }}", "", _cell(helps.get(name, "")), ""]
        lines += ["```text", usage, "```", ""]
        if command.description:
            lines += [command.description.strip(), ""]
        lines += ["| option | default | choices | description |", "| --- | --- | --- | --- |"]
        lines += [_option_row(a) for a in command._actions if not isinstance(a, argparse._HelpAction)]
        if command.epilog:
            lines += ["", command.epilog.strip()]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- #
# the nodes: from their declarations
# --------------------------------------------------------------------------- #
def node_interfaces() -> dict[str, dict[str, Any]]:
    """Every node's parameters, topics, services and actions, per mode: the one source of the
    node reference. Today the nodes are built and their declarations noted
    (``node_interfaces.py``, in a process of its own: rclpy and the nodes stay out of MkDocs').
    A declared parameter catalog would replace this function's body alone."""
    env = dict(os.environ)
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)  # the venv is the ament prefix
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"  # nothing to discover: the nodes are only built
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    found = {}
    for mode in MODES:
        done = subprocess.run([sys.executable, str(HERE / "node_interfaces.py"), mode], env=env, cwd=ROOT,
                              capture_output=True, text=True, timeout=600, check=False)
        if done.returncode != 0:
            tail = "\n".join(done.stderr.strip().splitlines()[-5:])
            raise RuntimeError(f"node reference: building the nodes in {mode} failed:\n{tail}")
        found[mode] = json.loads(done.stdout)
    return found


def _allowed(info: dict[str, Any]) -> str:
    parts = [f"a {info['type'].replace('_', ' ')}"] if "type" in info else []
    if "range" in info:
        lo, hi = info["range"]
        parts.append(f"[{lo:g}, {hi:g}]" if isinstance(lo, (int, float)) else f"[{lo}, {hi}]")
    if info.get("constraints"):
        parts.append(info["constraints"])
    return _cell("; ".join(parts))


def _default(value: Any) -> str:
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return _code(str(value).lower())
    if value == "":
        return '`""`'
    return _code(json.dumps(value) if isinstance(value, (list, str)) and not isinstance(value, str) else value)


RCLPY_PARAMETERS = ("use_sim_time", "start_type_description_service")


def parameter_table(found: dict[str, dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Every node's parameter rows (``name``, ``default``, ``realtime_default``, ``allowed``,
    ``description``) by fully qualified node name, in declaration order: the one source of the
    parameter tables. Today they are the declarations the nodes made when built
    (:func:`node_interfaces`); a declared catalog of the nodes' parameters would be read here
    instead, the rest of the page unchanged."""
    rows: dict[str, list[dict[str, Any]]] = {}
    for name, info in found["lockstep"].items():
        realtime = found["realtime"].get(name, {}).get("parameters", {})
        rows[name] = [{"name": pname, "default": p["default"],
                       "realtime_default": realtime.get(pname, {}).get("default", p["default"]),
                       "allowed": _allowed(p), "description": p.get("description", "")}
                      for pname, p in info["parameters"].items() if pname not in RCLPY_PARAMETERS]
    return rows


def nodes_reference(found: dict[str, dict[str, Any]]) -> str:
    """Markdown of every node: what :func:`node_interfaces` found."""
    lockstep, realtime = found["lockstep"], found["realtime"]
    parameters = parameter_table(found)
    executables: dict[str, list[str]] = {}
    for name, info in lockstep.items():  # in the order the executables built them
        executables.setdefault(info["executable"], []).append(name)
    lines = [
        "# Node reference",
        "",
        ("Generated at build time from the nodes themselves: each executable's nodes are built as "
        "`ros2 run pdsmc_ros EXECUTABLE` builds them, once in `mode:=lockstep` (the serial arm) and "
        "once in `mode:=realtime` (the five-bar), and every parameter declaration (name, default, "
        "range, allowed values, description), publisher, subscription, service and action server "
        "they make is listed. A topic or service one mode alone opens is marked. rclpy's own "
        "parameters (`use_sim_time`, `start_type_description_service`) and services (parameter "
        "services, type description) are on every node and left out. How the topics are used: "
        "[nodes and topics](nodes-topics.md)."),
        "",
        "| executable | nodes |",
        "| --- | --- |",
    ]
    lines += [f"| [`{exe}`](#{exe.replace('_', '-')}) | {', '.join(_code(n) for n in names)} |"
              for exe, names in executables.items()]
    for exe, names in executables.items():
        lines += ["", f"## {exe} {{ #{exe.replace('_', '-')} }}", ""]
        for name in names:
            info, rt = lockstep[name], realtime.get(name, {})
            lines += [f"### `{name}`", ""]
            rows = parameters.get(name, [])
            if rows:
                lines += ["| parameter | default | allowed | description |", "| --- | --- | --- | --- |"]
                for row in rows:
                    default = _default(row["default"])
                    if row["realtime_default"] != row["default"]:
                        default += f" (real time: {_default(row['realtime_default'])})"
                    lines.append(f"| `{row['name']}` | {default} | {row['allowed']} | {_cell(row['description'])} |")
                lines.append("")
            for kind, title in (("publishers", "publishes"), ("subscriptions", "subscribes")):
                seen: dict[tuple[str, str], str] = {}
                for mode, source in (("lockstep", info), ("realtime", rt)):
                    for topic, msg_type, qos in source.get(kind, []):
                        key = (topic, msg_type)
                        if key in seen:
                            if seen[key] != mode and not seen[key].startswith("both"):
                                seen[key] = "both" if seen[key].split(":")[1] == qos else f"both:{qos}"
                        else:
                            seen[key] = f"{mode}:{qos}"
                if not seen:
                    continue
                lines += [f"| {title} | type | QoS | modes |", "| --- | --- | --- | --- |"]
                for (topic, msg_type), note in seen.items():
                    mode, _, qos = note.partition(":")
                    qos_of = {m: q for m, s in (("lockstep", info), ("realtime", rt))
                              for t, ty, q in s.get(kind, []) if (t, ty) == (topic, msg_type)}
                    qos_text = (qos_of.get("lockstep", "") if len(set(qos_of.values())) == 1 else
                                "; ".join(f"{m}: {q}" for m, q in qos_of.items()))
                    modes = "both" if len(qos_of) == 2 else f"{mode} only"
                    lines.append(f"| `{topic}` | `{msg_type}` | {qos_text} | {modes} |")
                lines.append("")
            services = info.get("services", []) or rt.get("services", [])
            if services:
                lines += ["| service | type |", "| --- | --- |"]
                lines += [f"| `{s}` | `{t}` |" for s, t in services]
                lines.append("")
            actions = info.get("actions", []) or rt.get("actions", [])
            if actions:
                lines += ["| action server | type |", "| --- | --- |"]
                lines += [f"| `{a}` | `{t}` |" for a, t in actions]
                lines.append("")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- #
# the hook
# --------------------------------------------------------------------------- #
def on_files(files: Files, config: Any) -> Files:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))  # the tree's code is what the pages describe
    files.append(File.generated(config, CLI_PAGE, content=cli_reference()))
    files.append(File.generated(config, NODES_PAGE, content=nodes_reference(node_interfaces())))
    return files
