"""The CI regression gate: run the short CI scenarios, compare with results/baseline.json.

The baseline holds, per CI scenario, each method's mean absolute errors (rotation, x, y), its
mean signed errors (the bias an offset would show, which a mean absolute error can hide or even
lower), its failed frames and its ``"ok"`` frames off by more than 5 degrees or 10 px (an
``"ok"`` that cannot be trusted; none may appear or go unnoticed), and the ground truth's own
mean motion and failed frames (a change of the simulation or of the truth moves every method's
errors, some of them down). A figure fails the gate when it moves from its baseline by more
than its tolerance, either way: worse is a regression, better (or a moved truth) a change of
results that was not made on purpose, for on purpose the baseline is rewritten in the same
commit (``--update-baseline``).
On one machine the same code gives the same figures bit for bit; the tolerances absorb what
another machine (CPU, Mesa, a numpy release) may move, and a frame or two whose status it flips.
"""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

from scenarios import SCENARIOS_DIR
from sim.atomic import prepare_output_dir, write_text_atomic
from sim.harness.interrupts import Interrupted

#: The CI scenario set: short walks (a few seconds each), run by ``egostab gate``.
CI_SCENARIOS_DIR = SCENARIOS_DIR / "ci"
#: Each method's gated figures and how far each may move from its baseline, either way: the
#: mean absolute errors and the mean signed errors (estimate less truth; degrees, pixels) over
#: the frames with an estimate and a truth, the frames without an estimate, and the frames
#: whose ``"ok"`` estimate is off by more than ``scoring.LARGE_ERROR_DEG`` or
#: ``scoring.LARGE_ERROR_PX`` (``MethodScore.n_large_errors``), to the frame.
METHOD_TOLERANCES = {"rotation_mean_deg": 0.03, "x_mean_px": 0.05, "y_mean_px": 0.05,
                     "rotation_bias_deg": 0.03, "x_bias_px": 0.05, "y_bias_px": 0.05,
                     "failed_frames": 2, "large_error_frames": 0}
#: The ground truth's entry in each scenario (no method is called so), its figures (the mean
#: true motion over the frames with a truth, and the frames without one) and their tolerances.
TRUTH = "(ground truth)"
TRUTH_TOLERANCES = {"angle_mean_deg": 0.03, "dx_mean_px": 0.05, "dy_mean_px": 0.05,
                    "failed_frames": 2}
BASELINE_FORMAT = "egostab-baseline/3"


class RunNotComplete(Exception):
    """A CI run that ended before its last frame (the robot fell): a regression, not bad
    input; the message says how it ended."""


def tolerances_of(entry: str) -> dict[str, float]:
    """The figures and tolerances of a scenario's entry: a method, or :data:`TRUTH`."""
    return TRUTH_TOLERANCES if entry == TRUTH else METHOD_TOLERANCES


def gate_metrics(metrics: dict, rows: list[dict]) -> dict[str, dict[str, float]]:
    """Entry (each method, and :data:`TRUTH`) -> its gated figures, from one run's metrics.json
    and the rows of its frames.csv."""
    from stabilizer.motion import OK, wrap_angle_deg

    if metrics["status"] == "interrupted":  # the gate was stopped: a stop, not bad input
        raise Interrupted.named_in(metrics["run"].get("message", ""))
    if metrics["status"] != "complete":
        raise RunNotComplete(f"{metrics['status']} ({metrics['run'].get('message', '')})")

    def mean(values: list[float]) -> float:
        return math.fsum(values) / len(values) if values else math.nan

    gated = {}
    for method, score in metrics["summary"]["run"].items():
        errors = score["errors"]
        scored = [row for row in rows if row["method"] == method and row["status"] == OK
                  and row["truth_status"] == OK]
        gated[method] = {
            "rotation_mean_deg": errors["rotation"]["mean"], "x_mean_px": errors["x"]["mean"],
            "y_mean_px": errors["y"]["mean"],
            "rotation_bias_deg": mean([float(wrap_angle_deg(float(row["est_angle_deg"])
                                                            - float(row["true_angle_deg"])))
                                       for row in scored]),
            "x_bias_px": mean([float(row["est_dx_px"]) - float(row["true_dx_px"])
                               for row in scored]),
            "y_bias_px": mean([float(row["est_dy_px"]) - float(row["true_dy_px"])
                               for row in scored]),
            "failed_frames": score["n_failed"], "large_error_frames": score["n_large_errors"]}
    first = next(iter(metrics["summary"]["run"]), None)
    frames = [row for row in rows if row["method"] == first]
    with_truth = [row for row in frames if row["truth_status"] == OK]
    gated[TRUTH] = {"angle_mean_deg": mean([float(row["true_angle_deg"]) for row in with_truth]),
                    "dx_mean_px": mean([float(row["true_dx_px"]) for row in with_truth]),
                    "dy_mean_px": mean([float(row["true_dy_px"]) for row in with_truth]),
                    "failed_frames": len(frames) - len(with_truth)}
    return gated


