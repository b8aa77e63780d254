"""The CI regression gate: run the short CI scenarios, compare with results/baseline.json.

The baseline holds, per CI scenario and method, the run's mean absolute errors (rotation, x,
y) and failure rate on the main branch. A metric regresses when it exceeds its baseline by
more than the tolerance: ``value > baseline * (1 + REL_TOLERANCE) + ABS_TOLERANCE[metric]``.
Tolerances exist because a different machine (CPU, Mesa, a MuJoCo patch release) may move a
simulated walk slightly; on one machine the same code gives the same numbers bit for bit.
Improvements are reported too, but only regressions fail the gate; ``--update-baseline``
rewrites the baseline on purpose.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from scenarios import SCENARIOS_DIR
from sim.harness.atomic import prepare_output_dir, write_text_atomic

#: The CI scenario set: short walks (a few seconds each), run by ``egostab gate``.
CI_SCENARIOS_DIR = SCENARIOS_DIR / "ci"
#: Relative and absolute tolerances of a metric before it counts as a regression.
REL_TOLERANCE = 0.10
ABS_TOLERANCE = {"rotation_mean_deg": 0.05, "x_mean_px": 0.10, "y_mean_px": 0.10,
                 "failure_rate": 0.02}
BASELINE_FORMAT = "egostab-baseline/1"


def gate_metrics(metrics: dict) -> dict[str, dict[str, float]]:
    """method -> the gated figures of one run's metrics.json."""
    if metrics["status"] != "complete":
        raise ValueError(f"run {metrics['scenario'].get('name')} did not complete: "
                         f"{metrics['status']} ({metrics['run'].get('message', '')})")
    gated = {}
    for method, score in metrics["summary"]["run"].items():
        errors = score["errors"]
        gated[method] = {"rotation_mean_deg": errors["rotation"]["mean"],
                         "x_mean_px": errors["x"]["mean"], "y_mean_px": errors["y"]["mean"],
                         "failure_rate": score["failure_rate"]}
    return gated


def ci_scenario_paths() -> list[Path]:
    """The CI scenario files, sorted by name."""
    paths = sorted(CI_SCENARIOS_DIR.glob("*.toml"))
    if not paths:
        raise ValueError(f"no CI scenarios (*.toml) in {CI_SCENARIOS_DIR}")
    return paths


def expected_coverage() -> dict[str, tuple[str, ...]]:
    """scenario -> the methods its run scores: what the CI set produces, known before running."""
    from sim.harness.scenario import load_scenario

    return {path.stem: tuple(load_scenario(path).evaluation.methods)
            for path in ci_scenario_paths()}


def run_ci_scenarios(out_dir: Path) -> dict[str, dict[str, dict[str, float]]]:
    """Run every scenario of CI_SCENARIOS_DIR (no recording); scenario -> method -> figures."""
    from sim.harness.runner import RunConfig, run

    results = {}
    for path in ci_scenario_paths():
        metrics = run(RunConfig(scenario=str(path), out_dir=str(out_dir / path.stem),
                                record=False))
        results[path.stem] = gate_metrics(metrics)
    return results


#: Verdicts of a baseline that no longer matches the CI set: both fail the gate, because a
#: baseline that silently lacks a figure would let that figure regress unseen.
NOT_IN_BASELINE = "REGRESSED (not in baseline; run --update-baseline on purpose)"
NOT_RUN = "REGRESSED (in baseline, not produced by the CI set)"


def compare(current: dict, baseline: dict) -> list[dict]:
    """One row per (scenario, method, metric): baseline, current, limit, verdict.

    A scenario or method that the CI set produces but the baseline lacks, or that the baseline
    holds but the CI set no longer produces, is a regression: adding or removing one is what
    ``--update-baseline`` is for.
    """
    rows = []
    for scenario, methods in sorted(current.items()):
        for method, figures in methods.items():
            for metric, value in figures.items():
                base = baseline.get(scenario, {}).get(method, {}).get(metric)
                if base is None:
                    rows.append(dict(scenario=scenario, method=method, metric=metric,
                                     baseline=math.nan, current=value, limit=math.nan,
                                     verdict=NOT_IN_BASELINE))
                    continue
                limit = base * (1 + REL_TOLERANCE) + ABS_TOLERANCE[metric]
                if _is_nan(value) and not _is_nan(base):
                    verdict = "REGRESSED (no value)"
                elif not _is_nan(value) and value > limit:
                    verdict = "REGRESSED"
                elif not _is_nan(value) and value < base - ABS_TOLERANCE[metric]:
                    verdict = "improved"
                else:
                    verdict = "ok"
                rows.append(dict(scenario=scenario, method=method, metric=metric, baseline=base,
                                 current=value, limit=limit, verdict=verdict))
    for scenario in sorted(set(baseline) - set(current)):
        rows.append(dict(scenario=scenario, method="-", metric="-", baseline=math.nan,
                         current=math.nan, limit=math.nan, verdict=NOT_RUN))
    for scenario in sorted(set(baseline) & set(current)):
        for method in sorted(set(baseline[scenario]) - set(current[scenario])):
            rows.append(dict(scenario=scenario, method=method, metric="-", baseline=math.nan,
                             current=math.nan, limit=math.nan, verdict=NOT_RUN))
    return rows


