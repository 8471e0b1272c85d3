"""The vessel's own body: a WAM-V-like catamaran in base_link, which occludes the LiDAR's view."""

from __future__ import annotations

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field


class HullConfig(BaseModel):
    """Dimensions of a 16 ft WAM-V (the field study's class of boat), metres, in base_link."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    length_m: float = Field(4.9, gt=0, description="pontoon length, centred on base_link x")
    beam_m: float = Field(2.4, gt=0, description="outer width across both pontoons")
    pontoon_width_m: float = Field(0.5, gt=0, description="width of each inflatable pontoon")
    pontoon_height_m: float = Field(0.5, gt=0, description="pontoon top above the waterline")
    tray_length_m: float = Field(1.6, gt=0, description="payload tray length")
    tray_width_m: float = Field(1.5, gt=0, description="payload tray width")
    tray_top_m: float = Field(1.0, gt=0, description="payload tray top above the waterline")
    mast_size_m: float = Field(0.12, gt=0, description="square mast section under the LiDAR")


def hull_mesh(cfg: HullConfig, mast_top_m: float) -> trimesh.Trimesh:
    """Pontoons, payload tray and the mast up to `mast_top_m`, in base_link (z up from waterline)."""
    y_pontoon = cfg.beam_m / 2 - cfg.pontoon_width_m / 2
    parts = [
        _box((cfg.length_m, cfg.pontoon_width_m, cfg.pontoon_height_m), (0.0, side * y_pontoon, cfg.pontoon_height_m / 2)) for side in (-1.0, 1.0)
    ]
    tray_bottom = cfg.pontoon_height_m + 0.2
    parts.append(
        _box(
            (cfg.tray_length_m, cfg.tray_width_m, cfg.tray_top_m - tray_bottom),
            (0.0, 0.0, (cfg.tray_top_m + tray_bottom) / 2),
        )
    )
    if mast_top_m > cfg.tray_top_m:
        h = mast_top_m - cfg.tray_top_m
        parts.append(_box((cfg.mast_size_m, cfg.mast_size_m, h), (0.0, 0.0, cfg.tray_top_m + h / 2)))
    hull = trimesh.util.concatenate(parts)
    assert isinstance(hull, trimesh.Trimesh)  # concatenating meshes gives a mesh
    return hull


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float]) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(np.asarray(centre))
    return box
