"""Scenario files (TOML): what a walking run does, validated before anything runs.

This module is the one place the keys, their defaults and their allowed values are documented:
the dataclasses below, one per TOML table. Example::

    name = "corridor_straight"            # default: the file's stem
    description = "straight walk down the corridor"
    scene = "corridor"                    # a key of sim.world.scenes.SCENES
    scene_seed = 0                        # placement of the scene's furniture
    seed = 0                              # sensor noise and anything else random in the run
    duration_s = 30.0

    [scene_params]                        # the scene's parameters (docs/scenes.md); any
    half_width_m = [0.7, 0.8]             # left out keeps its default. A range [low, high]
    clutter_count = [2, 3]                # is drawn from scene_seed's generator.

    [[commands]]                          # walk commands, in time order, the first at t = 0
    t = 0.0                               # each holds until the next one
    speed = 0.0                           # forward speed, m/s (0 = stand / stop)
    yaw_rate = 0.0                        # turn rate, deg/s, counter-clockwise positive
    [[commands]]
    t = 1.0
    speed = 0.1

    [floor]                               # the floor (docs/scenes.md, "Floors"); default flat
    slope_deg = 2.0                       # 0 to 3 degrees
    slope_direction_deg = 90.0            # the uphill direction, deg counter-clockwise from +x
    bump_height_m = 0.003                 # 0 to 0.005 m; bumps drawn from scene_seed

    [[pushes]]                            # pushes on the torso, in any order; default none
    t = 5.0                               # required: start, s (before duration_s)
    impulse_ns = [0.0, 1.5, 0.0]          # required: impulse, N s, world x, y, z (each -10
                                          # to 10)
    duration_s = 0.1                      # delivered as a constant force over this time, s
                                          # (a whole number of 0.0025 s physics steps)

    [gait]
    preset = "default"                    # a key of sim.world.walking.gait.GAIT_PRESETS
    overrides = { step_height_m = 0.035 } # any GaitParams field

    [sensor]
    preset = "sr4000"                     # a key of sim.world.sensor.tof_model.TOF_PRESETS
    fps = 30.0
    noise_scale = 1.0                     # multiplies the noise sigmas of the preset
    overrides = { mixed_pixel_weight = 0.3 }  # any ToFParams field

    [evaluation]
    reference = "cycle_start"             # "cycle_start", "previous" or "first"
    methods = ["t2fuzzy", "sift"]         # stabilizer.available_methods(), entry points or
                                          # package.module:Name (docs/plugins.md)

    [recording]
    enabled = true
    frame_stride = 1

Any unknown key, missing required key, wrong type or out-of-range value raises
:class:`ScenarioError` (a ValueError) naming the file, the key and what is allowed.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import typing
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from scenarios import SCENARIOS_DIR
from sim.world.assembly import PHYSICS_TIMESTEP_S
from sim.world.scenes import SCENES, Floor, SceneParameterError, scene_layout
from sim.world.scenes.floor import FLOOR_BOUNDS
from sim.world.sensor.tof_model import MAX_FPS, TOF_PRESETS, ToFParams
from sim.harness.methods import ACCEPTED_FORMS, MethodError, method_factory
from sim.harness.validation import (FileValueError, is_finite_number, is_int, is_seed,
                                   read_toml)
from stabilizer.api import available_methods

REFERENCE_POLICIES = ("cycle_start", "previous", "first")
#: Longest scenario, seconds.
MAX_DURATION_S = 3600.0
#: Largest push impulse along each world axis, N s (the robot is 6 kg: 10 N s ~ 1.7 m/s).
MAX_PUSH_IMPULSE_NS = 10.0
#: Longest push, seconds.
MAX_PUSH_DURATION_S = 1.0


class ScenarioError(FileValueError):
    """A scenario file that cannot run: names the file, the key and what is allowed."""


def _key(default, allowed: str, check=None, doc: str = ""):
    """A dataclass field with its allowed values (text and check) beside its default; a
    ``dataclasses.MISSING`` default makes the key required."""
    factory = {"default_factory": default} if callable(default) else {"default": default}
    return field(**factory, metadata={"allowed": allowed, "check": check, "doc": doc})


@dataclass(frozen=True)
class Command:
    """From time ``t`` on, walk at ``speed`` m/s turning at ``yaw_rate`` deg/s."""

    t: float = _key(0.0, "a time >= 0 s, increasing from command to command",
                    lambda v: 0 <= v <= MAX_DURATION_S)
    speed: float = _key(0.0, "0 to 0.5 m/s (and at most the gait's top speed)",
                        lambda v: 0 <= v <= 0.5)
    yaw_rate: float = _key(0.0, "-90 to 90 deg/s (and at most the gait's top turn rate)",
                           lambda v: -90 <= v <= 90)


@dataclass(frozen=True)
class Push:
    """From time ``t`` on, push the robot's torso with the impulse ``impulse_ns`` (N s, world
    x, y, z), delivered as a constant force ``impulse_ns / duration_s`` at its centre of mass
    (sim.world.walking.simulation.RobotSimulation.schedule_push)."""

    t: float = _key(dataclasses.MISSING, "a time >= 0 s, before duration_s",
                    lambda v: 0 <= v <= MAX_DURATION_S)
    impulse_ns: tuple = _key(dataclasses.MISSING, f"three numbers [x, y, z], N s in the world "
                             f"frame, each -{MAX_PUSH_IMPULSE_NS:g} to {MAX_PUSH_IMPULSE_NS:g}")
    duration_s: float = _key(0.1, f"{PHYSICS_TIMESTEP_S:g} to {MAX_PUSH_DURATION_S:g} s, a "
                             f"whole number of physics steps ({PHYSICS_TIMESTEP_S:g} s)",
                             lambda v: (PHYSICS_TIMESTEP_S - 1e-12 <= v <= MAX_PUSH_DURATION_S
                                        and _whole_steps(v)))


def _whole_steps(duration_s: float) -> bool:
    """True if ``duration_s`` is a whole number of physics steps (so the impulse is exact)."""
    steps = duration_s / PHYSICS_TIMESTEP_S
    return abs(steps - round(steps)) < 1e-6


def _is_one_line(text: str) -> bool:
    """True if ``text`` has no control character (line break, tab, escape...): the name heads
    summary.md and labels table rows, where one would break the line."""
    return not any(unicodedata.category(c) in ("Cc", "Zl", "Zp") for c in text)


@dataclass(frozen=True)
class FloorSpec:
    """The floor the scene stands on (sim.world.scenes.floor, docs/scenes.md "Floors"): its
    slope and bumps; the bumps are drawn from ``scene_seed``. The default is level and smooth."""

    slope_deg: float = _key(0.0, FLOOR_BOUNDS["slope_deg"][2],
                            lambda v: FLOOR_BOUNDS["slope_deg"][0] <= v
                            <= FLOOR_BOUNDS["slope_deg"][1])
    slope_direction_deg: float = _key(0.0, FLOOR_BOUNDS["slope_direction_deg"][2],
                                      lambda v: FLOOR_BOUNDS["slope_direction_deg"][0] <= v
                                      <= FLOOR_BOUNDS["slope_direction_deg"][1])
    bump_height_m: float = _key(0.0, FLOOR_BOUNDS["bump_height_m"][2],
                                lambda v: FLOOR_BOUNDS["bump_height_m"][0] <= v
                                <= FLOOR_BOUNDS["bump_height_m"][1])

    def floor(self) -> Floor:
        """The scene option ``sim.world.scenes.build_scene(..., floor=...)``."""
        return Floor(self.slope_deg, self.slope_direction_deg, self.bump_height_m)


@dataclass(frozen=True)
class GaitSpec:
    """The walking gait: a preset of sim.world.walking.gait.GAIT_PRESETS and field overrides."""

    preset: str = _key("default", "a preset of sim.world.walking.gait.GAIT_PRESETS")
    overrides: dict = _key(dict, "a table of GaitParams fields -> numbers")

    def params(self):
        from sim.world.walking.gait import GAIT_PRESETS

        return dataclasses.replace(GAIT_PRESETS[self.preset], **self.overrides)


@dataclass(frozen=True)
class SensorSpec:
    """The SR4000 emulation: a ToF preset, field overrides, a noise scale and the frame rate."""

    preset: str = _key("sr4000", f"one of {', '.join(TOF_PRESETS)}",
                       lambda v: v in TOF_PRESETS)
    fps: float = _key(30.0, f"0 < fps <= {MAX_FPS:g} (the SR4000's limit)",
                      lambda v: 0 < v <= MAX_FPS)
    noise_scale: float = _key(1.0, "0 to 100 (multiplies the preset's noise sigmas)",
                              lambda v: 0 <= v <= 100)
    overrides: dict = _key(dict, "a table of ToFParams fields -> values of the field's type")

    def tof_params(self) -> ToFParams:
        """The ToFParams of this sensor: preset, then noise scale, then overrides."""
        return dataclasses.replace(self.scaled_preset(), **self.overrides)

    def scaled_preset(self) -> ToFParams:
        """The preset with its noise sigmas multiplied by ``noise_scale``."""
        base = TOF_PRESETS[self.preset]
        return dataclasses.replace(base, **{
            name: getattr(base, name) * self.noise_scale
            for name in ("noise_sigma_ref_m", "noise_sigma_min_m", "noise_sigma_max_m")})


@dataclass(frozen=True)
class EvaluationSpec:
    """What is scored: the reference-frame policy and the methods."""

    reference: str = _key("cycle_start", f"one of {', '.join(REFERENCE_POLICIES)}",
                          lambda v: v in REFERENCE_POLICIES)
    methods: tuple = _key(available_methods, f"a non-empty list of distinct methods, each "
                          f"{ACCEPTED_FORMS}", lambda v: v and len(set(v)) == len(v))


@dataclass(frozen=True)
class RecordingSpec:
    """Whether a rerun recording is written, and every how many frames."""

    enabled: bool = _key(True, "true or false")
    frame_stride: int = _key(1, "an integer 1 to 1000", lambda v: 1 <= v <= 1000)


@dataclass(frozen=True)
class Scenario:
    """One walking run, as loaded from a TOML file (see the module docstring for the layout)."""

    name: str = _key("", "a name without control characters such as line breaks or tabs "
                     "(default: the file's stem)", _is_one_line)
    description: str = _key("", "free text")
    scene: str = _key("corridor", f"one of {', '.join(SCENES)}", lambda v: v in SCENES)
    scene_seed: int = _key(0, "an integer from 0 to 2**63 - 1", is_seed)
    scene_params: dict = _key(dict, "a table [scene_params] of the scene's parameters "
                              "(docs/scenes.md); resolved, it lists every parameter")
    floor: FloorSpec = _key(FloorSpec, "a table [floor]")
    seed: int = _key(0, "an integer from 0 to 2**63 - 1", is_seed)
    duration_s: float = _key(20.0, f"0 < duration_s <= {MAX_DURATION_S:g}",
                             lambda v: 0 < v <= MAX_DURATION_S)
    commands: tuple = _key(lambda: (Command(),), "an array of tables [[commands]] with t, "
                           "speed, yaw_rate; the first at t = 0, times increasing")
    pushes: tuple = _key((), "an array of tables [[pushes]] with t, impulse_ns, duration_s")
    gait: GaitSpec = _key(GaitSpec, "a table [gait]")
    sensor: SensorSpec = _key(SensorSpec, "a table [sensor]")
    evaluation: EvaluationSpec = _key(EvaluationSpec, "a table [evaluation]")
    recording: RecordingSpec = _key(RecordingSpec, "a table [recording]")
    source: str = field(default="", compare=False)

    def to_dict(self) -> dict:
        """Plain JSON-ready dict of the resolved scenario (for metrics.json)."""
        return _plain(dataclasses.asdict(self))

    def command_at(self, time_s: float) -> Command:
        """The command in force at ``time_s``."""
        times = [c.t for c in self.commands]
        return self.commands[max(0, int(np.searchsorted(times, time_s, side="right")) - 1)]


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


# -- loading and validation -------------------------------------------------------------------

_SECTIONS = {"floor": FloorSpec, "gait": GaitSpec, "sensor": SensorSpec,
             "evaluation": EvaluationSpec, "recording": RecordingSpec}


def load_scenario(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read and validate a scenario file.

    Args:
        path: the TOML file, or the name of a shipped scenario (``scenarios/<name>.toml``).
        overrides: dotted keys -> values set before validation, e.g.
            ``{"sensor.noise_scale": 2.0, "seed": 3}`` (sweeps, command-line overrides).

    Raises:
        ScenarioError: unknown key, wrong type or out-of-range value (file, key, allowed).
        FileNotFoundError: no such file or shipped scenario.
    """
    path = resolve_scenario_path(path)
    source = str(path)
    raw = read_toml(path, ScenarioError)
    for dotted, value in (overrides or {}).items():
        _set_dotted(raw, dotted, value, source)
    raw.setdefault("name", path.stem)
    return scenario_from_dict(raw, source)


