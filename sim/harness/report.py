"""A run's outputs: frames.csv, failures.jsonl, metrics.json, summary.md (the paper's Table I
layout), plots.

Every file is written atomically (sim/atomic.py), so a run that ends early (a fall,
Ctrl-C) leaves complete files; metrics.json is written last and says how the run ended. The same
Markdown tables serve summary.md and the one-screen terminal summary; ``score_rows`` reads a
run's figures back from metrics.json for the tables over several runs (``aggregate_runs`` and
the sweep's table, sim/harness/sweep/tables.py).

Table I of Kang, Zhang & Park (2009) ("Errors in the ideal case") lists, for the rotation, the
X-axis and the Y-axis displacement, one row per method with the mean and the variance of its
errors; here the errors are absolute errors against the simulated ground truth, with the
maximum beside them. Beside Table I, each method's end-point error (EPE, px) and how far it
lies above the ground truth's own, the floor of any 2-D rigid estimate
(sim/harness/scoring.py). Fig. 8/9 of the paper plot the displacements over the frames of a cycle;
``plot_estimates`` draws the same three stacked axes, estimate against truth.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, is_dataclass, replace
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from sim.atomic import atomic_path, prepare_output_dir, write_text_atomic
from sim.harness.provenance import provenance
from sim.harness.scoring import (AXES, AXIS_UNITS, LARGE_ERROR_DEG, LARGE_ERROR_PX, RECORD_FIELDS,
                                 FrameRecord, LargeError, MethodScore, RunSummary,
                                 TruthResidual)

FRAMES_CSV = "frames.csv"
FAILURES_JSONL = "failures.jsonl"
METRICS_JSON = "metrics.json"
SUMMARY_MD = "summary.md"
HISTOGRAMS_PNG = "error_histograms.png"
#: Identifies the layout of metrics.json for readers such as ``aggregate_runs``.
METRICS_FORMAT = "egostab-metrics/1"
AXIS_TITLES = {"rotation": "Rotation displacement", "x": "X-axis displacement",
               "y": "Y-axis displacement"}
PLOT_DPI = 100
RECORDING_NOTE = "rerun recording (open: rerun FILE)"
#: Keys of ``score_rows`` holding the mean and the variance of |error| of each axis.
MEAN_ERROR_COLUMNS = {axis: f"{axis}_mean_abs_error_{AXIS_UNITS[axis]}" for axis in AXES}
ERROR_VARIANCE_COLUMNS = {axis: f"{axis}_abs_error_variance_{AXIS_UNITS[axis]}" for axis in AXES}


@dataclass(frozen=True)
class RunFiles:
    """Where a run's outputs are, and (once written) the content of metrics.json."""

    run_dir: Path
    frames_csv: Path
    failures_jsonl: Path
    metrics_json: Path
    summary_md: Path
    plots: tuple[Path, ...]
    recording: Path | None = None
    metrics: dict = field(default_factory=dict, compare=False, repr=False)

    def listing(self) -> list[tuple[str, Path]]:
        """(what, path) pairs, for summaries."""
        listing = [("per-frame results", self.frames_csv),
                   ("failed estimates' diagnostics", self.failures_jsonl),
                   ("metrics", self.metrics_json), ("summary (Table I)", self.summary_md)]
        if self.recording is not None:
            listing.append((RECORDING_NOTE, self.recording))
        return listing + [("plot", path) for path in self.plots]


# ----------------------------------------------------------------------------- formatting
def format_number(value: float | None, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}f}"


