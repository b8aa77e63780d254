"""Stage 6 of Kang, Zhang & Park (2009): translation by fast normalised cross-correlation.

The paper's eq. (7) is Lewis's (1995) normalised cross-correlation of a template t with the image
f under it,

    gamma(u, v) = sum (f - mean_f_uv)(t - mean_t)
                  / sqrt(sum (f - mean_f_uv)^2 * sum (t - mean_t)^2),

which ``cv2.matchTemplate(..., cv2.TM_CCOEFF_NORMED)`` computes the fast way (correlation by
DFT, local sums by running-sum tables). The integer peak is refined to sub-pixel precision by a
3-point parabola through the peak and its two neighbours along each axis,
delta = (c_minus - c_plus) / (2 (c_minus - 2 c_0 + c_plus)).

Template pixels marked invalid (0 = no measurement) can be excluded with a mask, which OpenCV
supports for this method; image pixels cannot be masked by OpenCV.

:class:`RotatedTemplate` is the paper's "rotation compensation, then translation": the central
region of the reference, rotated by a candidate angle about the image centre, matched in the
current frame, whose offset is then the translation of the docs/design.md motion convention.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class TemplateMatch:
    """Where the template's top-left corner lies in the image (sub-pixel), and the NCC there.

    ``at_border`` is True when the integer peak lies on the edge of the search range: the true
    match may be outside it, and that axis is not refined. ``height`` is the peak value of the
    fitted parabolas (a smooth function of the image motion, unlike the sampled ``peak``).
    """

    x: float
    y: float
    peak: float
    at_border: bool
    height: float = np.nan


def parabolic_vertex(c_minus: float, c_0: float, c_plus: float) -> tuple[float, float]:
    """Offset (clipped to +-0.5) and height of the vertex of the parabola through the samples.

    Without a strict finite maximum at the centre the offset is 0 and the height ``c_0``.
    """
    c_minus, c_0, c_plus = float(c_minus), float(c_0), float(c_plus)  # plain floats: fast
    curvature = c_minus - 2.0 * c_0 + c_plus
    if not (math.isfinite(curvature) and curvature < 0.0):
        return 0.0, c_0
    offset = min(0.5, max(-0.5, (c_minus - c_plus) / (2.0 * curvature)))
    return offset, c_0 + 0.25 * (c_plus - c_minus) * offset


def match_template(image: np.ndarray, template: np.ndarray,
                   mask: np.ndarray | None = None) -> TemplateMatch:
    """Best match of ``template`` in ``image`` by TM_CCOEFF_NORMED with sub-pixel refinement.

    Args:
        image: 2-D uint8 or float32 search image.
        template: 2-D array of the same dtype, no larger than ``image``.
        mask: optional template-sized mask; zero entries are left out of the correlation.

    Returns:
        The match; ``peak`` is NaN when the correlation is undefined everywhere (a flat
        template or image).
    """
    mask_u8 = None if mask is None else (mask > 0).view(np.uint8)
    _, spread = cv2.meanStdDev(template, mask=mask_u8)
    if not spread[0, 0] > 0:  # OpenCV scores a flat (or fully masked) template 1 everywhere
        return TemplateMatch(np.nan, np.nan, np.nan, True)
    scores = cv2.matchTemplate(image, template, cv2.TM_CCOEFF_NORMED, mask=mask)
    _, peak, _, (col, row) = cv2.minMaxLoc(scores)
    if not math.isfinite(peak):  # non-finite scores (flat image windows): ignore them
        scores = np.where(np.isfinite(scores), scores, -np.inf)
        row, col = np.unravel_index(int(np.argmax(scores)), scores.shape)
        peak = float(scores[row, col])
        if not math.isfinite(peak):
            return TemplateMatch(np.nan, np.nan, np.nan, True)
    at_border = False
    x, y, height = float(col), float(row), peak
    if 0 < col < scores.shape[1] - 1:
        offset, top = parabolic_vertex(scores[row, col - 1], peak, scores[row, col + 1])
        x += offset
        height += top - peak
    else:
        at_border = True
    if 0 < row < scores.shape[0] - 1:
        offset, top = parabolic_vertex(scores[row - 1, col], peak, scores[row + 1, col])
        y += offset
        height += top - peak
    else:
        at_border = True
    return TemplateMatch(x, y, peak, at_border, height)


class RotatedTemplate:
    """FNCC of the rotation-compensated central region of a reference in later frames.

    The current frame is the reference rotated by theta about the image centre, then shifted by
    (dx, dy) (docs/design.md). Rotating the reference by theta leaves only the shift, so the offset
    of the rotated reference's central region in the current frame is (dx, dy) directly. Only
    the template region is warped (bilinear); invalid reference pixels are masked out.

    Args:
        reference: disparity-like reference (0 = invalid), uint8 or float.
        margin: template = the region ``margin`` pixels in from each side; it is also the
            largest shift found along each axis.
        centre: centre of rotation in this image's pixels; default the image centre (another
            one for a reduced-resolution copy of a frame, whose centre maps back to the full
            frame's).
        valid: mask of measured reference pixels; default ``reference > 0``.
    """

    def __init__(self, reference: np.ndarray, margin: int,
                 centre: tuple[float, float] | None = None, valid: np.ndarray | None = None):
        height, width = reference.shape
        self.margin = int(margin)
        self.size = (width - 2 * self.margin, height - 2 * self.margin)
        self._reference = reference.astype(np.float32)
        self._valid = (reference > 0 if valid is None else valid).astype(np.uint8)
        self._centre = ((width - 1) / 2.0, (height - 1) / 2.0) if centre is None else centre
        # Every rotation of the template lies in the disc through its corners: if that disc is
        # all valid, no rotated template needs a mask.
        radius = np.hypot(*self.size) / 2.0 + 1.0
        rows, columns = np.mgrid[:height, :width]
        disc = np.hypot(columns - self._centre[0], rows - self._centre[1]) <= radius
        self._needs_mask = bool(np.any(disc & (self._valid == 0)))
        # Rotation 0 is asked for on many frames (a translation-only guess, the identity
        # candidate): warp it once.
        self._upright = self._rotated(0.0)

    def template(self, angle_deg: float) -> tuple[np.ndarray, np.ndarray | None]:
        """The template at ``angle_deg`` and its validity mask (None when all valid)."""
        return self._upright if angle_deg == 0.0 else self._rotated(angle_deg)

    def _rotated(self, angle_deg: float) -> tuple[np.ndarray, np.ndarray | None]:
        rotation = cv2.getRotationMatrix2D(self._centre, float(angle_deg), 1.0)
        rotation[:, 2] -= self.margin  # template pixel (0, 0) = rotated pixel (m, m)
        template = cv2.warpAffine(self._reference, rotation, self.size, flags=cv2.INTER_LINEAR)
        if not self._needs_mask:
            return template, None
        valid = cv2.warpAffine(self._valid, rotation, self.size, flags=cv2.INTER_NEAREST)
        return template, (None if valid.all() else valid.astype(np.float32))

    def match(self, current: np.ndarray, angle_deg: float,
              near: tuple[float, float] | None = None, radius: int = 2) -> TemplateMatch:
        """Shift (dx, dy) of the current float32 frame for rotation ``angle_deg``.

        With ``near`` = a previous (dx, dy), only shifts within ``radius`` pixels of it are
        searched (cheap); otherwise the whole +-margin range.
        """
        template, mask = self.template(angle_deg)
        left = top = 0
        image = current
        if near is not None:
            left = min(max(round(near[0]) + self.margin - radius, 0), 2 * self.margin)
            top = min(max(round(near[1]) + self.margin - radius, 0), 2 * self.margin)
            right = min(left + self.size[0] + 2 * radius, current.shape[1])
            bottom = min(top + self.size[1] + 2 * radius, current.shape[0])
            image = current[top:bottom, left:right]
        found = match_template(image, template, mask)
        return TemplateMatch(found.x + left - self.margin, found.y + top - self.margin,
                             found.peak, found.at_border, found.height)
