"""Time-of-flight model of the MESA SwissRanger SR4000: rendered depth -> what the sensor reports.

Every artifact is one parameter of :class:`ToFParams` and can be switched off; ``ToFParams.noiseless()``
switches all of them off, and then the reported depth equals the rendered depth exactly.

Model, per frame (docs/sensor.md, "Artifacts of a real ToF camera", which also gives the
sensor's published figures and the model's known gaps):

1. Radial range r = z * sqrt(1 + x_n^2 + y_n^2) from the planar depth z the renderer gives.
2. Amplitude A = (rho / rho_ref) * cos(theta) * (d_ref / r)^2, so A = 1 for a 99 % target head-on
   at 2 m (the datasheet's reference condition); theta from the depth image's surface normals;
   rho per pixel from the surface's material (:mod:`sim.world.sensor.materials`) or one value.
3. Phasor averaging: each sub-render contributes A * exp(i 2 pi r / U), U = c / (2 f_mod). Mixed
   ("flying") pixels blend a pixel's phasor with its 4-neighbours' mean (weight uniform in
   [0, ``mixed_pixel_weight``] per pixel: where an edge falls in the pixel footprint is unknown);
   motion blur averages the phasors of the sub-renders over the integration window.
4. Systematic "wiggling": r += a * sin(2 pi r / (U / 4) + phase): 4-phase sampling aliases the
   odd harmonics of the modulation onto a quarter of the unambiguous range.
5. Random noise on r: sigma = min(sqrt(sigma_min^2 + (sigma_ref^2 - sigma_min^2) / A^2),
   sigma_max): a part inversely proportional to amplitude (Lange's phase noise) in quadrature
   with an amplitude-independent part, calibrated to the datasheet's repeatability (4 mm at
   A = 1) and to Chiabrando et al.'s 3.7-4.0 mm on a white wall at 1.3 m
   (:mod:`sim.world.sensor.calibration`).
6. Phase wrapping: r mod U.
7. Quantization: 14 significant bits over U.
8. Validity: invalid (0) where there is no surface, the measured range is nearer than
   ``min_range_m`` or farther than ``max_range_m``, the amplitude is below ``min_amplitude``
   (too dark / too far) or above ``saturation_amplitude`` (saturated).
9. Back to planar depth z = r / sqrt(1 + x_n^2 + y_n^2) (the driver reports Cartesian z).

Defaults follow the datasheet and Chiabrando et al.; the materials' reflectivities, the
confidence and saturation thresholds, the noise cap, the mixed-pixel weight and the integration
time are choices of this model (docs/sensor.md).

References:
    MESA Imaging, SR4000 data sheet (rev. 5.1, 2011) and user manual.
    Chiabrando, Chiabrando, Piatti & Rinaudo, "Sensors for 3D imaging: metric evaluation and
    calibration of a CCD/CMOS time-of-flight camera", Sensors 9 (2009).
    Lange, "3D time-of-flight distance measurement with custom solid-state image sensors in
    CMOS/CCD technology", PhD thesis, University of Siegen (2000).
    Lindner & Kolb, "Lateral and depth calibration of PMD-distance sensors", ISVC 2006.
    Foix, Alenya & Torras, "Lock-in time-of-flight (ToF) cameras: a survey", IEEE Sensors J. 11
    (2011).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from sim.world.camera import CameraIntrinsics

SPEED_OF_LIGHT_M_S = 299_792_458.0
#: The SR4000's highest frame rate (datasheet).
MAX_FPS = 54.0


#: Largest range noise sigma a ToFParams takes (metres): above the presets' largest cap (0.15 m,
#: high_noise) scaled by the scenarios' largest noise_scale, 100. Beyond some 1e154 m its square
#: overflows.
MAX_NOISE_SIGMA_M = 20.0


@dataclass(frozen=True)
class ToFParams:
    """Parameters of the SR4000 model; defaults are the datasheet's (docs/sensor.md).

    Switching an effect off: ``phase_wrapping=False``; ``noise_sigma_ref_m=0``;
    ``wiggle_amplitude_m=0``; ``quantization_bits=0``; ``mixed_pixel_weight=0``;
    ``motion_blur_subframes=1``; ``incidence_angle=False``; ``material_reflectivity=False`` (every
    surface ``reflectivity``); ``min_range_m=0``,
    ``max_range_m=inf``, ``min_amplitude=0``, ``saturation_amplitude=inf`` (no invalid pixels
    other than "no surface").

    Attributes:
        modulation_hz: modulation frequency; unambiguous range U = c / (2 f). Default 30 MHz (5 m).
        phase_wrapping: report the range modulo U. Default True.
        min_range_m: measured ranges nearer are invalid. Default 0.1 m (datasheet).
        max_range_m: measured ranges farther are invalid. Default 5.0 m (calibrated range).
        reflectivity: near-infrared reflectivity rho, 0-1, of every surface when
            ``material_reflectivity`` is False, else of the surfaces without a material of
            :data:`sim.world.sensor.materials.NIR_REFLECTIVITY`. Default 0.8.
        material_reflectivity: rho per pixel from the material of the surface it sees (the
            geom ids of the centre sub-render; :mod:`sim.world.sensor.materials`). Default
            True.
        incidence_angle: amplitude falls with cos(theta) of the incidence angle. Default True.
        min_amplitude: confidence threshold on the relative amplitude (1 = 99 % target head-on at
            2 m). Default 0.02: a white wall (rho = 0.85) head-on stays valid to about 13 m,
            carbon-black plastic (0.05) to 3.2 m.
        saturation_amplitude: amplitudes above are invalid. Default 100 (rho = 0.8 nearer
            than about 0.18 m).
        noise_sigma_ref_m: range noise sigma at amplitude 1 (repeatability at 2 m, 99 %
            target). Default 0.004 m. 0 switches noise off.
        noise_sigma_min_m: amplitude-independent part of sigma, added in quadrature: the value
            sigma falls to at high amplitude; at most ``noise_sigma_ref_m``. Default 0.0038 m
            (fitted to Chiabrando et al.'s white wall at 1.3 m:
            ``python -m sim.world.sensor.calibration``).
        noise_sigma_max_m: cap of sigma. Default 0.05 m.
        wiggle_amplitude_m: amplitude of the periodic systematic error (bounded by the
            absolute accuracy). Default 0.010 m. 0 switches it off.
        wiggle_phase_rad: phase of the wiggling sinusoid. Default 0.
        quantization_bits: significant bits of the range over U. Default 14; 0 = off.
        mixed_pixel_weight: largest fraction of a pixel's light that comes from its
            4-neighbours (mixed pixels at depth edges). Default 0.5; 0 = off.
        motion_blur_subframes: renders averaged over the integration time. Default 3; 1 = off.
        integration_time_s: integration time (0.3-25.8 ms on the SR4000). Default 0.005 s.
    """

    modulation_hz: float = 30e6
    phase_wrapping: bool = True
    min_range_m: float = 0.1
    max_range_m: float = 5.0
    reflectivity: float = 0.8
    material_reflectivity: bool = True
    incidence_angle: bool = True
    min_amplitude: float = 0.02
    saturation_amplitude: float = 100.0
    noise_sigma_ref_m: float = 0.004
    noise_sigma_min_m: float = 0.0038
    noise_sigma_max_m: float = 0.05
    wiggle_amplitude_m: float = 0.010
    wiggle_phase_rad: float = 0.0
    quantization_bits: int = 14
    mixed_pixel_weight: float = 0.5
    motion_blur_subframes: int = 3
    integration_time_s: float = 0.005

    #: Amplitude reference: the datasheet's repeatability condition (2 m, 99 % target).
    reference_distance_m = 2.0
    reference_reflectivity = 0.99

    def __post_init__(self):
        checks = {
            "modulation_hz": (1e6 <= self.modulation_hz <= 1e9, "1e6 to 1e9 Hz"),
            "min_range_m": (self.min_range_m >= 0, ">= 0"),
            "max_range_m": (self.max_range_m > self.min_range_m, "> min_range_m"),
            "reflectivity": (0 < self.reflectivity <= 1, "in (0, 1]"),
            "min_amplitude": (self.min_amplitude >= 0, ">= 0"),
            "saturation_amplitude": (self.saturation_amplitude > self.min_amplitude,
                                     "> min_amplitude"),
            # At most MAX_NOISE_SIGMA_M: above 100 times the presets' caps, beyond any sensor.
            "noise_sigma_ref_m": (0 <= self.noise_sigma_ref_m <= MAX_NOISE_SIGMA_M,
                                  f"0 to {MAX_NOISE_SIGMA_M} m"),
            "noise_sigma_min_m": (0 <= self.noise_sigma_min_m <= self.noise_sigma_ref_m
                                  or self.noise_sigma_ref_m == 0,
                                  ">= 0 and <= noise_sigma_ref_m (unless noise is off)"),
            "noise_sigma_max_m": (self.noise_sigma_min_m <= self.noise_sigma_max_m
                                  <= MAX_NOISE_SIGMA_M,
                                  f">= noise_sigma_min_m, at most {MAX_NOISE_SIGMA_M} m"),
            "wiggle_amplitude_m": (self.wiggle_amplitude_m >= 0, ">= 0"),
            "wiggle_phase_rad": (math.isfinite(self.wiggle_phase_rad), "finite"),
            "quantization_bits": (0 <= self.quantization_bits <= 32, "0 (off) to 32"),
            "mixed_pixel_weight": (0 <= self.mixed_pixel_weight <= 1, "in [0, 1]"),
            "motion_blur_subframes": (1 <= self.motion_blur_subframes <= 16, "1 (off) to 16"),
            "integration_time_s": (0 < self.integration_time_s <= 0.0258,
                                   "in (0, 0.0258] s (SR4000: 0.3-25.8 ms)"),
        }
        for name, (ok, allowed) in checks.items():
            if not ok:
                raise ValueError(f"ToFParams.{name}={getattr(self, name)!r} is out of range; "
                                 f"allowed: {allowed}")

    @classmethod
    def noiseless(cls) -> "ToFParams":
        """Every effect off: the reported depth is the rendered depth."""
        return cls(phase_wrapping=False, min_range_m=0.0, max_range_m=math.inf,
                   material_reflectivity=False, incidence_angle=False, min_amplitude=0.0,
                   saturation_amplitude=math.inf, noise_sigma_ref_m=0.0,
                   noise_sigma_min_m=0.0, noise_sigma_max_m=0.0, wiggle_amplitude_m=0.0,
                   quantization_bits=0, mixed_pixel_weight=0.0, motion_blur_subframes=1)

    @property
    def unambiguous_range_m(self) -> float:
        return SPEED_OF_LIGHT_M_S / (2.0 * self.modulation_hz)

    @property
    def quantization_step_m(self) -> float:
        """Range step of the reported distance; 0 when quantization is off."""
        if self.quantization_bits == 0:
            return 0.0
        return self.unambiguous_range_m / 2**self.quantization_bits

    def relative_amplitude(self, range_m, cos_incidence=1.0, reflectivity=None):
        """A = (rho / rho_ref) cos(theta) (d_ref / r)^2: 1 at the datasheet's reference.

        ``reflectivity`` (a number or a per-pixel image) is rho; None: ``self.reflectivity``.
        The returned light of a Lambertian surface scales with rho cos(theta) / r^2 (Lange 2000).
        """
        rho = self.reflectivity if reflectivity is None else reflectivity
        return (rho / self.reference_reflectivity * cos_incidence
                * (self.reference_distance_m / np.maximum(range_m, 1e-6)) ** 2)

    def wiggle_error_m(self, range_m):
        """Systematic range error: a sinusoid of period U / 4 (4-phase sampling)."""
        period = self.unambiguous_range_m / 4.0
        return self.wiggle_amplitude_m * np.sin(2 * np.pi * range_m / period
                                                + self.wiggle_phase_rad)

    def noise_sigma_m(self, amplitude):
        """Range noise sigma = min(sqrt(sigma_min^2 + (b / A)^2), sigma_max).

        b / A is Lange's phase noise, inversely proportional to the amplitude, with
        b^2 = sigma_ref^2 - sigma_min^2 so that sigma = sigma_ref at A = 1; sigma_min is the part
        that does not fall with the amplitude (docs/sensor.md, "Random noise").
        """
        amplitude = np.asarray(amplitude)
        if self.noise_sigma_ref_m == 0:
            return np.zeros_like(amplitude, dtype=float)
        floor_sq = self.noise_sigma_min_m ** 2
        with np.errstate(divide="ignore"):
            sigma = np.sqrt(floor_sq + (self.noise_sigma_ref_m ** 2 - floor_sq)
                            / np.square(amplitude))
        return np.minimum(sigma, self.noise_sigma_max_m)


#: Named parameter sets; scenarios pick one and may override fields.
TOF_PRESETS: dict[str, ToFParams] = {
    "sr4000": ToFParams(),
    "noiseless": ToFParams.noiseless(),
    # 3x the noise and 2x the wiggling, stronger mixing and a stricter confidence threshold: a
    # worn or badly lit sensor, for robustness tests.
    "high_noise": ToFParams(noise_sigma_ref_m=0.012, noise_sigma_min_m=0.0114,
                            noise_sigma_max_m=0.15,
                            wiggle_amplitude_m=0.02, mixed_pixel_weight=0.8,
                            min_amplitude=0.05),
}


class ToFModel:
    """Turns planar depth renders (one per sub-frame) into the SR4000's reported depth.

    Args:
        params: the effects and their sizes.
        intrinsics: pinhole intrinsics of the rendered images (radial range, normals).
        no_surface_depth_m: rendered depth at or beyond which a pixel saw no surface (the far
            clip plane); such pixels are always invalid.
    """

    def __init__(self, params: ToFParams, intrinsics: CameraIntrinsics,
                 no_surface_depth_m: float = math.inf):
        self.params = params
        self.intrinsics = intrinsics
        self.no_surface_depth_m = float(no_surface_depth_m)
        u = (np.arange(intrinsics.width) - intrinsics.cx) / intrinsics.fx
        v = (np.arange(intrinsics.height) - intrinsics.cy) / intrinsics.fy
        # float32 throughout: 0.3 um resolution at 5 m, twice the speed of float64.
        self._xn, self._yn = (g.astype(np.float32) for g in np.meshgrid(u, v))
        #: r = z * ray_scale for every pixel.
        self.ray_scale = np.sqrt(1.0 + self._xn**2 + self._yn**2)

    def radial_range(self, depth_m: np.ndarray) -> np.ndarray:
        return depth_m * self.ray_scale

    def cos_incidence(self, depth_m: np.ndarray) -> np.ndarray:
        """cos of the angle between each pixel's ray and the surface normal, from the depth.

        Derivatives are the smaller of the two one-sided differences, so a pixel beside a depth
        edge gets the normal of its own surface. With P = z (x_n, y_n, 1), the normal
        dP/du x dP/dv is proportional to n = (-z_u fx, -z_v fy, z_u fx x_n + z_v fy y_n + z),
        and n . (x_n, y_n, 1) = z.
        """
        k = self.intrinsics
        z_u, z_v = _one_sided_gradient(depth_m, 1), _one_sided_gradient(depth_m, 0)
        a, b = z_u * k.fx, z_v * k.fy
        c = a * self._xn + b * self._yn + depth_m
        return depth_m / (np.sqrt(a * a + b * b + c * c) * self.ray_scale)

    def apply(self, renders: list[np.ndarray], rng: np.random.Generator,
              reflectivity: np.ndarray | None = None):
        """Reported (depth_m float32 with 0 where invalid, valid bool) from sub-frame renders.

        The centre render (the middle one of the integration window) is the reference the
        reported depth is built on, so the noiseless preset returns it unchanged.
        ``reflectivity`` is the per-pixel rho of the centre render's surfaces, used for every
        sub-render (the surfaces move by a pixel or two within the window); None gives every
        surface ``params.reflectivity``.
        """
        p = self.params
        if len(renders) != p.motion_blur_subframes:
            raise ValueError(f"need {p.motion_blur_subframes} sub-frame renders "
                             f"(motion_blur_subframes); got {len(renders)}")
        depths = [np.asarray(d, dtype=np.float32) for d in renders]
        if reflectivity is not None and np.shape(reflectivity) != depths[0].shape:
            raise ValueError(f"reflectivity image has shape {np.shape(reflectivity)}; the "
                             f"renders have {depths[0].shape}")
        # Sub-renders of an unchanged state come as one array (SR4000.expose): work on it once.
        per_render = {}
        for d in depths:
            if id(d) not in per_render:
                surface, range_m = d < self.no_surface_depth_m, self.radial_range(d)
                per_render[id(d)] = (surface, range_m,
                                     self._amplitude(d, range_m, surface, reflectivity))
        surfaces, ranges, amplitudes = (list(values) for values in
                                        zip(*(per_render[id(d)] for d in depths)))
        surface = np.logical_or.reduce(surfaces)
        centre = len(renders) // 2
        true_range = ranges[centre]
        if p.mixed_pixel_weight > 0 or len(renders) > 1:
            measured, amplitude = self._phasor_average(ranges, amplitudes, rng)
        else:
            measured, amplitude = true_range.copy(), amplitudes[0]
        if p.wiggle_amplitude_m > 0:
            measured += p.wiggle_error_m(measured)
        if p.noise_sigma_ref_m > 0:
            noise = rng.standard_normal(measured.shape, dtype=np.float32)
            measured += p.noise_sigma_m(amplitude) * noise
        if p.phase_wrapping:
            measured = np.mod(measured, np.float32(p.unambiguous_range_m))
        step = np.float32(p.quantization_step_m)
        if step > 0:
            measured = np.rint(measured / step) * step
        valid = (surface & (measured >= p.min_range_m) & (measured <= p.max_range_m)
                 & (amplitude >= p.min_amplitude) & (amplitude <= p.saturation_amplitude))
        # z + (r_meas - r_true) / scale rather than r_meas / scale: exact when nothing changed.
        depth = depths[centre] + (measured - true_range) / self.ray_scale
        depth[~valid] = 0.0
        return depth, valid

    def _amplitude(self, depth, range_m, surface, reflectivity):
        cos = self.cos_incidence(depth) if self.params.incidence_angle else np.float32(1.0)
        amplitude = self.params.relative_amplitude(range_m, cos,
                                                   reflectivity).astype(np.float32)
        amplitude[~surface] = 0.0
        return amplitude

    def _phasor_average(self, ranges, amplitudes, rng):
        """Mix neighbours and sub-frames as complex phasors A e^{i 2 pi r / U} (docs/sensor.md)."""
        p = self.params
        period = np.float32(p.unambiguous_range_m)
        to_phase = np.float32(2 * np.pi) / period
        real, imag = np.zeros_like(ranges[0]), np.zeros_like(ranges[0])
        phasors = {}
        for r, a in zip(ranges, amplitudes):
            if id(r) not in phasors:
                phasors[id(r)] = cv2.polarToCart(a, np.mod(r, period) * to_phase)
            x, y = phasors[id(r)]
            real += x
            imag += y
        # Amplitude-weighted linear mean: picks the right period when wrapping is off.
        linear = None if p.phase_wrapping else [sum(amplitudes),
                                                sum(r * a for r, a in zip(ranges, amplitudes))]
        if p.mixed_pixel_weight > 0:
            w = rng.random(real.shape, dtype=np.float32) * np.float32(p.mixed_pixel_weight)
            # The outermost pixels' outer neighbours were not rendered: leave them unmixed.
            w[[0, -1], :] = 0.0
            w[:, [0, -1]] = 0.0
            real, imag = (x + w * (self._neighbour_mean(x) - x) for x in (real, imag))
            if linear is not None:
                linear = [x + w * (self._neighbour_mean(x) - x) for x in linear]
        # np.arctan2, not cv2.cartToPolar: the latter's angle error reaches 0.13 mm of range.
        amplitude = np.hypot(real, imag) / np.float32(len(ranges))
        measured = np.mod(np.arctan2(imag, real), np.float32(2 * np.pi)) / to_phase
        if linear is not None:
            weight, weighted = linear
            mean = np.divide(weighted, weight, out=ranges[len(ranges) // 2].copy(),
                             where=weight > 0)
            measured += np.rint((mean - measured) / period) * period
        return measured, amplitude

    @staticmethod
    def _neighbour_mean(image: np.ndarray) -> np.ndarray:
        kernel = np.array([[0, 0.25, 0], [0.25, 0, 0.25], [0, 0.25, 0]], dtype=np.float32)
        return cv2.filter2D(image, -1, kernel, borderType=cv2.BORDER_REPLICATE)


def _one_sided_gradient(image: np.ndarray, axis: int) -> np.ndarray:
    """Per-pixel derivative along ``axis``: the smaller of the forward and backward differences."""
    diff = np.diff(image, axis=axis)
    moved, out = np.moveaxis(diff, axis, 0), np.empty_like(image)
    out_moved = np.moveaxis(out, axis, 0)
    backward, forward = moved[:-1], moved[1:]
    out_moved[1:-1] = np.where(np.abs(backward) < np.abs(forward), backward, forward)
    out_moved[0], out_moved[-1] = moved[0], moved[-1]
    return out