#: Characters a Markdown table cell cannot hold as they are.
CONTROL_CHARACTERS = re.compile(r"[\x00-\x1f\x7f]")


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_table_cell(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def _table_cell(text: str) -> str:
    """``text`` as one Markdown table cell: '|' escaped, line breaks and other control
    characters as spaces (a failure status or a name from another program may hold them)."""
    return CONTROL_CHARACTERS.sub(" ", text).replace("|", "\\|")



def table_one(scores: Mapping[str, MethodScore]) -> str:
    """Table I layout: per displacement, one row per method, mean / variance / max of |error|."""
    rows = []
    for axis in AXES:
        for position, (method, score) in enumerate(scores.items()):
            stats = score.errors[axis]
            label = f"{AXIS_TITLES[axis]} ({AXIS_UNITS[axis]})" if position == 0 else ""
            rows.append((label, method, format_number(stats.mean), format_number(stats.variance),
                         format_number(stats.max), str(stats.n)))
    return markdown_table(("Displacement", "Method", "Mean of errors", "Variance", "Max",
                            "Frames"), rows)


def epe_table(scores: Mapping[str, MethodScore]) -> str:
    """Per method: mean EPE, the truth's mean EPE over the same frames (the floor), the mean
    above it, and the variance and maximum of the per-frame EPE (px)."""
    rows = [(method, format_number(score.epe.mean), format_number(score.epe_floor_px),
             format_number(score.epe_above_floor_px), format_number(score.epe.variance),
             format_number(score.epe.max), str(score.epe.n))
            for method, score in scores.items()]
    return markdown_table(("Method", "Mean EPE", "Floor (truth's EPE)", "Mean above floor",
                           "Variance", "Max", "Frames"), rows)


#: Title of the count of "ok" estimates off by more than the large-error limits.
LARGE_ERRORS_TITLE = f"Ok but off (> {LARGE_ERROR_DEG:g}° or {LARGE_ERROR_PX:g} px)"


def large_errors_cell(n_large: int | None, n_scored: int) -> str:
    """``n_large`` of ``n_scored`` "ok" estimates off by more than the large-error limits;
    n/a when they were not counted (a metrics.json from before)."""
    return "n/a" if n_large is None else f"{n_large} of {n_scored:,}"


#: Most "ok but off" estimates a table lists per method; the rest are counted, and every one is
#: in frames.csv (a run) or suite.json (a suite).
MAX_LISTED_LARGE_ERRORS = 20


def large_errors_section(rows: Sequence[tuple[str, str | None, LargeError]],
                         where: str = "") -> list[str]:
    """The lines of a Markdown section listing the "ok" estimates off by more than the
    large-error limits, a row each: the method, where (the second item of each row; a column
    only when some row has one), the frame and the absolute errors; at most
    ``MAX_LISTED_LARGE_ERRORS`` per method, then a row counting the rest. ``where`` ends the
    section's sentence. No lines without rows."""
    if not rows:
        return []
    with_source = any(source is not None for _, source, _ in rows)
    by_method: dict[str, list[tuple[str | None, LargeError]]] = {}
    for method, source, error in rows:
        by_method.setdefault(method, []).append((source, error))
    lines = []
    for method, entries in by_method.items():
        for source, error in entries[:MAX_LISTED_LARGE_ERRORS]:
            lines.append((method, *((source or "",) if with_source else ()), str(error.frame),
                          format_number(error.rotation_deg), format_number(error.x_px),
                          format_number(error.y_px)))
        if len(entries) > MAX_LISTED_LARGE_ERRORS:
            rest = len(entries) - MAX_LISTED_LARGE_ERRORS
            lines.append((method, *(("",) if with_source else ()),
                          f"and {rest:,} more", "", "", ""))
    table = markdown_table(("Method", *(("Sequence",) if with_source else ()), "Frame",
                            "Rotation error (deg)", "X error (px)", "Y error (px)"), lines)
    return [f"### {LARGE_ERRORS_TITLE}: the frames", "",
            f"Estimates the method and the trust check called ok, off the truth by more than "
            f"{LARGE_ERROR_DEG:g}° or {LARGE_ERROR_PX:g} px along an axis (absolute errors)"
            f"{where}.", "", table, ""]


def reliability_table(scores: Mapping[str, MethodScore]) -> str:
    """Failure rate, "ok" estimates off by more than the large-error limits, time per frame and
    ITF (compensated vs raw) per method."""
    rows = [(method, f"{format_number(100 * score.failure_rate, 1)}% ({score.n_failed}/"
                     f"{score.n_frames})",
             ", ".join(f"{status} {count}" for status, count in score.failures.items()) or "-",
             str(score.n_truth_failed), large_errors_cell(score.n_large_errors, score.n_scored),
             format_number(score.ms_mean), format_number(score.ms_median),
             format_number(score.itf_db), format_number(score.itf_raw_db))
            for method, score in scores.items()]
    return markdown_table(("Method", "Failure rate", "Reasons", "Truth failed",
                            LARGE_ERRORS_TITLE, "ms/frame mean", "ms/frame median",
                            "ITF compensated (dB)", "ITF raw (dB)"), rows)


def cycle_table(summary: RunSummary) -> str:
    """Mean / variance of |error| per gait cycle and method."""
    rows = []
    for cycle, scores in summary.cycles.items():
        for method, score in scores.items():
            cells = [f"{format_number(score.errors[axis].mean)} / {format_number(score.errors[axis].variance)}"
                     for axis in AXES]
            rows.append((str(cycle), method, str(score.n_frames), *cells,
                         f"{format_number(score.epe.mean)} / "
                         f"{format_number(score.epe_above_floor_px)}",
                         f"{format_number(100 * score.failure_rate, 1)}%", format_number(score.itf_db),
                         format_number(score.itf_raw_db)))
    return markdown_table(("Cycle", "Method", "Frames", "Rotation (deg)", "X (px)", "Y (px)",
                            "EPE / above floor (px)", "Failures", "ITF (dB)", "ITF raw (dB)"),
                          rows)


def _scenario_name(scenario: Mapping, run_dir: Path) -> str:
    return str(scenario.get("name") or run_dir.name)


def summary_markdown(*, scenario: Mapping, summary: RunSummary, meta: Mapping, status: str,
                     files: RunFiles) -> str:
    """The content of summary.md."""
    state = provenance()
    seed = meta.get("seed", scenario.get("seed"))
    notes = run_notes(meta)
    lines = [
        f"# {_scenario_name(scenario, files.run_dir)}: stabilizer errors against the simulated "
        "ground truth",
        "",
        f"Run status: **{status}**. Frames: {summary.n_frames}. Seed: {seed}. "
        f"Commit: {state['git_commit'] or 'unknown'}"
        f"{' (uncommitted changes)' if state['git_dirty'] else ''}.",
        "",
        *(line for note in notes for line in (note, "")),
        "## Absolute errors (the layout of Table I of Kang, Zhang & Park 2009)",
        "",
        "Mean, population variance and maximum of |estimate - truth| over the frames where both "
        "exist.",
        "",
        table_one(summary.run),
        "",
        "## End-point error (px)",
        "",
        "EPE: the mean distance between where the estimate sends each sampled reference pixel "
        "and where that pixel truly went (exact poses and depth), over the pixels that stay in "
        "view. Floor: the same for the ground truth's own rigid fit, over the same frames; no "
        "2-D rigid estimate gets far below it (the fit's RMS EPE is the exact lower bound of "
        "any rigid estimate's RMS EPE; for the mean it is close, not exact).",
        "",
        epe_table(summary.run),
        "",
        truth_residual_line(summary.truth_residual),
        "",
        "## Failures, time and inter-frame transformation fidelity",
        "",
        "ITF: mean PSNR between consecutive frames of the stabilized stream toward the same "
        "reference (a frame the method failed on as measured), on pixels valid in both; the "
        "raw column is the uncompensated stream.",
        "",
        reliability_table(summary.run),
        "",
        *large_errors_section([(method, None, error) for method, score in summary.run.items()
                               for error in score.large_errors]),
        "## Per gait cycle (mean / variance of |error|; EPE mean / mean above floor)",
        "",
        cycle_table(summary),
        "",
        "## Files",
        "",
        *(f"- {what}: `{path.name}`" for what, path in files.listing()),
        "",
    ]
    return "\n".join(lines)


def truth_residual_line(residual: TruthResidual) -> str:
    """One sentence on the ground truth's own residual (what per-axis errors cannot go below)."""
    if residual.n == 0:
        return "Ground truth's own residual: no frame with a ground truth."
    return (f"Ground truth's own residual (RMS distance between its rigid fit and its points: "
            f"parallax and zoom no 2-D rigid motion removes): median "
            f"{format_number(residual.median_px)} px, largest {format_number(residual.max_px)} "
            f"px, over {residual.n:,} frames (per frame: `truth_residual_px` in frames.csv).")


def cut_short_note(meta: Mapping) -> str | None:
    """The note that a scored sequence's recording was interrupted, so that its frames end
    before its scenario does; None for a run that simulated, or a whole sequence."""
    recorded = meta.get("sequence")
    if not recorded or recorded["ended"] != "interrupted":
        return None
    return f"Note: the sequence's recording was cut short ({recorded['message']})."


def run_notes(meta: Mapping) -> list[str]:
    """The notes a run's summaries open with (:func:`cut_short_note`, :func:`unchecked_note`),
    from its metrics.json ``run``; empty for a complete, checked run."""
    return [note for note in (cut_short_note(meta), unchecked_note(meta)) if note]


def unchecked_note(meta: Mapping) -> str | None:
    """The note that the methods' estimates were scored without the trust check
    (``egostab score --no-check``); None when they passed it, as in every other run."""
    if meta.get("trust_check", True):
        return None
    return ("Note: scored without the trust check (`--no-check`): each method's `ok` is the "
            "method's own, not confirmed by the check that the `ok` of every other run passes "
            "(docs/method.md, section 11).")


def terminal_summary(metrics: Mapping, run_dir: str | Path | None = None) -> str:
    """One screen for the end of a run: Table I, EPE, failures/time/ITF, where the files are.

    Args:
        metrics: the content of metrics.json (``RunFiles.metrics`` or ``read_metrics``).
        run_dir: the run's folder, to list the files in it.
    """
    summary = RunSummary.from_dict(metrics["summary"])
    lines = [f"Run {metrics['status']}: {summary.n_frames} frames.", "", table_one(summary.run),
             "", epe_table(summary.run), "", reliability_table(summary.run)]
    for note in run_notes(metrics.get("run", {})):
        lines += ["", note]
    kept = _run_on_disk(run_dir) if run_dir is not None else None
    if kept is not None and kept.get("run", {}).get("wall_time_s") != metrics.get(
            "run", {}).get("wall_time_s"):
        # A stopped run over a finished one is dropped, and the finished one stays.
        lines += ["", f"Not kept: {Path(run_dir)}/ holds the previous run ({kept.get('status')}),"
                      f" as it was."]
    elif run_dir is not None:
        listed = metrics.get("files", {})
        names = [(what, name) for what, name in listed.items() if what != "plots"]
        names += [("plot", name) for name in listed.get("plots", ())]
        lines += ["", f"Results in {Path(run_dir)}/:"]
        lines += [f"  {name:<28} {what}" for what, name in names]
    return "\n".join(lines)


def _run_on_disk(run_dir: str | Path) -> dict | None:
    """The metrics.json in ``run_dir`` (:func:`read_metrics`), or None when there is none."""
    try:
        return read_metrics(Path(run_dir))
    except ValueError:
        return None


# ----------------------------------------------------------------------------- files
def _json_ready(value):
    """Nested plain types for JSON: NaN/inf -> None, numpy -> Python, Path -> str."""
    if isinstance(value, Mapping):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if is_dataclass(value) and not isinstance(value, type):
        return _json_ready(asdict(value))
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_json_ready(item) for item in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return str(value)


def frames_csv_text(records: Iterable[FrameRecord]) -> str:
    """frames.csv: one row per (frame, method), columns ``sim.harness.scoring.RECORD_FIELDS``."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(RECORD_FIELDS)
    # Plain attribute reads: dataclasses.asdict deep-copies every field, which made this the
    # slowest part of a checkpoint.
    writer.writerows([getattr(record, name) for name in RECORD_FIELDS] for record in records)
    return buffer.getvalue()


def failures_jsonl_text(failures: Iterable[Mapping]) -> str:
    """failures.jsonl: one JSON object per line and failed estimate, in frame order
    (``sim.harness.scoring.failure_entry``); NaN and infinite numbers as null."""
    return "".join(json.dumps(_json_ready(entry), allow_nan=False) + "\n" for entry in failures)


def metrics_document(*, scenario: Mapping, summary: RunSummary, meta: Mapping, status: str,
                     files: RunFiles) -> dict:
    """The content of metrics.json (JSON-ready)."""
    return _json_ready({
        "format": METRICS_FORMAT,
        "status": status,
        "seed": meta.get("seed", scenario.get("seed")),
        "scenario": scenario,
        "run": meta,
        "provenance": provenance(),
        "summary": summary.to_dict(),
        "files": {what: path.name for what, path in files.listing() if what != "plot"}
                 | {"plots": [path.name for path in files.plots]},
    })


def safe_name(method: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", method)


def estimates_plot_names(methods: Sequence[str]) -> list[str]:
    """``estimates_<method>.png`` per method, its name made safe for a file; methods whose safe
    names coincide (``a/b`` and ``a_b``, names of other scripts) get ``_2``, ``_3``... in their
    order, so that no plot overwrites another."""
    names, taken = [], set()
    for method in methods:
        stem, count = f"estimates_{safe_name(method)}", 1
        while (name := stem + (f"_{count}" if count > 1 else "") + ".png") in taken:
            count += 1
        taken.add(name)
        names.append(name)
    return names


def save_figure(figure: Figure, path: Path) -> Path:
    FigureCanvasAgg(figure)
    with atomic_path(path) as temporary:
        # zlib level 1: a fifth of the default level's time for a file about 10% larger.
        figure.savefig(temporary, format="png", dpi=PLOT_DPI, pil_kwargs={"compress_level": 1})
    return path


#: Estimates and errors beyond this (degrees or pixels) are drawn at it.
PLOT_LIMIT = 1e9


def plot_estimates(path: Path, records: Sequence[FrameRecord], method: str) -> Path:
    """Fig. 8/9 style: rotation, x and y over time, estimate against truth, for one method.

    The truth's fit residual is shaded around the x and y truth (image motion no rigid model
    explains); frames without an estimate are marked with red crosses on the truth; dotted
    lines mark reference-frame changes (the start of each gait cycle by default).
    """
    records = [record for record in records if record.method == method]
    times = np.array([record.time_s for record in records])
    # Fixed margins: the constrained layout cost a third of a run's final write.
    figure = Figure(figsize=(9, 7))
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.07, top=0.95, hspace=0.08)
    axes = figure.subplots(3, 1, sharex=True)
    failed = np.array([record.status != "ok" for record in records], dtype=bool)
    residual = np.array([record.truth_residual_px for record in records])
    changes = [record.time_s for previous, record in zip(records, records[1:])
               if record.reference_index != previous.reference_index]
    for ax, axis in zip(axes, AXES):
        truth = np.array([record.truth_of(axis) for record in records])
        # Any finite estimate is scored; one near the float range would break the axis ticks.
        estimate = np.clip([record.estimate_of(axis) for record in records], -PLOT_LIMIT,
                           PLOT_LIMIT)
        ax.plot(times, truth, color="black", linewidth=1.2, label="ground truth")
        if axis != "rotation":
            ax.fill_between(times, truth - residual, truth + residual, color="0.85",
                            label="truth ± fit residual")
        ax.plot(times, estimate, color="tab:blue", linewidth=1.0, marker=".", markersize=3,
                label=method)
        if failed.any():
            ax.plot(times[failed], truth[failed], "x", color="tab:red", label="no estimate")
        # One collection per axes: an axvline per change cost a third of the figure's time.
        ax.vlines(changes, 0.0, 1.0, transform=ax.get_xaxis_transform(), colors="0.6",
                  linestyles=":", linewidths=0.8)
        ax.set_ylabel(f"{AXIS_TITLES[axis].split()[0]} ({AXIS_UNITS[axis]})")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[0].set_title(f"{method}: estimated and true displacement of each frame")
    axes[-1].set_xlabel("simulated time (s)")
    return save_figure(figure, path)


#: Narrowest range a histogram spans: equal errors (an estimates file with a constant offset)
#: would otherwise ask numpy for more bins than floats exist in their range.
MIN_HISTOGRAM_RANGE = 1e-3
MAX_HISTOGRAM_BINS = 100


def _shared_bins(values: np.ndarray) -> np.ndarray:
    """Bin edges for all methods' errors: the square-root rule, at most MAX_HISTOGRAM_BINS."""
    low, high = float(values.min()), float(values.max())
    middle, half = (low + high) / 2, max(high - low, MIN_HISTOGRAM_RANGE) / 2
    n_bins = min(MAX_HISTOGRAM_BINS, int(np.ceil(np.sqrt(values.size))))
    return np.linspace(middle - half, middle + half, n_bins + 1)


