"""Where ``t2fuzzy`` fails on walking scenes it was never tuned on, and what its refinements do.

Three steps (docs/method.md, section 12, shows their output):

    python benchmarks/t2fuzzy_failures.py record  --out /tmp/t2f/seq     # 24 sequences
    python benchmarks/t2fuzzy_failures.py table   /tmp/t2f/seq/*          # before / after / ECC
    python benchmarks/t2fuzzy_failures.py summary /tmp/t2f/seq/*          # one line per method
    python benchmarks/t2fuzzy_failures.py margins /tmp/t2f/seq/*          # the check's margins
    python benchmarks/t2fuzzy_failures.py switch  /tmp/t2f/seq/* --param A [B ...]  # whole runs
    python benchmarks/t2fuzzy_failures.py switch  /tmp/t2f/seq/* --param image_border --tie-break
    python benchmarks/t2fuzzy_failures.py overlap-climb /tmp/t2f/seq/*    # their cost
    python benchmarks/t2fuzzy_failures.py second-look /tmp/t2f/seq/*      # the second look's
    python benchmarks/t2fuzzy_failures.py astray-climb /tmp/t2f/seq/*     # the recovery's
    python benchmarks/t2fuzzy_failures.py rivals  /tmp/t2f/seq/*          # rival second looks
    python benchmarks/t2fuzzy_failures.py grid-reach /tmp/t2f/seq/*       # the check's grid search
    python benchmarks/t2fuzzy_failures.py check-time /tmp/t2f/seq/* --param NAME --values A B
    python benchmarks/t2fuzzy_failures.py stage6  /tmp/t2f/seq/*          # stage 6 alone
    python benchmarks/t2fuzzy_failures.py flow-tiles /tmp/t2f/seq/off_pa_2009 272   # non-rigid
    python benchmarks/t2fuzzy_failures.py figures /tmp/t2f/seq --out docs/figures

``record`` walks the four shipped scenes (corridor, lab, office, hall) with both gaits on the
tuning scene seeds 2001-2003 (the held-out suite's seeds 1000-1003 are for scoring only and
are refused here), 300 frames each; the office walk turns from 4 s so that its turn falls in
those frames. ``table`` scores each sequence, reference = first frame of each gait cycle, with
``t2fuzzy`` as it was before the refinements of section 12 (the same class with them switched
off), ``t2fuzzy`` and ``ecc``: mean absolute errors of the ``ok`` frames, the largest, the
number of ``ok`` frames off by more than 5 degrees or 10 px, the failure rate; once with each
method's own statuses only (``verification=None``) and once through the shared trust check;
and the time per frame of both ``t2fuzzy`` variants, measured alternately in this process.
``stage6`` judges stage 6 alone, at the true rotation. ``figures`` draws the failing frames of
docs/method.md, section 12.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

# First: importing sim puts numpy and OpenCV on the SIMD paths of egostab's runs, and
# limit_threads gives them one thread each, as where egostab estimates, before they load.
from sim.harness.threads import limit_threads

limit_threads()

import cv2
import numpy as np

TUNING_SCENE_SEEDS = (2001, 2002, 2003)
SCENARIOS = {"cor": "corridor_straight", "lab": "lab_clutter", "off": "office_turn",
             "hall": "paper_like_gait"}
GAITS = {"de": "default", "pa": "paper_like"}
#: The office walk turns from 4 s (its scenario from 16 s) so that 300 frames hold the turn.
OFFICE_EARLY_TURN = [{"t": 0.0, "speed": 0.0}, {"t": 1.0, "speed": 0.1},
                     {"t": 4.0, "speed": 0.1, "yaw_rate": 7.162},
                     {"t": 16.566, "speed": 0.1, "yaw_rate": 0.0}]
FRAMES = 300


def before_refinements():
    """``t2fuzzy``'s refinements as they were before section 12: no wide search, no search
    without ellipse estimates, no unconverged failures, no rotation range, no large template."""
    from stabilizer.t2fuzzy_refinements import Refinements

    return Refinements(wide_search_px=0, search_without_estimates=False, fail_unconverged=False,
                       max_rotation_deg=math.inf, large_template_border_px=0)


def heldout_scene_seeds() -> set[int]:
    """Scene seeds of the held-out suite (scenarios/suites/heldout.toml): never tuned on."""
    from scenarios import SUITES_DIR
    from sim.harness.suite import load_suite

    return {sequence.scene_seed for sequence in load_suite(SUITES_DIR / "heldout.toml").sequences}


def check_tuning_seeds(seeds: list[int]) -> None:
    """A ValueError naming the first of ``seeds`` that the held-out suite uses."""
    heldout = heldout_scene_seeds()
    for seed in seeds:
        if seed in heldout:
            raise ValueError(f"scene seed {seed} is a seed of the held-out suite "
                             f"({min(heldout)}-{max(heldout)}), for scoring only; use others, "
                             f"e.g. 2001-2003")


def record(out: Path, seeds: list[int]) -> None:
    """The tuning sequences of ``seeds`` (none held out) into ``out``; those there are kept."""
    from sim.harness.runner import RecordConfig, record as record_sequence

    check_tuning_seeds(seeds)
    for seed in seeds:
        for short, scenario in SCENARIOS.items():
            for gait_short, gait in GAITS.items():
                folder = out / f"{short}_{gait_short}_{seed}"
                if (folder / "truth.csv").exists():
                    continue
                overrides = {"scene_seed": seed, "gait.preset": gait,
                             "recording.enabled": False}
                if short == "off":
                    overrides["commands"] = OFFICE_EARLY_TURN
                header = record_sequence(RecordConfig(scenario, str(folder), FRAMES,
                                                      overrides=overrides))
                print(f"{folder}: {header['frames']} frames, {header['ended']}", flush=True)


def _frames(folder: Path):
    """Disparity frames, reference indices, truths and truth validity of a sequence."""
    from sim.harness.sequence import load_sequence

    sequence = load_sequence(folder)
    frames = np.stack([sequence.frame(row.frame, exact=False).disparity8
                       for row in sequence.rows])
    references = np.array([row.reference_frame for row in sequence.rows])
    truth = np.array([(row.angle_deg, row.dx, row.dy) for row in sequence.rows])
    truth_ok = np.array([row.truth_status == "ok" for row in sequence.rows])
    return frames, references, truth, truth_ok


def _estimates(frames, references, method, verify, stride=1, clock=time.perf_counter,
               **params):
    """One Motion for every ``stride``-th frame, each against its reference; and the seconds
    spent (on ``clock``). ``verify``: True (the trust check's defaults), False (no check) or
    the check's VerificationParams."""
    from stabilizer import Stabilizer
    from stabilizer.verification import VerificationParams

    verification = VerificationParams() if verify is True else verify or None
    motions, seconds, tracker, current = [], 0.0, None, None
    for index in range(0, len(frames), stride):
        start = clock()
        if references[index] != current:
            current = references[index]
            tracker = Stabilizer(frames[current], method, verification=verification, **params)
        motions.append(tracker.estimate(frames[index]))
        seconds += clock() - start
    return motions, seconds


def _status_name(motion) -> str:
    """The status, with the trust check's reason for ``"unverified"``."""
    reason = motion.diagnostics.get("verify_failed") if motion.status == "unverified" else None
    return f"{motion.status}: {reason}" if reason else motion.status


def summary(folders: list[Path], methods: list[str], stride: int,
            refinements: dict | None = None) -> None:
    """One line per method over every sequence, through the trust check: the mean over the
    sequences of the ok frames' mean errors and of the failure rates, the ok frames off by more
    than 5 deg or 10 px, the process CPU ms per frame, and the count of each status; then the
    mean signed x and y errors of each sequence's ok frames (a bias against the rigid truth).
    ``refinements``: settings of :class:`~stabilizer.t2fuzzy_refinements.Refinements` for the
    ``t2fuzzy`` method (its defaults otherwise)."""
    from collections import Counter

    from stabilizer.t2fuzzy_refinements import Refinements

    loaded = [_frames(folder) for folder in folders]
    for method in methods:
        params = ({"refinements": Refinements(**refinements)}
                  if refinements and method == "t2fuzzy" else {})
        rows, statuses, seconds, n_frames = [], Counter(), 0.0, 0
        for frames, references, truth, truth_ok in loaded:
            motions, spent = _estimates(frames, references, method, True, stride,
                                        time.process_time, **params)
            seconds, n_frames = seconds + spent, n_frames + len(motions)
            statuses.update(_status_name(m) for m in motions if m.status != "ok")
            rows.append(_summary(motions, truth[::stride], truth_ok[::stride]))
        mean = np.mean([row["mean"] for row in rows], axis=0)
        print(f"{method}: rotation / x / y {mean[0]:.3f} / {mean[1]:.3f} / {mean[2]:.3f}, "
              f"ok > 5 deg or 10 px {sum(row['large'] for row in rows)}, failures "
              f"{100 * np.mean([row['failures'] for row in rows]):.1f}%, "
              f"{1e3 * seconds / n_frames:.2f} ms/frame (CPU), {n_frames} frames of "
              f"{len(folders)} sequences")
        print("   " + ", ".join(f"{name} {count}" for name, count in statuses.most_common()))
        print("   signed x / y error, mean, sequence by sequence (px): " + ", ".join(
            f"{row['signed'][0]:+.2f} / {row['signed'][1]:+.2f}" for row in rows))


def rivals(folders: list[Path]) -> None:
    """``t2fuzzy``'s second looks that pass the trust check but line the depth edges up worse
    than its estimate, with the rule of docs/method.md, section 12, "Rivals" switched off
    (``second_look_rivals=False``: every such estimate stands): how many, how many lie beyond
    the check's offset limits of the estimate (those the rule fails), and how near the truth
    each side of those is; and the second looks that replace the estimate from beyond the
    limits. Near: within 2 deg and 4 px of the truth; far: off by more than 5 deg or 10 px."""
    from collections import Counter

    from stabilizer import Motion
    from stabilizer.verification import VerificationParams

    params = VerificationParams(second_look_rivals=False)

    def nearness(motion, truth) -> str:
        error = (abs(float((motion[0] - truth[0] + 180.0) % 360.0 - 180.0)),
                 abs(motion[1] - truth[1]), abs(motion[2] - truth[2]))
        return ("far" if error[0] > 5.0 or max(error[1:]) > 10.0 else
                "near" if error[0] <= 2.0 and max(error[1:]) <= 4.0 else "between")

    n_frames = n_ok = n_worse = 0
    worse_beyond, replaced_beyond = Counter(), Counter()
    for folder in folders:
        frames, references, truth, truth_ok = _frames(folder)
        motions, _ = _estimates(frames, references, "t2fuzzy", params)
        for index, motion in enumerate(motions):
            n_frames += 1
            if not (motion.ok and truth_ok[index]):
                continue
            n_ok += 1
            found = motion.diagnostics
            if found.get("second_look_failed") == "edges":
                n_worse += 1
                first, second = motion, Motion(*found["second_look"])
                pair = worse_beyond
            elif "second_look_from" in found:
                first, second = Motion(*found["second_look_from"]), motion
                pair = replaced_beyond
            else:
                continue
            if params.beyond_offset(second, first):
                pair[(nearness(first.as_tuple(), truth[index]),
                      nearness(second.as_tuple(), truth[index]))] += 1

    def listed(pairs: Counter) -> str:
        return "; ".join(f"estimate {first}, second look {second}: {count}"
                         for (first, second), count in sorted(pairs.items())) or "none"

    print(f"t2fuzzy on {n_frames} frames of {len(folders)} sequences, the rule off: {n_ok} ok "
          f"(with a valid truth); second looks that pass with worse edges {n_worse}, beyond the "
          f"offset limits {sum(worse_beyond.values())} (the rule fails these)")
    print(f"   those beyond the limits: {listed(worse_beyond)}")
    print(f"second looks that replace the estimate from beyond the limits "
          f"{sum(replaced_beyond.values())}: {listed(replaced_beyond)}")


def overlap_climb_time(folders: list[Path], stride: int) -> None:
    """Process CPU ms per frame of ``t2fuzzy`` (no trust check) with its defaults, with the
    final shift on the whole overlap, with the final climb there, and with that climb and no
    large template, the four alternating frame by frame (docs/method.md, section 12)."""
    from stabilizer.t2fuzzy_refinements import Refinements

    _alternating_times(folders, stride, None, {
        "defaults": Refinements(),
        "final_overlap_shift": Refinements(final_overlap_shift=True),
        "final_overlap_climb": Refinements(final_overlap_climb=True),
        "final_overlap_climb, large_template_border_px=0":
            Refinements(final_overlap_climb=True, large_template_border_px=0)})


#: What the timing commands of a refinement compare: the command, the names of the variants
#: with and without it, the setting that switches it off, the diagnostics keys that say it ran
#: on a frame, and how the count is printed (docs/method.md, section 12).
REFINEMENT_TIMINGS = {
    "second-look": ("second look", "no second look", {"doubtful_offset_deg": math.inf},
                    ("second_look_from", "second_look"), "second looks"),
    "astray-climb": ("recovery", "no recovery", {"astray_climb_recovery": False},
                     ("astray_climb",), "astray climbs recovered"),
}


def refinement_time(folders: list[Path], stride: int, command: str) -> None:
    """Process CPU ms per frame of ``t2fuzzy`` through the trust check with a refinement and
    without it (``REFINEMENT_TIMINGS[command]``), the two alternating frame by frame, and on
    how many frames the refinement ran."""
    from stabilizer.t2fuzzy_refinements import Refinements
    from stabilizer.verification import VerificationParams

    on, off, switched_off, keys, counted = REFINEMENT_TIMINGS[command]
    motions = _alternating_times(folders, stride, VerificationParams(), {
        on: Refinements(), off: Refinements(**switched_off)})[on]
    ran = sum(any(key in m.diagnostics for key in keys) for m in motions)
    print(f"{counted}: {ran} of {len(motions)} frames")


def check_time(folders: list[Path], stride: int, param: str, values: list[float]) -> None:
    """Process CPU ms per check of the trust check with each value of ``param`` (a field of
    :class:`~stabilizer.verification.VerificationParams`), on the same ``t2fuzzy`` estimates
    (made once without the check), the variants alternating frame by frame; and how many
    full-resolution climbs each ran (docs/method.md, section 11, "Half a step astray")."""
    from stabilizer.verification import Verifier

    seconds, climbs, checks = dict.fromkeys(values, 0.0), dict.fromkeys(values, 0), 0
    for folder in folders:
        frames, references, _, _ = _frames(folder)
        motions = _estimates(frames, references, "t2fuzzy", False, stride)[0]
        current, verifiers = None, {}
        for index, motion in zip(range(0, len(frames), stride), motions):
            if references[index] != current:
                current = references[index]
                verifiers = {value: Verifier(frames[current], _check_params(param, value))
                             for value in values}
                for value, verifier in verifiers.items():
                    _count_calls(verifier, "full_resolution_optimum", climbs, value)
            if not motion.ok:
                continue
            checks += 1
            for value, verifier in verifiers.items():
                start = time.process_time()
                verifier(frames[index], motion)
                seconds[value] += time.process_time() - start
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
    for value in values:
        print(f"{param} {value}: {1e3 * seconds[value] / checks:.3f} ms per check (CPU), "
              f"{climbs[value]} full-resolution climbs, {checks} checks")
    print(f"load average {load}")


def _check_params(param: str, value: float):
    """:class:`~stabilizer.verification.VerificationParams` with ``param`` set to ``value``; a
    switch (a field whose default is True or False) takes 0 or 1. ValueError for a value or a
    name the check does not accept."""
    from stabilizer.verification import VerificationParams

    names = [field.name for field in dataclasses.fields(VerificationParams)]
    if param not in names:
        raise ValueError(f"--param {param}: no such setting of the check; accepted: "
                         f"{', '.join(names)}")
    if isinstance(getattr(VerificationParams(), param), bool):
        if value not in (0.0, 1.0):
            raise ValueError(f"--values {value:g}: {param} is a switch; accepted: 0 and 1")
        value = bool(value)
    return VerificationParams(**{param: value})


def _count_calls(instance, name: str, counts: dict, key) -> None:
    """Wraps ``instance``'s method ``name`` so that each call adds 1 to ``counts[key]``."""
    method = getattr(instance, name)

    def counted(*args, **kwargs):
        counts[key] += 1
        return method(*args, **kwargs)

    setattr(instance, name, counted)


def _alternating_times(folders: list[Path], stride: int, verification,
                       variants: dict) -> dict[str, list]:
    """Prints the process CPU ms per frame of ``t2fuzzy`` with each of ``variants`` (name ->
    Refinements) on every ``stride``-th frame, the variants alternating frame by frame, and the
    load; returns each variant's motions."""
    from stabilizer import Stabilizer

    seconds = dict.fromkeys(variants, 0.0)
    motions: dict[str, list] = {name: [] for name in variants}
    for folder in folders:
        frames, references, _, _ = _frames(folder)
        current, trackers = None, {}
        for index in range(0, len(frames), stride):
            if references[index] != current:
                current = references[index]
                trackers = {name: Stabilizer(frames[current], "t2fuzzy",
                                             verification=verification, refinements=refinements)
                            for name, refinements in variants.items()}
            for name, tracker in trackers.items():
                start = time.process_time()
                motions[name].append(tracker.estimate(frames[index]))
                seconds[name] += time.process_time() - start
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
    for name, spent in seconds.items():
        n_frames = len(motions[name])
        print(f"{name}: {1e3 * spent / n_frames:.2f} ms/frame (CPU), {n_frames} frames")
    print(f"load average {load}")
    return motions


def margins(folders: list[Path], methods: list[str], stride: int, values: list[float],
            param: str = "candidate_margin") -> None:
    """For each value of a margin of the trust check (``param``, a field of
    :class:`~stabilizer.verification.VerificationParams`), per method, the ok frames off by
    more than 5 deg or 10 px and the failure rate (mean over the sequences): every method's
    estimates are made once without the check, and each variant of the check is applied to the
    same estimates (docs/method.md, section 11, "Ambiguity" and "Ridges")."""
    from stabilizer.verification import Verifier

    loaded = [_frames(folder) for folder in folders]
    found = {margin: {} for margin in values}
    for method in methods:
        unchecked = [_estimates(frames, references, method, False, stride)[0]
                     for frames, references, _, _ in loaded]
        for margin in values:
            params = _check_params(param, margin)
            rows = []
            for (frames, references, truth, truth_ok), motions in zip(loaded, unchecked):
                checked, verifier, current = [], None, None
                for index, motion in zip(range(0, len(frames), stride), motions):
                    if references[index] != current:
                        current = references[index]
                        verifier = Verifier(frames[current], params)
                    checked.append(verifier(frames[index], motion))
                rows.append(_summary(checked, truth[::stride], truth_ok[::stride]))
            found[margin][method] = (sum(row["large"] for row in rows),
                                     100 * np.mean([row["failures"] for row in rows]))
    for margin, by_method in found.items():
        print(f"{param} {margin:+.2f}: " + ", ".join(
            f"{method} {large} large, {failures:.1f}%"
            for method, (large, failures) in by_method.items()))


def switch(folders: list[Path], methods: list[str], stride: int, params: list[str],
           tie_break: bool = False) -> None:
    """Switches of the trust check (``params``, True/False fields of
    :class:`~stabilizer.verification.VerificationParams`) all off and all on (``tie_break``:
    in the depth edges of ``t2fuzzy``'s tie-break, ``RotationSearch.edge_params``, the check
    keeping its defaults), each method run
    whole through the check (``t2fuzzy``'s second looks included, unlike :func:`margins`),
    frame by frame on every ``stride``-th frame with a valid truth: per method, the ``"ok"``
    estimates and those off by more than 5 deg or 10 px with each setting; the ``"ok"``
    estimates lost and gained by switching on, and how many of them lay within 1 deg and 2 px
    of the truth or beyond 5 deg or 10 px; how many ``"ok"`` estimates both settings give but
    differently; and each frame off by more than 5 deg or 10 px with either setting."""
    from unittest import mock

    from sim.harness.scoring import LARGE_ERROR_DEG, LARGE_ERROR_PX
    from stabilizer.motion import wrap_angle_deg
    from stabilizer.t2fuzzy_refinements import RotationSearch
    from stabilizer.verification import VerificationParams

    def errors(motion, truth) -> np.ndarray | None:
        if not motion.ok:
            return None
        off = np.abs(np.subtract(motion.as_tuple(), truth))
        off[0] = abs(float(wrap_angle_deg(motion.angle_deg - truth[0])))
        return off

    def large(off) -> bool:
        return off is not None and (off[0] > LARGE_ERROR_DEG or max(off[1:]) > LARGE_ERROR_PX)

    def accurate(off) -> bool:
        return off is not None and off[0] <= 1.0 and max(off[1:]) <= 2.0

    def estimates(frames, references, method, setting):
        if not tie_break:
            return _estimates(frames, references, method, setting, stride)[0]
        with mock.patch.object(RotationSearch, "edge_params", setting):
            return _estimates(frames, references, method, True, stride)[0]

    label = " + ".join(params) + (" (the tie-break's edges)" if tie_break else "")
    settings = [VerificationParams(**dict.fromkeys(params, value)) for value in (False, True)]
    loaded = [(folder, _frames(folder)) for folder in folders]
    for method in methods:
        rows = []  # (sequence, frame, errors off, errors on)
        for folder, (frames, references, truth, truth_ok) in loaded:
            switched_off, switched_on = (estimates(frames, references, method, setting)
                                         for setting in settings)
            name = folder.parent.name if folder.name == "sequence" else folder.name  # a suite's
            rows += [(name, index, errors(before, truth[index]),
                      errors(after, truth[index]))
                     for index, before, after in zip(range(0, len(frames), stride),
                                                     switched_off, switched_on)
                     if truth_ok[index]]
        for setting, column in (("off", 2), ("on", 3)):
            print(f"{method}, {label} {setting}: {sum(row[column] is not None for row in rows)} "
                  f"ok of {len(rows)}, {sum(large(row[column]) for row in rows)} off by more "
                  f"than {LARGE_ERROR_DEG:g} deg or {LARGE_ERROR_PX:g} px")
        for change, was, now in (("lost", 2, 3), ("gained", 3, 2)):
            changed = [row for row in rows if row[was] is not None and row[now] is None]
            print(f"  ok {change}: {len(changed)} ({sum(accurate(row[was]) for row in changed)} "
                  f"within 1 deg and 2 px, {sum(large(row[was]) for row in changed)} off by more)")
        moved = sum(row[2] is not None and row[3] is not None
                    and not np.array_equal(row[2], row[3]) for row in rows)
        print(f"  ok both ways, another estimate: {moved}")
        for name, index, before, after in rows:
            if large(before) or large(after):
                shown = ["-" if off is None else "/".join(f"{value:.2f}" for value in off)
                         for off in (before, after)]
                print(f"  {name} frame {index}: off {shown[0]}, on {shown[1]}")


def grid_reach(folders: list[Path], stride: int) -> None:
    """How often the trust check's search over the grid of angles (its candidate, climbed at
    half resolution; test 5 climbs it at full resolution too when that climb travels far) ends
    within the offset limits of the truth, by the length of the truth's translation; every ``stride``-th frame whose truth is valid, the
    references left out (docs/method.md, section 11, "Both measures")."""
    from stabilizer import Motion
    from stabilizer.verification import Verifier

    bounds_px = (0, 10, 20, 30, 40, 50, 60, 80, math.inf)
    reached, counted = np.zeros(len(bounds_px) - 1, int), np.zeros(len(bounds_px) - 1, int)
    for folder in folders:
        frames, references, truth, truth_ok = _frames(folder)
        verifier, current = None, None
        for index in range(0, len(frames), stride):
            if not truth_ok[index] or references[index] == index:
                continue
            if references[index] != current:
                current = references[index]
                verifier = Verifier(frames[current])
            measured, true = verifier.measure(frames[index]), Motion(*truth[index])
            candidate = verifier.candidate(measured.half)
            end = verifier.local_optimum(measured.half, candidate) or candidate
            row = int(np.searchsorted(bounds_px, math.hypot(true.dx, true.dy), side="right")) - 1
            counted[row] += 1
            reached[row] += not verifier.params.beyond_offset(end, true)
    for low, high, hits, frames_in in zip(bounds_px[:-1], bounds_px[1:], reached, counted):
        if frames_in:
            print(f"translation {low:g}-{high:g} px: {frames_in} frames, the grid search ends "
                  f"within the offset limits of the truth on {100 * hits / frames_in:.0f}%")
    print(f"all: {counted.sum()} frames, {100 * reached.sum() / max(counted.sum(), 1):.1f}%")


def _summary(motions, truth, truth_ok) -> dict:
    from sim.harness.scoring import LARGE_ERROR_DEG, LARGE_ERROR_PX

    status = np.array([m.status for m in motions])
    estimates = np.array([m.as_tuple() for m in motions])
    scored = (status == "ok") & truth_ok
    errors = np.abs(estimates - truth)[scored]
    errors[:, 0] = np.abs((estimates - truth)[scored, 0] + 180.0) % 360.0 - 180.0
    errors[:, 0] = np.abs(errors[:, 0])
    large = (errors[:, 0] > LARGE_ERROR_DEG) | (errors[:, 1:] > LARGE_ERROR_PX).any(axis=1)
    return {"mean": errors.mean(axis=0), "max": errors.max(axis=0), "large": int(large.sum()),
            "failures": float(np.mean(status != "ok")),
            "signed": (estimates - truth)[scored, 1:].mean(axis=0)}


def table(folders: list[Path]) -> None:
    variants = {"before": ("t2fuzzy", {"refinements": before_refinements()}),
                "t2fuzzy": ("t2fuzzy", {}), "ecc": ("ecc", {})}
    seconds = {"before": 0.0, "t2fuzzy": 0.0}
    n_frames = 0
    print("| sequence | check | method | rotation / x / y, mean | max | ok > 5 deg or 10 px "
          "| failures |")
    print("|---|---|---|---|---|---|---|")
    for folder in folders:
        frames, references, truth, truth_ok = _frames(folder)
        n_frames += len(frames)
        for verify in (False, True):
            for name, (method, params) in variants.items():
                motions, spent = _estimates(frames, references, method, verify, **params)
                if not verify and name in seconds:
                    seconds[name] += spent
                s = _summary(motions, truth, truth_ok)
                mean, top = s["mean"], s["max"]
                print(f"| {folder.name} | {'trust check' if verify else 'own'} | {name} "
                      f"| {mean[0]:.2f} / {mean[1]:.2f} / {mean[2]:.2f} "
                      f"| {top[0]:.1f} / {top[1]:.1f} / {top[2]:.1f} | {s['large']} "
                      f"| {100 * s['failures']:.1f}% |", flush=True)
    print(f"\nms per frame without the trust check (same frames, one process): "
          f"before {1e3 * seconds['before'] / n_frames:.2f}, "
          f"t2fuzzy {1e3 * seconds['t2fuzzy'] / n_frames:.2f}")


def stage6(folders: list[Path]) -> None:
    """Stage 6 alone, at the true rotation, on every other frame: the share of frames whose
    shift is off by more than 4 px, for the central template (full resolution, +-44 px) and for
    the masked whole overlap (half resolution, +-72 px, the wide search of section 12)."""
    from stabilizer.fncc import RotatedTemplate
    from stabilizer.t2fuzzy_refinements import WideSearch, half_resolution_valid

    print("| sequence | frames | central template off > 4 px | whole overlap off > 4 px |")
    print("|---|---|---|---|")
    for folder in folders:
        frames, references, truth, truth_ok = _frames(folder)
        off = {"central": [], "whole": []}
        for index in range(0, len(frames), 2):
            reference = references[index]
            if not truth_ok[index] or reference == index:
                continue
            smooth = [cv2.GaussianBlur(frames[i].astype(np.float32), (0, 0), 1.0)
                      for i in (reference, index)]
            angle, shift = truth[index][0], truth[index][1:]
            central = RotatedTemplate(smooth[0], 44, valid=frames[reference] > 0)
            found = central.match(smooth[1], angle)
            off["central"].append(np.max(np.abs(np.array([found.x, found.y]) - shift)) > 4)
            wide = WideSearch(smooth[0], frames[reference] > 0, 72, 0.3)
            spectra = wide.spectra(cv2.pyrDown(smooth[1]),
                                   half_resolution_valid(frames[index] > 0))
            found = wide.match(spectra, angle)
            off["whole"].append(np.max(np.abs(np.array([found.x, found.y]) - shift)) > 4)
        print(f"| {folder.name} | {len(off['central'])} | {100 * np.mean(off['central']):.1f}% "
              f"| {100 * np.mean(off['whole']):.1f}% |", flush=True)


def flow_tiles(folder: Path, index: int, methods: list[str], grid: int = 3) -> None:
    """How far the true image motion of one frame is from rigid: the ground truth's rigid fit
    and its residual, the zoom of the least-squares similarity of the same correspondences, and
    per tile of a ``grid`` x ``grid`` split of the reference the mean (dx, dy) by which the true
    motion of its pixels differs from the rigid truth and from each method's own estimate
    (without the trust check); and what the trust check says of each of those motions and where
    its grid of angles points (docs/method.md, section 11, "What it promises, and what it cannot
    see")."""
    from sim.harness.runner import frame_truth
    from sim.harness.sequence import load_sequence
    from stabilizer import Stabilizer
    from stabilizer.motion import transform_points
    from stabilizer.verification import (
        VerificationParams,
        Verifier,
        edge_image,
        structure_correlation,
    )

    try:
        sequence = load_sequence(folder)
    except (OSError, ValueError) as error:
        print(error, file=sys.stderr)  # names the folder and what is accepted
        raise SystemExit(2) from None
    if not 0 <= index < sequence.n_frames:
        print(f"frame {index} is not in {folder}; accepted: 0-{sequence.n_frames - 1}",
              file=sys.stderr)
        raise SystemExit(2)
    row = sequence.rows[index]
    reference, current = sequence.frame(row.reference_frame), sequence.frame(index)
    truth = frame_truth(reference, current, sequence.intrinsics)
    pairs = truth.correspondences
    source, target = pairs.source_px.astype(np.float64), pairs.target_px.astype(np.float64)
    # Every correspondence an inlier: the least-squares similarity, refined.
    similarity, _ = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC,
                                                ransacReprojThreshold=1e6, refineIters=20)
    zoom = math.hypot(similarity[0, 0], similarity[1, 0])
    turn = math.degrees(math.atan2(similarity[0, 1], similarity[0, 0]))  # Motion's sign
    print(f"{folder.name} frame {index} (reference {row.reference_frame}): truth "
          f"{np.round(truth.motion.as_tuple(), 2)}, residual {truth.residual_rms_px:.2f} px RMS "
          f"over {truth.n_points} points; the similarity fit: zoom {zoom:.3f}, rotation "
          f"{turn:.2f} deg")
    height, width = pairs.shape
    tile = (np.minimum(source[:, 1] * grid // height, grid - 1) * grid
            + np.minimum(source[:, 0] * grid // width, grid - 1)).astype(int)
    params = VerificationParams()
    verifier = Verifier(reference.disparity8, params)
    edges = verifier.measure(current.disparity8)
    candidate = verifier.candidate(edges.half)
    climbed = verifier.local_optimum(edges.half, candidate)
    print(f"the check's grid candidate {np.round(candidate.as_tuple(), 2)}, climbed at half "
          f"resolution to ", end="")
    if climbed is None:
        print("nothing (ECC gave up)")
    else:
        reference_edges = edge_image(reference.disparity8, params.sigma_px, params.clip_factor,
                                     params.image_border)  # as the check's own
        correlation, _ = structure_correlation(*reference_edges, *edges.edges, climbed)
        print(f"{np.round(climbed.as_tuple(), 2)} (edge correlation {correlation:.3f})")
    motions = {"rigid truth": truth.motion}
    for method in methods:
        motions[method] = Stabilizer(reference.disparity8, method,
                                     verification=None).estimate(current.disparity8)
    for name, motion in motions.items():
        print(f"\n{name}: {motion.status} {np.round(motion.as_tuple(), 2)}")
        if not motion.ok:
            continue
        measured = verifier(current.disparity8, motion).diagnostics
        rival = measured.get("verify_candidate")
        print(f"  the check: {measured.get('verify_failed', 'ok')}, edge correlation "
              f"{measured.get('verify_correlation', math.nan):.3f}, its optimum "
              f"{np.round(measured.get('verify_optimum', (math.nan,) * 3), 2)} at "
              f"{measured.get('verify_optimum_correlation', math.nan):.3f}"
              + ("" if rival is None else f", rival {np.round(rival, 2)} at "
                 f"{measured['verify_candidate_correlation']:.3f}")
              + f"; disparity difference "
              f"{_disparity_difference(reference.disparity8, current.disparity8, motion):.2f}")
        off = target - transform_points(motion, source, pairs.shape)
        for row_of_tiles in range(grid):
            cells = []
            for column in range(grid):
                inside = tile == row_of_tiles * grid + column
                cells.append(f"{off[inside, 0].mean():6.1f} {off[inside, 1].mean():6.1f} "
                             f"({np.count_nonzero(inside):4d})" if inside.any() else " " * 20)
            print(" | ".join(cells))


def _disparity_difference(reference: np.ndarray, current: np.ndarray, motion) -> float:
    """Mean absolute difference (gray levels) of the reference and the current frame
    compensated by ``motion``, where both measure."""
    from stabilizer.motion import compensate

    compensated = compensate(current, motion).astype(np.float64)
    both = (compensated > 0) & (reference > 0)
    return float(np.abs(compensated - reference)[both].mean())


def _surfaces(reference, current, truth):
    """The central template's FNCC surface and the masked whole-overlap one, both at the true
    rotation and full resolution, over shifts of +-72 px."""
    from stabilizer.fncc import MaskedCorrelation, RotatedTemplate

    smooth = [cv2.GaussianBlur(f.astype(np.float32), (0, 0), 1.0) for f in (reference, current)]
    template, mask = RotatedTemplate(smooth[0], 44, valid=reference > 0).template(truth[0])
    central = cv2.matchTemplate(smooth[1], template, cv2.TM_CCOEFF_NORMED, mask=mask)
    rotation = cv2.getRotationMatrix2D(((reference.shape[1] - 1) / 2.0,
                                        (reference.shape[0] - 1) / 2.0), float(truth[0]), 1.0)
    size = reference.shape[::-1]
    rotated = cv2.warpAffine(smooth[0], rotation, size, flags=cv2.INTER_LINEAR)
    valid = cv2.warpAffine((reference > 0).view(np.uint8), rotation, size,
                           flags=cv2.INTER_NEAREST) > 0
    correlation = MaskedCorrelation(reference.shape, 72, 0.3)
    whole = correlation.surface(correlation.spectra(rotated, valid, False),
                                correlation.spectra(smooth[1], current > 0, True))
    return central, whole


#: The failing frames docs/method.md, section 12, draws: (sequence under `record`'s folder,
#: frame, figure file).
FIGURE_CASES = [("hall_de_2001", 227, "t2f_fail_hall_ridge.png"),
                ("off_pa_2001", 216, "t2f_fail_office_beyond_range.png"),
                ("lab_pa_2001", 288, "t2f_fail_lab_wrapped.png")]


def figures(root: Path, out: Path) -> None:
    """The figures of docs/method.md, section 12."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim.atomic import atomic_path

    out.mkdir(parents=True, exist_ok=True)
    for name, index, file_name in FIGURE_CASES:
        frames, references, truth, _ = _frames(root / name)
        reference, current = frames[references[index]], frames[index]
        before = _estimates(frames[[references[index], index]], np.array([0, 0]), "t2fuzzy",
                            False, refinements=before_refinements())[0][1]
        after = _estimates(frames[[references[index], index]], np.array([0, 0]), "t2fuzzy",
                           False)[0][1]
        central, whole = _surfaces(reference, current, truth[index])
        figure, axes = plt.subplots(1, 4, figsize=(19, 3.8))
        axes[0].imshow(reference, cmap="gray")
        axes[0].set_title(f"{name}: reference {references[index]}")
        axes[1].imshow(current, cmap="gray")
        axes[1].set_title(f"frame {index}: truth {np.round(truth[index], 1)}")
        for axis, scores, reach, title in ((axes[2], central, 44, "central template"),
                                           (axes[3], whole, 72, "whole overlap, masked")):
            shown = np.where(np.isfinite(scores), scores, np.nan)
            image = axis.imshow(shown, extent=(-reach - 0.5, reach + 0.5, reach + 0.5,
                                               -reach - 0.5), vmin=-0.2, vmax=1.0)
            axis.plot(truth[index][1], truth[index][2], "r+", ms=16, mew=2, label="truth")
            for motion, marker, label in ((before, "wx", "before"), (after, "co", "t2fuzzy")):
                if motion.ok:
                    axis.plot(motion.dx, motion.dy, marker, ms=9, mfc="none", mew=2, label=label)
            axis.set_xlim(-72.5, 72.5)
            axis.set_ylim(72.5, -72.5)
            axis.set_title(f"FNCC at the true rotation:\n{title}")
            axis.set_xlabel("dx (px)")
            axis.set_ylabel("dy (px)")
            figure.colorbar(image, ax=axis, fraction=0.04)
        axes[3].legend(loc="lower right", fontsize=8)
        status = (f"before: {before.status} {np.round(before.as_tuple(), 1)};  "
                  f"t2fuzzy: {after.status} {np.round(after.as_tuple(), 1)}")
        figure.suptitle(status, y=0.02, fontsize=10)
        with atomic_path(out / file_name) as temporary:
            figure.savefig(temporary, format="png", dpi=72, bbox_inches="tight")
        plt.close(figure)
        print(out / file_name)


def _sequences(folders: list[Path]) -> list[Path]:
    """The sequence folders among ``folders``, sorted; a folder without sequence.json (a
    recording that did not finish) is named and left out; none left: a ValueError."""
    complete = []
    for folder in sorted(folders):
        if (folder / "sequence.json").is_file():
            complete.append(folder)
        else:
            print(f"{folder}: no sequence.json (a recording that did not finish); left out")
    if not complete:
        raise ValueError(f"no sequence among the {len(folders)} folder(s) given; accepted: "
                         f"folders `record` wrote (each with its sequence.json)")
    return complete


def _setting(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` with a Python literal value (True, 0, 1.5) or ``inf``."""
    import ast

    name, separator, value = text.partition("=")
    value = value.strip()
    try:
        if not (separator and name.strip()):
            raise ValueError
        return name.strip(), math.inf if value == "inf" else ast.literal_eval(value)
    except (ValueError, SyntaxError):
        raise argparse.ArgumentTypeError(f"{text!r}: accepted: NAME=VALUE, VALUE a Python "
                                         f"literal (True, 0, 1.5) or inf") from None


def _check_refinements(settings: dict) -> None:
    """A ValueError naming a setting that :class:`~stabilizer.t2fuzzy_refinements.Refinements`
    does not have or refuses."""

    from stabilizer.t2fuzzy_refinements import Refinements

    names = {field.name for field in dataclasses.fields(Refinements)}
    unknown = sorted(set(settings) - names)
    if unknown:
        raise ValueError(f"--refinements {unknown[0]}: no such setting; accepted: "
                         f"{', '.join(sorted(names))}")
    Refinements(**settings)


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import (MAX_SEED, POSITIVE_INTEGER, OneLineParser, integer_option,
                                  path_option)
    from stabilizer.verification import VerificationParams

    parser = OneLineParser(prog="t2fuzzy_failures.py", description=__doc__.splitlines()[0])
    commands = parser.commands = parser.add_subparsers(dest="command", required=True)
    recorder = commands.add_parser("record", help="record the tuning sequences")
    recorder.add_argument("--out", type=path_option, required=True)
    recorder.add_argument("--seeds", type=integer_option(0, MAX_SEED), nargs="+",
                          default=list(TUNING_SCENE_SEEDS))
    scorer = commands.add_parser("table", help="before / after / ECC per sequence")
    scorer.add_argument("folders", type=Path, nargs="+")
    overall = commands.add_parser("summary", help="one line per method, through the check")
    overall.add_argument("folders", type=Path, nargs="+")
    overall.add_argument("--methods", nargs="+", default=["t2fuzzy", "ecc"])
    overall.add_argument("--stride", type=POSITIVE_INTEGER, default=2,
                         help="score every n-th frame")
    overall.add_argument("--refinements", type=_setting, nargs="+", default=[],
                         metavar="NAME=VALUE",
                         help="t2fuzzy Refinements settings, e.g. final_overlap_climb=True")
    timed = commands.add_parser("overlap-climb",
                                help="t2fuzzy's time with the final shift and the final climb")
    timed.add_argument("folders", type=Path, nargs="+")
    timed.add_argument("--stride", type=POSITIVE_INTEGER, default=4, help="time every n-th frame")
    looked = commands.add_parser("second-look", help="t2fuzzy's time with its second look")
    looked.add_argument("folders", type=Path, nargs="+")
    looked.add_argument("--stride", type=POSITIVE_INTEGER, default=4, help="time every n-th frame")
    recovering = commands.add_parser("astray-climb",
                                     help="t2fuzzy's time with its recovery of astray climbs")
    recovering.add_argument("folders", type=Path, nargs="+")
    recovering.add_argument("--stride", type=POSITIVE_INTEGER, default=4,
                            help="time every n-th frame")
    checked = commands.add_parser("check-time", help="the trust check's time per setting")
    checked.add_argument("folders", type=Path, nargs="+")
    checked.add_argument("--stride", type=POSITIVE_INTEGER, default=4,
                         help="time every n-th frame")
    checked.add_argument("--param", default="full_resolution_travel_deg")
    checked.add_argument("--values", type=float, nargs="+", default=[5.0, 2.5])
    swept = commands.add_parser("margins", help="a margin of the check, every method")
    swept.add_argument("folders", type=Path, nargs="+")
    swept.add_argument("--methods", nargs="+", default=["t2fuzzy", "t2fuzzy_paper", "sift",
                                                        "icp", "ecc", "fourier_mellin"])
    swept.add_argument("--stride", type=POSITIVE_INTEGER, default=2, help="score every n-th frame")
    swept.add_argument("--values", type=float, nargs="+",
                       default=[-0.1, -0.05, 0.03, 0.05, 0.08, 0.1])
    swept.add_argument("--param", default="candidate_margin",
                       choices=["candidate_margin", "outside_margin", "ridge_margin",
                                "null_margin", "full_resolution_travel_deg",
                                "strong_edge_ridge", "weighted_rivals",
                                "plain_shift_rivals", "image_border"])
    switched = commands.add_parser("switch", help="a switch of the check, whole runs")
    switched.add_argument("folders", type=Path, nargs="+")
    switched.add_argument("--methods", nargs="+", default=["t2fuzzy", "ecc"])
    switched.add_argument("--stride", type=POSITIVE_INTEGER, default=2,
                          help="every n-th frame")
    switched.add_argument("--param", nargs="+", default=["image_border"],
                          help="switched off and on together",
                          choices=[field.name for field in dataclasses.fields(VerificationParams)
                                   if isinstance(field.default, bool)])
    switched.add_argument("--tie-break", action="store_true",
                          help="switch them in t2fuzzy's tie-break edges, not in the check")
    reaching = commands.add_parser("grid-reach", help="the check's grid search against the truth")
    reaching.add_argument("folders", type=Path, nargs="+")
    reaching.add_argument("--stride", type=POSITIVE_INTEGER, default=3,
                          help="every n-th frame")
    rivalled = commands.add_parser("rivals", help="second looks that pass with worse edges")
    rivalled.add_argument("folders", type=Path, nargs="+")
    isolated = commands.add_parser("stage6", help="stage 6 alone at the true rotation")
    isolated.add_argument("folders", type=Path, nargs="+")
    tiled = commands.add_parser("flow-tiles", help="how far one frame's true motion is from rigid")
    tiled.add_argument("folder", type=Path)
    tiled.add_argument("frame", type=integer_option(0))
    tiled.add_argument("--methods", nargs="+", default=["t2fuzzy", "ecc"])
    drawer = commands.add_parser("figures", help="the failing frames of docs/method.md")
    drawer.add_argument("root", type=Path, help="the folder `record` wrote")
    drawer.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    try:
        if args.command == "record":
            check_tuning_seeds(args.seeds)
            try:
                args.out.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise ValueError(f"--out {args.out}: {error.strerror}; accepted: a folder that "
                                 f"can be created and written") from None
        if args.command == "summary":
            _check_refinements(dict(args.refinements))
        if args.command in ("check-time", "margins"):
            for value in args.values:
                _check_params(args.param, value)
        sequences = _sequences(args.folders) if hasattr(args, "folders") else None
        if args.command == "figures":
            missing = [name for name, _, _ in FIGURE_CASES
                       if not (args.root / name / "sequence.json").is_file()]
            if missing:
                raise ValueError(f"{args.root / missing[0]}: no sequence; accepted: the folder "
                                 f"`record` wrote, which holds "
                                 f"{', '.join(name for name, _, _ in FIGURE_CASES)}")
    except ValueError as error:
        print(f"t2fuzzy_failures.py {args.command}: error: {error}", file=sys.stderr)
        return 2
    if args.command == "record":
        record(args.out, args.seeds)
    elif args.command == "table":
        table(sequences)
    elif args.command == "summary":
        summary(sequences, args.methods, args.stride, dict(args.refinements))
    elif args.command == "overlap-climb":
        overlap_climb_time(sequences, args.stride)
    elif args.command in REFINEMENT_TIMINGS:
        refinement_time(sequences, args.stride, args.command)
    elif args.command == "check-time":
        check_time(sequences, args.stride, args.param, args.values)
    elif args.command == "margins":
        margins(sequences, args.methods, args.stride, args.values, args.param)
    elif args.command == "flow-tiles":
        flow_tiles(args.folder, args.frame, args.methods)
    elif args.command == "rivals":
        rivals(sequences)
    elif args.command == "switch":
        switch(sequences, args.methods, args.stride, args.param, args.tie_break)
    elif args.command == "grid-reach":
        grid_reach(sequences, args.stride)
    elif args.command == "stage6":
        stage6(sequences)
    elif args.command == "figures":
        figures(args.root, args.out)
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