def scenario_from_dict(raw: Mapping[str, Any], source: str = "<dict>") -> Scenario:
    """Validate a scenario given as a (TOML-like) dict; ``source`` names it in errors."""
    values = _check_table(Scenario, raw, "", source,
                          nested=("commands", "pushes", "scene_params", *_SECTIONS))
    values["scene_params"] = _check_scene_params(
        raw.get("scene_params", {}), values.get("scene", Scenario.scene), source)
    for section, cls in _SECTIONS.items():
        table = raw.get(section, {})
        if not isinstance(table, Mapping):
            raise ScenarioError(source, section, f"must be a table, got {table!r}",
                                f"a table [{section}]")
        values[section] = cls(**_check_table(cls, table, f"{section}.", source,
                                             nested=("overrides",), raw_keys=("overrides",)))
    values["commands"] = _check_commands(raw.get("commands"), values.get("duration_s", 20.0),
                                         source)
    values["pushes"] = _check_pushes(raw.get("pushes", []), values.get("duration_s", 20.0),
                                     source)
    scenario = Scenario(**values, source=source)
    _check_gait(scenario, source)
    _check_sensor(scenario, source)
    _check_methods(scenario, source)
    return scenario


def _check_table(cls, table: Mapping, prefix: str, source: str, nested=(), raw_keys=()):
    """Check keys, types and ranges of one table against the fields of ``cls``."""
    specs = {f.name: f for f in dataclasses.fields(cls) if f.name != "source"}
    hints = typing.get_type_hints(cls)
    for key in table:
        if key not in specs:
            raise ScenarioError(source, prefix + str(key), "unknown key",
                                f"keys {', '.join(specs)}")
    values = {}
    for name, spec in specs.items():
        if name not in table and _is_required(spec):
            raise ScenarioError(source, prefix + name, "missing", spec.metadata["allowed"])
        if name not in table or (name in nested and name not in raw_keys):
            continue
        value = table[name]
        if name in raw_keys:
            if not isinstance(value, Mapping):
                raise ScenarioError(source, prefix + name, f"must be a table, got {value!r}",
                                    spec.metadata["allowed"])
            values[name] = dict(value)
            continue
        value = _coerce(value, hints[name], source, prefix + name, spec.metadata["allowed"])
        check = spec.metadata["check"]
        if check is not None and not check(value):
            raise ScenarioError(source, prefix + name, f"{value!r} is out of range",
                                spec.metadata["allowed"])
        values[name] = value
    return values


