"""The README's tables are the ones the committed results and ``egostab``'s help give: a
regenerated ``results/`` whose README was not regenerated with it, or a command or option the
README does not name, fails here."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from sim.harness.cli import build_parser
from sim.harness.report import aggregate_runs
from sim.harness.scenario import list_scenarios

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


@pytest.fixture(scope="module")
def readme() -> str:
    return (ROOT / "README.md").read_text(encoding="utf-8")


def section(text: str, heading: str) -> str:
    """The text under ``heading`` (a whole heading line) up to the next heading of any level."""
    lines = text.splitlines()
    start = lines.index(heading) + 1
    end = next((index for index in range(start, len(lines)) if lines[index].startswith("#")),
               len(lines))
    return "\n".join(lines[start:end])


def table_rows(text: str) -> list[str]:
    """The rows of every Markdown table in ``text``, header rows included, rules left out."""
    return [line for line in text.splitlines()
            if line.startswith("|") and not line.startswith("|---")]


def test_the_shipped_walks_table_is_what_the_committed_runs_aggregate_to(readme):
    """README, "The paper's method and its peers on the shipped walks": ``egostab aggregate
    results/<scenario>... --compact`` over every shipped scenario, a row each."""
    runs = [RESULTS / path.stem for path in list_scenarios()]
    expected = table_rows(aggregate_runs(runs, compact=True))
    shown = table_rows(section(readme, "### The paper's method and its peers on the shipped "
                                       "walks (Table I on simulated frames)"))
    assert shown[0] == expected[0]
    assert sorted(shown[1:]) == sorted(expected[1:])


def test_the_ideal_experiment_table_is_what_its_committed_runs_aggregate_to(readme):
    runs = sorted(path for path in (RESULTS / "ideal").iterdir()
                  if (path / "metrics.json").exists())
    assert [path.name for path in runs] == ["corridor", "hall", "lab", "office"]
    expected = table_rows(aggregate_runs(runs, compact=True))
    shown = table_rows(section(readme, "### The ideal experiment (the paper's section III-A)"))
    assert shown[1:] and sorted(shown[1:]) == sorted(expected[1:])


@pytest.mark.parametrize("heading, source", [
    ("### Held-out walks: scene layouts no method was tuned on", "suites/heldout/suite.md"),
    ("### Speed", "bench.md"),
])
def test_the_held_out_and_speed_tables_are_copied_from_the_committed_results(readme, heading,
                                                                               source):
    shown = table_rows(section(readme, heading))
    written = set(table_rows((RESULTS / source).read_text(encoding="utf-8")))
    assert len(shown) > 5
    assert [row for row in shown if row not in written] == []


def test_the_command_table_names_every_command_and_each_of_its_options(readme, capsys,
                                                                       monkeypatch):
    """README, "Commands": a row per ``egostab`` command, naming every option its ``--help``
    gives, and no other."""
    monkeypatch.setenv("COLUMNS", "80")  # the help's layout, whatever the terminal's width

    def help_text(*argv: str) -> str:
        with pytest.raises(SystemExit):
            build_parser().parse_args([*argv, "--help"])
        return capsys.readouterr().out

    rows = {match.group(1): set(re.findall(r"--[a-z][a-z-]*", match.group(2)))
            for match in re.finditer(r"^\| `egostab (\w+)([^`]*)` \|", readme, re.MULTILINE)}
    commands = re.findall(r"^    ([a-z]+)(?:  |$)", help_text(), re.MULTILINE)  # under COMMAND
    assert sorted(rows) == sorted(commands)
    for command in commands:
        usage = help_text(command).split("\n\n", 1)[0]  # the usage lines: the options only
        assert rows[command] == set(re.findall(r"--[a-z][a-z-]*", usage)) - {"--help"}, command


def test_the_truth_residual_figures_are_those_of_the_committed_runs(readme):
    """README, the shipped walks: the range of the ground truth's median residual over the
    walks, the one walk below it, and the largest single frame (each run's summary)."""
    import json

    residuals = {path.stem: json.loads((RESULTS / path.stem / "metrics.json").read_text(
        encoding="utf-8"))["summary"]["truth_residual"] for path in list_scenarios()}
    match = re.search(r"medians of ([\d.]+)-([\d.]+) px RMS on the shipped walks \(([\d.]+) px "
                      r"on `(\w+)`[^)]*\), single frames up to ([\d.]+) px",
                      " ".join(readme.split()))
    assert match, "the README's sentence on the truth's residual was not found"
    low, high, still, still_walk, largest = match.groups()
    medians = {name: round(figures["median_px"], 1) for name, figures in residuals.items()}
    assert medians.pop(still_walk) == float(still)
    assert (min(medians.values()), max(medians.values())) == (float(low), float(high))
    assert round(max(figures["max_px"] for figures in residuals.values()), 1) == float(largest)
