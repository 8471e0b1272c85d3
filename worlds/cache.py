"""On-disk cache of built preset worlds: one .npz per (preset, resolved params, builder code) hash.

The key hashes the preset name, its resolved parameters and the source of every module in the
worlds package (plus BUILDER_VERSION), so a code change can never serve a stale world. Entries
are written atomically (temporary name, then rename); an entry that does not read back is
rebuilt, never fatal.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from worlds.crowns import Crowns
from worlds.materials import MATERIALS
from worlds.route import Route
from worlds.world import Part, World

BUILDER_VERSION = 1


def cache_dir() -> Path:
    """$RIVERBENCH_CACHE, else ~/.cache/riverbench/worlds."""
    env = os.environ.get("RIVERBENCH_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "riverbench" / "worlds"


def _code_digest() -> str:
    """Hash of the worlds package's source files: any builder change gives new keys."""
    h = hashlib.sha256(str(BUILDER_VERSION).encode())
    for path in sorted(Path(__file__).parent.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def key(preset: str, params: dict) -> str:
    """Cache key of a preset built with resolved, json-able params."""
    blob = json.dumps({"preset": preset, "params": params, "code": _code_digest()}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:32]


def save(world: World, path: Path) -> None:
    """Write `world` to `path` (.npz) atomically."""
    meta = {
        "name": world.name,
        "origin": list(world.origin),
        "params": world.params,
        "parts": [{"name": p.name, "kind": p.kind, "material": p.material.name} for p in world.parts],
    }
    arrays = {"meta": np.array(json.dumps(meta))}
    for i, p in enumerate(world.parts):
        arrays[f"v{i}"] = np.asarray(p.mesh.vertices, dtype=np.float64)
        arrays[f"f{i}"] = np.asarray(p.mesh.faces, dtype=np.int64)
    r = world.route
    arrays |= {"route_xy": r.xy, "route_s": r.s, "route_heading": r.heading, "route_left": r.left_m, "route_right": r.right_m}
    arrays |= {"crown_centre": world.crowns.centre, "crown_radius": world.crowns.radius, "crown_extinction": world.crowns.extinction_per_m}
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, allow_pickle=False, **arrays)  # plain numeric and string arrays: never a pickle
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read(path: Path) -> World:
    """The world stored at `path`; raises on a missing or corrupt entry."""
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        parts = [
            Part(m["name"], m["kind"], MATERIALS[m["material"]], trimesh.Trimesh(data[f"v{i}"], data[f"f{i}"], process=False))
            for i, m in enumerate(meta["parts"])
        ]
        route = Route(xy=data["route_xy"], s=data["route_s"], heading=data["route_heading"], left_m=data["route_left"], right_m=data["route_right"])
        crowns = Crowns(data["crown_centre"], data["crown_radius"], data["crown_extinction"])
    return World(name=meta["name"], parts=parts, route=route, origin=tuple(meta["origin"]), params=meta["params"], crowns=crowns)


def load_or_build(preset: str, params: dict, build) -> World:
    """The cached world for (preset, params), building and storing it when absent or unreadable."""
    path = cache_dir() / f"{preset}-{key(preset, params)}.npz"
    if path.exists():
        try:
            return read(path)
        except Exception:
            pass
    world = build()
    with contextlib.suppress(OSError):  # a read-only or full cache directory only costs the next load a rebuild
        save(world, path)
    return world
