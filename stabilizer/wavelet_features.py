"""Stage 3 of Kang, Zhang & Park (2009), section II-B and Fig. 5: two-level wavelet features of
each object.

Each segmented object (stage 2) becomes several point sets, one per wavelet subband of its mask:
the LL band describes the region, the detail bands its outline at two scales. Stage 4
(:mod:`stabilizer.ellipse`) fits an ellipse to every set, so each object yields several rotation
estimates ("Many rotation values can be obtained according to the level of wavelet transform and
the number of segmented objects").

Each segmented object's binary mask is decomposed like ``pywt.wavedec2(mask, wavelet, level)``
into ``[cA_L, (cH_L, cV_L, cD_L), ..., (cH_1, cV_1, cD_1)]`` (cA = the paper's LL, cH/cV/cD its
detail subbands). The point set of a subband is the set of its *significant* coefficients
(magnitude above ``significance`` times the subband's largest magnitude), each mapped back to the
image coordinates of the centre of the pixel block it covers, so that every point set of every
object shares the image frame (docs/method.md, section 3). Each point carries its coefficient's
relative magnitude as a weight: for the LL band of a mask that is the fraction of the block the
object covers, an anti-aliased description of the region.

With ``merge_details`` (default) the three detail subbands of a level form one point set (the
object's outline at that scale, weighted by the detail magnitude sqrt(cH^2 + cV^2 + cD^2)):
each of cH, cV, cD alone only sees edges of some orientations, a selection that does not rotate
with the object.

Invalid pixels never count as scene: a detail coefficient whose block lies within
``edge_margin`` pixels of an invalid pixel or the image border describes the edge of the
measurement, not of an object, and is dropped. All objects are transformed at once on a stacked
(objects, H, W) array. For the Haar wavelet (the default) one analysis step is the 2 x 2 block
sum and differences, computed here by reshaping (PyWavelets' coefficients times 2 per level, which
a test checks; several times faster on these small integer stacks), and the merged detail
magnitude of a block follows from its sums without the three bands (:func:`haar_detail_energy`);
other wavelets use ``pywt.dwt2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import pywt

#: Most decomposition levels: each halves the subbands, and ten take a 1024-pixel side to one
#: pixel; deeper levels only add empty subbands (a million levels ran for minutes).
MAX_LEVEL = 10
#: Widest ``edge_margin`` (pixels): a margin of 100 on every side leaves nothing of a frame the
#: methods are made for (the SR4000's 176 x 144); its dilation kernel grows as its square (10^6
#: asked for 4 TB).
MAX_EDGE_MARGIN = 100


@dataclass(frozen=True)
class PointSets:
    """Wavelet point sets of all objects of one frame, flattened.

    Attributes
    ----------
    x, y : (P,) ndarray of float
        Image coordinates of all points.
    weight : (P,) ndarray of float
        Magnitude of each point's coefficient relative to its subband's largest.
    set_id : (P,) ndarray of int
        Index of the point set of each point, ``object_index * n_subbands + subband``.
    n_objects : int
        Number of objects (stacked masks) decomposed.
    n_subbands : int
        Point sets per object (see ``WaveletFeatures.subband_names``).
    """

    x: np.ndarray
    y: np.ndarray
    weight: np.ndarray
    set_id: np.ndarray
    n_objects: int
    n_subbands: int

    @property
    def n_sets(self) -> int:
        return self.n_objects * self.n_subbands


def _block_centre(index: np.ndarray, level: int, filter_length: int) -> np.ndarray:
    """Image coordinate of the centre of the input block covered by coefficient ``index``.

    PyWavelets' analysis step at one level computes coefficient k from input samples
    2k + 1 - (L - 1) .. 2k + 1 (L = filter length): their centre is 2k + 1 - (L - 1) / 2.
    Applied ``level`` times from the coarse level down to the image.
    """
    position = index.astype(np.float64)
    for _ in range(level):
        position = 2.0 * position + 1.0 - (filter_length - 1) / 2.0
    return position


def _even_sized(stack: np.ndarray) -> np.ndarray:
    """Odd sizes of the last two axes extended by repeating the last row or column
    (PyWavelets' "symmetric" mode, as far as one Haar step reaches)."""
    if stack.shape[-2] % 2 or stack.shape[-1] % 2:
        pad = [(0, 0)] * (stack.ndim - 2) + [(0, stack.shape[-2] % 2), (0, stack.shape[-1] % 2)]
        stack = np.pad(stack, pad, mode="edge")
    return stack


def _block_sums(stack: np.ndarray) -> np.ndarray:
    """Sums of the 2 x 2 blocks of the last two (even) axes."""
    row_sum = stack[..., 0::2, :] + stack[..., 1::2, :]
    return row_sum[..., 0::2] + row_sum[..., 1::2]


def haar_sums(stack: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """One 2-D Haar analysis step over the last two axes, unnormalised.

    The 2 x 2 block sums and differences, in integers for integer input (only relative
    magnitudes are used here). Rows then columns, each as contiguous pairs. Odd sizes are
    extended by repeating the last row or column (PyWavelets' "symmetric" mode).

    Parameters
    ----------
    stack : (..., H, W) ndarray
        Images (object masks) stacked along the leading axes.

    Returns
    -------
    LL, (H, V, D) : ndarray
        2 x ``pywt.dwt2(stack, "haar")``, each (..., ceil(H / 2), ceil(W / 2)).
    """
    stack = _even_sized(stack)
    upper, lower = stack[..., 0::2, :], stack[..., 1::2, :]
    row_sum, row_difference = upper + lower, upper - lower
    return (row_sum[..., 0::2] + row_sum[..., 1::2],
            (row_difference[..., 0::2] + row_difference[..., 1::2],
             row_sum[..., 0::2] - row_sum[..., 1::2],
             row_difference[..., 0::2] - row_difference[..., 1::2]))


def haar_detail_energy(stack: np.ndarray,
                       binary: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """LL of :func:`haar_sums` and the float32 magnitude sqrt(H^2 + V^2 + D^2) of its details.

    Without forming the three detail bands: for each 2 x 2 block (a, b, c, d) the Haar step is
    orthogonal up to a factor 2, so LL^2 + H^2 + V^2 + D^2 = 4 (a^2 + b^2 + c^2 + d^2). For
    integer stacks (masks and their block sums) every term is an integer computed exactly, so
    the result equals the sum of the squared bands bit for bit.

    Parameters
    ----------
    stack : (..., H, W) ndarray
        Images (object masks or their block sums) stacked along the leading axes.
    binary : bool, optional
        The stack holds only 0 and 1 (masks), so a^2 = a and the block sums of the squares are
        LL itself. Default False.

    Returns
    -------
    LL : ndarray
        As :func:`haar_sums`.
    detail : ndarray of float32
        sqrt(H^2 + V^2 + D^2), the shape of LL.
    """
    stack = _even_sized(stack)
    approximation = _block_sums(stack)
    energy = (approximation.astype(np.float32) if binary
              else _block_sums(np.square(stack, dtype=np.float32)))
    energy *= 4.0
    energy -= np.square(approximation, dtype=np.float32)
    return approximation, np.sqrt(energy, out=energy)


def _even_steps(indices: np.ndarray) -> slice | np.ndarray:
    """``indices`` as a slice when they are evenly spaced (cheap basic indexing), else as is."""
    steps = np.diff(indices)
    if indices.size >= 2 and steps[0] > 0 and np.all(steps == steps[0]):
        return slice(int(indices[0]), int(indices[-1]) + 1, int(steps[0]))
    return indices


class WaveletFeatures:
    """Point sets of the wavelet subbands of object masks.

    Parameters
    ----------
    wavelet : str, optional
        PyWavelets wavelet name. Default ``"haar"`` (keeps object edges sharp, cheap; the paper
        names none).
    level : int, optional
        Decomposition levels, at most :data:`MAX_LEVEL` (10). Default 2, the paper's ("the
        level set was determined to be two").
    significance : float, optional
        A coefficient is significant if its magnitude exceeds this fraction of the largest
        magnitude in its subband. Default 0 (every non-zero coefficient).
    edge_margin : int, optional
        Detail points within this many pixels of an invalid pixel or of the image border are
        dropped (their edge is the measurement's, not the scene's); at most
        :data:`MAX_EDGE_MARGIN` (100). Default 2.
    merge_details : bool, optional
        One point set per level for the three detail subbands (see the module docstring)
        instead of one per subband. Default True.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-B and Fig. 5.
    .. [2] S. G. Mallat, "A theory for multiresolution signal decomposition: the wavelet
           representation", IEEE Trans. PAMI 11(7), 674-693, 1989.
    """

    def __init__(self, wavelet: str = "haar", level: int = 2, significance: float = 0.0,
                 edge_margin: int = 2, merge_details: bool = True):
        if wavelet not in pywt.wavelist(kind="discrete"):
            raise ValueError(f"wavelet must be a discrete PyWavelets wavelet; got {wavelet!r}")
        if not 1 <= int(level) <= MAX_LEVEL:
            raise ValueError(f"level must be from 1 to {MAX_LEVEL}; got {level}")
        if not (0.0 <= significance < 1.0):
            raise ValueError(f"significance must be in [0, 1); got {significance}")
        if not 0 <= edge_margin <= MAX_EDGE_MARGIN:
            raise ValueError(f"edge_margin must be from 0 to {MAX_EDGE_MARGIN}; got {edge_margin}")
        self.wavelet = pywt.Wavelet(wavelet)
        self.level = int(level)
        self.significance = float(significance)
        self.edge_margin = int(edge_margin)
        self.merge_details = bool(merge_details)
        detail_names = ["D"] if self.merge_details else ["cH", "cV", "cD"]
        #: Name of each point set of an object, in set order (wavedec2's: coarse to fine).
        self.subband_names = [f"cA{self.level}"] + [f"{name}{lev}"
                                                    for lev in range(self.level, 0, -1)
                                                    for name in detail_names]
        self.n_subbands = len(self.subband_names)
        self._grids: dict = {}
        self._edge_kernel = cv2.getStructuringElement(
            cv2.MORPH_RECT, (2 * self.edge_margin + 1, 2 * self.edge_margin + 1))

    def decompose(self, masks: np.ndarray) -> list[tuple[np.ndarray, int, str]]:
        """Subbands of a mask stack.

        Magnitudes are up to a constant factor per subband (all that the relative significance
        and weights use); merged details are sqrt(cH^2 + cV^2 + cD^2).

        Parameters
        ----------
        masks : (objects, H, W) ndarray
            Object masks; a boolean stack is taken as 0/1 masks.

        Returns
        -------
        list of (ndarray, int, str)
            (magnitudes, level, name) per point set, details from fine to coarse, then LL.
        """
        binary = masks.dtype == bool
        approximation = masks.astype(np.int16) if binary else masks
        subbands = []
        for lev in range(1, self.level + 1):
            if self.wavelet.name == "haar" and self.merge_details:
                approximation, energy = haar_detail_energy(approximation, binary and lev == 1)
                subbands.append((energy, lev, f"D{lev}"))
                continue
            if self.wavelet.name == "haar":
                approximation, details = haar_sums(approximation)
            else:
                approximation, details = pywt.dwt2(approximation.astype(np.float32),
                                                   self.wavelet, axes=(-2, -1))
            if self.merge_details:
                squares = [np.square(band, dtype=np.float32) for band in details]
                energy = np.sqrt(squares[0] + squares[1] + squares[2])
                subbands.append((energy, lev, f"D{lev}"))
            else:
                subbands += [(np.abs(band), lev, f"{name}{lev}")
                             for band, name in zip(details, ("cH", "cV", "cD"))]
        subbands.append((np.abs(approximation), self.level, f"cA{self.level}"))
        return subbands

    def __call__(self, labels: np.ndarray, object_labels: np.ndarray,
                 valid: np.ndarray) -> PointSets:
        """Point sets of the objects ``object_labels`` of a label image.

        Parameters
        ----------
        labels : (H, W) ndarray of int
            Label image (stage 2).
        object_labels : (n_objects,) array_like of int
            The labels to decompose, one object each.
        valid : (H, W) ndarray of bool
            Mask of measured pixels (image > 0).

        Returns
        -------
        PointSets
            All sets of all objects in the order of ``object_labels``, each object's sets in
            ``subband_names`` order.
        """
        if np.ndim(labels) != 2 or np.shape(valid) != np.shape(labels):
            raise ValueError(f"labels and valid must be 2-D arrays of one shape; got "
                             f"{np.shape(labels)} and {np.shape(valid)}")
        if np.asarray(valid).dtype != bool:
            raise ValueError(f"valid must be a boolean mask; got dtype {np.asarray(valid).dtype}")
        masks = (labels[None, :, :] == np.asarray(object_labels)[:, None, None])
        near_edge = self._measurement_edge(valid)
        xs, ys, weights, ids = [], [], [], []
        for magnitude, band_level, name in self.decompose(masks):
            height, width = magnitude.shape[1:]
            row_y, column_x, pixels = self._block_grid(band_level, height, width, labels.shape)
            if not name.startswith("cA"):  # detail points on the measurement's edge: dropped
                np.copyto(magnitude, 0, where=near_edge[pixels])
            peak = magnitude.reshape(len(magnitude), -1).max(axis=1)
            floor = self.significance * peak[:, None, None] if self.significance > 0 else 0
            flat = np.flatnonzero(magnitude > floor)
            obj, position = np.divmod(flat, height * width)
            row, col = np.divmod(position, width)
            weights.append(magnitude.ravel()[flat] / peak[obj])
            xs.append(column_x[col])
            ys.append(row_y[row])
            ids.append(obj * self.n_subbands + self.subband_names.index(name))
        return PointSets(np.concatenate(xs), np.concatenate(ys), np.concatenate(weights),
                         np.concatenate(ids), len(object_labels), self.n_subbands)

    def _block_grid(self, level: int, height: int, width: int, image_shape: tuple[int, int]):
        """Block-centre coordinates of a subband's rows and columns, and the image pixels
        (an index: two slices when evenly spaced, as for Haar, else ``np.ix_``) nearest to them;
        cached per subband geometry."""
        key = (level, height, width, image_shape)
        if key not in self._grids:
            row_y = _block_centre(np.arange(height), level, self.wavelet.dec_len)
            column_x = _block_centre(np.arange(width), level, self.wavelet.dec_len)
            rows = np.clip(np.rint(row_y).astype(np.intp), 0, image_shape[0] - 1)
            columns = np.clip(np.rint(column_x).astype(np.intp), 0, image_shape[1] - 1)
            strided = (_even_steps(rows), _even_steps(columns))
            pixels = (strided if all(isinstance(index, slice) for index in strided)
                      else np.ix_(rows, columns))
            self._grids[key] = (row_y, column_x, pixels)
        return self._grids[key]

    def _measurement_edge(self, valid: np.ndarray) -> np.ndarray:
        """Pixels within ``edge_margin`` of an invalid pixel or of the image border."""
        # Outside the image counts as invalid: a constant border of ones.
        return cv2.dilate((~valid).view(np.uint8), self._edge_kernel,
                          borderType=cv2.BORDER_CONSTANT, borderValue=1).view(bool)
