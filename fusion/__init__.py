"""Fusion: estimators that fuse GPS fixes with scan-matching odometry, and GPS integrity monitors.

`available()` lists the estimators; `create(name, matcher=..., monitor=..., **params)` builds one.
Filters see only what a real boat logs: the receiver's fixes (position, quality, HDOP...) and
the matchers' `MatchResult`s; never the simulator's truth.
"""

from __future__ import annotations

from pydantic import BaseModel

from fusion import monitors
from fusion.ekf import Ekf, EkfParams
from fusion.estimator import Estimator
from fusion.gps_only import GpsOnly, GpsOnlyParams
from fusion.hdop_switch import HdopSwitch, HdopSwitchParams
from fusion.monitors import validate_params
from fusion.pf import Pf, PfParams
from fusion.verdict import Event, Verdict

_ESTIMATORS: dict[str, tuple[type[Estimator], type[BaseModel]]] = {
    "gps_only": (GpsOnly, GpsOnlyParams),
    "hdop_switch": (HdopSwitch, HdopSwitchParams),
    "ekf": (Ekf, EkfParams),
    "pf": (Pf, PfParams),
}


def available() -> list[str]:
    """Names of the estimators create() knows."""
    return list(_ESTIMATORS)


def params_model(name: str) -> type[BaseModel]:
    """The pydantic model of estimator `name`'s parameters (documented defaults)."""
    if name not in _ESTIMATORS:
        raise ValueError(f"unknown estimator '{name}' (available: {', '.join(available())})")
    return _ESTIMATORS[name][1]


def create(name: str, **params) -> Estimator:
    """A fresh estimator by name; unknown names, parameters and monitors raise ValueError naming them."""
    if name not in _ESTIMATORS:
        raise ValueError(f"unknown estimator '{name}' (available: {', '.join(available())})")
    cls = _ESTIMATORS[name][0]
    p = validate_params(params_model(name), params, f"estimator '{name}'")
    monitor = monitors.create(p.monitor, **p.monitor_params)
    return cls(p, monitor)


__all__ = ["Estimator", "Event", "Verdict", "available", "create", "monitors", "params_model"]