def _is_required(spec: dataclasses.Field) -> bool:
    """True for a key the file must give: a field without a default (a push's time and
    impulse: a push left without them is a slip, and a zero would hide it)."""
    return spec.default is dataclasses.MISSING and spec.default_factory is dataclasses.MISSING


def _coerce(value, kind, source, key, allowed):
    """``value`` as ``kind`` (bool, int, float, str, tuple of str) or a ScenarioError."""
    ok = {
        bool: isinstance(value, bool),
        int: is_int(value),
        float: is_finite_number(value),
        str: isinstance(value, str),
        tuple: isinstance(value, list) and all(isinstance(v, str) for v in value),
    }[kind]
    if not ok:
        # TOML's inf and nan are floats, but no figure of a scenario is infinite or undefined
        # (and metrics.json, strict JSON, could not store them).
        expected = {tuple: "a list of strings", float: "a finite number"}.get(
            kind, f"a {kind.__name__}")
        raise ScenarioError(source, key, f"wrong type: {value!r} is not {expected}", allowed)
    return tuple(value) if kind is tuple else kind(value)


def _check_commands(raw_commands, duration_s, source) -> tuple[Command, ...]:
    if raw_commands is None:
        return (Command(),)
    allowed = Scenario.__dataclass_fields__["commands"].metadata["allowed"]
    if not isinstance(raw_commands, list) or not raw_commands:
        raise ScenarioError(source, "commands", f"got {raw_commands!r}", allowed)
    commands = []
    for i, table in enumerate(raw_commands):
        if not isinstance(table, Mapping):
            raise ScenarioError(source, f"commands[{i}]", f"got {table!r}", allowed)
        commands.append(Command(**_check_table(Command, table, f"commands[{i}].", source)))
    times = [c.t for c in commands]
    if times[0] != 0.0:
        raise ScenarioError(source, "commands[0].t", f"{times[0]!r}: the first must be at 0",
                            allowed)
    for i in range(1, len(times)):
        if not times[i - 1] < times[i] < duration_s:
            raise ScenarioError(source, f"commands[{i}].t", f"{times[i]!r} does not increase "
                                f"or is not before duration_s={duration_s}", allowed)
    return tuple(commands)


