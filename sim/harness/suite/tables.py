"""A suite's figures: per-sequence rows, means with intervals, paired differences; the files.

Per sequence and method the figures are the run's own (``sim.harness.report.score_rows``): the
mean absolute error of rotation, x and y over the frames the method estimated, and its failure
rate; beside the means, the count over all sequences of "ok" estimates off by more than the
large-error limits (``sim.harness.scoring.LARGE_ERROR_DEG``, ``LARGE_ERROR_PX``), and the failed
frames over all sequences by status (the method's own reasons, and ``"unverified"``: the trust
check could not confirm the estimate). How sequences count:

- a sequence whose run scored no frame (it raised, or the robot fell at once) counts for no
  method; a run that fell later counts with the frames scored before the fall;
- a method with no successful estimate in a sequence has failure rate 1 there (every frame
  failed) and no errors: its error means leave that sequence out;
- every mean says how many sequences it covers (``n``); a paired difference covers the
  sequences where both methods have the figure, and is called clear (one method is lower)
  only when its interval excludes 0 and it covers at least ``MIN_VERDICT_SEQUENCES``.

Files (written atomically): ``suite.md`` (the tables), ``suite.csv`` (a row per sequence and
method) and ``suite.json`` (every figure: sequences, rows, intervals, differences).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from sim.atomic import write_text_atomic
from sim.harness.report import (LARGE_ERRORS_TITLE, MEAN_ERROR_COLUMNS, format_number,
                                large_errors_cell, large_errors_section, markdown_table,
                                score_rows)
from sim.harness.runner import FELL
from sim.harness.scoring import AXES, AXIS_UNITS, LargeError
from sim.harness.suite.spec import SuiteSpec
from sim.harness.suite.statistics import (BOOTSTRAP_SEED, CONFIDENCE_LEVEL, N_RESAMPLES,
                                          mean_interval, paired_difference)
from sim.harness.sweep.plan import RunOutcome

TABLE_MD, TABLE_CSV, TABLE_JSON = "suite.md", "suite.csv", "suite.json"
#: Fewest sequences for a verdict on a difference: a bootstrap interval from fewer samples is
#: too narrow (with 2 it spans just the two values), so it would claim too much.
MIN_VERDICT_SEQUENCES = 10
FAILURE_RATE = "failure_rate"
#: The figures with intervals (all: lower is better) -> their titles.
FIGURES = {**{MEAN_ERROR_COLUMNS[axis]: f"{axis.capitalize()} mean abs error ({AXIS_UNITS[axis]})"
              for axis in AXES},
           FAILURE_RATE: "Failure rate"}
#: Columns of suite.csv.
COLUMNS = ("sequence", "scenario", "scene", "gait", "scene_seed", "seed", "run_status",
           "method", "frames", *FIGURES, "scored_frames", "large_errors")
COUNTING = ("A sequence whose run scored no frame counts for no method; a run that fell counts "
            "with the frames scored before the fall. A method with no successful estimate in a "
            "sequence has failure rate 1 there and no errors (its error means leave that "
            "sequence out). n is the number of sequences a figure covers; a difference gets a "
            f"verdict from {MIN_VERDICT_SEQUENCES} sequences on.")


@dataclass(frozen=True)
class SuiteResult:
    """The outcome of a suite: per-run outcomes, the rows, the figures and the files written."""

    outcomes: tuple[RunOutcome, ...]
    rows: tuple[dict, ...]
    figures: dict
    markdown: str
    files: tuple[Path, ...]

    @property
    def failed(self) -> tuple[RunOutcome, ...]:
        return tuple(outcome for outcome in self.outcomes if outcome.error)


def sequence_rows(outcomes: Sequence[RunOutcome], methods: Sequence[str]) -> list[dict]:
    """One row per sequence and method of the runs that scored frames (``COLUMNS``)."""
    rows = []
    for outcome in outcomes:
        sequence = outcome.run.sequence
        scores = {score["method"]: score for score in score_rows(outcome.metrics)}
        if not scores:
            continue
        head = {"sequence": sequence.name, "scenario": Path(sequence.scenario).stem,
                "scene": sequence.scene, "gait": sequence.gait,
                "scene_seed": sequence.scene_seed, "seed": sequence.seed,
                "run_status": outcome.status}
        for method in methods:
            score = scores.get(method, {})
            rows.append({**head, "method": method, "frames": score.get("frames", 0),
                         **{figure: float(score.get(figure, math.nan)) for figure in FIGURES},
                         "scored_frames": score.get("scored_frames", 0),
                         "large_errors": score.get("large_errors", 0),
                         "large_error_frames": [dataclasses.asdict(error) for error in
                                                score.get("large_error_frames", ())],
                         "failures": score.get("failures", {})})
    return rows


def method_samples(rows: Sequence[dict], method: str, figure: str) -> list[float]:
    """``method``'s per-sequence values of ``figure``, in row order (NaN where it has none)."""
    return [row[figure] for row in rows if row["method"] == method]


