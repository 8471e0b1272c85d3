"""Fusion: estimators that fuse GPS fixes with scan-matching odometry, and GPS integrity monitors.

`available()` lists the estimators (built-in, then those installed plugins register);
`create(name, matcher=..., monitor=..., **params)` builds one, `name` also a plugin 'package.module:Class'.
Filters see only what a real boat logs: the receiver's fixes (position, quality, HDOP...) and
the matchers' `MatchResult`s; never the simulator's truth.
"""

from __future__ import annotations

import riverbench  # noqa: F401  (first, before numpy loads: it pins the numeric kernels, riverbench.kernels)

# isort: split

from collections.abc import Callable
from typing import Any

from fusion import monitors
from fusion.ekf import Ekf, EkfParams
from fusion.estimator import Estimator
from fusion.gps_only import GpsOnly, GpsOnlyParams
from fusion.hdop_switch import HdopSwitch, HdopSwitchParams
from fusion.monitors import validate_params
from fusion.params import BaseEstimatorParams, EstimatorParams
from fusion.pf import Pf, PfParams
from fusion.verdict import Event, Verdict
from riverbench import plugins

_ESTIMATORS: dict[str, tuple[Callable[..., Estimator], type[BaseEstimatorParams]]] = {  # (class, its parameter model)
    "gps_only": (GpsOnly, GpsOnlyParams),
    "hdop_switch": (HdopSwitch, HdopSwitchParams),
    "ekf": (Ekf, EkfParams),
    "pf": (Pf, PfParams),
}
GROUP = "riverbench.estimators"
"""The entry-point group in which installed packages register estimators."""


def built_in() -> list[str]:
    """Names of the estimators riverbench ships (a scenario's default stack)."""
    return list(_ESTIMATORS)


def available() -> list[str]:
    """Names create() knows: the built-in estimators, then those installed plugins register."""
    return built_in() + [name for name in plugins.names(GROUP) if name not in _ESTIMATORS]


def params_model(name: str) -> type[BaseEstimatorParams]:
    """The pydantic model of estimator `name`'s parameters (documented defaults); `name` may be 'package.module:Class'."""
    return _ESTIMATORS[name][1] if name in _ESTIMATORS else _plugin(name).Params


def create(name: str, *, templates: monitors.Cn0Templates | None = None, **params) -> Estimator:
    """A fresh estimator by name; unknown names, parameters and monitors raise ValueError naming them. `templates`: the
    receiver's C/N0 templates its monitor shares with the other built-in estimators' that screen its fixes alike
    (monitors.create; a plugin, which may judge fixes its own way, learns its own)."""
    cls = _ESTIMATORS[name][0] if name in _ESTIMATORS else _plugin(name)
    p = validate_params(params_model(name), params, f"estimator '{name}'")
    shared = None
    if templates is not None and name in _ESTIMATORS and isinstance(p, EstimatorParams):
        shared = templates.stream(("dead_reckoning", p.accept_dead_reckoning))
    monitor = monitors.create(p.monitor, templates=shared, **p.monitor_params)
    return cls(p, monitor)


def _plugin(name: str) -> type[Any]:
    """The plugin estimator class `name` names (checked), or a ValueError listing the known names."""
    if not plugins.is_path(name) and name not in plugins.names(GROUP):
        raise ValueError(f"unknown estimator '{name}' (available: {', '.join(available())}, or a plugin 'package.module:Class')")
    return plugins.load(name, GROUP, "estimator", methods=("add_fix", "add_match"), properties=("pose", "cov"), params=BaseEstimatorParams)


__all__ = ["GROUP", "BaseEstimatorParams", "Estimator", "Event", "Verdict", "available", "built_in", "create", "monitors", "params_model"]