def plot_error_histograms(path: Path, records: Sequence[FrameRecord],
                          methods: Sequence[str]) -> Path:
    """Histograms of the absolute errors per axis, one outline per method, shared bins."""
    figure = Figure(figsize=(12, 4))
    figure.subplots_adjust(left=0.06, right=0.99, bottom=0.13, top=0.97, wspace=0.25)
    axes = figure.subplots(1, 3)
    for ax, axis in zip(axes, AXES):
        errors = {method: np.minimum([r.error_of(axis) for r in records
                                      if r.method == method and r.scored], PLOT_LIMIT)
                  for method in methods}
        pooled = np.concatenate([values for values in errors.values()] or [np.empty(0)])
        if pooled.size == 0:
            ax.text(0.5, 0.5, "no scored frames", ha="center", va="center",
                    transform=ax.transAxes)
        else:
            bins = _shared_bins(pooled)
            for method, values in errors.items():
                if values.size:
                    ax.hist(values, bins=bins, histtype="step", linewidth=1.5, label=method)
            ax.legend(fontsize="small")
        ax.set_xlabel(f"|error| {AXIS_TITLES[axis].split()[0].lower()} ({AXIS_UNITS[axis]})")
        ax.set_ylabel("frames")
        ax.grid(True, alpha=0.3)
    return save_figure(figure, path)


