"""A suite file and its validation.

A suite scores methods over many sequences: walks of scenario templates on procedural scenes
(``scene_seed`` places the furniture), under a gait preset and a run seed. Each
``[[sequences]]`` entry names one template and lists what to vary; its sequences are every
combination of its gaits, scene seeds and seeds. Example (the shipped suite is
``scenarios/suites/heldout.toml``)::

    name = "heldout"                           # default: the file's stem
    description = "scoring only: no method is tuned on these scene seeds"
    methods = ["t2fuzzy", "sift"]              # built-in names, entry points or
                                               # package.module:Name; every sequence scores all
    max_frames = 360                           # default: each sequence's whole duration
    record = false                             # rerun recordings; default false

    [overrides]                                # optional: dotted scenario keys, every sequence
    duration_s = 12.0

    [[sequences]]
    scenario = "corridor_straight"             # a shipped name, or a TOML path (relative
                                               # paths: from the suite file's folder)
    gaits = ["default", "paper_like"]          # values of gait.preset; default: the template's
    scene_seeds = [1000, 1001]                 # integers 0 to 2**63 - 1, distinct
    seeds = [0]                                # run seeds; default [0]
    overrides = { duration_s = 20.0 }          # optional: over the suite's overrides

The scene of a sequence is its template's (so the template's commands fit the scene's path).
Unknown keys, wrong types, out-of-range values and a sequence listed twice raise
:class:`SuiteError` (a ValueError) naming the file, the key and what is allowed. Every sequence
is also loaded through ``sim.harness.scenario.load_scenario`` before anything runs.
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
from sim.harness.validation import FileValueError, distinct_list, is_seed

#: Scenario keys a suite sets from its lists; overrides may not set them.
VARIED_KEYS = ("gait.preset", "scene_seed", "seed")
#: Keys of a suite file -> what is allowed (the module docstring shows them in use).
ALLOWED = {
    "name": "a non-empty name of letters, digits, '_', '-', '.', not only dots (default: "
            "the file's stem)",
    "description": "free text",
    "methods": f"a non-empty list of distinct methods, each {ACCEPTED_FORMS}",
    "max_frames": "an integer >= 1",
    "record": "true or false",
    "overrides": f"a table of dotted scenario keys -> single values (not "
                 f"{', '.join(VARIED_KEYS)})",
    "sequences": "a non-empty list of [[sequences]] tables",
}
#: Keys of one ``[[sequences]]`` table -> what is allowed.
SEQUENCE_ALLOWED = {
    "scenario": "a shipped scenario name or a TOML path",
    "gaits": "a non-empty list of distinct gait presets (sim.world.walking.gait.GAIT_PRESETS)",
    "scene_seeds": "a non-empty list of distinct integers from 0 to 2**63 - 1",
    "seeds": "a non-empty list of distinct integers from 0 to 2**63 - 1",
    "overrides": ALLOWED["overrides"],
}
_REQUIRED = ("methods", "sequences")
_SEQUENCE_REQUIRED = ("scenario", "scene_seeds")


class SuiteError(FileValueError):
    """A suite file that cannot run: names the file, the key and what is allowed."""


@dataclass(frozen=True)
class SuiteSequence:
    """One sequence of a suite: a template walked on one scene layout, gait and seed.

    Attributes:
        scenario: the template, a shipped name or an absolute TOML path.
        scene: the template's scene.
        gait: the gait preset (``gait.preset``).
        scene_seed, seed: the scene layout and the run seed.
        overrides: every scenario key the suite sets for this sequence (its overrides and the
            varied keys).
    """

    scenario: str
    scene: str
    gait: str
    scene_seed: int
    seed: int
    overrides: Mapping[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The sequence's folder name: template, gait, scene seed and seed."""
        return (f"{safe_name(scenario_name(self.scenario))}__{self.gait}__scene{self.scene_seed}"
                f"__seed{self.seed}")


@dataclass(frozen=True)
class SuiteSpec:
    """A validated suite (see the module docstring for the file layout).

    Attributes:
        name: the suite's name.
        methods: the methods every sequence scores.
        sequences: every sequence, in file order (entry, then gait, scene seed, seed).
        max_frames: frames per sequence; None = each sequence's duration.
        record: write rerun recordings.
        description, source: free text; the file the spec came from.
    """

    name: str
    methods: tuple[str, ...]
    sequences: tuple[SuiteSequence, ...]
    max_frames: int | None = None
    record: bool = False
    description: str = ""
    source: str = "<dict>"


def load_suite(path: str | os.PathLike) -> SuiteSpec:
    """Read and validate a suite file; relative scenario paths are taken from its folder."""
    raw = read_runset_file(path, SuiteError, "suite")
    return suite_from_dict(raw, source=str(path), base_dir=Path(path).parent)


