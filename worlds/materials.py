"""Surface materials: LiDAR reflectivity at 905 nm and whether GNSS L1 signals reflect off them."""

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
    """

    name: str
    reflectivity: float
    gnss_reflective: bool
    water: bool = False
    foliage: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.reflectivity <= 1.0:
            raise ValueError(f"material {self.name!r}: reflectivity must be in [0, 1], got {self.reflectivity}")


WATER = Material("water", reflectivity=0.02, gnss_reflective=False, water=True)
CONCRETE = Material("concrete", reflectivity=0.35, gnss_reflective=True)
GRANITE = Material("granite", reflectivity=0.30, gnss_reflective=True)
BRICK = Material("brick", reflectivity=0.28, gnss_reflective=True)
STEEL = Material("steel", reflectivity=0.22, gnss_reflective=True)
GLASS = Material("glass", reflectivity=0.08, gnss_reflective=True)
TIMBER = Material("timber", reflectivity=0.30, gnss_reflective=False)
GRASS = Material("grass", reflectivity=0.45, gnss_reflective=False)
SOIL = Material("soil", reflectivity=0.20, gnss_reflective=False)
# broadleaf foliage at 905 nm: ~0.45 (leaves reflect 0.4-0.5 in the near infrared, e.g. the PROSPECT model)
VEGETATION = Material("vegetation", reflectivity=0.45, gnss_reflective=False, foliage=True)
# white gelcoat hulls: bright, but a curved dielectric that scatters L1 rather than mirroring it
FIBREGLASS = Material("fibreglass", reflectivity=0.55, gnss_reflective=False)
ALUMINIUM = Material("aluminium", reflectivity=0.40, gnss_reflective=True)

MATERIALS: dict[str, Material] = {
    m.name: m for m in (WATER, CONCRETE, GRANITE, BRICK, STEEL, GLASS, TIMBER, GRASS, SOIL, VEGETATION, FIBREGLASS, ALUMINIUM)
}
