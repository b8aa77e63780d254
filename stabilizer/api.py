"""One interface for every estimator: ``estimate``, ``Stabilizer`` and the method registry.

Every method's estimate goes through the same steps: the frames' type and size are checked
before any work (each method has a smallest image side, all share the largest,
:data:`MAX_SIDE`); the method estimates; an ``"ok"`` estimate is then checked by the shared
trust check (:class:`stabilizer.verification.Verifier`, docs/method.md section 11), so that
``"ok"`` means the compensated current frame does line up with the reference. An estimator that
has a ``second_look(current, checked) -> Motion | None`` method is offered every estimate it
made, after the check: a Motion it returns is a new estimate, checked in its turn. After a first
estimate that passed, it replaces the first if it passes and lines up the frames' depth edges at
least as well (``verify_correlation``); one that passes but lines them up worse, beyond the
check's offset limits of the first, is a rival: the estimate fails as ``"ambiguous"``
(``VerificationParams.second_look_rivals``), as it does when such a second look, climbed by the
method's own measure from the first estimate (its diagnostics' ``second_look_from`` is the first
estimate), is rejected only for the edges' preference (``"not_optimum"``, ``"ambiguous"``;
``VerificationParams.rejected_second_look_rivals``). After a rejected first estimate, it is the
result if it passes. The estimator chooses where to look again: ``t2fuzzy`` at the estimates the
check doubts, and from the check's own optimum at those it rejects as not at that optimum
(:meth:`stabilizer.t2fuzzy.T2FuzzyEstimator.second_look`; docs/method.md, section 12, measures
what the second chance lets through).

======================  ===========================================  ========================
method                  estimator                                    smallest image side
======================  ===========================================  ========================
``t2fuzzy``             the paper's method with its refinements      2 * ``max_shift_px`` + 8
                        (:mod:`stabilizer.t2fuzzy`)                  (96 by default)
``t2fuzzy_paper``       the paper's pipeline as written              2 * ``max_shift_px`` + 8
                                                                     (96 by default)
``sift``                :mod:`stabilizer.peers.sift`                 64
``icp``                 :mod:`stabilizer.peers.icp`                  64
``ecc``                 :mod:`stabilizer.peers.ecc`                  64
``fourier_mellin``      :mod:`stabilizer.peers.fourier_mellin`       64
======================  ===========================================  ========================

Every method takes images of at most :data:`MAX_SIDE` x :data:`MAX_SIDE` (4096 x 4096) pixels.
Why these sizes: docs/method.md, section 9, and docs/peers.md, "Image sizes".
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import replace
from typing import Any

import numpy as np

from stabilizer.inputs import as_disparity
from stabilizer.motion import Motion
from stabilizer.t2fuzzy_refinements import Refinements
from stabilizer.verification import UNVERIFIED, VerificationParams, shared_verifier

#: Method name -> ("module:class", default parameters). Each class is built as
#: ``cls(reference, **params)`` (the reference analysed once), has ``estimate(current) ->
#: Motion`` and ``min_side(**params) -> int``, the smallest image side it accepts with those
#: parameters. "t2fuzzy_paper" is the paper's pipeline as written, without the refinements of
#: "t2fuzzy" (stabilizer.t2fuzzy_refinements), so that what the refinements add stays
#: measurable.
_METHODS = {
    "t2fuzzy": ("stabilizer.t2fuzzy:T2FuzzyEstimator", {}),
    "t2fuzzy_paper": ("stabilizer.t2fuzzy:T2FuzzyEstimator", {"refinements": Refinements.off()}),
    "sift": ("stabilizer.peers.sift:SiftEstimator", {}),
    "icp": ("stabilizer.peers.icp:IcpEstimator", {}),
    "ecc": ("stabilizer.peers.ecc:EccEstimator", {}),
    "fourier_mellin": ("stabilizer.peers.fourier_mellin:FourierMellinEstimator", {}),
}
#: Largest image side (pixels) of every method: 16.8 million pixels bound the memory and time
#: of one estimate (the SR4000 gives 176 x 144, a megapixel ToF camera about 1024 x 1024).
MAX_SIDE = 4096


def available_methods() -> tuple[str, ...]:
    """Names accepted by ``method=``, the paper's method first."""
    return tuple(_METHODS)


def _estimator_class(method: str):
    if not isinstance(method, str) or method not in _METHODS:  # a list is not hashable
        raise ValueError(f"unknown method {method!r}; accepted: {', '.join(_METHODS)}")
    module_name, class_name = _METHODS[method][0].split(":")
    return getattr(importlib.import_module(module_name), class_name)


