"""GPS integrity monitors: hdop (baseline), nis, consistency, cn0, shadow, combined, combined_cn0, combined_shadow, none, and plugins."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from fusion.monitors.base import FixContext, Monitor
from fusion.monitors.cn0 import Cn0Monitor, Cn0Params, Cn0Templates
from fusion.monitors.combined import CombinedCn0Params, CombinedMonitor, CombinedParams, CombinedShadowParams
from fusion.monitors.consistency import ConsistencyMonitor, ConsistencyParams
from fusion.monitors.hdop import HdopMonitor, HdopParams
from fusion.monitors.nis import NisMonitor, NisParams
from fusion.monitors.none import NoMonitor, NoneParams
from fusion.monitors.shadow import ShadowMonitor, ShadowParams
from riverbench import plugins
from riverbench.errors import validation_message

_MONITORS: dict[str, tuple[Callable[..., Monitor], type[BaseModel]]] = {  # (class, its parameter model)
    "hdop": (HdopMonitor, HdopParams),
    "nis": (NisMonitor, NisParams),
    "consistency": (ConsistencyMonitor, ConsistencyParams),
    "cn0": (Cn0Monitor, Cn0Params),
    "combined": (CombinedMonitor, CombinedParams),
    "combined_cn0": (CombinedMonitor, CombinedCn0Params),
    "combined_shadow": (CombinedMonitor, CombinedShadowParams),
    "none": (NoMonitor, NoneParams),
    "shadow": (ShadowMonitor, ShadowParams),
}
GROUP = "riverbench.monitors"
"""The entry-point group in which installed packages register monitors."""

M = TypeVar("M", bound=BaseModel)


def available() -> list[str]:
    """Names create() knows: the built-in monitors, then those installed plugins register."""
    return sorted(_MONITORS) + [name for name in plugins.names(GROUP) if name not in _MONITORS]


def validate_params(model: type[M], params: dict, what: str) -> M:
    """Validate params with a pydantic model; a bad key or value is a one-line ValueError naming it."""
    try:
        return model(**params)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, what)) from None


def params_model(name: str) -> type[BaseModel]:
    """The pydantic model of monitor `name`'s parameters; `name` may be 'package.module:Class'."""
    return _MONITORS[name][1] if name in _MONITORS else _plugin(name).Params


def validated(name: str, params: dict) -> BaseModel:
    """Monitor `name`'s parameters validated, a combined monitor's members and their parameters with them, so that a
    scenario can be checked before anything runs; a bad name, key or value is a one-line ValueError naming it."""
    p = validate_params(params_model(name), params, f"monitor '{name}'")
    if isinstance(p, CombinedParams) and name in _MONITORS:
        nested = [m for m in p.members if m in _MONITORS and _MONITORS[m][0] is CombinedMonitor]
        if nested:
            raise ValueError(f"monitor '{name}': parameter 'members' cannot contain '{nested[0]}'")
        unknown = set(p.member_params) - set(p.members)
        if unknown:
            raise ValueError(f"monitor '{name}': parameter 'member_params' names a non-member '{sorted(unknown)[0]}'")
        for member in p.members:
            validated(member, p.member_params.get(member, {}))
    return p


def create(name: str, *, templates: Cn0Templates | None = None, **params) -> Monitor:
    """A fresh monitor by name; unknown names and parameters raise ValueError naming them. `templates`: the C/N0
    templates learned from the receiver whose fixes it judges, shared with the other monitors judging them (None: a
    cn0 monitor learns its own; the verdicts are the same, the learning is done once per fix when shared)."""
    cls = _MONITORS[name][0] if name in _MONITORS else _plugin(name)
    p = validated(name, params)
    if isinstance(p, CombinedParams) and cls is CombinedMonitor:
        return CombinedMonitor(p, [create(m, templates=templates, **p.member_params.get(m, {})) for m in p.members])
    if isinstance(p, Cn0Params) and cls is Cn0Monitor:
        return Cn0Monitor(p, templates.get(p) if templates is not None else None)
    return cls(p)


def _plugin(name: str) -> type[Any]:
    """The plugin monitor class `name` names (checked), or a ValueError listing the known names."""
    if not plugins.is_path(name) and name not in plugins.names(GROUP):
        raise ValueError(f"unknown monitor '{name}' (available: {', '.join(available())}, or a plugin 'package.module:Class')")
    return plugins.load(name, GROUP, "monitor", methods=("check", "commit", "reset", "note_outage"))


__all__ = ["GROUP", "Cn0Templates", "FixContext", "Monitor", "available", "create", "params_model", "validate_params", "validated"]