def write_run_outputs(run_dir: str | Path, *, scenario: Mapping,
                      records: Sequence[FrameRecord], summary: RunSummary, meta: Mapping,
                      status: str, failures: Sequence[Mapping] = (), plots: bool = True,
                      recording: str | Path | None = None, plot_pool=None) -> RunFiles:
    """Write frames.csv, failures.jsonl, the plots, summary.md and (last) metrics.json into
    ``run_dir``.

    Safe to call repeatedly during a run (each call replaces complete files with complete
    files); pass ``plots=False`` for cheap checkpoints.

    Args:
        run_dir: the run's folder (created if missing).
        scenario: the resolved scenario (JSON-able mapping; ``name`` and ``seed`` are shown).
        records: every FrameRecord of the run, in frame order.
        summary: ``sim.harness.scoring.summarize(records, itf)``.
        meta: facts about the run: ``seed``, methods and their parameters, reference policy,
            duration, anything worth keeping (stored under "run" in metrics.json).
        status: how the run ended, e.g. "complete", "interrupted", "fell at 3.2 s".
        failures: the failed estimates' entries (``sim.harness.scoring.failure_entry``), in
            frame order.
        plots: draw the PNG plots (about 0.2 s per method).
        recording: the run's .rrd (written by ``sim.harness.recording.RunRecorder``), to list it.
        plot_pool: a pool of worker processes (``threads.single_thread_pool``) that draws the
            per-method plots (each gets its method's records) while this process draws the
            histograms; None: all here.
    """
    if not isinstance(status, str) or not status:
        raise ValueError(f"status must be a non-empty string such as 'complete'; got {status!r}")
    run_dir = Path(run_dir)
    records = list(records)
    plot_paths = ()
    if plots:
        plot_paths = tuple(run_dir / name for name in estimates_plot_names(summary.methods)) \
            + (run_dir / HISTOGRAMS_PNG,)
    files = RunFiles(run_dir, run_dir / FRAMES_CSV, run_dir / FAILURES_JSONL,
                     run_dir / METRICS_JSON, run_dir / SUMMARY_MD, plot_paths,
                     None if recording is None else Path(recording))
    write_text_atomic(files.frames_csv, frames_csv_text(records))
    write_text_atomic(files.failures_jsonl, failures_jsonl_text(failures))
    if plots:
        jobs = [(path, [record for record in records if record.method == method], method)
                for method, path in zip(summary.methods, plot_paths)]
        drawn = [plot_pool.submit(plot_estimates, *job) for job in jobs] if plot_pool else None
        if drawn is None:
            for job in jobs:
                plot_estimates(*job)
        plot_error_histograms(plot_paths[-1], records, summary.methods)
        for plot in drawn or ():
            plot.result()
    context = dict(scenario=scenario, summary=summary, meta=meta, status=status, files=files)
    write_text_atomic(files.summary_md, summary_markdown(**context))
    document = metrics_document(**context)
    write_text_atomic(files.metrics_json, json.dumps(document, indent=2, allow_nan=False) + "\n")
    return replace(files, metrics=document)