class Stabilizer:
    """Estimates the motion of many current frames against one reference analysed once.

    Args:
        reference: uint8 disparity-like image (0 = invalid) or float depth in metres, between
            the method's smallest side (module docstring) and :data:`MAX_SIDE` on each side.
        method: one of :func:`available_methods`; default ``"t2fuzzy"`` (Kang et al. 2009).
        verification: the thresholds of the trust check that every ``"ok"`` estimate passes
            (:class:`~stabilizer.verification.VerificationParams`); an estimate that fails it
            has the status ``"unverified"``. None: no check (the method's own criteria only).
            Stabilizers of equal references with equal thresholds share one check
            (:func:`~stabilizer.verification.shared_verifier`): the reference is analysed
            once, and a frame that several methods estimate in turn is measured once.
        **params: the method's own parameters, passed to its estimator class (see its
            docstring); for example ``refinements=Refinements(rotation_search=False)`` or
            ``translation=TranslationParams(max_shift_px=20)`` for the ``t2fuzzy`` methods
            (:mod:`stabilizer.t2fuzzy`).

    Raises:
        ValueError: an unknown method, a frame of the wrong type, dimensions or size (the
            message names the size and the accepted range), or a bad parameter value.
        TypeError: an unknown parameter, or one of the wrong type (a number where the method
            takes a parameter object, say).

    Not for several threads at once: an estimator keeps state between the steps of an
    estimate (``t2fuzzy``'s rotation search), and Stabilizers of one reference share their
    check. Parallelism comes from processes, one Stabilizer each, as in the harness.
    """

    def __init__(self, reference: np.ndarray, method: str = "t2fuzzy", *,
                 verification: VerificationParams | None = VerificationParams(),
                 **params: Any):
        estimator_class = _estimator_class(method)
        if verification is not None and not isinstance(verification, VerificationParams):
            raise TypeError(f"verification must be a VerificationParams "
                             f"(stabilizer.verification) or None; got {verification!r}")
        accepted = [name for name in inspect.signature(estimator_class).parameters
                    if name != "reference"]
        unknown = [name for name in params if name not in accepted]
        if unknown:
            raise TypeError(f"{method} has no parameter {unknown[0]!r}; accepted: "
                            f"{', '.join(accepted)}")
        params = {**_METHODS[method][1], **params}
        self.method = method
        # A copy: a caller may fill the same buffer with its next frame.
        self.reference = np.array(as_disparity(reference, "reference",
                                               min_side=estimator_class.min_side(**params),
                                               max_side=MAX_SIDE, method=method))
        self._estimator = estimator_class(self.reference, **params)
        self._verifier = shared_verifier(self.reference, verification) if verification else None

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` relative to the reference (docs/design.md convention)."""
        current = as_disparity(current, "current", reference_shape=self.reference.shape)
        motion = self._estimator.estimate(current)
        if self._verifier is None or not motion.ok:
            return motion
        measured = self._verifier.measure(current)
        checked = self._verifier.check(measured, motion)
        second_look = getattr(self._estimator, "second_look", None)
        again = second_look(current, checked) if second_look else None
        if again is None:
            return checked
        rechecked = self._verifier.check(measured, again)
        params = self._verifier.params
        if not rechecked.ok:
            failed = rechecked.diagnostics.get("verify_failed", rechecked.status)
            # Climbed by the method's own measure from a first estimate that passed, to beyond
            # the limits, and rejected for the edges' preference alone: the measures disagree.
            rival = (params.rejected_second_look_rivals and checked.ok
                     and again.diagnostics.get("second_look_from") == checked.as_tuple()
                     and failed in ("not_optimum", "ambiguous")
                     and params.beyond_offset(again, checked))
        elif not checked.ok:  # a second look at a rejected estimate: kept if it passes
            return rechecked
        elif (rechecked.diagnostics["verify_correlation"]
              < checked.diagnostics["verify_correlation"]):
            failed = "edges"  # the new estimate passes, but lines the depth edges up worse
            # Two motions beyond the offset limits of each other both pass: a rival.
            rival = params.second_look_rivals and params.beyond_offset(again, checked)
        else:
            return rechecked
        if rival:
            return Motion.failed(UNVERIFIED, **dict(
                checked.diagnostics, verify_failed="ambiguous",
                unverified_motion=checked.as_tuple(), verify_candidate=again.as_tuple(),
                verify_candidate_correlation=rechecked.diagnostics["verify_correlation"],
                second_look=again.as_tuple(), second_look_failed=failed))
        return replace(checked, diagnostics=dict(checked.diagnostics, second_look=again.as_tuple(),
                                                 second_look_failed=failed))


def estimate(reference: np.ndarray, current: np.ndarray, method: str = "t2fuzzy",
             **params: Any) -> Motion:
    """Motion of ``current`` relative to ``reference`` (docs/design.md convention) by ``method``.

    ``params``: ``verification`` and the method's own parameters, as for :class:`Stabilizer`.
    """
    return Stabilizer(reference, method, **params).estimate(current)