def _check_pushes(raw_pushes, duration_s, source) -> tuple[Push, ...]:
    allowed = Scenario.__dataclass_fields__["pushes"].metadata["allowed"]
    if not isinstance(raw_pushes, list):
        raise ScenarioError(source, "pushes", f"got {raw_pushes!r}", allowed)
    pushes = []
    for i, table in enumerate(raw_pushes):
        if not isinstance(table, Mapping):
            raise ScenarioError(source, f"pushes[{i}]", f"got {table!r}", allowed)
        values = _check_table(Push, table, f"pushes[{i}].", source, nested=("impulse_ns",))
        values["impulse_ns"] = _impulse(table["impulse_ns"], f"pushes[{i}].impulse_ns", source)
        push = Push(**values)
        if not push.t < duration_s:
            raise ScenarioError(source, f"pushes[{i}].t", f"{push.t!r} is not before "
                                f"duration_s={duration_s}", "a time >= 0 s, before duration_s")
        # A push still on at the end would deliver only part of the impulse it records.
        if push.t + push.duration_s > duration_s:
            raise ScenarioError(source, f"pushes[{i}].duration_s",
                                f"{push.duration_s!r} s from t={push.t!r} s runs past "
                                f"duration_s={duration_s}", "a push that ends by duration_s")
        pushes.append(push)
    return tuple(pushes)


