"""Suites: many sequences (scene layouts x gaits x seeds), every method scored, with intervals.

One concept per module:

- ``spec``: the suite file (its layout is in that module's docstring) and its validation;
- ``run``: ``run_suite``, one run per sequence on the sweep's executors (local processes or
  Ray), resumable;
- ``statistics``: bootstrap intervals over sequences, and paired differences;
- ``tables``: per-sequence rows, the figures, and suite.md / suite.csv / suite.json;
- ``command``: the ``egostab suite`` subcommand.

Output folder of a suite (``run_suite(spec, out_dir)``)::

    <out_dir>/runs/<template>__<gait>__scene<scene seed>__seed<seed>/   one run's files
    <out_dir>/suite.md, suite.csv, suite.json                           the figures

A run whose metrics.json says ``"status": "complete"`` (or ``"fell"``) and that scored every
method of the suite is skipped, so an interrupted suite is resumed by running it again, and a
method added to the suite file is scored on the recorded sequences by running it again.
docs/suites.md explains the figures.
"""

from sim.harness.suite.command import add_suite_parser, run_suite_command
from sim.harness.suite.run import SuiteRun, default_suite_dir, plan_suite, run_suite
from sim.harness.suite.spec import (ALLOWED, SEQUENCE_ALLOWED, VARIED_KEYS, SuiteError,
                                    SuiteSequence, SuiteSpec, load_suite, suite_from_dict)
from sim.harness.suite.statistics import (BOOTSTRAP_SEED, CONFIDENCE_LEVEL, Interval,
                                          mean_interval, paired_difference)
from sim.harness.suite.tables import (COLUMNS, FIGURES, TABLE_CSV, TABLE_JSON, TABLE_MD,
                                      SuiteResult, suite_figures, write_suite_outputs)

__all__ = [
    "ALLOWED", "BOOTSTRAP_SEED", "COLUMNS", "CONFIDENCE_LEVEL", "FIGURES", "SEQUENCE_ALLOWED",
    "TABLE_CSV", "TABLE_JSON", "TABLE_MD", "VARIED_KEYS", "Interval", "SuiteError", "SuiteResult",
    "SuiteRun", "SuiteSequence", "SuiteSpec", "add_suite_parser", "default_suite_dir",
    "load_suite", "mean_interval", "paired_difference", "plan_suite", "run_suite",
    "run_suite_command", "suite_figures", "suite_from_dict", "write_suite_outputs",
]