# ----------------------------------------------------------------------------- several runs
def read_metrics(run: str | Path) -> dict:
    """metrics.json of a run folder (or the file itself); ValueError if absent or unreadable."""
    path = Path(run)
    if path.is_dir():
        path = path / METRICS_JSON
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"cannot read run metrics {path}: {error}; expected a run folder "
                         f"holding {METRICS_JSON} (written by a run)") from error
    if not isinstance(document, dict) or document.get("format") != METRICS_FORMAT:
        found = document.get("format") if isinstance(document, dict) else type(document).__name__
        raise ValueError(f"{path} is not a run's metrics file (format {found!r}, expected "
                         f"{METRICS_FORMAT!r})")
    for key, kind in (("status", str), ("scenario", dict), ("run", dict), ("summary", dict)):
        if not isinstance(document.get(key), kind):
            raise ValueError(f"{path}: '{key}' is missing or not a {kind.__name__}; expected the "
                             f"{METRICS_JSON} a run writes")
    if not isinstance(document["summary"].get("run"), dict):
        raise ValueError(f"{path}: 'summary.run' is missing or not a dict; expected the "
                         f"{METRICS_JSON} a run writes")
    for method, figures in document["summary"]["run"].items():
        try:
            MethodScore.from_dict(figures)
        except (TypeError, ValueError, KeyError, AttributeError) as error:
            raise ValueError(f"{path}: 'summary.run.{method}' is not a method's figures "
                             f"({type(error).__name__}: {error}); expected the {METRICS_JSON} "
                             f"a run writes") from None
    return document