def _is_nan(value) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def format_rows(rows: list[dict]) -> str:
    lines = ["| scenario | method | metric | baseline | current | limit | verdict |",
             "|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['scenario']} | {row['method']} | {row['metric']} | "
                     f"{row['baseline']:.4f} | {row['current']:.4f} | {row['limit']:.4f} | "
                     f"{row['verdict']} |")
    return "\n".join(lines)


def read_baseline(path: Path) -> dict:
    """The ``scenarios`` of a baseline file, checked against its schema.

    A baseline is ``{"format": BASELINE_FORMAT, "scenarios": {scenario: {method: {metric:
    number}}}}`` with at least one scenario, at least one method per scenario, and exactly the
    metrics of ``ABS_TOLERANCE`` per method (a number, or null/NaN for a figure with no value).
    Anything else raises ValueError naming the file and what is wrong.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no baseline at {path}; accepted: the committed one (run from the "
                         "repository's root, or give --baseline PATH), or a new one made on "
                         "purpose with `egostab gate --update-baseline`")
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not valid JSON ({error}); expected a baseline written by "
                         "`egostab gate --update-baseline`") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"{path}: cannot be read ({error})") from None
    if not isinstance(document, dict) or document.get("format") != BASELINE_FORMAT:
        raise ValueError(f"{path}: not a baseline of format {BASELINE_FORMAT!r} (expected a JSON "
                         f"object with \"format\": {BASELINE_FORMAT!r})")
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
            if not isinstance(figures, dict) or set(figures) != set(ABS_TOLERANCE):
                raise ValueError(f"{path}: {key} must hold exactly the metrics "
                                 f"{', '.join(sorted(ABS_TOLERANCE))}")
            for metric, value in figures.items():
                if value is not None and (isinstance(value, bool)
                                          or not isinstance(value, (int, float))):
                    raise ValueError(f"{path}: {key}.{metric} is {value!r}; accepted: a number "
                                     "or null")
    return scenarios


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

    document = {"format": BASELINE_FORMAT, "tolerances": {"relative": REL_TOLERANCE,
                                                          "absolute": ABS_TOLERANCE},
                "provenance": provenance(), "scenarios": results}
    write_text_atomic(path, json.dumps(document, indent=2, sort_keys=True) + "\n")


def run_gate(baseline_path: Path, update: bool = False,
             out_dir: Path = Path("results/gate")) -> int:
    """Run the CI scenarios; compare with (or, with ``update``, rewrite) the baseline.

    Returns the exit code: 0 when nothing regressed, 1 otherwise.
    """
    baseline = None
    if not update:
        baseline = read_baseline(Path(baseline_path))
        check_coverage(baseline, expected_coverage(), Path(baseline_path))
    prepare_output_dir(Path(out_dir))  # after the baseline: a refused gate leaves no folder
    results = run_ci_scenarios(Path(out_dir))
    if update:
        write_baseline(Path(baseline_path), results)
        print(f"baseline written to {baseline_path} "
              f"({sum(len(m) for m in results.values())} scenario x method entries)")
        return 0
    rows = compare(results, baseline)
    regressed = [row for row in rows if row["verdict"].startswith("REGRESSED")]
    print(format_rows(rows))
    if regressed:
        print(f"\nREGRESSION: {len(regressed)} figure(s) got worse than the baseline allows "
              f"(limit = baseline x {1 + REL_TOLERANCE:g} + absolute tolerance):")
        print(format_rows(regressed))
        return 1
    print(f"\ngate passed: {len(rows)} figures within tolerance of {baseline_path}")
    return 0