def large_error_totals(rows: Sequence[dict], methods: Sequence[str]) -> dict[str, dict]:
    """Per method: "count", its "ok" estimates off by more than the large-error limits over all
    sequences (None when a run's metrics.json did not count them), of "scored_frames", and
    "frames", those estimates in sequence order, each {"sequence", "frame", "rotation_deg",
    "x_px", "y_px"} (absolute errors; those of a metrics.json that did not list them are
    missing)."""
    totals = {}
    for method in methods:
        mine = [row for row in rows if row["method"] == method]
        counts = [row["large_errors"] for row in mine]
        totals[method] = {"count": None if None in counts else sum(counts),
                          "scored_frames": sum(row["scored_frames"] for row in mine),
                          "frames": [{"sequence": row["sequence"], **error} for row in mine
                                     for error in row["large_error_frames"]]}
    return totals


def failure_totals(rows: Sequence[dict], methods: Sequence[str]) -> dict[str, dict]:
    """Per method over all sequences: "frames", "failed" and "by_status" (status -> failed
    frames, sorted by status)."""
    totals = {}
    for method in methods:
        mine = [row for row in rows if row["method"] == method]
        by_status: dict[str, int] = {}
        for row in mine:
            for status, count in row["failures"].items():
                by_status[status] = by_status.get(status, 0) + count
        totals[method] = {"frames": sum(row["frames"] for row in mine),
                          "failed": sum(by_status.values()),
                          "by_status": dict(sorted(by_status.items()))}
    return totals


def suite_figures(rows: Sequence[dict], methods: Sequence[str]) -> dict:
    """Per method the interval of each figure's mean and its large errors; per pair of methods,
    the interval of the difference."""
    means = {method: {figure: mean_interval(method_samples(rows, method, figure))
                      for figure in FIGURES} for method in methods}
    differences = []
    for first, second in itertools.combinations(methods, 2):
        for figure in FIGURES:
            interval = paired_difference(method_samples(rows, first, figure),
                                         method_samples(rows, second, figure))
            lower = (first if interval.mean < 0 else second if interval.mean > 0 else "")
            differences.append({"first": first, "second": second, "figure": figure,
                                **interval.to_dict(), "lower": lower,
                                "clear": (interval.n >= MIN_VERDICT_SEQUENCES
                                          and interval.excludes_zero())})
    return {"means": {method: {figure: interval.to_dict() for figure, interval in by.items()}
                      for method, by in means.items()},
            "large_errors": large_error_totals(rows, methods),
            "failures": failure_totals(rows, methods), "differences": differences}


def _value(figure: str, value: float) -> str:
    return (f"{format_number(100 * value, 1)}%" if figure == FAILURE_RATE and math.isfinite(value)
            else format_number(value, 3))


def _difference(figure: str, value: float) -> str:
    """A difference of two methods' figures: of failure rates in percentage points (a rate
    of 8% against 10% differs by 2 points, not by 2%)."""
    return (format_number(100 * value, 1) if figure == FAILURE_RATE and math.isfinite(value)
            else format_number(value, 3))