def score_rows(metrics: Mapping | None) -> list[dict]:
    """One row per method of a run: its figures over the whole run, read from metrics.json.

    Args:
        metrics: the content of a run's metrics.json (``read_metrics``), or None for a run
            that left none.

    Returns:
        Dicts with the keys "method", "frames", the mean and the variance of |error| of each
        axis (``MEAN_ERROR_COLUMNS``, ``ERROR_VARIANCE_COLUMNS``), "epe_mean_px",
        "epe_above_floor_px", "failure_rate", "ms_per_frame", "itf_db", "itf_raw_db",
        "scored_frames", "large_errors" (``MethodScore.n_large_errors``: None when not
        counted), "large_error_frames" (``MethodScore.large_errors``) and "failures" (status
        -> failed frames); a figure metrics.json has none of is NaN.
        A run that scored no frame (it fell at once) has no row.
    """
    scores = ((metrics or {}).get("summary") or {}).get("run") or {}
    rows = []
    for method, data in scores.items():
        score = MethodScore.from_dict(data)
        rows.append({"method": method, "frames": score.n_frames,
                     **{MEAN_ERROR_COLUMNS[axis]: score.errors[axis].mean for axis in AXES},
                     **{ERROR_VARIANCE_COLUMNS[axis]: score.errors[axis].variance
                        for axis in AXES},
                     "epe_mean_px": score.epe.mean,
                     "epe_above_floor_px": score.epe_above_floor_px,
                     "failure_rate": score.failure_rate, "ms_per_frame": score.ms_mean,
                     "itf_db": score.itf_db, "itf_raw_db": score.itf_raw_db,
                     "scored_frames": score.n_scored, "large_errors": score.n_large_errors,
                     "large_error_frames": score.large_errors,
                     "failures": dict(score.failures)})
    return rows


