"""The ``egostab suite`` subcommand: its options and its handler (cli.py wires it in)."""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

from sim.harness.threads import WORKERS_PER_CORE
from sim.command_line import POSITIVE_INTEGER, path_option


def add_suite_parser(commands, results: Path) -> argparse.ArgumentParser:
    """Add the ``suite`` subcommand to ``commands`` (an argparse subparsers object); suites
    write to ``results/suites/<name>`` unless ``--out`` says otherwise."""
    suite = commands.add_parser(
        "suite", help="run a suite file: many sequences, means with 95%% bootstrap intervals")
    suite.add_argument("suite_file", type=Path,
                       help="a suite TOML file (see scenarios/suites/ and docs/suites.md)")
    suite.add_argument("--out", type=path_option, default=None,
                       help="suite folder (default: results/suites/<name>; resumable: complete "
                            "runs are skipped)")
    suite.add_argument("--workers", type=POSITIVE_INTEGER, default=None,
                       help="runs at a time (default: one per core; locally at most "
                            f"{WORKERS_PER_CORE} per core; with --ray, any)")
    suite.add_argument("--estimates", type=_estimates, action="append", default=None,
                       metavar="NAME=PATH",
                       help="estimates of another program, one CSV per sequence (columns "
                            "frame, angle_deg, dx, dy [, status]); {sequence} in PATH stands "
                            "for each sequence's folder name, e.g. mine=mine/{sequence}.csv; "
                            "scored and compared like a method; repeatable")
    suite.add_argument("--check-estimates", action="store_true",
                       help="pass the estimates files' ok rows through the trust check every "
                            "method's ok passes (rows it cannot confirm become unverified); "
                            "default: scored as given")
    suite.add_argument("--ray", action="store_true", help="run on a Ray cluster (extra 'cluster')")
    suite.add_argument("--ray-address", default=None,
                       help="with --ray: the Ray cluster address ('auto', 'ray://host:10001'; "
                            "default: $RAY_ADDRESS or a local instance)")
    suite.set_defaults(handler=run_suite_command, results=results)
    return suite


def _estimates(text: str) -> tuple[str, str]:
    from sim.harness.score import parse_estimates_argument

    refused = argparse.ArgumentTypeError(f"{text!r}: accepted: NAME=PATH, NAME not blank, "
                                         f"{{sequence}} in PATH standing for each sequence's "
                                         f"folder name")
    if "=" not in text:  # a file's stem names nothing here: every sequence has its own file
        raise refused
    try:
        name, path = parse_estimates_argument(text)
    except ValueError:
        raise refused from None
    return name, str(Path(path).absolute())  # the workers may run in another folder


def run_suite_command(args: argparse.Namespace) -> int:
    """Run the suite; print its tables. Exit status 1 if a run failed, 2 without Ray's extra."""
    from sim.atomic import prepare_output_dir
    from sim.harness.runner import check_folder_of_its_own
    from sim.harness.runset import command_line_backend, run_on_command_line
    from sim.harness.score import estimates_by_name
    from sim.harness.suite.run import check_estimates_files, default_suite_dir, run_suite
    from sim.harness.suite.spec import load_suite

    backend = command_line_backend(args.ray, args.ray_address, args.workers)
    spec = load_suite(args.suite_file)
    estimates = estimates_by_name(args.estimates)
    check_estimates_files(spec, estimates, args.check_estimates)  # before any folder
    out_dir = args.out or default_suite_dir(spec, args.results)
    check_folder_of_its_own(out_dir, "suite")
    out_dir = prepare_output_dir(out_dir)
    return run_on_command_line("suite", functools.partial(run_suite, estimates=estimates,
                                                          check_estimates=args.check_estimates),
                               spec, out_dir, backend, args.workers, args.ray_address)
