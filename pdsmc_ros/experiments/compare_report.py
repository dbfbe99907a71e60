"""The report of ``pdsmc compare``: ``compare.md`` (and a self-contained ``compare.html``), its
figures and its data, written only once everything has run.

One list of blocks (headings, paragraphs, tables, figures) is rendered as Markdown (figures
linked, the PNGs beside it) or as HTML (figures embedded as base64 ``data:`` URIs, so the file
stands alone). Nothing here computes a statistic: it lays out what :mod:`.compare` and
:mod:`.compare_mc` produced.
"""

from __future__ import annotations

import base64
import csv
import html
import json
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..metrics.statistics import Samples
from .bootstrap import LEVEL, RESAMPLES, SEED
from .compare import DIVERGED, Column, LawRow, LawSpec, best_marks, cell, setup_description
from .compare_mc import interval_rows

FORMATS = ("md", "html")


@dataclass
class Report:
    """Blocks in order: ``(kind, ...)`` with kind ``h1``, ``h2``, ``p``, ``table`` (head, rows)
    or ``img`` (file name, caption). A cell ``**x**`` is the best of its column."""

    blocks: list[tuple[Any, ...]] = field(default_factory=list)

    def add(self, kind: str, *content: Any) -> None:
        self.blocks.append((kind, *content))


def _markdown_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    def line(cells: Sequence[str]) -> str:  # a | inside a cell (|e1|) would end it
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return "\n".join([line(head), "|" + "---|" * len(head), *map(line, rows)]) + "\n"


MARKDOWN: dict[str, Callable[..., str]] = {
    "h1": lambda text: f"# {text}\n", "h2": lambda text: f"## {text}\n", "p": lambda text: f"{text}\n",
    "table": _markdown_table, "img": lambda name, caption: f"![{caption}]({name})\n"}
"""How each kind of block is written in Markdown."""


def to_markdown(report: Report) -> str:
    return "\n".join(MARKDOWN[kind](*content) for kind, *content in report.blocks)


def _inline_html(text: str) -> str:
    return re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", re.sub(r"`(.+?)`", r"<code>\1</code>", html.escape(text)))


def _html_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    return ("<table><tr>" + "".join(f"<th>{_inline_html(h)}</th>" for h in head) + "</tr>"
            + "".join("<tr>" + "".join(f"<td>{_inline_html(c)}</td>" for c in row) + "</tr>" for row in rows)
            + "</table>")


def to_html(report: Report, folder: Path) -> str:
    """The report as one HTML page, each figure of ``folder`` embedded."""
    def figure(name: str, caption: str) -> str:
        data = base64.b64encode((folder / name).read_bytes()).decode("ascii")
        return (f'<figure><img src="data:image/png;base64,{data}" alt="{html.escape(caption)}">'
                f"<figcaption>{html.escape(caption)}</figcaption></figure>")

    kinds: dict[str, Callable[..., str]] = {
        "h1": lambda text: f"<h1>{_inline_html(text)}</h1>", "h2": lambda text: f"<h2>{_inline_html(text)}</h2>",
        "p": lambda text: f"<p>{_inline_html(text)}</p>", "table": _html_table, "img": figure}
    body = [kinds[kind](*content) for kind, *content in report.blocks]
    style = ("body{font-family:sans-serif;max-width:75em;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:.25em .5em;"
             "text-align:right}td:first-child,th:first-child{text-align:left}img{max-width:100%}")
    title = next((c[0] for k, *c in report.blocks if k == "h1"), "pdsmc compare")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def table_rows(rows: Sequence[LawRow], cols: Sequence[Column]) -> list[list[str]]:
    """The comparison table's cells, the best of each column in bold, a diverged row without numbers."""
    best = best_marks(rows, cols)
    out = []
    for r in rows:
        if r.values is None:
            out.append([r.label, f"**{DIVERGED}** ({r.diverged})", *("-" for _ in cols[1:])])
        else:
            out.append([r.label, *(f"**{cell(r.values[c.key], c)}**" if r.law in best.get(c.key, ())
                                   else cell(r.values[c.key], c) for c in cols)])
    return out


