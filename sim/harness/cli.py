"""``egostab``: the harness's one console command.

Subcommands: ``run`` a walking scenario, ``record`` it as a sequence folder, ``score`` a
sequence folder (methods, or estimates written by any program), ``ideal`` (the paper's ideal
experiment on one image), ``aggregate`` several runs into one table, ``list`` the shipped
scenarios, ``methods`` the methods that can be scored (docs/plugins.md), ``bench`` the speed
figures, ``gate`` the CI regression gate, ``sweep`` many runs in parallel (locally or on Ray),
``suite`` held-out sequences with confidence intervals (docs/suites.md). Each has ``--help``.
"""

from __future__ import annotations

# Only light modules here: the heavy ones (numpy, OpenCV, MuJoCo, the subcommands' modules: a
# second) load within main(), where a stop signal ends the command with one line.
import argparse
import signal
import sys
from pathlib import Path
from typing import NoReturn

from scenarios import DEFAULT_SCENARIO
from sim.command_line import (BROKEN_PIPE_STATUS, MAX_SEED, POSITIVE_INTEGER, OneLineParser,
                              discard_output, integer_option, number_option, path_option)
from sim.harness.interrupts import (INTERRUPTED_STATUS, STOP_SIGNALS, ProcessStops,
                                    interrupt_reason, stop_signals_interrupt)
from sim.harness.threads import WORKERS_PER_CORE

#: Where runs write unless told otherwise: results/<scenario name>/.
DEFAULT_RESULTS = Path("results")
#: Where `record` writes unless told otherwise: sequences/<scenario name>/.
DEFAULT_SEQUENCES = Path("sequences")


#: The most frames of the ideal experiment's cycle (each held in memory: 25 kB at 176 x 144).
MAX_IDEAL_FRAMES = 10_000
#: The largest unit of a 16-bit depth PNG (1 m: 65 km at most).
MAX_DEPTH_UNIT_MM = 1000.0


