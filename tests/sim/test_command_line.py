"""sim.command_line: one-line errors with exit status 2, and the tools that use them."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from sim.command_line import OneLineParser, integer_option, number_option


def test_an_error_is_one_line_naming_the_usage(capsys):
    parser = OneLineParser(prog="tool")
    parser.add_argument("--count", type=integer_option(1, 9))
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--count", "10"])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.count("\n") == 1
    assert err == "tool: error: argument --count: '10': accepted: an integer from 1 to 9 " \
                  "(usage: tool --help)\n"


def test_an_integer_option_takes_its_ends_and_refuses_one_beyond():
    bounded, unbounded = integer_option(1, 9), integer_option(1)
    assert (bounded("1"), bounded("9"), unbounded("1"), unbounded(str(10**12))) == \
        (1, 9, 1, 10**12)
    for parse, text in ((bounded, "0"), (bounded, "10"), (unbounded, "0"), (bounded, "1.0"),
                        (bounded, "x")):
        with pytest.raises(Exception, match=f"'{re.escape(text)}': accepted: an integer"):
            parse(text)


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "0", "x", "2.5"])
def test_a_number_option_refuses_what_lies_outside_its_range(text):
    parse = number_option(0.0, 2.0)
    with pytest.raises(Exception, match="accepted: a number greater than 0 and at most 2"):
        parse(text)
    assert parse("2") == 2.0 and parse("1e-9") == 1e-9


@pytest.mark.parametrize("module, argv, named", [
    ("sim.world.walking.push_recovery", ["--seeds", "0"], "--seeds: '0': accepted"),
    ("sim.world.walking.push_recovery", ["--gaits", "fast"], "invalid choice: 'fast'"),
    ("sim.world.walking.push_recovery", ["--speed", "nan"], "--speed: 'nan': accepted"),
    ("sim.world.walking.camera_swing", ["fast"], "gait 'fast': accepted: default, paper_like"),
    ("sim.world.walking.camera_swing", ["--seconds", "-1"], "--seconds: '-1': accepted"),
    ("sim.world.render_robot", ["--width", "0"], "--width: '0': accepted: an integer from 1"),
    ("sim.world.render_robot", ["--out", "no_such_folder/robot.png"],
     "--out no_such_folder/robot.png: accepted: a .png file in an existing folder"),
    ("sim.world.sensor.calibration", ["--table", "2"], "unrecognized arguments: --table 2"),
])
def test_the_world_tools_refuse_bad_options_in_one_line(module, argv, named):
    # Each ended in a traceback (seeds 0: min() of nothing; an unknown gait; a non-finite
    # speed; a negative walk: an empty array; a 0-pixel picture; an unwritable path), or, for
    # the calibration tables, ignored its arguments.
    done = subprocess.run([sys.executable, "-m", module, *argv], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert named in done.stderr and done.stdout == ""


def test_a_camera_swing_walk_too_short_to_measure_is_refused():
    from sim.world.walking.camera_swing import measure_camera_swing

    with pytest.raises(ValueError, match="a walk of 1 s ends within its first 3 gait cycles"):
        measure_camera_swing("default", walk_s=1.0)


@pytest.mark.parametrize("tool", [
    ["benchmarks/trust_properties.py", "--cases", "1", "--methods", "icp"],
    ["-m", "sim.world.sensor.calibration"],
])
def test_a_tools_output_to_a_reader_that_has_gone_ends_quietly_with_status_141(tool):
    # `python benchmarks/floor_walks.py | head`: the pipe's reading end closed before the first
    # line. They ended in a BrokenPipeError traceback; `egostab` ends with 141 and no message.
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = subprocess.run([sys.executable, "-u", *tool], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, timeout=120,
                              cwd=Path(__file__).parents[2])
    finally:
        os.close(write_end)
    assert done.returncode == 141 and done.stderr == ""