def _interval_cell(figure: str, interval: dict) -> str:
    bounds = ("no interval" if not interval["method"] else
              f"[{_value(figure, interval['low'])}, {_value(figure, interval['high'])}]")
    return f"{_value(figure, interval['mean'])} {bounds} (n={interval['n']})"


def means_markdown(figures: dict) -> str:
    """Per method: each figure's mean over sequences with its 95% interval and n, and its "ok"
    estimates off by more than the large-error limits, of its scored frames."""
    large = figures["large_errors"]
    return markdown_table(("Method", *FIGURES.values(), f"{LARGE_ERRORS_TITLE}, all sequences"),
                          ([method, *(_interval_cell(f, by[f]) for f in FIGURES),
                            large_errors_cell(large[method]["count"],
                                              large[method]["scored_frames"])]
                           for method, by in figures["means"].items()))


def failures_markdown(figures: dict) -> str:
    """Per method: its failed frames over all sequences, and how many of each status, each
    also as a share of all its frames."""
    def share(count: int, frames: int) -> str:
        return f"{format_number(100 * count / frames, 1)}%" if frames else "n/a"

    return markdown_table(
        ("Method", "Failed frames, all sequences", "By status"),
        ([method, (f"{totals['failed']:,} of {totals['frames']:,} "
                   f"({share(totals['failed'], totals['frames'])})"),
          ", ".join(f"{status} {count:,} ({share(count, totals['frames'])})"
                    for status, count in totals["by_status"].items()) or "-"]
         for method, totals in figures["failures"].items()))


def differences_markdown(figures: dict) -> str:
    """Per pair of methods and figure: the paired difference, its interval and what it says."""
    def verdict(entry: dict) -> str:
        if entry["n"] < MIN_VERDICT_SEQUENCES:
            return f"too few sequences for a verdict (n < {MIN_VERDICT_SEQUENCES})"
        if not entry["clear"]:
            return "no clear difference (interval contains 0)"
        return f"{entry['lower']} is lower (interval excludes 0)"

    def figure(name: str) -> str:
        return FIGURES[name] + (" (points)" if name == FAILURE_RATE else "")

    if not figures["differences"]:
        return "No pairs to compare: the suite scores one method."
    return markdown_table(
        ("First", "Second", "Figure", "First - second", f"{CONFIDENCE_LEVEL:.0%} interval", "n",
         "Verdict"),
        ([d["first"], d["second"], figure(d["figure"]), _difference(d["figure"], d["mean"]),
          (f"[{_difference(d['figure'], d['low'])}, {_difference(d['figure'], d['high'])}]"
           if d["method"] else "n/a"), str(d["n"]), verdict(d)]
         for d in figures["differences"]))


def _large_errors_section(figures: dict) -> list[str]:
    """suite.md's list of every method's "ok" estimates off by more than the large-error
    limits, with their sequences; none when there are none."""
    return large_errors_section(
        [(method, entry["sequence"], LargeError(entry["frame"], entry["rotation_deg"],
                                                entry["x_px"], entry["y_px"]))
         for method, totals in figures["large_errors"].items() for entry in totals["frames"]],
        where="; per frame in the sequence's frames.csv (`runs/<sequence>/`)")


def sequences_markdown(outcomes: Sequence[RunOutcome]) -> str:
    """Per sequence: what it is, how its run ended and the frames it scored."""
    def frames(outcome: RunOutcome) -> str:
        return str(((outcome.metrics or {}).get("run") or {}).get("frames_done", 0))

    return markdown_table(("Sequence", "Scene", "Gait", "Scene seed", "Seed", "Status", "Frames"),
                          ([o.run.sequence.name, o.run.sequence.scene, o.run.sequence.gait,
                            str(o.run.sequence.scene_seed), str(o.run.sequence.seed), o.status,
                            frames(o)] for o in outcomes))


