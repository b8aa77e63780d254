"""A sweep file and its validation.

A sweep file (TOML) lists what to vary; every combination of scenario, seed and noise level is
one run of ``sim.harness.runner.run`` (each run scores all the sweep's methods on the same
simulated frames, so methods are not a run dimension). Example
(``scenarios/sweeps/noise_sweep.toml``)::

    name = "noise_sweep"                      # default: the file's stem
    description = "error against sensor noise"
    scenarios = ["corridor_straight", "lab_clutter"]  # shipped names, or TOML paths
                                              # (relative paths: from the sweep file's folder)
    seeds = [0, 1]                            # integers 0 to 2**63 - 1, distinct
    noise_levels = [0.5, 1.0, 2.0, 4.0]       # numbers, distinct; each is written to noise_key
    noise_key = "sensor.noise_scale"          # default; any dotted scenario key taking
                                              # numbers (integers for scene_seed, say)
    methods = ["t2fuzzy", "sift"]             # default: each scenario's own list; built-in
                                              # names, entry points or package.module:Name
    max_frames = 90                           # default: the scenario's whole duration
    record = false                            # rerun recordings; default false

    [overrides]                               # optional: dotted scenario keys for every run
    "evaluation.reference" = "previous"

Unknown keys, wrong types and out-of-range values raise :class:`SweepError` (a ValueError)
naming the file, the key and what is allowed. Every (scenario, noise level) is also loaded
through ``sim.harness.scenario.load_scenario`` before anything runs, so a noise level the
scenario rejects fails at once, not after hours of other runs.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim.harness.methods import ACCEPTED_FORMS
from sim.harness.report import safe_name
from sim.harness.runner import scenario_name
from sim.harness.runset import (check_header, check_methods, checked_overrides,
                                read_runset_file, resolve_scenario_entry, set_by)
from sim.harness.scenario import ScenarioError, load_scenario
from sim.harness.validation import (FileValueError, distinct_list, is_dotted_key,
                                    is_finite_number, is_seed)

DEFAULT_NOISE_KEY = "sensor.noise_scale"
#: Keys of a sweep file -> what is allowed (the module docstring shows them in use).
ALLOWED = {
    "name": "a non-empty name of letters, digits, '_', '-', '.', not only dots (default: "
            "the file's stem)",
    "description": "free text",
    "scenarios": "a non-empty list of distinct shipped scenario names or TOML paths",
    "seeds": "a non-empty list of distinct integers from 0 to 2**63 - 1",
    "noise_levels": "a non-empty list of distinct finite numbers",
    "noise_key": "a dotted scenario key such as sensor.noise_scale",
    "methods": f"a non-empty list of distinct methods, each {ACCEPTED_FORMS}",
    "max_frames": "an integer >= 1",
    "record": "true or false",
    "overrides": "a table of dotted scenario keys -> single values (not seed, not the noise "
                 "key)",
}
_REQUIRED = ("scenarios", "seeds", "noise_levels")


class SweepError(FileValueError):
    """A sweep file that cannot run: names the file, the key and what is allowed."""


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep (see the module docstring for the file layout).

    Attributes:
        name: the sweep's name.
        scenarios: scenario names (shipped) or absolute TOML paths, in the file's order.
        seeds, noise_levels: the values swept, in the file's order.
        noise_key: the dotted scenario key each noise level is written to.
        methods: methods every run scores; None = each scenario's own list.
        max_frames: frames per run; None = the scenario's duration.
        record: write rerun recordings.
        overrides: dotted scenario keys -> values applied to every run.
        description, source: free text; the file the spec came from.
    """

    name: str
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    noise_levels: tuple[int | float, ...]
    noise_key: str = DEFAULT_NOISE_KEY
    methods: tuple[str, ...] | None = None
    max_frames: int | None = None
    record: bool = False
    overrides: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""
    source: str = "<dict>"

    @property
    def n_runs(self) -> int:
        return len(self.scenarios) * len(self.seeds) * len(self.noise_levels)


