"""Procedural river worlds: typed mesh parts, materials, the route, presets and mesh file I/O.

worlds.available()                      -> sorted preset names
worlds.load("canal_lock", width_m=30)   -> World (preset with overrides; cached on disk)
worlds.load("scan.ply", route=[[0, 0], [100, 0]])  -> World from any mesh file trimesh reads
worlds.export(world, "out.glb")         -> writes the world's triangles atomically
worlds.describe(world)                  -> json-able summary
"""

from __future__ import annotations

import riverbench  # noqa: F401  (first, before numpy loads: it pins the numeric kernels, riverbench.kernels)

# isort: split

import os
from pathlib import Path

from worlds import cache, presets
from worlds.describe import describe
from worlds.io import add_mesh_part, export, world_from_file
from worlds.materials import MATERIALS, Material
from worlds.route import Route
from worlds.world import PART_KINDS, Part, World

__all__ = [
    "MATERIALS",
    "PART_KINDS",
    "Material",
    "Part",
    "Route",
    "World",
    "add_mesh_part",
    "available",
    "describe",
    "export",
    "load",
    "resolve_params",
]


def available() -> list[str]:
    """Names of the preset worlds, sorted."""
    return sorted(presets.PRESETS)


def resolve_params(name: str, **params) -> dict:
    """The preset's full parameter set (every default filled in) as json-able data."""
    return presets.resolve(name, params).model_dump(mode="json")


def load(name_or_path: str | os.PathLike, *, use_cache: bool = True, **params) -> World:
    """A preset by name (keyword overrides of its parameters) or a world from a mesh file path.

    Presets are cached on disk by a hash of (preset, resolved params, builder code) under
    $RIVERBENCH_CACHE or ~/.cache/riverbench/worlds; `use_cache=False` always builds fresh.
    For a mesh file, see `worlds.io.world_from_file` (params: route, left_m, right_m, origin,
    material; without `route` it runs along the longest horizontal bounding-box axis).
    """
    name = str(name_or_path)
    if name in presets.PRESETS:
        resolved = presets.resolve(name, params)
        build = lambda: presets.build(name, resolved)
        if not use_cache:
            return build()
        return cache.load_or_build(name, resolved.model_dump(mode="json"), build)
    if isinstance(name_or_path, Path) or os.sep in name or Path(name).suffix:
        return world_from_file(name_or_path, **params)
    raise ValueError(f"unknown world {name!r}; available: {', '.join(available())} (or a mesh file path)")