def aggregate_runs(run_dirs: Iterable[str | Path], out_path: str | Path | None = None,
                   compact: bool = False) -> str:
    """One Markdown table over several runs: a row per run and method, Table I figures.

    A run that scored no frame (it fell at once) still gets a row, with its status. With
    ``compact``, a row per run and a column per method instead, each cell the mean absolute
    error of rotation (deg) / x (px) / y (px) and the failure rate (the README's layout). With
    ``out_path`` the table is also written there (atomically).
    """
    runs = [Path(run) for run in run_dirs]
    if not runs:
        raise ValueError("no runs to aggregate; give one or more run folders")
    if out_path is not None and Path(out_path).is_dir():
        raise ValueError(f"--out {out_path}: is a folder; accepted: the path of a file for the "
                         "table")
    table = _compact_table(runs) if compact else _long_table(runs)
    if out_path is not None:  # its folder made only now: a refused table leaves none behind
        _check_not_a_run_file(Path(out_path), runs)
        prepare_output_dir(Path(out_path).parent, option="--out's folder")
        write_text_atomic(out_path, table + "\n")
    return table


def _check_not_a_run_file(out_path: Path, runs: list[Path]) -> None:
    """ValueError when ``out_path`` is the metrics.json of one of ``runs`` or a file it lists:
    the table would replace what it was read from."""
    target = out_path.resolve()
    for run in runs:
        folder = run if run.is_dir() else run.parent
        listed = read_metrics(run).get("files")
        names = [METRICS_JSON]
        for entry in (listed.values() if isinstance(listed, dict) else ()):
            names.extend(entry if isinstance(entry, list) else [entry])
        if any(isinstance(name, str) and (folder / name).resolve() == target for name in names):
            raise ValueError(f"--out {out_path}: is a file of the run {folder}; accepted: a path "
                             f"other than the runs' own files")