def suite_from_dict(raw: Mapping[str, Any], source: str = "<dict>",
                    base_dir: str | os.PathLike = ".") -> SuiteSpec:
    """Validate a suite given as a (TOML-like) dict; ``source`` names it in errors."""
    def fail(key: str, problem: str) -> SuiteError:
        return SuiteError(source, key, problem, ALLOWED[key.split("[")[0]])

    header = check_header(raw, ALLOWED, _REQUIRED, SuiteError, source, fail, "suite")
    methods = distinct_list(raw["methods"], "methods", fail, lambda v: isinstance(v, str))
    check_methods(methods, fail)
    overrides = checked_overrides(raw.get("overrides", {}), "overrides", VARIED_KEYS, fail)

    entries = raw["sequences"]
    if not isinstance(entries, list) or not entries:
        raise fail("sequences", f"got {entries!r}")
    sequences: list[SuiteSequence] = []
    for index, entry in enumerate(entries):
        for sequence in _entry_sequences(entry, f"sequences[{index}]", overrides,
                                         Path(base_dir), source):
            twin = next((s for s in sequences if s.name == sequence.name), None)
            if twin is not None:
                if twin.scenario != sequence.scenario:
                    raise SuiteError(source, f"sequences[{index}]", f"templates "
                                     f"{twin.scenario} and {sequence.scenario} share the name "
                                     f"of sequence {sequence.name}",
                                     "templates with distinct file names")
                raise SuiteError(source, f"sequences[{index}]", f"sequence {sequence.name} is "
                                 "listed twice", "each template, gait, scene seed and seed once")
            sequences.append(sequence)
    return SuiteSpec(name=header.name, methods=methods, sequences=tuple(sequences),
                     max_frames=header.max_frames, record=header.record,
                     description=header.description, source=source)


def _entry_sequences(entry: Any, where: str, suite_overrides: dict, base_dir: Path,
                     source: str) -> list[SuiteSequence]:
    """The sequences of one ``[[sequences]]`` table, each loaded once to check it."""
    def fail(key: str, problem: str) -> SuiteError:
        return SuiteError(source, f"{where}.{key}", problem,
                          SEQUENCE_ALLOWED[key.split("[")[0]])

    if not isinstance(entry, Mapping):
        raise SuiteError(source, where, f"got {entry!r}", "a table with keys "
                         f"{', '.join(SEQUENCE_ALLOWED)}")
    for key in entry:
        if key not in SEQUENCE_ALLOWED:
            raise SuiteError(source, f"{where}.{key}", "unknown key",
                             f"keys {', '.join(SEQUENCE_ALLOWED)}")
    for key in _SEQUENCE_REQUIRED:
        if key not in entry:
            raise fail(key, "missing")
    scenario = resolve_scenario_entry(entry["scenario"], "scenario", base_dir, fail)
    own_overrides = checked_overrides(entry.get("overrides", {}), "overrides", VARIED_KEYS, fail)
    overrides = {**suite_overrides, **own_overrides}
    try:
        template = load_scenario(scenario, overrides)
    except ScenarioError as error:
        # A value an override sets is the suite file's, refused as the scenario refuses it.
        if set_by(error.key, own_overrides):
            raise SuiteError(source, f"{where}.overrides: {error.key}", error.problem,
                             error.allowed) from None
        if set_by(error.key, overrides):
            raise SuiteError(source, f"overrides: {error.key}", error.problem,
                             error.allowed) from None
        raise fail("scenario", f"scenario {scenario_name(scenario)} is refused ({error})") \
            from None
    gaits = distinct_list(entry.get("gaits", [template.gait.preset]), "gaits", fail,
                          lambda v: isinstance(v, str) and bool(v))
    scene_seeds = distinct_list(entry["scene_seeds"], "scene_seeds", fail, is_seed)
    seeds = distinct_list(entry.get("seeds", [0]), "seeds", fail, is_seed)
    sequences = []
    for index, gait in enumerate(gaits):
        for scene_seed in scene_seeds:
            for seed in seeds:
                varied = {"gait.preset": gait, "scene_seed": scene_seed, "seed": seed}
                try:
                    load_scenario(scenario, {**overrides, **varied})
                except ScenarioError as error:
                    key = f"gaits[{index}]" if error.key == "gait.preset" else "scenario"
                    raise fail(key, f"scenario {scenario_name(scenario)} with gait {gait!r}, "
                                    f"scene seed {scene_seed}, seed {seed} is refused "
                                    f"({error.problem})") from None
                sequences.append(SuiteSequence(scenario, template.scene, gait, scene_seed, seed,
                                          {**overrides, **varied}))
    return sequences
