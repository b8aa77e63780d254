"""A sweep's table and plots: sweep.md, sweep.csv and error against noise level per scenario.

The table has one row per run and method, with the run's figures read from its metrics.json by
``sim.harness.report.score_rows`` (the rows of ``egostab aggregate`` come from the same place).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from sim.atomic import write_text_atomic
from sim.harness.report import (AXIS_TITLES, MEAN_ERROR_COLUMNS, format_number, markdown_table,
                                save_figure, score_rows)
from sim.harness.scoring import AXES, AXIS_UNITS
from sim.harness.sweep.plan import RunOutcome
from sim.harness.sweep.spec import SweepSpec, scenario_label

TABLE_MD = "sweep.md"
TABLE_CSV = "sweep.csv"
#: Columns of the runs' mean absolute errors, per axis.
ERROR_COLUMNS = MEAN_ERROR_COLUMNS
#: Columns of sweep.csv (sweep.md shows the same, formatted).
COLUMNS = ("run", "scenario", "seed", "noise_level", "run_status", "method", "frames",
           *ERROR_COLUMNS.values(), "failure_rate", "ms_per_frame")


@dataclass(frozen=True)
class SweepResult:
    """The outcome of a sweep: per-run outcomes, the table and the files written."""

    outcomes: tuple[RunOutcome, ...]
    rows: tuple[dict, ...]
    markdown: str
    files: tuple[Path, ...]

    @property
    def failed(self) -> tuple[RunOutcome, ...]:
        return tuple(outcome for outcome in self.outcomes if outcome.error)


def table_rows(outcomes: Sequence[RunOutcome]) -> list[dict]:
    """One row per run and method (a run with no method scores gets one row with its status)."""
    rows = []
    for outcome in outcomes:
        sweep_run = outcome.run
        head = {"run": sweep_run.name, "scenario": sweep_run.scenario, "seed": sweep_run.seed,
                "noise_level": sweep_run.noise_level, "run_status": outcome.status}
        scores = score_rows(outcome.metrics)
        if not scores:
            rows.append({**head, **{column: "" for column in COLUMNS if column not in head}})
        for score in scores:
            row = {**head, **score}
            rows.append({column: row[column] for column in COLUMNS})
    return rows


def _csv_value(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def table_csv(rows: Sequence[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows([_csv_value(row[column]) for column in COLUMNS] for row in rows)
    return buffer.getvalue()


def table_markdown(rows: Sequence[dict]) -> str:
    """The sweep table: |error| means per axis, failure rate and time per frame."""
    def cell(column: str, value) -> str:
        if not isinstance(value, float):
            return str(value)
        if column == "noise_level":
            return f"{value:g}"
        return f"{format_number(100 * value, 1)}%" if column == "failure_rate" else format_number(value)

    header = ("Run", "Scenario", "Seed", "Noise", "Status", "Method", "Frames",
              *(f"{AXIS_TITLES[a].split()[0]} mean abs error ({AXIS_UNITS[a]})" for a in AXES),
              "Failure rate", "ms/frame")
    return markdown_table(header, ([cell(c, row[c]) for c in COLUMNS] for row in rows))


def plot_error_vs_noise(path: Path, rows: Sequence[dict], scenario: str,
                        noise_key: str) -> Path:
    """Mean |error| per axis and the failure rate against the noise level, a line per method.

    Each point is the mean over the seeds of the runs' mean |error|; the band spans the
    seeds' smallest to largest value.
    """
    series: dict[str, dict[float, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for row in rows:
        if row["scenario"] == scenario and row["method"]:
            series[row["method"]][row["noise_level"]].append(row)
    figure = Figure(figsize=(12, 8), layout="constrained")
    panels = figure.subplots(2, 2).ravel()
    quantities = [(column, f"mean |error| {AXIS_TITLES[axis].split()[0].lower()} "
                           f"({AXIS_UNITS[axis]})") for axis, column in ERROR_COLUMNS.items()]
    quantities.append(("failure_rate", "failure rate"))
    for ax, (column, label) in zip(panels, quantities):
        for method, by_level in series.items():
            levels = sorted(by_level)
            values = [np.array([r[column] for r in by_level[level]], float) for level in levels]
            finite = [v[np.isfinite(v)] for v in values]
            mean = [v.mean() if v.size else math.nan for v in finite]
            line, = ax.plot(levels, mean, marker="o", label=method)
            low = [v.min() if v.size else math.nan for v in finite]
            high = [v.max() if v.size else math.nan for v in finite]
            ax.fill_between(levels, low, high, color=line.get_color(), alpha=0.15)
        ax.set_xlabel(f"noise level ({noise_key})")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    if series:
        panels[0].legend(fontsize="small")
    figure.suptitle(f"{scenario}: error against noise level (mean over seeds, band = range)")
    return save_figure(figure, path)


def write_sweep_outputs(out_dir: str | os.PathLike, spec: SweepSpec,
                        outcomes: Sequence[RunOutcome]) -> SweepResult:
    """Write sweep.md, sweep.csv and one error-vs-noise plot per scenario (atomically)."""
    out_dir = Path(out_dir)
    rows = table_rows(outcomes)
    skipped = sum(outcome.skipped for outcome in outcomes)
    failed = [outcome for outcome in outcomes if outcome.error]
    markdown = "\n".join([
        f"# Sweep {spec.name}", "", *([spec.description, ""] if spec.description else []),
        f"Runs: {spec.n_runs} planned, {len(outcomes)} finished "
        f"({skipped} already complete before this call), {len(failed)} failed. "
        f"Noise levels are values of `{spec.noise_key}`. Errors are the runs' mean absolute "
        "errors against the ground truth.", "", table_markdown(rows), ""])
    files = [write_text_atomic(out_dir / TABLE_MD, markdown),
             write_text_atomic(out_dir / TABLE_CSV, table_csv(rows))]
    for scenario in dict.fromkeys(scenario_label(s) for s in spec.scenarios):
        files.append(plot_error_vs_noise(out_dir / f"error_vs_noise__{scenario}.png", rows,
                                         scenario, spec.noise_key))
    return SweepResult(tuple(outcomes), tuple(rows), markdown, tuple(files))
