"""The shared validation of input files: the error every validator raises, and the value checks."""

from __future__ import annotations

import math
import pickle

import pytest

from sim.harness.scenario import ScenarioError
from sim.harness.sweep import SweepError
from sim.harness.validation import (FileValueError, distinct_list, is_dotted_key,
                                    is_finite_number, is_int, is_safe_name, is_seed, read_toml)


def test_validation_helpers_accept_and_name_the_bad_item():
    def fail(key, problem):
        return ValueError(f"{key}: {problem}")

    assert distinct_list([3, 1], "seeds", fail, is_int) == (3, 1)
    for value, message in [([], r"^seeds: got \[\]"), ([1, True], r"^seeds\[1\]: got True"),
                           ([1, 1], r"^seeds\[1\]: 1 is listed twice")]:
        with pytest.raises(ValueError, match=message):
            distinct_list(value, "seeds", fail, is_int)
    assert is_finite_number(2) and is_finite_number(0.5)
    assert not any(is_finite_number(v) for v in (True, math.inf, math.nan, "1"))
    assert is_dotted_key("sensor.noise_scale") and not is_dotted_key("sensor..noise")
    assert is_safe_name("noise_sweep-2.b") and not is_safe_name("a/b") and not is_safe_name("")
    assert is_seed(0) and is_seed(2**63 - 1)
    assert not any(is_seed(v) for v in (-1, 2**63, True, 1.0))


@pytest.mark.parametrize("kind", [FileValueError, ScenarioError, SweepError])
def test_every_file_error_names_the_file_key_problem_and_what_is_allowed(kind):
    error = kind("a.toml", "sensor.fps", "got 0", "1 to 50 frames/s")
    assert isinstance(error, FileValueError) and isinstance(error, ValueError)
    assert str(error) == "a.toml: sensor.fps: got 0; allowed: 1 to 50 frames/s"
    copy = pickle.loads(pickle.dumps(error))  # process pools send errors back pickled
    assert type(copy) is kind and str(copy) == str(error)


@pytest.mark.parametrize("content, problem", [(b'scene = "lab"\nduration_s = [\n',
                                               "not valid TOML"),
                                              (b"\xff\xfe", "not UTF-8 text")])
def test_a_file_that_is_not_toml_is_named(tmp_path, content, problem):
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    with pytest.raises(SweepError, match=rf"{path}: \(file\): {problem}"):
        read_toml(path, SweepError)


def test_a_file_saved_with_a_byte_order_mark_reads_the_same(tmp_path):
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text('scene = "lab"\n[sensor]\nfps = 20.0\n', encoding="utf-8")
    marked.write_text(plain.read_text(), encoding="utf-8-sig")
    assert read_toml(marked) == read_toml(plain) == {"scene": "lab", "sensor": {"fps": 20.0}}