def ci_scenario_paths() -> list[Path]:
    """The CI scenario files, sorted by name."""
    paths = sorted(CI_SCENARIOS_DIR.glob("*.toml"))
    if not paths:
        raise ValueError(f"no CI scenarios (*.toml) in {CI_SCENARIOS_DIR}")
    return paths


def expected_coverage() -> dict[str, tuple[str, ...]]:
    """scenario -> the entries its run gives (the methods it scores, and :data:`TRUTH`): what
    the CI set produces, known before running."""
    from sim.harness.scenario import load_scenario

    return {path.stem: (*load_scenario(path).evaluation.methods, TRUTH)
            for path in ci_scenario_paths()}


def run_ci_scenarios(out_dir: Path) -> tuple[dict[str, dict[str, dict[str, float]]],
                                              dict[str, str]]:
    """Run every scenario of CI_SCENARIOS_DIR (no recording): scenario -> entry -> figures of
    the runs that completed, and scenario -> how it ended for those that did not."""
    from sim.harness.runner import RunConfig, run

    results, not_complete = {}, {}
    for path in ci_scenario_paths():
        run_dir = out_dir / path.stem
        metrics = run(RunConfig(scenario=str(path), out_dir=str(run_dir), record=False))
        with open(run_dir / "frames.csv", newline="", encoding="utf-8") as handle:
            try:
                results[path.stem] = gate_metrics(metrics, list(csv.DictReader(handle)))
            except RunNotComplete as ended:
                not_complete[path.stem] = str(ended)
    return results, not_complete


#: Verdicts of a baseline that no longer matches the CI set: both fail the gate, because a
#: baseline that silently lacks a figure would let that figure move unseen.
NOT_IN_BASELINE = "REGRESSED (not in baseline; run --update-baseline on purpose)"
NOT_RUN = "REGRESSED (in baseline, not produced by the CI set)"
#: Verdicts of a figure: within its tolerance, or beyond it (each fails the gate).
WITHIN = "ok"
WORSE = "REGRESSED"
NO_VALUE = "REGRESSED (no value)"
BETTER = "CHANGED (better: if on purpose, --update-baseline)"
MOVED = "CHANGED (if on purpose, --update-baseline)"


def verdict(entry: str, metric: str, baseline: float, current: float) -> str:
    """Whether ``current`` stays within the tolerance of ``baseline`` and, if not, which way it
    moved: lower is better for errors and failed frames, nearer 0 for a bias; the ground
    truth only moves."""
    if _is_nan(baseline) and _is_nan(current):
        return WITHIN
    if _is_nan(current):
        return NO_VALUE
    if _is_nan(baseline):  # a figure that had no value has one now
        return MOVED
    if abs(current - baseline) <= tolerances_of(entry)[metric]:
        return WITHIN
    if entry == TRUTH:
        return MOVED
    if "_bias_" in metric:  # a bias that only changed sign is no nearer 0
        return (WORSE if abs(current) > abs(baseline) else
                BETTER if abs(current) < abs(baseline) else MOVED)
    return WORSE if current > baseline else BETTER


