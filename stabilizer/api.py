"""One interface for every estimator: ``estimate``, ``Stabilizer`` and the method registry."""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from stabilizer.inputs import as_disparity, check_same_shape
from stabilizer.motion import Motion
from stabilizer.t2fuzzy_refinements import Refinements

#: Method name -> ("module:class", default parameters). Each class is built as
#: ``cls(reference, **params)`` (the reference analysed once) and has
#: ``estimate(current) -> Motion``. "t2fuzzy_paper" is the paper's pipeline as written, without
#: the refinements of "t2fuzzy" (stabilizer.t2fuzzy_refinements), so that what the refinements
#: add stays measurable.
_METHODS = {
    "t2fuzzy": ("stabilizer.t2fuzzy:T2FuzzyEstimator", {}),
    "t2fuzzy_paper": ("stabilizer.t2fuzzy:T2FuzzyEstimator", {"refinements": Refinements.off()}),
    "sift": ("stabilizer.peers.sift:SiftEstimator", {}),
    "icp": ("stabilizer.peers.icp:IcpEstimator", {}),
    "ecc": ("stabilizer.peers.ecc:EccEstimator", {}),
    "fourier_mellin": ("stabilizer.peers.fourier_mellin:FourierMellinEstimator", {}),
}


def available_methods() -> tuple[str, ...]:
    """Names accepted by ``method=``, the paper's method first."""
    return tuple(_METHODS)


def _estimator(method: str, reference: np.ndarray, params: dict[str, Any]):
    if method not in _METHODS:
        raise ValueError(f"unknown method {method!r}; accepted: {', '.join(_METHODS)}")
    target, defaults = _METHODS[method]
    module_name, class_name = target.split(":")
    estimator_class = getattr(importlib.import_module(module_name), class_name)
    return estimator_class(reference, **{**defaults, **params})


class Stabilizer:
    """Estimates the motion of many current frames against one reference analysed once.

    Args:
        reference: uint8 disparity-like image (0 = invalid) or float depth in metres.
        method: one of :func:`available_methods`; default ``"t2fuzzy"`` (Kang et al. 2009).
        **params: the method's own parameters, passed to its estimator class (see its
            docstring); for example ``refinements=Refinements(rotation_search=False)`` or
            ``translation=TranslationParams(max_shift_px=20)`` for the ``t2fuzzy`` methods
            (:mod:`stabilizer.t2fuzzy`).
    """

    def __init__(self, reference: np.ndarray, method: str = "t2fuzzy", **params: Any):
        self.method = method
        self.reference = as_disparity(reference, "reference")
        self._estimator = _estimator(method, self.reference, params)

    def estimate(self, current: np.ndarray) -> Motion:
        current = as_disparity(current, "current")
        check_same_shape(self.reference, current)
        return self._estimator.estimate(current)


def estimate(reference: np.ndarray, current: np.ndarray, method: str = "t2fuzzy",
             **params: Any) -> Motion:
    """Motion of ``current`` relative to ``reference`` (docs/design.md convention) by ``method``."""
    return Stabilizer(reference, method, **params).estimate(current)
