"""The evaluation harness: scenario files, ground truth, scoring, the run loop, outputs,
recordings, the CI gate, sweeps, benchmarks and the ``egostab`` command."""