def scenario_label(scenario: str) -> str:
    """Short name of a scenario entry: a shipped name, or a TOML file's stem."""
    return safe_name(scenario_name(scenario))


def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and validate a sweep file; relative scenario paths are taken from its folder."""
    raw = read_runset_file(path, SweepError, "sweep")
    return sweep_from_dict(raw, source=str(path), base_dir=Path(path).parent)


def sweep_from_dict(raw: Mapping[str, Any], source: str = "<dict>",
                    base_dir: str | os.PathLike = ".") -> SweepSpec:
    """Validate a sweep given as a (TOML-like) dict; ``source`` names it in errors."""
    def fail(key: str, problem: str) -> SweepError:
        return SweepError(source, key, problem, ALLOWED[key.split("[")[0]])

    header = check_header(raw, ALLOWED, _REQUIRED, SweepError, source, fail, "sweep")
    noise_key = raw.get("noise_key", DEFAULT_NOISE_KEY)
    if not is_dotted_key(noise_key) or noise_key == "seed":
        raise fail("noise_key", f"got {noise_key!r}")
    overrides = checked_overrides(raw.get("overrides", {}), "overrides", ("seed", noise_key),
                                  fail)

    scenarios = distinct_list(raw["scenarios"], "scenarios", fail,
                              lambda v: isinstance(v, str) and bool(v.strip()))
    seeds = distinct_list(raw["seeds"], "seeds", fail, is_seed)
    # As written: an integer key (scene_seed, recording.frame_stride) takes integers.
    noise_levels = tuple(distinct_list(raw["noise_levels"], "noise_levels", fail,
                                       is_finite_number))
    methods = raw.get("methods")
    if methods is not None:
        methods = distinct_list(methods, "methods", fail, lambda v: isinstance(v, str))
        check_methods(methods, fail)

    resolved = tuple(resolve_scenario_entry(entry, f"scenarios[{index}]", Path(base_dir), fail)
                     for index, entry in enumerate(scenarios))
    spec = SweepSpec(name=header.name, scenarios=resolved, seeds=seeds,
                     noise_levels=noise_levels, noise_key=noise_key, methods=methods,
                     max_frames=header.max_frames, record=header.record, overrides=overrides,
                     description=header.description, source=source)
    _check_runs_load(spec)
    return spec


def _check_runs_load(spec: SweepSpec) -> None:
    """Load every (scenario, noise level) now, so a bad combination fails before any run."""
    for scenario in spec.scenarios:
        for index, level in enumerate(spec.noise_levels):
            try:
                load_scenario(scenario, {**spec.overrides, spec.noise_key: level})
            except ScenarioError as error:
                # A value the sweep file sets is its own, refused as the scenario refuses it.
                if set_by(error.key, {spec.noise_key: level}):
                    raise SweepError(spec.source, f"noise_levels[{index}]",
                                     f"{spec.noise_key}: {error.problem}",
                                     error.allowed) from None
                if set_by(error.key, spec.overrides):
                    raise SweepError(spec.source, f"overrides: {error.key}", error.problem,
                                     error.allowed) from None
                key = ("overrides" if spec.overrides and _loads(scenario,
                                                                {spec.noise_key: level})
                       else f"scenarios[{spec.scenarios.index(scenario)}]")
                values = ", ".join(f"{name} = {value!r}" for name, value in
                                   {**spec.overrides, spec.noise_key: level}.items())
                raise SweepError(spec.source, key, f"scenario {scenario_label(scenario)} with "
                                 f"{values} is refused ({error})",
                                 "values every scenario of the sweep accepts") from None


def _loads(scenario: str, overrides: dict) -> bool:
    """Whether ``scenario`` loads with ``overrides``: a refusal that goes away without the
    sweep's shared overrides is theirs (a shorter duration_s than the scenario's last push)."""
    try:
        load_scenario(scenario, overrides)
    except ScenarioError:
        return False
    return True
