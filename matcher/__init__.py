"""Scan matchers under test (pcl6d, bev3dof, kiss_icp, gicp, and plugins) and the point-count scan gate."""

from __future__ import annotations

import riverbench  # noqa: F401  (first, before numpy loads: it pins the numeric kernels, riverbench.kernels)

# isort: split

from importlib import import_module
from typing import Any

from pydantic import BaseModel, ValidationError

from matcher.base import Matcher, MatcherParams
from matcher.result import MatchResult
from riverbench import plugins
from riverbench.errors import validation_message

_MATCHERS = {
    "pcl6d": ("matcher.pcl6d", "Pcl6d", "Pcl6dParams"),
    "bev3dof": ("matcher.bev3dof", "Bev3dof", "Bev3dofParams"),
    "kiss_icp": ("matcher.kiss", "KissIcp", "KissIcpParams"),
    "gicp": ("matcher.gicp", "Gicp", "GicpParams"),
}
GROUP = "riverbench.matchers"
"""The entry-point group in which installed packages register matchers."""

__all__ = ["GROUP", "MatchResult", "Matcher", "MatcherParams", "available", "create", "params_model"]


def available() -> list[str]:
    """Names accepted by `create`: the built-in matchers, then those installed plugins register."""
    return list(_MATCHERS) + [name for name in plugins.names(GROUP) if name not in _MATCHERS]


def params_model(name: str) -> type[BaseModel]:
    """The pydantic model of matcher `name`'s parameters (documented defaults); `name` may be 'package.module:Class'."""
    if name in _MATCHERS:
        module, _, model = _MATCHERS[name]
        return getattr(import_module(module), model)
    return _plugin(name).Params


def create(name: str, **params) -> Matcher:
    """A fresh matcher `name` (or 'package.module:Class') with `params`; an unknown name or a bad parameter is a ValueError naming it."""
    model = params_model(name)
    try:
        validated = model(**params)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, f"matcher {name!r}")) from None
    if name in _MATCHERS:
        module, cls, _ = _MATCHERS[name]
        return getattr(import_module(module), cls)(validated)
    return _plugin(name)(validated)


def _plugin(name: str) -> type[Any]:
    """The plugin matcher class `name` names (checked), or a ValueError listing the known names."""
    if not plugins.is_path(name) and name not in plugins.names(GROUP):
        raise ValueError(f"unknown matcher {name!r} (one of {', '.join(available())}, or a plugin 'package.module:Class')")
    return plugins.load(name, GROUP, "matcher", methods=("register",))
