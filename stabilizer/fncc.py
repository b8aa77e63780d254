"""Stage 6 of Kang, Zhang & Park (2009), section II-C: translation by fast normalised
cross-correlation.

After the rotation is compensated, the translation is where the reference's central region
correlates best with the current frame. The paper's eq. (7) is Lewis's (1995) normalised
cross-correlation of a template t with the image f under it,

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

    Attributes
    ----------
    x, y : float
        Sub-pixel position of the template's top-left corner (NaN when undefined).
    peak : float
        The largest sampled NCC, eq. (7).
    at_border : bool
        The integer peak lies on the edge of the search range: the true match may be outside
        it, and that axis is not refined.
    height : float
        The peak value of the fitted parabolas (a smooth function of the image motion, unlike
        the sampled ``peak``).
    """

    x: float
    y: float
    peak: float
    at_border: bool
    height: float = np.nan


def parabolic_vertex(c_minus: float, c_0: float, c_plus: float) -> tuple[float, float]:
    """Offset and height of the vertex of the parabola through three equally spaced samples.

    delta = (c_minus - c_plus) / (2 (c_minus - 2 c_0 + c_plus)), clipped to +-0.5.

    Parameters
    ----------
    c_minus, c_0, c_plus : float
        Samples at -1, 0 and +1.

    Returns
    -------
    offset, height : float
        The vertex; without a strict finite maximum at the centre, 0 and ``c_0``.
    """
    c_minus, c_0, c_plus = float(c_minus), float(c_0), float(c_plus)  # plain floats: fast
    curvature = c_minus - 2.0 * c_0 + c_plus
    if not (math.isfinite(curvature) and curvature < 0.0):
        return 0.0, c_0
    offset = min(0.5, max(-0.5, (c_minus - c_plus) / (2.0 * curvature)))
    return offset, c_0 + 0.25 * (c_plus - c_minus) * offset


def match_template(image: np.ndarray, template: np.ndarray,
                   mask: np.ndarray | None = None) -> TemplateMatch:
    """Best match of ``template`` in ``image`` by normalised cross-correlation, sub-pixel.

    Parameters
    ----------
    image : (H, W) ndarray of uint8 or float32
        Search image.
    template : (h, w) ndarray
        Of the same dtype, h <= H and w <= W.
    mask : (h, w) ndarray, optional
        Zero entries are left out of the correlation.

    Returns
    -------
    TemplateMatch
        The match; ``peak`` is NaN when the correlation is undefined everywhere (a flat
        template or image).

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-C, eq. (7).
    .. [2] J. P. Lewis, "Fast normalized cross-correlation", Vision Interface 1995, 120-123.
    """
    if image.ndim != 2 or template.ndim != 2 or image.dtype != template.dtype:
        raise ValueError(f"image and template must be 2-D arrays of one dtype; got "
                         f"{image.dtype} {image.shape} and {template.dtype} {template.shape}")
    if template.shape[0] > image.shape[0] or template.shape[1] > image.shape[1]:
        raise ValueError(f"template {template.shape} must be no larger than image {image.shape}")
    if mask is not None and mask.shape != template.shape:
        raise ValueError(f"mask must have the template's shape {template.shape}; got "
                         f"{mask.shape}")
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

    Parameters
    ----------
    reference : (H, W) ndarray of uint8 or float
        Disparity-like reference, 0 = invalid.
    margin : int
        Template = the region ``margin`` pixels in from each side; it is also the largest shift
        found along each axis. 0 <= 2 ``margin`` < min(H, W).
    centre : (float, float), optional
        Centre of rotation in this image's pixels; default the image centre (another one for a
        reduced-resolution copy of a frame, whose centre maps back to the full frame's).
    valid : (H, W) ndarray of bool, optional
        Mask of measured reference pixels; default ``reference > 0``.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, section II-C: "After proceeding the
           rotation compensation, rotated image is used as the input data for the translation
           compensation", eq. (7).
    .. [2] J. P. Lewis, "Fast normalized cross-correlation", Vision Interface 1995, 120-123.
    """

    def __init__(self, reference: np.ndarray, margin: int,
                 centre: tuple[float, float] | None = None, valid: np.ndarray | None = None):
        if np.ndim(reference) != 2:
            raise ValueError(f"reference must be a 2-D image; got shape {np.shape(reference)}")
        height, width = reference.shape
        if not 0 <= 2 * int(margin) < min(height, width):
            raise ValueError(f"margin must be in [0, {(min(height, width) - 1) // 2}] for a "
                             f"{height} x {width} reference; got {margin}")
        if valid is not None and np.shape(valid) != reference.shape:
            raise ValueError(f"valid must have the reference's shape {reference.shape}; got "
                             f"{np.shape(valid)}")
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
        """Shift (dx, dy) of the current frame for the rotation ``angle_deg``.

        Parameters
        ----------
        current : (H, W) ndarray of float32
            The current frame, the reference's size.
        angle_deg : float
            Rotation (Motion convention) the template is turned by before matching.
        near : (float, float), optional
            A previous (dx, dy): only shifts within ``radius`` pixels of it are searched
            (cheap). Default: the whole +-``margin`` range.
        radius : int, optional
            Half-width of the search around ``near``. Default 2.

        Returns
        -------
        TemplateMatch
            ``x``, ``y`` are the shift (dx, dy).
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
