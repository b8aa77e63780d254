"""The synthetic scenes of stabilizer.testing: the tests' scene and the varied corpus."""

import numpy as np
import pytest

import stabilizer
from stabilizer.testing import (
    CORPUS_GENERATORS,
    SR4000_SHAPE,
    corpus_frames,
    corrupt_depth,
    make_depth_scene,
)


def _spread(depth):
    """Share of the valid pixels outside the 10 most populous disparity levels."""
    counts = np.bincount(stabilizer.depth_to_disparity(depth).ravel(), minlength=256)[1:]
    return 1.0 - np.sort(counts)[-10:].sum() / counts.sum()


def _distinct_regions(depth):
    """Distinct depths of the scene's flat regions (slanted planes count once per level)."""
    return np.unique(np.round(depth[depth > 0], 1)).size


@pytest.mark.parametrize("generator", list(CORPUS_GENERATORS))
def test_corpus_is_a_pure_function_of_the_seed(generator):
    first = corpus_frames(generator, 3, 2)
    again = corpus_frames(generator, 3, 2)
    other = corpus_frames(generator, 4, 2)
    assert np.array_equal(first[0], again[0])
    assert all(np.array_equal(a, b) for a, b in zip(first[1], again[1]))
    assert [m.as_tuple() for m in first[2]] == [m.as_tuple() for m in again[2]]
    assert not np.array_equal(first[0], other[0])
    reference, frames, motions = first
    assert reference.shape == SR4000_SHAPE and reference.dtype == np.uint8
    assert len(frames) == len(motions) == 2
    assert all(frame.shape == SR4000_SHAPE and frame.dtype == np.uint8 for frame in frames)


def test_the_tests_generator_is_the_tests_scene():
    reference, _, _ = corpus_frames("tests", 7, 0)
    assert np.array_equal(reference, stabilizer.depth_to_disparity(make_depth_scene(7)))


def test_generators_differ_in_what_they_vary():
    make = {name: entry[0] for name, entry in CORPUS_GENERATORS.items()}
    seeds = range(5)
    few = np.mean([_distinct_regions(make["few_objects"](seed)) for seed in seeds])
    many = np.mean([_distinct_regions(make["many_objects"](seed)) for seed in seeds])
    assert many > few + 4
    # Gradients: a floor (and a ceiling) spread the disparity histogram over many levels.
    for name, least, most in (("few_objects", 0.0, 0.15), ("gradient_floor", 0.15, 1.0),
                              ("clutter", 0.3, 1.0)):
        for seed in seeds:
            assert least <= _spread(make[name](seed)) <= most, (name, seed)
    # Invalid pixels: a far region that holds a 9 x 9 square, and more than the frame edge.
    depth = make["invalid_pixels"](0)
    invalid = depth == 0
    assert 0.02 < invalid.mean() < 0.3
    windows = np.lib.stride_tricks.sliding_window_view(invalid, (9, 9))
    assert windows.all(axis=(2, 3)).any()
    assert not (make["clutter"](0) == 0).any()


def test_noise_and_dropouts_are_drawn_for_every_frame():
    reference, frames, motions = corpus_frames("noisy", 0, 2, max_angle_deg=0.0,
                                               max_shift_px=0.0)
    assert all(m.as_tuple() == (0.0, 0.0, 0.0) for m in motions)
    # Unmoved frames still differ from the reference and from each other: the noise is new.
    assert not np.array_equal(frames[0], reference)
    assert not np.array_equal(frames[0], frames[1])
    # The noise stays small: a few gray levels where measured.
    both = (frames[0] > 0) & (reference > 0)
    assert np.median(np.abs(frames[0][both].astype(int) - reference[both])) <= 3
    rng = np.random.default_rng(0)
    depth = np.full((100, 100), 2.0, np.float32)
    depth[:10] = 0.0
    dropped = corrupt_depth(depth, rng, dropouts=0.1)
    assert (dropped[:10] == 0).all()
    assert 0.05 < np.mean(dropped[10:] == 0) < 0.15


def test_depth_noise_grows_with_the_depth():
    depth = np.zeros((200, 200), np.float32)
    depth[:100], depth[100:150] = 1.0, 4.0  # the rest unmeasured
    noisy = corrupt_depth(depth, np.random.default_rng(1), noise=0.01)
    for level, rows in ((1.0, slice(0, 100)), (4.0, slice(100, 150))):
        error = noisy[rows] - level
        assert abs(error.mean()) < 0.1 * 0.01 * level
        assert error.std() == pytest.approx(0.01 * level, rel=0.05)
    assert not noisy[150:].any()


def test_motions_stay_within_their_bounds():
    _, _, motions = corpus_frames("clutter", 1, 50, max_angle_deg=5.0, max_shift_px=10.0)
    values = np.array([m.as_tuple() for m in motions])
    assert np.all(np.abs(values[:, 0]) <= 5.0) and np.all(np.abs(values[:, 1:]) <= 10.0)
    assert values[:, 0].std() > 1.0


def test_the_paper_method_recovers_the_motions_of_every_generator():
    """The corpus is a fair test of the method, not noise: most motions are recovered."""
    for generator in CORPUS_GENERATORS:
        recovered = []
        for seed in range(2):
            reference, frames, motions = corpus_frames(generator, seed, 3)
            tracker = stabilizer.Stabilizer(reference, "t2fuzzy")
            for frame, truth in zip(frames, motions):
                error = np.abs(np.subtract(tracker.estimate(frame).as_tuple(), truth.as_tuple()))
                recovered.append(bool(np.all(error <= [1.0, 1.0, 1.0])))
        assert np.mean(recovered) >= 4 / 6, generator


def test_unknown_generators_and_negative_counts_are_refused():
    with pytest.raises(ValueError, match="unknown corpus generator 'walls'.*accepted: tests"):
        corpus_frames("walls", 0, 1)
    with pytest.raises(ValueError, match="n_frames must be >= 0; got -1"):
        corpus_frames("tests", 0, -1)