def table_csv(rows: Sequence[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows([("" if row[c] is None or isinstance(row[c], float) and math.isnan(row[c])
                       else repr(row[c]) if isinstance(row[c], float) else str(row[c]))
                      for c in COLUMNS] for row in rows)
    return buffer.getvalue()


def _finite_or_none(value):
    """JSON has no NaN: a missing figure is null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(item) for item in value]
    return value


def write_suite_outputs(out_dir: str | os.PathLike, spec: SuiteSpec,
                        outcomes: Sequence[RunOutcome],
                        estimates: Mapping[str, str] | None = None,
                        check_estimates: bool = False) -> SuiteResult:
    """Write suite.md, suite.csv and suite.json (atomically) from the finished runs; the
    estimates files (name -> path of each sequence's file; through the trust check with
    ``check_estimates``) count as methods after the suite's."""
    out_dir = Path(out_dir)
    estimates = dict(estimates or {})
    names = (*spec.methods, *estimates)
    rows = sequence_rows(outcomes, names)
    figures = suite_figures(rows, names)
    counted = len({row["sequence"] for row in rows})
    skipped = sum(outcome.skipped for outcome in outcomes)
    failed = sum(bool(outcome.error) for outcome in outcomes)
    fell = sum(outcome.status == FELL for outcome in outcomes)
    summary = (f"Sequences: {len(spec.sequences)} planned, {len(outcomes)} finished "
               f"({skipped} already done before this call), {failed} failed, {fell} fell; "
               f"{counted} scored frames and are counted.")
    intervals = (f"Means over sequences (each sequence's mean is one sample; frames are not "
                 f"resampled) with {CONFIDENCE_LEVEL:.0%} bootstrap intervals: BCa, or the "
                 f"percentile interval where BCa is degenerate; {N_RESAMPLES} resamples, seed "
                 f"{BOOTSTRAP_SEED}.")
    estimates_line = ("Estimates files of other programs, scored beside the methods: "
                      + "; ".join(f"{name} ({path})" for name, path in estimates.items())
                      + (". Their ok rows passed the trust check every method's ok passes, or "
                         "became unverified." if check_estimates else
                         ". Scored as given, without the trust check the methods' ok passes."))
    markdown = "\n".join([
        f"# Suite {spec.name}", "", *([spec.description, ""] if spec.description else []),
        summary, "", *([estimates_line, ""] if estimates else []), intervals, COUNTING, "",
        "## Means over sequences", "",
        means_markdown(figures), "", *_large_errors_section(figures), "## Failures by status", "",
        "Every failed frame of every sequence, pooled; `unverified`: the method answered, and "
        "the trust check could not confirm its answer (docs/method.md, section 11); any other "
        "status is the method's own.", "", failures_markdown(figures), "",
        "## Paired differences",
        "", "Per-sequence differences of two methods on the same sequences, bootstrapped; "
        "lower is better for every figure.", "", differences_markdown(figures), "",
        "## Sequences", "", sequences_markdown(outcomes), ""])
    document = {
        "name": spec.name, "description": spec.description, "source": spec.source,
        "methods": list(spec.methods), "estimates": estimates,
        "estimates_checked": check_estimates, "summary": summary,
        "counting": COUNTING,
        "bootstrap": {"confidence_level": CONFIDENCE_LEVEL, "n_resamples": N_RESAMPLES,
                      "seed": BOOTSTRAP_SEED, "unit": "sequence"},
        "sequences": [{"name": o.run.sequence.name, "scenario": o.run.sequence.scenario,
                       "scene": o.run.sequence.scene, "gait": o.run.sequence.gait,
                       "scene_seed": o.run.sequence.scene_seed, "seed": o.run.sequence.seed,
                       "status": o.status} for o in outcomes],
        "rows": rows, **figures}
    files = (write_text_atomic(out_dir / TABLE_MD, markdown),
             write_text_atomic(out_dir / TABLE_CSV, table_csv(rows)),
             write_text_atomic(out_dir / TABLE_JSON, json.dumps(
                 _finite_or_none(document), indent=2, allow_nan=False) + "\n"))
    return SuiteResult(tuple(outcomes), tuple(rows), figures, markdown, files)