def compare(current: dict, baseline: dict) -> list[dict]:
    """One row per (scenario, entry, figure): baseline, current, change, tolerance, verdict.

    A scenario or entry that the CI set produces but the baseline lacks, or that the baseline
    holds but the CI set no longer produces, fails too: adding or removing one is what
    ``--update-baseline`` is for.
    """
    rows = []
    for scenario, entries in sorted(current.items()):
        for entry, figures in entries.items():
            for metric, value in figures.items():
                base = baseline.get(scenario, {}).get(entry, {}).get(metric)
                tolerance = tolerances_of(entry)[metric]
                if base is None and entry not in baseline.get(scenario, {}):
                    rows.append(dict(scenario=scenario, method=entry, metric=metric,
                                     baseline=math.nan, current=value, tolerance=tolerance,
                                     verdict=NOT_IN_BASELINE))
                    continue
                base = math.nan if base is None else base
                value = math.nan if value is None else value
                rows.append(dict(scenario=scenario, method=entry, metric=metric, baseline=base,
                                 current=value, tolerance=tolerance,
                                 verdict=verdict(entry, metric, base, value)))
    for scenario in sorted(set(baseline) - set(current)):
        rows.append(dict(scenario=scenario, method="-", metric="-", baseline=math.nan,
                         current=math.nan, tolerance=math.nan, verdict=NOT_RUN))
    for scenario in sorted(set(baseline) & set(current)):
        for entry in sorted(set(baseline[scenario]) - set(current[scenario])):
            rows.append(dict(scenario=scenario, method=entry, metric="-", baseline=math.nan,
                             current=math.nan, tolerance=math.nan, verdict=NOT_RUN))
    return rows


def _is_nan(value) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def format_rows(rows: list[dict]) -> str:
    lines = ["| scenario | method | figure | baseline | current | change | tolerance | verdict |",
             "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['scenario']} | {row['method']} | {row['metric']} | "
                     f"{row['baseline']:.4f} | {row['current']:.4f} | "
                     f"{row['current'] - row['baseline']:+.4f} | {row['tolerance']:g} | "
                     f"{row['verdict']} |")
    return "\n".join(lines)