def _methods(text: str) -> tuple[str, ...]:
    """The methods of ``--methods``, each resolved now so a bad one is refused up front."""
    from sim.harness.methods import ACCEPTED_FORMS, MethodError, method_factory

    methods = tuple(name.strip() for name in text.split(",") if name.strip())
    if not methods:
        raise argparse.ArgumentTypeError(
            f"no method given; accepted: {ACCEPTED_FORMS}; several comma separated, or 'all'")
    for name in methods:
        try:
            method_factory(name)
        except MethodError as error:
            raise argparse.ArgumentTypeError(f"{error}; several comma separated, or 'all'") \
                from None
    repeated = sorted({name for name in methods if methods.count(name) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(
            f"method(s) {', '.join(repeated)} given more than once; accepted: each method once")
    return methods


def method_list(text: str) -> tuple[str, ...]:
    """The argparse ``type`` of ``--methods``: comma-separated methods, each resolved now, or
    ``all`` alone (every available built-in method)."""
    from sim.harness.methods import ALL_BUILT_INS
    from stabilizer import available_methods

    # As _methods reads a list: " all" and "all," are "all" too.
    names = [name.strip() for name in text.split(",") if name.strip()]
    if names == [ALL_BUILT_INS]:
        return available_methods()
    if ALL_BUILT_INS in names:  # not an entry point of that name either: `egostab methods`
        raise argparse.ArgumentTypeError(f"{ALL_BUILT_INS!r} among other methods; accepted: "
                                         f"{ALL_BUILT_INS!r} alone (every built-in method), or "
                                         f"a list of methods")
    return _methods(text)


def _cmd_run(args: argparse.Namespace) -> int:
    from sim.harness.runner import RunConfig, run, scenario_name
    from sim.harness.report import terminal_summary

    from sim.atomic import prepare_output_dir
    from sim.harness.scenario import load_scenario
    from sim.harness.threads import check_local_workers

    # A bad scenario or worker count is reported before any folder is made.
    load_scenario(args.scenario)
    check_local_workers(args.workers)
    out_dir = prepare_output_dir(args.out or DEFAULT_RESULTS / scenario_name(args.scenario))
    metrics = run(RunConfig(scenario=args.scenario, out_dir=str(out_dir), methods=args.methods,
                            record=not args.no_record, max_frames=args.max_frames,
                            seed=args.seed, progress=not args.quiet, workers=args.workers))
    print(terminal_summary(metrics, out_dir))
    return _ending("egostab run", metrics["status"], metrics["run"].get("message", ""))


def _cmd_record(args: argparse.Namespace) -> int:
    from sim.atomic import prepare_output_dir
    from sim.harness.runner import RecordConfig, record, scenario_name
    from sim.harness.scenario import load_scenario

    load_scenario(args.scenario)  # a bad scenario is reported before any folder is made
    # record() refuses a folder of the user's own files before simulating (it exists already).
    out_dir = prepare_output_dir(args.out or DEFAULT_SEQUENCES / scenario_name(args.scenario))
    header = record(RecordConfig(scenario=args.scenario, out_dir=str(out_dir),
                                 max_frames=args.max_frames, seed=args.seed,
                                 progress=not args.quiet))
    print(f"sequence folder: {out_dir} ({header['frames']} frames, {header['ended']})")
    return _ending("egostab record", header["ended"], header["message"])


def _ending(command: str, status: str, message: str) -> int:
    """The exit status of a run or recording that ended with ``status``, after saying how it
    ended: a stop in one line on stderr, as every stop of the command (status 130), a fall as a
    note with the results (status 0); a run that ended in error: status 1."""
    if status == "interrupted":
        print(f"{command}: {message}", file=sys.stderr)
        return INTERRUPTED_STATUS
    if message:
        print(f"Note: {message}")
    return 0 if status in ("complete", "fell") else 1


def _estimates(text: str) -> tuple[str, str]:
    from sim.harness.score import parse_estimates_argument

    try:
        return parse_estimates_argument(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _sequence_name(sequence: Path) -> str:
    """A sequence folder's name; for a suite's (``runs/<name>/sequence``), its run's name, so
    that scoring several of a suite's sequences does not write them all to one folder."""
    from sim.harness.suite.run import SEQUENCE_FOLDER

    folder = Path(sequence).resolve()  # `depth/..` or `.` name the folder they stand for
    return folder.parent.name if folder.name == SEQUENCE_FOLDER else folder.name


def _cmd_score(args: argparse.Namespace) -> int:
    from sim.atomic import check_output_path
    from sim.harness.report import terminal_summary
    from sim.harness.score import ScoreConfig, estimates_by_name, score
    from sim.harness.sequence import load_sequence

    estimates = estimates_by_name(args.estimates)
    # A bad sequence or --out is reported before any folder is made (score() reads each
    # estimates file once, a pipe too, and refuses a bad one before it makes the folder).
    load_sequence(args.sequence)
    out = Path(args.out or DEFAULT_RESULTS / _sequence_name(args.sequence))
    if args.out is None and out.resolve().is_relative_to(Path(args.sequence).resolve()):
        raise ValueError(f"the default run folder {out} (results/<sequence name> in the working "
                         "directory) is in the sequence folder; accepted: --out a folder of its "
                         "own, or scoring from outside the sequence folder")
    # Built before the folder is made: ScoreConfig refuses a run folder in the sequence folder.
    config = ScoreConfig(sequence=str(args.sequence), out_dir=str(out), methods=args.methods,
                         estimates=estimates, check_estimates=args.check_estimates,
                         trust_check=not args.no_check,
                         record=not args.no_record, workers=args.workers,
                         max_frames=args.max_frames, progress=not args.quiet)
    out_dir = check_output_path(out)
    metrics = score(config)
    print(terminal_summary(metrics, out_dir))
    return _ending("egostab score", metrics["status"], metrics["run"].get("message", ""))


def _cmd_ideal(args: argparse.Namespace) -> int:
    from sim.harness.ideal import IdealConfig, run_ideal
    from sim.harness.report import terminal_summary

    metrics = run_ideal(IdealConfig(image=args.image, out_dir=str(args.out),
                                    trajectory=args.trajectory, methods=args.methods,
                                    n_frames=args.frames, resize=args.resize,
                                    depth_unit_mm=args.depth_unit_mm))
    print(terminal_summary(metrics, args.out))
    return _ending("egostab ideal", metrics["status"], metrics["run"].get("message", ""))


def _cmd_aggregate(args: argparse.Namespace) -> int:
    from sim.harness.report import aggregate_runs

    table = aggregate_runs(args.runs, out_path=args.out, compact=args.compact)
    print(table)
    return 0


def _cmd_list(args: argparse.Namespace) -> int:
    from sim.harness.scenario import list_scenarios, load_scenario

    for path in list_scenarios():
        scenario = load_scenario(path)
        print(f"{path.stem:24s} {scenario.scene:10s} {scenario.duration_s:6.1f} s  "
              f"{scenario.description}")
    return 0


def _cmd_methods(args: argparse.Namespace) -> int:
    from sim.harness.methods import list_methods

    found = list_methods()
    width = max(len(info.name) for info in found)
    for info in found:
        print(f"{info.name:{width}s}  {info.origin}")
    print("Import paths are accepted too: package.module:Name, a class Name(reference, "
          "**params) with .estimate(current) -> Motion, or a function (reference, current) -> "
          "Motion or (angle_deg, dx, dy) (docs/plugins.md).")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from sim.atomic import prepare_output_dir
    from sim.harness.bench import run_benchmarks

    if args.out is not None:
        prepare_output_dir(args.out.parent or Path("."), option="--out's folder")
    run_benchmarks(quick=args.quick, out_path=args.out)
    return 0


def _cmd_gate(args: argparse.Namespace) -> int:
    from sim.atomic import prepare_output_dir
    from sim.harness.gate import run_gate
    from sim.harness.runner import check_folder_of_its_own

    check_folder_of_its_own(args.out, "gate")  # before the baseline's folder is made
    if args.update_baseline:
        if args.baseline.is_dir():
            raise ValueError(f"--baseline {args.baseline}: is a folder; accepted: the path of "
                             f"a JSON file (written at the end)")
        prepare_output_dir(args.baseline.parent or Path("."), option="--baseline's folder")
    return run_gate(baseline_path=args.baseline, update=args.update_baseline,
                    out_dir=args.out)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from sim.atomic import prepare_output_dir
    from sim.harness.runner import check_folder_of_its_own
    from sim.harness.runset import command_line_backend, run_on_command_line
    from sim.harness.sweep import default_sweep_dir, load_sweep, run_sweep

    backend = command_line_backend(args.ray, args.ray_address, args.workers)
    spec = load_sweep(args.sweep_file)
    out_dir = args.out or default_sweep_dir(spec, DEFAULT_RESULTS)
    check_folder_of_its_own(out_dir, "sweep")
    out_dir = prepare_output_dir(out_dir)
    return run_on_command_line("sweep", run_sweep, spec, out_dir, backend, args.workers,
                               args.ray_address)


def _add_simulation_arguments(parser: argparse.ArgumentParser, out_help: str) -> None:
    """The options of the commands that simulate a scenario (run, record)."""
    parser.add_argument("--out", type=path_option, default=None, help=out_help)
    parser.add_argument("--max-frames", type=POSITIVE_INTEGER, default=None,
                        help="stop after N frames")
    parser.add_argument("--seed", type=integer_option(0, MAX_SEED), default=None,
                        help="override the scenario's seed")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="egostab", description=__doc__.split("\n\n")[0].replace("``", ""),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.commands = parser.add_subparsers(dest="command", required=True,
                                                       metavar="COMMAND")

    run = commands.add_parser("run", help="run a walking scenario and score the stabilizers")
    run.add_argument("scenario", nargs="?", default=DEFAULT_SCENARIO,
                     help=f"scenario name (see `egostab list`) or TOML path "
                          f"(default: {DEFAULT_SCENARIO})")
    run.add_argument("--methods", type=method_list, default=None,
                     help="comma-separated methods (built-in, entry point or "
                          "package.module:Name; see `egostab methods`), or 'all' for the "
                          "built-in ones (default: the scenario's)")
    _add_simulation_arguments(run, "run folder (default: results/<scenario>)")
    run.add_argument("--no-record", action="store_true", help="do not write recording.rrd")
    run.add_argument("--workers", type=POSITIVE_INTEGER, default=None,
                     help="processes running the methods beside the simulation, one thread "
                          "each; 1: the methods run in this process (default: one per method "
                          "and core when more than one method runs, else 1; at most "
                          f"{WORKERS_PER_CORE} per core)")
    run.set_defaults(handler=_cmd_run)

    recorder = commands.add_parser(
        "record", help="simulate a scenario once and write it as a sequence folder "
                       "(docs/sequence-format.md)")
    recorder.add_argument("scenario", nargs="?", default=DEFAULT_SCENARIO,
                          help=f"scenario name or TOML path (default: {DEFAULT_SCENARIO})")
    _add_simulation_arguments(recorder, "sequence folder (default: sequences/<scenario>)")
    recorder.set_defaults(handler=_cmd_record)

    scorer = commands.add_parser(
        "score", help="score a sequence folder without simulating: methods and/or estimates "
                      "files; writes the run folder `run` writes")
    scorer.add_argument("sequence", type=path_option, help="sequence folder (`egostab record`)")
    scorer.add_argument("--methods", type=method_list, default=None,
                        help="comma-separated methods, or 'all' (default: the scenario's, or "
                             "none when --estimates is given)")
    scorer.add_argument("--estimates", type=_estimates, action="append", default=None,
                        metavar="[NAME=]FILE.csv",
                        help="estimates of another program: columns frame, angle_deg, dx, dy "
                             "[, status]; named NAME or the file's stem; repeatable")
    scorer.add_argument("--check-estimates", action="store_true",
                        help="pass the estimates files' ok rows through the trust check every "
                             "method's ok passes (rows it cannot confirm become unverified); "
                             "default: scored as given")
    scorer.add_argument("--no-check", action="store_true",
                        help="score the methods' estimates as each method reports them, without "
                             "the trust check their ok passes by default (figures not "
                             "comparable with a checked run's)")
    scorer.add_argument("--out", type=path_option, default=None,
                        help="run folder (default: results/<sequence folder name>; for a "
                             "suite's runs/<name>/sequence, results/<name>)")
    scorer.add_argument("--workers", type=POSITIVE_INTEGER, default=None,
                        help="processes running the methods, one thread each; 1: this "
                             "process (default: one per core; at most "
                             f"{WORKERS_PER_CORE} per core)")
    scorer.add_argument("--max-frames", type=POSITIVE_INTEGER, default=None,
                        help="score only the first N frames (default: every frame)")
    scorer.add_argument("--no-record", action="store_true", help="do not write recording.rrd")
    scorer.add_argument("--quiet", action="store_true", help="no progress bar")
    scorer.set_defaults(handler=_cmd_score)

    ideal = commands.add_parser(
        "ideal", help="the paper's ideal experiment: move one image along a known trajectory")
    ideal.add_argument("image", help="PNG: 8-bit disparity or 16-bit depth (see "
                                     "--depth-unit-mm); .npy depth in metres; or a scene name "
                                     "to render noise-free (e.g. corridor)")
    ideal.add_argument("--trajectory", default="paper_cycle",
                       help="'paper_cycle' (default: one gait cycle of the paper's magnitudes) "
                            "or a frames.csv of a walking run (its ground truth is replayed, "
                            "every frame; rotations within 180 deg, shifts within the image's "
                            "width and height)")
    ideal.add_argument("--frames", type=integer_option(2, MAX_IDEAL_FRAMES), default=None,
                       help=f"frames of the paper cycle (default 30, at most "
                            f"{MAX_IDEAL_FRAMES:,}); refused with a frames.csv trajectory")
    ideal.add_argument("--depth-unit-mm", type=number_option(0.0, MAX_DEPTH_UNIT_MM),
                       default=None, metavar="MM",
                       help="millimetres per unit of a 16-bit depth PNG (default: the unit "
                            "its sequence.json states for a frame of a sequence folder's "
                            "depth/ or exact/, 0.1 or 0.5; else 1)")
    ideal.add_argument("--methods", type=method_list, default=None,
                       help="comma-separated methods (built-in, entry point or "
                            "package.module:Name; see `egostab methods`), or 'all' (default: "
                            "all the built-in ones)")
    ideal.add_argument("--out", type=path_option,
                       default=DEFAULT_RESULTS / "ideal" / "custom",
                       help="output folder (default: results/ideal/custom)")
    ideal.add_argument("--resize", action="store_true",
                       help="scale an image larger than 1280 x 1024 pixels, or longer than "
                            "4096 on a side, down to fit (refused otherwise)")
    ideal.set_defaults(handler=_cmd_ideal)

    aggregate = commands.add_parser("aggregate", help="one table from several run folders")
    aggregate.add_argument("runs", nargs="+", type=path_option, help="run folders with metrics.json")
    aggregate.add_argument("--out", type=path_option, default=None,
                           help="also write the table here")
    aggregate.add_argument("--compact", action="store_true",
                           help="a row per run and a column per method: mean |error| of "
                                "rotation / x / y and the failure rate")
    aggregate.set_defaults(handler=_cmd_aggregate)

    listing = commands.add_parser("list", help="list the shipped scenarios")
    listing.set_defaults(handler=_cmd_list)

    methods = commands.add_parser(
        "methods", help="list the methods --methods accepts and where each comes from")
    methods.set_defaults(handler=_cmd_methods)

    bench = commands.add_parser("bench", help="print the speed figures, measured side by side")
    bench.add_argument("--quick", action="store_true", help="fewer repetitions")
    bench.add_argument("--out", type=path_option, default=None,
                       help="also write the figures as Markdown (e.g. results/bench.md)")
    bench.set_defaults(handler=_cmd_bench)

    gate = commands.add_parser(
        "gate", help="CI regression gate against results/baseline.json",
        description="Run the CI scenarios and compare their figures with the baseline. Exit "
                    "status: 0, every figure within its tolerance; 1, a figure moved or a CI "
                    "run did not complete (the robot fell), or the gate itself failed (with a "
                    "traceback); 2, bad input (options, a missing or malformed baseline), "
                    "refused before anything runs; 130, stopped (Ctrl-C, SIGTERM, SIGHUP).")
    gate.add_argument("--baseline", type=path_option,
                      default=DEFAULT_RESULTS / "baseline.json",
                      help="the baseline to compare with (default: results/baseline.json, "
                           "relative to the current folder: the repository's root)")
    gate.add_argument("--update-baseline", action="store_true",
                      help="rewrite the baseline with this run's metrics (on purpose)")
    gate.add_argument("--out", type=path_option, default=DEFAULT_RESULTS / "gate",
                      help="folder for the gate's runs (default: results/gate)")
    gate.set_defaults(handler=_cmd_gate)

    sweep = commands.add_parser("sweep", help="run a sweep file: scenarios x seeds x noise "
                                              "levels, every method on each run")
    sweep.add_argument("sweep_file", type=Path,
                       help="a sweep TOML file (see scenarios/sweeps/ and the README's Sweeps)")
    sweep.add_argument("--out", type=path_option, default=None,
                       help="sweep folder (default: results/sweeps/<name>; resumable: complete "
                            "runs are skipped)")
    sweep.add_argument("--workers", type=POSITIVE_INTEGER, default=None,
                       help="runs at a time (default: one per core; locally at most "
                            f"{WORKERS_PER_CORE} per core; with --ray, any)")
    sweep.add_argument("--ray", action="store_true", help="run on a Ray cluster (extra 'cluster')")
    sweep.add_argument("--ray-address", default=None,
                       help="with --ray: the Ray address ('auto' = running cluster; default: "
                            "$RAY_ADDRESS, or else a local instance)")
    sweep.set_defaults(handler=_cmd_sweep)

    from sim.harness.suite.command import add_suite_parser

    add_suite_parser(commands, DEFAULT_RESULTS)
    return parser


def _describe_os_error(error: OSError) -> str:
    """One line: the file and what the system said, or the message raised with it."""
    if error.errno is None:
        return str(error)
    where = f"{error.filename}: " if error.filename else ""
    return f"{where}{error.strerror or error}"


def main(argv: list[str] | None = None, stops: ProcessStops | None = None) -> int:
    """Run the ``egostab`` command ``argv`` (default: the process's arguments); return its exit
    status. Bad input and a stop (Ctrl-C, SIGTERM, SIGHUP) are one line each, status 2 and
    130, also during the imports; ``stops`` (:func:`console`'s) is told the command's name."""
    command = "egostab"  # until the arguments are read
    try:
        with stop_signals_interrupt():
            from sim.harness.threads import limit_threads

            # Before anything loads numpy or OpenCV (importing sim pinned their SIMD paths).
            limit_threads()
            args = build_parser().parse_args(argv)
            command = f"egostab {args.command}"
            if stops is not None:
                stops.job = command
            return args.handler(args)
    except ValueError as error:  # bad input named by the layer that found it
        print(f"{command}: error: {error}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader has gone (`egostab list | head -1`): end quietly
        discard_output()
        return BROKEN_PIPE_STATUS
    except RuntimeError as error:
        # Imported here: the module costs every command's start 15-20 ms.
        from concurrent.futures import BrokenExecutor

        if not isinstance(error, BrokenExecutor):
            raise
        # A method crashed a worker process (a segfault in native code, os._exit).
        print(f"{command}: error: a worker process died while estimating (a method crashed "
              f"it, in native code or by os._exit); the run folder keeps the frames scored "
              f"before, with the status 'error'", file=sys.stderr)
        return 1
    except OSError as error:  # a missing file, a permission, a full disk: the user's to fix
        print(f"{command}: error: {_describe_os_error(error)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        print(f"{command}: {interrupt_reason(interrupt)}", file=sys.stderr)
        return INTERRUPTED_STATUS


def _written_out(status: int, command: str) -> int:
    """``status`` once the buffered output is written: a reader that has gone ends the command
    quietly (:data:`BROKEN_PIPE_STATUS`); output that cannot be written (a full disk) is an
    error, status 2, not a success."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        discard_output()
        return BROKEN_PIPE_STATUS
    except OSError as error:
        discard_output()
        print(f"{command}: error: its output could not be written: {_describe_os_error(error)}",
              file=sys.stderr)
        return status or 2
    return status


def console() -> NoReturn:
    """The ``egostab`` process (pyproject's [project.scripts], ``python -m sim.harness.cli``):
    :func:`main`, then the end of the process. A stop signal ends it with one line from here to
    its end: within the command as :func:`main` says, before and after it at once
    (:class:`ProcessStops`: no work is under way then, and the files are complete)."""
    stops = ProcessStops("egostab")
    stops.install(STOP_SIGNALS)  # main's stop block raises on them, then restores this
    try:
        status = main(stops=stops)
        stops.install((signal.SIGINT,))  # main's Ctrl-C is Python's KeyboardInterrupt
    except KeyboardInterrupt:  # a Ctrl-C just outside main's stop block
        stops.stop(signal.SIGINT)
    stops.exit(_written_out(status, stops.job))


if __name__ == "__main__":
    console()