def _impulse(value, key: str, source: str) -> tuple[float, float, float]:
    allowed = Push.__dataclass_fields__["impulse_ns"].metadata["allowed"]
    if not (isinstance(value, (list, tuple)) and len(value) == 3
            and all(is_finite_number(v) for v in value)):
        raise ScenarioError(source, key, f"got {value!r}", allowed)
    if not all(abs(v) <= MAX_PUSH_IMPULSE_NS for v in value):
        raise ScenarioError(source, key, f"{list(value)!r} is out of range", allowed)
    return tuple(float(v) for v in value)


def _check_scene_params(table, scene: str, source: str) -> dict:
    """Every parameter of ``scene``: the table's values (checked) and the defaults."""
    if not isinstance(table, Mapping):
        raise ScenarioError(source, "scene_params", f"must be a table, got {table!r}",
                            Scenario.__dataclass_fields__["scene_params"].metadata["allowed"])
    try:
        return scene_layout(scene, **table).params()
    except SceneParameterError as error:
        raise ScenarioError(source, f"scene_params.{error.parameter}",
                            f"{error.problem} (scene {scene!r})", error.accepted) from None


def _check_gait(scenario: Scenario, source: str) -> None:
    from sim.world.walking.gait import GAIT_PRESETS, GaitParams

    gait = scenario.gait
    if gait.preset not in GAIT_PRESETS:
        raise ScenarioError(source, "gait.preset", f"unknown preset {gait.preset!r}",
                            f"one of {', '.join(GAIT_PRESETS)}")
    params = _replace_checked(GaitParams, GAIT_PRESETS[gait.preset], gait.overrides,
                              "gait.overrides", source)
    for i, command in enumerate(scenario.commands):
        if command.speed > params.max_forward_speed_mps + 1e-9:
            raise ScenarioError(source, f"commands[{i}].speed", f"{command.speed} m/s is faster "
                                f"than the gait walks", f"0 to {params.max_forward_speed_mps:.3f}"
                                " m/s for this gait (step_length_max_m / step_period_s)")
        if abs(command.yaw_rate) > params.max_yaw_rate_dps + 1e-9:
            raise ScenarioError(source, f"commands[{i}].yaw_rate", f"{command.yaw_rate} deg/s "
                                "turns faster than the gait", f"at most +-"
                                f"{params.max_yaw_rate_dps:.1f} deg/s for this gait")


def _check_sensor(scenario: Scenario, source: str) -> None:
    sensor = scenario.sensor
    try:
        scaled = sensor.scaled_preset()
    except ValueError as error:  # the scaled sigmas beyond ToFParams's range
        problem, _, allowed = str(error).partition("; allowed: ")
        raise ScenarioError(source, "sensor.noise_scale", problem,
                            allowed or "a smaller noise_scale") from None
    params = _replace_checked(ToFParams, scaled, sensor.overrides, "sensor.overrides", source)
    if params.integration_time_s >= 1.0 / sensor.fps:
        raise ScenarioError(source, "sensor.fps", f"{sensor.fps} frames/s leaves less than the "
                            f"integration time {params.integration_time_s} s per frame",
                            f"fps < {1.0 / params.integration_time_s:.1f}")
    if math.floor(scenario.duration_s * sensor.fps) < 1:
        raise ScenarioError(source, "duration_s", f"{scenario.duration_s} s holds no frame at "
                            f"{sensor.fps} frames/s", f"at least one frame period (1 / "
                            f"sensor.fps = {1.0 / sensor.fps:.9g} s)")


