"""Sweeps: scenarios x seeds x noise levels, run in parallel, resumable, aggregated.

One concept per module:

- ``spec``: the sweep file (its layout is in that module's docstring) and its validation,
  built from the generic checks of ``validation``;
- ``plan``: the runs of a sweep and which of them are done already (resuming);
- ``execute``: ``run_sweep``, on a local spawn process pool or on Ray;
- ``tables``: the table and the plots written at the end.

Output folder of a sweep (``run_sweep(spec, out_dir)``)::

    <out_dir>/runs/<scenario>__seed<seed>__noise<level>/   one run's files (metrics.json, ...)
    <out_dir>/sweep.md, sweep.csv                          one row per run and method
    <out_dir>/error_vs_noise__<scenario>.png               |error| and failures vs noise level

A run whose metrics.json says ``"status": "complete"`` (or ``"fell"``) and that scored every
method of the sweep is skipped, so an interrupted sweep is resumed by running it again, and a
method added to the sweep file is scored by running it again.
"""

from sim.harness.sweep.execute import BACKENDS, run_sweep
from sim.harness.sweep.plan import (DONE_STATUSES, RUNS_FOLDER, RunOutcome, SweepRun,
                                    completed_metrics, default_sweep_dir, expand_sweep,
                                    plan_sweep)
from sim.harness.sweep.spec import (ALLOWED, DEFAULT_NOISE_KEY, SweepError, SweepSpec,
                                    load_sweep, scenario_label, sweep_from_dict)
from sim.harness.sweep.tables import (COLUMNS, ERROR_COLUMNS, TABLE_CSV, TABLE_MD, SweepResult,
                                      table_csv, table_markdown, table_rows,
                                      write_sweep_outputs)

__all__ = [
    "ALLOWED", "BACKENDS", "COLUMNS", "DEFAULT_NOISE_KEY", "DONE_STATUSES", "ERROR_COLUMNS",
    "RUNS_FOLDER", "TABLE_CSV", "TABLE_MD", "RunOutcome", "SweepError", "SweepResult",
    "SweepRun", "SweepSpec", "completed_metrics", "default_sweep_dir", "expand_sweep",
    "load_sweep", "plan_sweep", "run_sweep", "scenario_label", "sweep_from_dict", "table_csv",
    "table_markdown", "table_rows", "write_sweep_outputs",
]
