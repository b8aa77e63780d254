"""Near-infrared reflectivity of the scenes' materials: what the SR4000's 850 nm light sees.

The SR4000 measures with its own 850 nm illumination, so a surface's amplitude (and with it its
noise, validity and saturation) follows its diffuse reflectance at 850 nm, not its visible
colour. Each material of the scenes (``sim.world.scenes.arena.MATERIALS``, the arena's ``floor``
and the plain floor ``grid`` of ``sim.world.assembly.floor_arena``) gets one value here, keyed by
the MJCF material name. Geoms without a material, or with a material not listed (the robot's
own geoms), take ``ToFParams.reflectivity``.

The values are this model's assumptions, not measurements of the scenes' (imaginary) surfaces:
each is a typical value inside the range stated for the material class, and the range is the
uncertainty. What they rest on (docs/sensor.md, "Reflectivity per surface"):

- White pigment (titanium dioxide) scatters strongly and the usual binders absorb little at
  850 nm, so white interior paint stays bright in the near infrared; carbon black absorbs from
  the visible through the near infrared; many organic colorants (phthalocyanine blue, most
  textile dyes) are nearly transparent at 850 nm, so coloured plastics and dark fabrics look
  brighter to the sensor than to the eye (Levinson, Berdahl & Akbari 2005, a survey of the
  solar-spectrum reflectance of common colorants).
- Cellulose (wood, paper, cardboard) absorbs little between 700 and 1300 nm, so wood and kraft
  board are brighter at 850 nm than in the visible.
- Measured spectra of such materials: the USGS Spectral Library version 7 (Kokaly et al.
  2017, man-made materials) and the ECOSTRESS library (Meerdink et al. 2019), both at normal
  incidence; a 2023 Data in Brief dataset gives angle-dependent reflectances of 283 materials
  measured by a 945 nm ToF camera. Use them to replace a value here by a measured one.

References:
    R. Levinson, P. Berdahl, H. Akbari, "Solar spectral optical properties of pigments, Part II:
    survey of common colorants", Solar Energy Materials & Solar Cells 89 (2005) 351-389.
    R. F. Kokaly et al., "USGS Spectral Library Version 7", USGS Data Series 1035 (2017).
    S. K. Meerdink et al., "The ECOSTRESS spectral library version 1.0", Remote Sensing of
    Environment 230 (2019).
    "Angle-dependent spectral reflectance material dataset based on 945 nm time-of-flight
    camera measurements", Data in Brief (2023), PMC10034426; data: Zenodo record 7467552.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class NirReflectivity:
    """Diffuse reflectance at 850 nm assumed for a material: ``value``, within [low, high]."""

    value: float
    low: float
    high: float
    surface: str


#: Material name -> its assumed 850 nm reflectance (docs/sensor.md, "Reflectivity per surface").
NIR_REFLECTIVITY: dict[str, NirReflectivity] = {
    "wall": NirReflectivity(0.85, 0.75, 0.90, "off-white interior paint on plaster"),
    "door": NirReflectivity(0.55, 0.35, 0.70, "stained or painted wooden door, mid brown"),
    "wood": NirReflectivity(0.60, 0.45, 0.75, "light wood: desk tops, shelves, tables"),
    "metal": NirReflectivity(0.45, 0.20, 0.60, "painted or brushed steel legs, rails, lamps "
                             "(diffuse part; the specular lobe is not modelled)"),
    "plastic": NirReflectivity(0.50, 0.30, 0.80, "blue polyethylene barrel"),
    "cardboard": NirReflectivity(0.70, 0.55, 0.80, "kraft cardboard crates, book covers"),
    "fabric": NirReflectivity(0.50, 0.30, 0.70, "dyed upholstery of chairs (dark red)"),
    "concrete": NirReflectivity(0.35, 0.25, 0.45, "grey cast concrete: stairs, pillars, sills"),
    "dark": NirReflectivity(0.05, 0.03, 0.10, "carbon-black plastic: monitors, bins"),
    "floor": NirReflectivity(0.40, 0.20, 0.60, "grey-brown vinyl or linoleum floor"),
    "grid": NirReflectivity(0.40, 0.20, 0.60, "the plain test floor (blue-grey checker)"),
}


def material_key(name: str) -> str:
    """The table key of an MJCF material name: the name without a dm_control attachment prefix
    (``robot/wood`` -> ``wood``)."""
    return name.rsplit("/", 1)[-1]


def geom_reflectivity(model: mujoco.MjModel, default: float) -> np.ndarray:
    """Reflectivity of every geom of ``model`` (shape (ngeom,), float32) from its material;
    ``default`` for geoms without a material or with one not in :data:`NIR_REFLECTIVITY`."""
    table = np.full(model.ngeom, default, dtype=np.float32)
    for geom in range(model.ngeom):
        material = model.geom_matid[geom]
        if material >= 0:
            known = NIR_REFLECTIVITY.get(material_key(model.mat(material).name))
            if known is not None:
                table[geom] = known.value
    return table


def reflectivity_image(geom_ids: np.ndarray, geom_table: np.ndarray,
                       default: float) -> np.ndarray:
    """Per-pixel reflectivity (H x W float32) from the geom id of each pixel (-1: no geom).

    Pixels showing a geom get ``geom_table[id]`` (:func:`geom_reflectivity`), the others (no
    surface) ``default``.
    """
    return np.where(geom_ids >= 0, geom_table[np.maximum(geom_ids, 0)],
                    np.float32(default)).astype(np.float32)
