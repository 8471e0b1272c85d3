"""Surface materials: LiDAR reflectivity at 905 nm and whether GNSS L1 signals reflect off them.

Reflectivities are diffuse reflectances near 905 nm, rounded, from the ECOSTRESS / ASTER spectral
library (Meerdink et al. 2019, Remote Sens. Environ. 230:111196; Baldridge et al. 2009, Remote Sens.
Environ. 113:711-715; https://speclib.jpl.nasa.gov) for the class named in each material's `source` (library classes; the values are rounded
typical figures of the class, not one spectrum).
The HDL-32E model (sim.lidar) turns them into detection probability and intensity.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Material:
    """Optical and radio properties of a surface.

    reflectivity: diffuse (Lambertian) reflectance at 905 nm, 0..1; scales LiDAR intensity.
    gnss_reflective: True when L1 signals reflect specularly off it (concrete, stone, steel, glass),
    so the GNSS model considers its vertical faces for multipath; False for vegetation, soil and the
    water surface (an antenna 1.3 m above the water gets at most 2.6 m of extra path from it, under
    ~1 m of code error, which the noise model covers).
    water: True for the water surface, which returns almost no 905 nm light.
    foliage: True for tree crowns: porous to L1, which crosses them with a loss per metre of
    foliage instead of being blocked (sim.gnss; the crown envelopes are `World.crowns`).
    source: where the reflectivity comes from (spectral library class or measurement).
    """

    name: str
    reflectivity: float
    gnss_reflective: bool
    water: bool = False
    foliage: bool = False
    source: str = ""

    def __post_init__(self) -> None:
        if not 0.0 <= self.reflectivity <= 1.0:
            raise ValueError(f"material {self.name!r}: reflectivity must be in [0, 1], got {self.reflectivity}")


LIB = "ECOSTRESS/ASTER spectral library"
# water absorbs 905 nm (reflectance ~0.02 at normal incidence, mostly specular): an HDL-32E on a WAM-V
# gets only a very few returns from a lake's surface (osrf/vrx issue #29, HDL-32 data)
WATER = Material("water", reflectivity=0.02, gnss_reflective=False, water=True, source=f"{LIB}: tap water; osrf/vrx#29")
CONCRETE = Material("concrete", reflectivity=0.35, gnss_reflective=True, source=f"{LIB}: construction concrete")
GRANITE = Material("granite", reflectivity=0.30, gnss_reflective=True, source=f"{LIB}: granite")
BRICK = Material("brick", reflectivity=0.28, gnss_reflective=True, source=f"{LIB}: red brick")
STEEL = Material("steel", reflectivity=0.22, gnss_reflective=True, source=f"{LIB}: painted / weathered steel")
GLASS = Material("glass", reflectivity=0.08, gnss_reflective=True, source="clear glass: ~8% Fresnel reflection, the rest transmitted")
TIMBER = Material("timber", reflectivity=0.30, gnss_reflective=False, source=f"{LIB}: weathered wood")
GRASS = Material("grass", reflectivity=0.45, gnss_reflective=False, source=f"{LIB}: green grass")
SOIL = Material("soil", reflectivity=0.20, gnss_reflective=False, source=f"{LIB}: brown loam")
# broadleaf foliage at 905 nm: ~0.45 (leaves reflect 0.4-0.5 in the near infrared, e.g. the PROSPECT model)
VEGETATION = Material("vegetation", reflectivity=0.45, gnss_reflective=False, foliage=True, source=f"{LIB}: deciduous leaves; PROSPECT")
# white gelcoat / hull paint: bright, but a curved dielectric that scatters L1 rather than mirroring it
FIBREGLASS = Material("fibreglass", reflectivity=0.55, gnss_reflective=False, source="white gelcoat / hull paint (bright in the near infrared)")
ALUMINIUM = Material("aluminium", reflectivity=0.40, gnss_reflective=True, source=f"{LIB}: weathered aluminium")

MATERIALS: dict[str, Material] = {
    m.name: m for m in (WATER, CONCRETE, GRANITE, BRICK, STEEL, GLASS, TIMBER, GRASS, SOIL, VEGETATION, FIBREGLASS, ALUMINIUM)
}


def material_named(name: str, where: str) -> Material:
    """The material called `name`; ValueError (one line, naming `where`) when there is none."""
    if name not in MATERIALS:
        raise ValueError(f"{where}: unknown material {name!r} (one of {', '.join(sorted(MATERIALS))})")
    return MATERIALS[name]
