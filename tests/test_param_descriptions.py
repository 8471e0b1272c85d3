"""Every parameter a user can set is documented in its model: each property of each parameter model's JSON
schema (nested models included) has a non-empty description, for every registered matcher, estimator and
monitor kind and for sim's models."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest
from pydantic import BaseModel

import fusion
import fusion.monitors
import matcher
import sim


def _sim_models() -> dict[str, type[BaseModel]]:
    """Every pydantic model defined in a module of sim/."""
    found: dict[str, type[BaseModel]] = {}
    for info in pkgutil.iter_modules(sim.__path__):
        module = importlib.import_module(f"sim.{info.name}")
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and issubclass(obj, BaseModel) and obj.__module__ == module.__name__:
                found[f"sim.{info.name}.{name}"] = obj
    return found


MODELS: dict[str, type[BaseModel]] = {
    **{f"matcher {k}": matcher.params_model(k) for k in matcher.available()},
    **{f"estimator {k}": fusion.params_model(k) for k in fusion.available()},
    **{f"monitor {k}": fusion.monitors.params_model(k) for k in fusion.monitors.available()},
    **_sim_models(),
}


def _undocumented(schema: dict) -> list[str]:
    """Properties of the schema and of its $defs without a non-empty description."""
    missing = [p for p, spec in schema.get("properties", {}).items() if not str(spec.get("description", "")).strip()]
    for name, sub in schema.get("$defs", {}).items():
        missing += [f"{name}.{p}" for p in _undocumented(sub)]
    return missing


def test_the_registries_and_sim_are_covered():
    assert {"matcher gicp", "estimator ekf", "estimator pf", "monitor cn0", "sim.gnss.GnssConfig", "sim.lidar.HDL32EConfig"} <= set(MODELS)


@pytest.mark.parametrize("what", sorted(MODELS))
def test_every_parameter_has_a_description(what):
    assert _undocumented(MODELS[what].model_json_schema()) == [], f"{what}: parameters without a description"
