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
supports for this method; image pixels cannot be masked by OpenCV. OpenCV's masked matching
always correlates by DFT over the whole image, which costs the same for a +-2 pixel search as for
a search of every shift: a search of at most :data:`DIRECT_SEARCH_SHIFTS` shifts is computed
directly from Lewis's sums instead (:func:`masked_ncc_direct`), 2.7 times faster on the
searches of a walking run.

:class:`RotatedTemplate` is the paper's "rotation compensation, then translation": the central
region of the reference, rotated by a candidate angle about the image centre, matched in the
current frame, whose offset is then the translation of the docs/design.md motion convention.
"""

from __future__ import annotations

import copy
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
    n_shifts = (image.shape[0] - template.shape[0] + 1) * (image.shape[1] - template.shape[1] + 1)
    if mask_u8 is not None and n_shifts <= DIRECT_SEARCH_SHIFTS:
        scores = masked_ncc_direct(image, template, mask_u8)
    else:
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


#: Searches of at most this many shifts (9 x 9) are scored by :func:`masked_ncc_direct`, whose cost
#: grows with the number of shifts, rather than by OpenCV's DFTs, whose cost does not.
DIRECT_SEARCH_SHIFTS = 81


def masked_ncc_direct(image: np.ndarray, template: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Eq. (7) at every shift of ``template`` inside ``image``, over the template's pixels where
    ``mask`` is non-zero: what ``cv2.matchTemplate(image, template, cv2.TM_CCOEFF_NORMED,
    mask=mask)`` computes for a binary mask, summed directly.

    With the template made zero-mean on its n valid pixels (t', 0 where masked), Lewis's
    numerator is sum f t' and the image's sum of squares about its window mean is
    sum_m f^2 - (sum_m f)^2 / n (sums over the valid pixels under the template): three
    correlations, each one ``np.correlate`` of a row-major strip of the image with the template
    laid out at the image's row stride. The image is first made zero-mean on the valid pixels
    under the central shift, so that these float32 sums do not cancel. A shift whose window is
    flat (its spread is rounding, below 1e-5 of its sum of squares) scores NaN, OpenCV's 0 / 0
    (whose DFTs leave some flat windows a rounding residue, around 1e-8, instead).

    Parameters
    ----------
    image : (H, W) ndarray of float32 or uint8
    template : (h, w) ndarray
        h <= H and w <= W; not flat on its valid pixels.
    mask : (h, w) ndarray
        Non-zero where the template is valid.

    Returns
    -------
    (H - h + 1, W - w + 1) ndarray of float32
        The NCC at each shift (row = y, column = x of the template's top-left corner).

    References
    ----------
    .. [1] J. P. Lewis, "Fast normalized cross-correlation", Vision Interface 1995, 120-123.
    """
    if image.ndim != 2 or template.ndim != 2 or np.shape(mask) != template.shape:
        raise ValueError(f"image and template must be 2-D and mask of the template's shape; got "
                         f"{image.shape}, {template.shape} and {np.shape(mask)}")
    height, width = template.shape
    rows, columns = image.shape[0] - height + 1, image.shape[1] - width + 1
    if rows < 1 or columns < 1:
        raise ValueError(f"template {template.shape} must be no larger than image {image.shape}")
    stride = image.shape[1]
    valid = (mask != 0).view(np.uint8)
    n_valid = cv2.countNonZero(valid)
    if n_valid == 0:
        raise ValueError("mask must keep at least one template pixel; got none")
    template = template.astype(np.float32, copy=False)
    zero_mean = (template - np.float32(cv2.mean(template, valid)[0])) * valid
    image = image.astype(np.float32, copy=False)
    centre = image[rows // 2:rows // 2 + height, columns // 2:columns // 2 + width]
    image = image - np.float32(cv2.mean(centre, valid)[0])
    # The template and mask at the image's row stride: shift (y, x) is then the dot product of
    # a strip starting at y * stride + x with them.
    length = (height - 1) * stride + width
    kernels = np.zeros((2, height, stride), np.float32)
    kernels[0, :, :width] = zero_mean
    kernels[1, :, :width] = valid
    kernels = kernels.reshape(2, -1)[:, :length]
    flat, squares = image.ravel(), np.square(image).ravel()
    sums = np.empty((3, rows, columns), np.float32)
    for row in range(rows):
        strip = slice(row * stride, row * stride + length + columns - 1)
        sums[0, row] = np.correlate(flat[strip], kernels[0], "valid")
        sums[1, row] = np.correlate(flat[strip], kernels[1], "valid")
        sums[2, row] = np.correlate(squares[strip], kernels[1], "valid")
    products, image_sums, image_squares = sums
    spread = image_squares - image_sums * image_sums / n_valid
    flat_window = spread <= 1e-5 * image_squares
    with np.errstate(divide="ignore", invalid="ignore"):
        scores = products / np.sqrt(spread * float(np.dot(zero_mean.ravel(), zero_mean.ravel())))
    scores[flat_window] = np.nan
    return scores


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
        self._reference = reference.astype(np.float32)
        self._valid = (reference > 0 if valid is None else valid).astype(np.uint8)
        self._centre = ((width - 1) / 2.0, (height - 1) / 2.0) if centre is None else centre
        rows, columns = np.nonzero(self._valid == 0)
        self._nearest_invalid = float(np.min(np.hypot(columns - self._centre[0],
                                                      rows - self._centre[1]), initial=np.inf))
        self._set_margin(int(margin))

    def _set_margin(self, margin: int) -> None:
        height, width = self._reference.shape
        self.margin = margin
        self.size = (width - 2 * margin, height - 2 * margin)
        # Every rotation of the template lies in the disc through its corners: if that disc is
        # all valid, no rotated template needs a mask.
        self._needs_mask = self._nearest_invalid <= np.hypot(*self.size) / 2.0 + 1.0
        # Rotation 0 is asked for on many frames (a translation-only guess, the identity
        # candidate): warp it once.
        self._upright = self._rotated(0.0)

    def with_margin(self, margin: int) -> RotatedTemplate:
        """The same reference, centre and validity with another ``margin`` (no copy of them)."""
        height, width = self._reference.shape
        if not 0 <= 2 * int(margin) < min(height, width):
            raise ValueError(f"margin must be in [0, {(min(height, width) - 1) // 2}] for a "
                             f"{height} x {width} reference; got {margin}")
        other = copy.copy(self)
        other._set_margin(int(margin))
        return other

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
            (cheap). Default, or when it is not finite (no previous shift was found): the
            whole +-``margin`` range.
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
        if near is not None and math.isfinite(near[0]) and math.isfinite(near[1]):
            left = min(max(round(near[0]) + self.margin - radius, 0), 2 * self.margin)
            top = min(max(round(near[1]) + self.margin - radius, 0), 2 * self.margin)
            right = min(left + self.size[0] + 2 * radius, current.shape[1])
            bottom = min(top + self.size[1] + 2 * radius, current.shape[0])
            image = current[top:bottom, left:right]
        found = match_template(image, template, mask)
        return TemplateMatch(found.x + left - self.margin, found.y + top - self.margin,
                             found.peak, found.at_border, found.height)


@dataclass(frozen=True)
class MaskedSpectra:
    """The DFTs one frame contributes to :class:`MaskedCorrelation`: of the frame (made
    zero-mean on its valid pixels, 0 elsewhere), of its square and of its validity mask; the
    number of valid pixels and their sum of squares (zero mean)."""

    image: np.ndarray
    square: np.ndarray
    mask: np.ndarray
    n_valid: int
    energy: float


#: Relative to a frame's whole sum of squares, the least sum of squares on an overlap that is
#: not a flat frame: float32 DFTs leave rounding residues of about 1e-5 of it.
FLAT_SPREAD = 1e-4


class MaskedCorrelation:
    """Eq. (7) over the whole overlap of two frames, each with its own validity mask, for every
    shift up to ``max_shift`` along each axis: Padfield's (2012) masked FNCC.

    Lewis's FNCC (:func:`match_template`) needs the template inside the image at every shift,
    so a search range of ``m`` pixels leaves a template ``m`` pixels in from every side: the
    structures near the border, which often pin a motion down (a pillar at the side of a hall,
    the edges of a doorway), are left out, and shifts beyond ``m`` cannot be found. Padfield
    writes the NCC of two images restricted to the pixels both measure at a shift d,

        gamma(d) = (S_fg - S_f S_g / N) / sqrt((S_ff - S_f^2 / N) (S_gg - S_g^2 / N)),

    with N the number of pixels valid in both, S_fg = sum f(x) g(x + d), S_f = sum f(x)
    m_g(x + d), S_g = sum m_f(x) g(x + d), S_ff = sum f(x)^2 m_g(x + d) and S_gg = sum m_f(x)
    g(x + d)^2 (f, g set to 0 where invalid): six correlations, each a product of DFTs (float32,
    sizes rounded up to multiples of 16, which OpenCV transforms fastest). Shifts whose overlap
    holds fewer than ``min_overlap`` of the fixed frame's valid pixels, or on which either frame
    is flat, score -inf.

    Parameters
    ----------
    shape : (int, int)
        (height, width) of both frames.
    max_shift : int
        Largest shift searched along each axis, pixels; less than either side.
    min_overlap : float
        Least share, in (0, 1], of the fixed frame's valid pixels a shift must keep.

    References
    ----------
    .. [1] D. Padfield, "Masked object registration in the Fourier domain", IEEE Trans. Image
           Processing 21(5), 2706-2718, 2012.
    .. [2] J. P. Lewis, "Fast normalized cross-correlation", Vision Interface 1995, 120-123.
    """

    def __init__(self, shape: tuple[int, int], max_shift: int, min_overlap: float):
        height, width = shape
        if not 0 < int(max_shift) < min(height, width):
            raise ValueError(f"max_shift must be in [1, {min(height, width) - 1}] for "
                             f"{height} x {width} frames; got {max_shift}")
        if not 0.0 < min_overlap <= 1.0:
            raise ValueError(f"min_overlap must be in (0, 1]; got {min_overlap}")
        self.shape = (int(height), int(width))
        self.max_shift = int(max_shift)
        self.min_overlap = float(min_overlap)
        # Padding of at least max_shift keeps the circular correlation of the DFTs from
        # wrapping one frame's pixels onto the other's at any searched shift.
        self._size = tuple(cv2.getOptimalDFTSize(-(-(side + self.max_shift) // 16) * 16)
                           for side in self.shape)

    def spectra(self, image: np.ndarray, valid: np.ndarray, moving: bool) -> MaskedSpectra:
        """The DFTs of ``image`` (float) on its ``valid`` pixels (bool, same shape), as the
        fixed frame or as the ``moving`` one (placed ``max_shift`` pixels down and right in the
        padded DFT, so that the searched shifts come out as one block)."""
        if image.shape != self.shape or valid.shape != self.shape:
            raise ValueError(f"image and valid must have the shape {self.shape}; got "
                             f"{image.shape} and {valid.shape}")
        mask = valid.astype(np.float32)
        n_valid = int(np.count_nonzero(valid))
        # Zero mean on the valid pixels: the same NCC, and sums of squares small enough that
        # S_ff - S_f^2 / N does not cancel away.
        values = image.astype(np.float32)
        values = (values - float(cv2.mean(values, mask=valid.view(np.uint8))[0])) * mask
        square = values * values
        offset = self.max_shift if moving else 0
        return MaskedSpectra(self._dft(values, offset), self._dft(square, offset),
                             self._dft(mask, offset), n_valid, float(square.sum()))

    def _dft(self, array: np.ndarray, offset: int) -> np.ndarray:
        padded = np.zeros(self._size, np.float32)
        padded[offset:offset + self.shape[0], offset:offset + self.shape[1]] = array
        return cv2.dft(padded)

    def _correlation(self, fixed: np.ndarray, moving: np.ndarray) -> np.ndarray:
        """sum_x a(x) b(x + d) over the searched shifts d, rows dy and columns dx."""
        product = cv2.mulSpectrums(moving, fixed, 0, conjB=True)
        full = cv2.idft(product, flags=cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE)
        span = 2 * self.max_shift + 1  # the moving frame sits max_shift down and right
        return full[:span, :span]

    def surface(self, fixed: MaskedSpectra, moving: MaskedSpectra,
                weighted: bool = False) -> np.ndarray:
        """NCC of ``fixed``(x) with ``moving``(x + d) for d in [-max_shift, max_shift]^2,
        rows dy and columns dx; -inf where the overlap is too small or a frame is flat on it.

        ``weighted``: each NCC times sqrt(S_ff' S_gg' / (E_f E_g)), the geometric mean of the
        shares of each frame's sum of squares E (about its mean, on all its valid pixels) that
        the overlap's spreads S' hold: a shift that lines up only part of the frames then scores
        below one that lines up all of them as well."""
        ncc, weight, usable = self._ncc(fixed, moving, weighted)
        return np.where(usable, ncc * weight if weighted else ncc, -np.inf)

    def surfaces(self, fixed: MaskedSpectra,
                 moving: MaskedSpectra) -> tuple[np.ndarray, np.ndarray]:
        """The plain and the weighted :meth:`surface`, from one set of correlations."""
        ncc, weight, usable = self._ncc(fixed, moving, True)
        return np.where(usable, ncc, -np.inf), np.where(usable, ncc * weight, -np.inf)

    def _ncc(self, fixed: MaskedSpectra, moving: MaskedSpectra,
             weighted: bool) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """The NCC at every searched shift (clipped to [-1, 1]), its weight (None unless
        ``weighted``) and where it is usable."""
        overlap = np.rint(self._correlation(fixed.mask, moving.mask))
        s_f = self._correlation(fixed.image, moving.mask)
        s_g = self._correlation(fixed.mask, moving.image)
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse_n = 1.0 / overlap
            numerator = self._correlation(fixed.image, moving.image) - s_f * s_g * inverse_n
            spread_f = self._correlation(fixed.square, moving.mask) - s_f * s_f * inverse_n
            spread_g = self._correlation(fixed.mask, moving.square) - s_g * s_g * inverse_n
            ncc = numerator / np.sqrt(spread_f * spread_g)
            weight = (np.sqrt(spread_f * spread_g / (fixed.energy * moving.energy)) if weighted
                      else None)
        usable = ((overlap >= max(self.min_overlap * fixed.n_valid, 2.0))
                  & (spread_f > FLAT_SPREAD * fixed.energy)
                  & (spread_g > FLAT_SPREAD * moving.energy) & np.isfinite(ncc))
        return np.clip(ncc, -1.0, 1.0), weight, usable

    def match(self, fixed: MaskedSpectra, moving: MaskedSpectra) -> TemplateMatch:
        """The shift d of the highest NCC, refined by a parabola along each axis."""
        return surface_peak(self.surface(fixed, moving), self.max_shift)


def surface_peak(scores: np.ndarray, max_shift: int) -> TemplateMatch:
    """The peak of a correlation surface over shifts [-max_shift, max_shift]^2 (rows dy,
    columns dx), refined by a parabola along each axis as :func:`match_template` does; a peak
    whose neighbour along an axis is not finite or is outside the surface is not refined along
    it and is flagged ``at_border``. NaN shift and peak when no score is finite."""
    row, col = np.unravel_index(int(np.argmax(scores)), scores.shape)
    peak = float(scores[row, col])
    if not math.isfinite(peak):
        return TemplateMatch(np.nan, np.nan, np.nan, True)
    x, y, height, at_border = float(col), float(row), peak, False
    for axis, index in ((1, col), (0, row)):
        if not 0 < index < scores.shape[axis] - 1:
            at_border = True
            continue
        before = scores[row, col - 1] if axis == 1 else scores[row - 1, col]
        after = scores[row, col + 1] if axis == 1 else scores[row + 1, col]
        if not (math.isfinite(before) and math.isfinite(after)):
            at_border = True
            continue
        offset, top = parabolic_vertex(before, peak, after)
        height += top - peak
        if axis == 1:
            x += offset
        else:
            y += offset
    return TemplateMatch(x - max_shift, y - max_shift, peak, at_border, height)
