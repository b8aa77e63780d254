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

import importlib

# Each name's module, imported when the name is first read: the command line builds the
# ``suite`` subcommand's parser from ``command`` alone, without the suite's scoring and
# statistics (scipy, matplotlib), which cost every other command a second.
_MODULE_OF = {
    "add_suite_parser": "command",
    "run_suite_command": "command",
    "SuiteRun": "run",
    "default_suite_dir": "run",
    "plan_suite": "run",
    "run_suite": "run",
    "ALLOWED": "spec",
    "SEQUENCE_ALLOWED": "spec",
    "VARIED_KEYS": "spec",
    "SuiteError": "spec",
    "SuiteSequence": "spec",
    "SuiteSpec": "spec",
    "load_suite": "spec",
    "suite_from_dict": "spec",
    "BOOTSTRAP_SEED": "statistics",
    "CONFIDENCE_LEVEL": "statistics",
    "Interval": "statistics",
    "mean_interval": "statistics",
    "paired_difference": "statistics",
    "COLUMNS": "tables",
    "FIGURES": "tables",
    "TABLE_CSV": "tables",
    "TABLE_JSON": "tables",
    "TABLE_MD": "tables",
    "SuiteResult": "tables",
    "suite_figures": "tables",
    "write_suite_outputs": "tables",
}
__all__ = sorted(_MODULE_OF)


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
