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
from sim.harness.atomic import write_text_atomic

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


def run_ci_scenarios(out_dir: Path) -> dict[str, dict[str, dict[str, float]]]:
    """Run every scenario of CI_SCENARIOS_DIR (no recording); scenario -> method -> figures."""
    from sim.harness.runner import RunConfig, run

    results = {}
    for path in sorted(CI_SCENARIOS_DIR.glob("*.toml")):
        metrics = run(RunConfig(scenario=str(path), out_dir=str(out_dir / path.stem),
                                record=False))
        results[path.stem] = gate_metrics(metrics)
    if not results:
        raise ValueError(f"no CI scenarios (*.toml) in {CI_SCENARIOS_DIR}")
    return results


def compare(current: dict, baseline: dict) -> list[dict]:
    """One row per (scenario, method, metric): baseline, current, limit, verdict."""
    rows = []
    for scenario, methods in sorted(current.items()):
        for method, figures in methods.items():
            for metric, value in figures.items():
                base = baseline.get(scenario, {}).get(method, {}).get(metric)
                if base is None:
                    rows.append(dict(scenario=scenario, method=method, metric=metric,
                                     baseline=math.nan, current=value, limit=math.nan,
                                     verdict="new (not in baseline)"))
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
                         current=math.nan, limit=math.nan, verdict="REGRESSED (not run)"))
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
    if not path.is_file():
        raise ValueError(f"no baseline at {path}; create it on purpose with "
                         "`egostab gate --update-baseline`")
    document = json.loads(path.read_text(encoding="utf-8"))
    if document.get("format") != BASELINE_FORMAT:
        raise ValueError(f"{path}: not a baseline of format {BASELINE_FORMAT!r}")
    return document["scenarios"]


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
    baseline = None if update else read_baseline(Path(baseline_path))
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
