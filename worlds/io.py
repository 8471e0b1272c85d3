"""Mesh files: load any file trimesh reads as a whole world or as an extra part; export a world."""

from __future__ import annotations

import dataclasses
import os
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field

from worlds.assemble import BOSTON_BU_BRIDGE
from worlds.materials import material_named
from worlds.params import validate
from worlds.route import Route
from worlds.world import PART_KINDS, Part, World

SCENE_FORMATS = {"glb", "obj"}


class FileWorldParams(BaseModel):
    """Parameters of a world loaded from a mesh file."""

    model_config = ConfigDict(extra="forbid")

    route: list[tuple[float, float]] | None = Field(
        None, description="route waypoints [[x, y], ...] in the file's ENU metres; None = along the longest horizontal bounding-box axis at mid-width"
    )
    left_m: float | None = Field(None, gt=0.0, description="route distance to the left bank, m; None = half the bounding box across the route")
    right_m: float | None = Field(None, gt=0.0, description="route distance to the right bank, m; None = half the bounding box across the route")
    origin: tuple[float, float, float] = Field(BOSTON_BU_BRIDGE, description="geodetic origin (lat deg, lon deg, alt m) of the file's coordinates")
    material: str = Field("concrete", description="material of the single part (one of worlds.materials.MATERIALS)")


def read_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Every triangle in a mesh file as one Trimesh; ValueError (one line) when it cannot be used."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"mesh file {str(path)!r} does not exist")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:
        raise ValueError(f"mesh file {str(path)!r} could not be read: {type(exc).__name__}: {exc}".splitlines()[0]) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError(f"mesh file {str(path)!r} has no triangles")
    if not np.isfinite(np.asarray(loaded.vertices)).all():
        raise ValueError(f"mesh file {str(path)!r} has NaN or infinite vertices")
    return trimesh.Trimesh(np.asarray(loaded.vertices, float), np.asarray(loaded.faces, np.int64), process=False)


def _default_route(mesh: trimesh.Trimesh) -> tuple[np.ndarray, float]:
    """Waypoints along the longest horizontal bounding-box axis at mid-width, and half that width."""
    lo, hi = mesh.bounds[0, :2], mesh.bounds[1, :2]
    axis = int(np.argmax(hi - lo))
    other = 1 - axis
    mid = 0.5 * (lo[other] + hi[other])
    wp = np.zeros((2, 2))
    wp[:, axis] = lo[axis], hi[axis]
    wp[:, other] = mid
    return wp, max(0.5 * (hi[other] - lo[other]), 1.0)


def world_from_file(path: str | os.PathLike, **params) -> World:
    """A whole world from a mesh file: one part of kind 'other' (named after the file).

    The route follows `route` waypoints if given; otherwise it runs along the mesh's longest
    horizontal bounding-box axis at mid-width, with bank distances of half the box's other
    extent. That default is only a guess: a vessel on it may cross the geometry, so pass
    `route=[[x, y], ...]` for anything but a quick look.
    """
    p = validate(FileWorldParams, params, f"world file {str(path)!r}")
    mat = material_named(p.material, f"world file {str(path)!r}")
    mesh = read_mesh(path)
    if p.route is None:
        wp, half = _default_route(mesh)
    else:
        wp, half = np.asarray(p.route, float), 0.5 * float(np.ptp(mesh.bounds[:, :2], axis=0).min())
    route = Route.from_waypoints(wp, p.left_m or half, p.right_m or half)
    part = Part(Path(path).stem, "other", mat, mesh)
    return World(
        name=Path(path).stem, parts=[part], route=route, origin=p.origin, params={"file": str(Path(path).resolve())} | p.model_dump(mode="json")
    )


def add_mesh_part(
    world: World,
    path: str | os.PathLike,
    name: str | None = None,
    kind: str = "other",
    material: str = "concrete",
    transform: np.ndarray | None = None,
) -> World:
    """A new world: `world` plus the mesh in `path` as one part (kind, material, optional 4x4 transform)."""
    if kind not in PART_KINDS:
        raise ValueError(f"add_mesh_part: unknown kind {kind!r} (one of {', '.join(PART_KINDS)})")
    mat = material_named(material, "add_mesh_part")
    mesh = read_mesh(path)
    if transform is not None:
        transform = np.asarray(transform, float)
        if transform.shape != (4, 4) or not np.isfinite(transform).all():
            raise ValueError("add_mesh_part: transform must be a finite 4x4 matrix")
        mesh.apply_transform(transform)
    part = Part(name or Path(path).stem, kind, mat, mesh)
    extra = {"file": str(Path(path).resolve()), "name": part.name, "kind": kind, "material": material}
    params = world.params | {"extra_parts": [*world.params.get("extra_parts", []), extra]}
    return dataclasses.replace(world, parts=[*world.parts, part], params=params)


def _umask() -> int:
    """The process umask (read by setting and restoring it)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def export(world: World, path: str | os.PathLike) -> Path:
    """Write the world's triangles to any format trimesh writes (by extension), atomically.

    GLB and OBJ keep one named node/object per part; other formats (ply, stl, off, ...) get one
    merged mesh. Unsupported extensions raise ValueError and leave nothing behind.
    """
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if not fmt:
        raise ValueError(f"export: {str(path)!r} has no extension to choose the format from")
    obj: trimesh.Scene | trimesh.Trimesh
    if fmt in SCENE_FORMATS:
        scene = trimesh.Scene()
        for p in world.parts:
            scene.add_geometry(p.mesh, node_name=p.name, geom_name=p.name)
        obj = scene
    else:
        obj = world.mesh
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        obj.export(tmp, file_type=fmt)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except (ValueError, KeyError, NotImplementedError):
        Path(tmp).unlink(missing_ok=True)
        raise ValueError(f"export: trimesh cannot write format {fmt!r} ({str(path)!r})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
