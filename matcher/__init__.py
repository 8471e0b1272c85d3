"""Scan matchers under test (pcl6d, bev3dof, kiss_icp, gicp) and the point-count scan gate."""

from __future__ import annotations

from importlib import import_module

from pydantic import ValidationError

from matcher.base import Matcher, MatcherParams
from matcher.result import MatchResult

_MATCHERS = {
    "pcl6d": ("matcher.pcl6d", "Pcl6d", "Pcl6dParams"),
    "bev3dof": ("matcher.bev3dof", "Bev3dof", "Bev3dofParams"),
    "kiss_icp": ("matcher.kiss", "KissIcp", "KissIcpParams"),
    "gicp": ("matcher.gicp", "Gicp", "GicpParams"),
}

__all__ = ["MatchResult", "Matcher", "MatcherParams", "available", "create", "params_model"]


def available() -> list[str]:
    """Names accepted by `create`."""
    return list(_MATCHERS)


def params_model(name: str) -> type[MatcherParams]:
    """The pydantic model of matcher `name`'s parameters (documented defaults)."""
    if name not in _MATCHERS:
        raise ValueError(f"unknown matcher {name!r} (one of {', '.join(_MATCHERS)})")
    module, _, model = _MATCHERS[name]
    return getattr(import_module(module), model)


def create(name: str, **params) -> Matcher:
    """A fresh matcher `name` with `params`; an unknown name or a bad parameter is a ValueError naming it."""
    model = params_model(name)
    try:
        validated = model(**params)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or '?'}: {e['msg']}" for e in exc.errors())
        raise ValueError(f"matcher {name!r}: bad parameter {problems}") from None
    module, cls, _ = _MATCHERS[name]
    return getattr(import_module(module), cls)(validated)