def read_baseline(path: Path) -> dict:
    """The ``scenarios`` of a baseline file, checked against its schema.

    A baseline is ``{"format": BASELINE_FORMAT, "scenarios": {scenario: {entry: {figure:
    number}}}}`` with at least one scenario, at least one entry per scenario (the methods, and
    :data:`TRUTH`), and exactly the figures of :func:`tolerances_of` per entry (a number, or null
    for a figure with no value). Anything else raises ValueError naming the file and what is
    wrong.
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"--baseline {path}: is a folder; accepted: the baseline's JSON file "
                         "(results/baseline.json from the repository's root)")
    if not path.is_file():
        raise ValueError(f"no baseline at {path}; accepted: the committed one (run from the "
                         "repository's root, or give --baseline PATH), or a new one made on "
                         "purpose with `egostab gate --update-baseline`")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: cannot be read ({error})") from None
    try:
        document = json.loads(text)
    except ValueError as error:  # JSONDecodeError, or a number of more than 4300 digits
        raise ValueError(f"{path}: not valid JSON ({error}); expected a baseline written by "
                         "`egostab gate --update-baseline`") from None
    if not isinstance(document, dict) or document.get("format") != BASELINE_FORMAT:
        raise ValueError(f"{path}: not a baseline of format {BASELINE_FORMAT!r} (expected a JSON "
                         f"object with \"format\": {BASELINE_FORMAT!r}; an older format is "
                         "rewritten with `egostab gate --update-baseline`)")
    scenarios = document.get("scenarios")
    if not isinstance(scenarios, dict) or not scenarios:
        raise ValueError(f"{path}: 'scenarios' must be a non-empty object "
                         "{scenario: {method: {metric: number}}}")
    for scenario, methods in scenarios.items():
        if not isinstance(methods, dict) or not methods:
            raise ValueError(f"{path}: scenarios.{scenario} must be a non-empty object "
                             "{method: {metric: number}}")
        for method, figures in methods.items():
            key = f"scenarios.{scenario}.{method}"
            expected = tolerances_of(method)
            if not isinstance(figures, dict) or set(figures) != set(expected):
                raise ValueError(f"{path}: {key} must hold exactly the figures "
                                 f"{', '.join(sorted(expected))}")
            for metric, value in figures.items():
                if value is not None and (isinstance(value, bool)
                                          or not isinstance(value, (int, float))
                                          or abs(value) > sys.float_info.max):
                    raise ValueError(f"{path}: {key}.{metric} is {_shown(value)}; accepted: "
                                     "a number within the float range, or null")
    # The tolerances are the gate's (METHOD_TOLERANCES, TRUTH_TOLERANCES); the baseline records
    # those it was written with, so that an edit there is refused rather than silently ignored.
    if document.get("tolerances") != {"methods": METHOD_TOLERANCES, TRUTH: TRUTH_TOLERANCES}:
        raise ValueError(f"{path}: its 'tolerances' are not the ones the gate applies (those of "
                         "sim/harness/gate.py, which the baseline records); accepted: a baseline "
                         "written by `egostab gate --update-baseline` with these tolerances")
    return scenarios


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:40] + "..."


def check_coverage(baseline: dict, expected: dict[str, tuple[str, ...]], path: Path) -> None:
    """Refuse, before anything runs, a baseline that does not cover exactly the CI set."""
    problems = []
    for scenario in sorted(set(expected) - set(baseline)):
        problems.append(f"lacks scenario {scenario}")
    for scenario in sorted(set(baseline) - set(expected)):
        problems.append(f"has scenario {scenario}, which the CI set no longer runs")
    for scenario in sorted(set(expected) & set(baseline)):
        for method in sorted(set(expected[scenario]) - set(baseline[scenario])):
            problems.append(f"lacks method {method} of scenario {scenario}")
        for method in sorted(set(baseline[scenario]) - set(expected[scenario])):
            problems.append(f"has method {method} of scenario {scenario}, which the CI set "
                            "no longer scores")
    if problems:
        raise ValueError(f"{path}: the baseline does not match the CI set ({'; '.join(problems)})"
                         "; rewrite it on purpose with `egostab gate --update-baseline`")


def write_baseline(path: Path, results: dict) -> None:
    from sim.harness.provenance import provenance

    document = {"format": BASELINE_FORMAT, "tolerances": {"methods": METHOD_TOLERANCES,
                                                          TRUTH: TRUTH_TOLERANCES},
                "provenance": provenance(), "scenarios": results}
    write_text_atomic(path, json.dumps(document, indent=2, sort_keys=True) + "\n")


def run_gate(baseline_path: Path, update: bool = False,
             out_dir: Path = Path("results/gate")) -> int:
    """Run the CI scenarios; compare with (or, with ``update``, rewrite) the baseline.

    Returns the exit code: 0 when every figure is within its tolerance, 1 otherwise (a figure
    moved, or a CI run did not complete: the robot fell).
    """
    baseline = None
    if not update:
        baseline = read_baseline(Path(baseline_path))
        check_coverage(baseline, expected_coverage(), Path(baseline_path))
    prepare_output_dir(Path(out_dir))  # after the baseline: a refused gate leaves no folder
    results, not_complete = run_ci_scenarios(Path(out_dir))
    ended = "; ".join(f"{scenario} {how}" for scenario, how in not_complete.items())
    if update:
        if not_complete:
            print(f"baseline not written: CI run(s) did not complete: {ended}")
            return 1
        write_baseline(Path(baseline_path), results)
        print(f"baseline written to {baseline_path} "
              f"({sum(len(m) for m in results.values())} entries: each scenario's methods and "
              "its ground truth)")
        return 0
    rows = compare(results, baseline)
    moved = [row for row in rows if row["verdict"] != WITHIN]
    print(format_rows(rows))
    if not_complete:  # their figures are all "in baseline, not produced"
        print(f"\ngate failed: CI run(s) did not complete: {ended}")
        return 1
    if moved:
        worse = sum(row["verdict"].startswith("REGRESSED") for row in moved)
        better = sum(row["verdict"] == BETTER for row in moved)
        print(f"\ngate failed: {len(moved)} figure(s) moved from {baseline_path} beyond their "
              f"tolerance ({worse} worse, {better} better, {len(moved) - worse - better} "
              f"changed without a better way: the ground truth, a bias's sign, a figure without "
              f"a baseline value); "
              "a change that moves results on purpose rewrites the baseline in the same commit "
              "(egostab gate --update-baseline):")
        print(format_rows(moved))
        return 1
    print(f"\ngate passed: {len(rows)} figures within tolerance of {baseline_path}")
    return 0
