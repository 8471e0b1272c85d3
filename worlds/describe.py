"""A json-able summary of a world for `riverbench worlds show` and reports."""

from __future__ import annotations

import numpy as np

from worlds.world import World


def describe(world: World) -> dict:
    """Parts and triangles per kind, route length, bounds, origin and the placed structures."""
    kinds: dict[str, dict] = {}
    for p in world.parts:
        entry = kinds.setdefault(p.kind, {"parts": 0, "triangles": 0, "materials": []})
        entry["parts"] += 1
        entry["triangles"] += int(len(p.mesh.faces))
        if p.material.name not in entry["materials"]:
            entry["materials"].append(p.material.name)
    bounds = np.asarray(world.mesh.bounds)
    return {
        "name": world.name,
        "origin": list(world.origin),
        "parts": len(world.parts),
        "triangles": int(sum(len(p.mesh.faces) for p in world.parts)),
        "kinds": dict(sorted(kinds.items())),
        "route_length_m": round(world.route.length, 3),
        "route_width_m": [
            round(float((world.route.left_m + world.route.right_m).min()), 3),
            round(float((world.route.left_m + world.route.right_m).max()), 3),
        ],
        "bounds": {"min": bounds[0].round(3).tolist(), "max": bounds[1].round(3).tolist()},
        "structures": world.params.get("structures", []),
    }