def build_report(entries: Sequence[LawSpec], rows: Sequence[LawRow], cols: Sequence[Column],
                 figures: Sequence[Path], montecarlo: Mapping[str, Any] | None) -> Report:
    """The report's blocks: set-up, gains, the table, the figures, the Monte Carlo's intervals."""
    setup = setup_description(entries)
    report = Report()
    report.add("h1", f"Controller comparison: {setup['robot']} / {setup['contour']}")
    report.add("p", f"`pdsmc compare`: {', '.join(r.label for r in rows)} on the same reference, one run each.")
    report.add("h2", "Set-up")
    report.add("table", ["", ""], [
        ["robot", str(setup["robot"])], ["contour", f"{setup['contour']} ({setup['duration_s']:g} s)"],
        ["scenario", setup["scenario"] + (f" (payload {setup['payload_kg']:g} kg)" if setup["payload_kg"] else "")],
        ["control rate", f"{setup['control_rate_hz']:g} Hz"],
        ["statistics and scores at", f"{setup['sample_rate_hz']:g} Hz (docs/SCORES.md)"],
        ["contour error bound", f"{setup['contour_bound_m']:g} m"],
        ["torque clamped to the effort limits", "yes" if setup["enforce_limits"] else "no"]])
    report.add("h2", "Gains")
    report.add("table", ["law", "gains", "from", "equation"], [
        [e["label"], "; ".join(f"{k} = {', '.join(f'{x:g}' for x in v)}" for k, v in e["gains"].items()),
         e["source"], e["equation"] or "-"] for e in setup["laws"]])
    report.add("h2", "Table")
    report.add("p", "Lower is better in every column; the best of each is in **bold**. Contour error and "
               "each joint's mean |e| as the thesis's tables; the scores of docs/SCORES.md (HF share: "
               "the torque's power above 50 Hz); peak |tau| over the joints.")
    report.add("table", ["law", *(f"{c.label} ({c.unit})" for c in cols)], table_rows(rows, cols))
    if figures:
        report.add("h2", "Figures")
        for path in figures:
            report.add("img", path.name, path.stem.replace("_", " "))
    if montecarlo is not None:
        add_montecarlo(report, montecarlo, rows, cols)
    return report


def add_montecarlo(report: Report, mc: Mapping[str, Any], rows: Sequence[LawRow], cols: Sequence[Column]) -> None:
    """The Monte Carlo section: the spreads, the runs, a row per column with each law's mean and interval."""
    summary = mc["summary"]
    report.add("h2", f"Monte Carlo: {mc['runs']} drawn plants")
    spreads = ", ".join(f"{k} {v}" for k, v in mc["uncertainty"].items())
    report.add("p", f"Plants drawn around the nominal one from {mc['uncertainty_source']} ({spreads}); run i "
               f"draws from numpy's default_rng([{mc['seed']}, i]) (the plants of `pdsmc montecarlo --seed "
               f"{mc['seed']}`), every law on the same plants with its nominal model and gains. Each cell: "
               f"the mean over the runs that did not diverge [its {100 * LEVEL:g} % percentile-bootstrap "
               f"confidence interval: {RESAMPLES:,} resamples, seed {SEED}].")
    head, body = interval_rows(summary, {r.law: r.label for r in rows}, cols)
    report.add("table", ["", *head], body)
    report.add("img", mc["figure"], "distribution over the drawn plants (box: quartiles and median; whiskers: "
               "1.5 x the interquartile range; triangle: the mean)")


def write_figures(runs: Sequence[tuple[LawRow, Samples]], entries: Sequence[LawSpec], out: Path) -> list[Path]:
    """The thesis-style comparison figures (:func:`pdsmc_ros.experiments.plots.plot_controllers`) of the
    laws that did not diverge, every law on one axes."""
    from .plots import plot_controllers

    shown = [(row.law, samples) for row, samples in runs if row.values is not None]
    if not shown:
        return []
    spec = entries[0].spec
    return plot_controllers(shown, spec.robot, f"compare_{Path(spec.robot).stem}_{spec.contour}", spec.bound, out)


def write_report(report: Report, data: Mapping[str, Any], mc_rows: Sequence[Mapping[str, Any]] | None,
                 out: Path, fmt: str) -> list[Path]:
    """``compare.md`` (and ``compare.html`` for ``fmt == "html"``), ``compare.json`` and, with a Monte
    Carlo, ``compare_runs.csv`` (a row per run and law) into ``out``."""
    from .montecarlo import plain_cell

    written = [out / "compare.md", out / "compare.json"]
    written[0].write_text(to_markdown(report))
    written[1].write_text(json.dumps(data, indent=2, sort_keys=True))
    if fmt == "html":
        written.append(out / "compare.html")
        written[-1].write_text(to_html(report, out))
    if mc_rows:
        columns: list[str] = []
        for row in mc_rows:
            columns += [c for c in row if c not in columns]
        written.append(out / "compare_runs.csv")
        with written[-1].open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=columns, restval="nan")
            writer.writeheader()
            writer.writerows({k: plain_cell(v) for k, v in row.items()} for row in mc_rows)
    return written