def _check_methods(scenario: Scenario, source: str) -> None:
    """Every method resolves now (built-in, entry point or import path), before any run."""
    for name in scenario.evaluation.methods:
        try:
            method_factory(name)
        except MethodError as error:
            raise ScenarioError(source, "evaluation.methods", f"method {name!r}: "
                                f"{error.problem}", ACCEPTED_FORMS) from None


def _replace_checked(cls, base, overrides: Mapping, key: str, source: str):
    """``dataclasses.replace(base, **overrides)`` with field names and types checked."""
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    for name, value in overrides.items():
        if name not in names:
            raise ScenarioError(source, f"{key}.{name}", "unknown field",
                                f"fields of {cls.__name__}: {', '.join(names)}")
        _coerce(value, hints[name], source, f"{key}.{name}",
                "a finite number" if hints[name] is float else f"a {hints[name].__name__}")
    try:
        return dataclasses.replace(base, **overrides)
    except ValueError as error:  # the class's own check: it may say what is allowed
        problem, _, allowed = str(error).partition("; allowed: ")
        raise ScenarioError(source, key, problem,
                            allowed or f"valid {cls.__name__} values") from None


def _set_dotted(raw: dict, dotted: str, value, source: str) -> None:
    *tables, last = dotted.split(".")
    node = raw
    for name in tables:
        node = node.setdefault(name, {})
        if not isinstance(node, dict):
            raise ScenarioError(source, dotted, "override goes through a non-table",
                                "dotted keys of tables, e.g. sensor.noise_scale")
    node[last] = copy.deepcopy(value)


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A scenario file from a path, or from the name of a shipped one."""
    text = str(name_or_path)
    path = Path(text)
    accepted = "a scenario TOML file, or the name of a shipped one (egostab list)"
    if not text:
        raise FileNotFoundError(f"no scenario ''; accepted: {accepted}")
    # A name is a file name alone: "ci/ci_corridor" or "../pyproject" is a path, not a name.
    shipped = (SCENARIOS_DIR / f"{text}.toml" if path.name == text and text not in (".", "..")
               else None)
    # A folder does not hide a shipped scenario of its name: `egostab run corridor_straight
    # --out corridor_straight` makes that folder before the run reads its scenario.
    if (shipped is None or path.suffix == ".toml" or path.is_file()
            or (path.exists() and not shipped.is_file())):
        if path.is_dir():
            raise FileNotFoundError(f"{path} is a folder, not a scenario file; accepted: "
                                    f"{accepted}")
        if path.exists() and not path.is_file():
            raise FileNotFoundError(f"{path} is not a regular file; accepted: {accepted}")
        if not path.is_file():
            raise FileNotFoundError(f"no scenario file {path}; accepted: {accepted}")
        return path
    if not shipped.is_file():
        names = ", ".join(p.stem for p in list_scenarios())
        raise FileNotFoundError(f"no scenario {name_or_path!r}; accepted: a scenario TOML "
                                f"file, or one of the shipped scenarios: {names}")
    return shipped


def list_scenarios() -> list[Path]:
    """The shipped scenario files, sorted by name."""
    return sorted(SCENARIOS_DIR.glob("*.toml"))


def commanded_trajectory(scenario: Scenario, start_xy, start_yaw_deg: float,
                         dt: float = 0.02) -> np.ndarray:
    """(N, 2) floor positions of an ideal walker following the commands (unicycle model).

    Used to check that a scenario's commands keep to its scene's path.
    """
    xy = np.array(start_xy, dtype=float)
    yaw = math.radians(start_yaw_deg)
    points = [xy.copy()]
    for t in np.arange(0.0, scenario.duration_s, dt):
        command = scenario.command_at(t)
        xy += command.speed * dt * np.array([math.cos(yaw), math.sin(yaw)])
        yaw += math.radians(command.yaw_rate) * dt
        points.append(xy.copy())
    return np.array(points)