def _compact_table(runs: list[Path]) -> str:
    cells: dict[str, dict[str, str]] = {}
    methods: list[str] = []
    folders = [(run if run.is_dir() else run.parent) for run in runs]
    names = [folder.resolve().name for folder in folders]  # "." has a name too
    for run, folder, name in zip(runs, folders, names):
        document = read_metrics(run)
        # Two runs of one name (results/a/x, results/b/x) are told apart by their paths.
        label = str(folder) if names.count(name) > 1 else name
        if document["status"] != "complete":  # an unfinished run does not pass for a whole one
            label += f" ({document['status']})"
        if document["run"].get("max_frames") is not None:  # nor one cut short on purpose
            label += (f" (--max-frames {document['run']['max_frames']}: "
                      f"{document['run'].get('frames_done')} frames)")
        if label in cells:
            raise ValueError(f"run folder {folder} given twice; accepted: each run once")
        cells[label] = {}
        for score in score_rows(document):
            if score["method"] not in methods:
                methods.append(score["method"])
            cells[label][score["method"]] = (
                " / ".join(format_number(score[MEAN_ERROR_COLUMNS[axis]]) for axis in AXES)
                + f" ({format_number(100 * score['failure_rate'], 0)}%)")
    return markdown_table(("run", *methods), ((label, *(row.get(m, "n/a") for m in methods))
                                              for label, row in cells.items()))


def _long_table(runs: list[Path]) -> str:
    rows = []
    seen = set()
    for run in runs:
        folder = (run if run.is_dir() else run.parent).resolve()
        if folder in seen:  # it would count twice
            raise ValueError(f"run folder {run} given twice; accepted: each run once")
        seen.add(folder)
        document = read_metrics(run)
        head = (run.name if run.is_dir() else run.parent.name,
                str((document.get("scenario") or {}).get("name", "")), document["status"])
        scores = score_rows(document)
        if not scores:
            rows.append((*head, "-", "0", *("n/a",) * 7))
        rows += [(*head, score["method"], str(score["frames"]),
                  *(f"{format_number(score[MEAN_ERROR_COLUMNS[axis]])} / "
                    f"{format_number(score[ERROR_VARIANCE_COLUMNS[axis]])}" for axis in AXES),
                  f"{format_number(score['epe_mean_px'])} / "
                  f"{format_number(score['epe_above_floor_px'])}",
                  f"{format_number(100 * score['failure_rate'], 1)}%",
                  format_number(score["ms_per_frame"]),
                  f"{format_number(score['itf_db'])} / {format_number(score['itf_raw_db'])}")
                 for score in scores]
    return markdown_table(("Run", "Scenario", "Status", "Method", "Frames",
                           "Rotation mean / var (deg)", "X mean / var (px)",
                           "Y mean / var (px)", "EPE / above floor (px)", "Failure rate",
                           "ms/frame", "ITF comp / raw (dB)"), rows)
