"""The JSON Schema of a scenario file: the pydantic models' schema, with each free `params` table
bound to its kind's own parameter model (if kind == X then params follows X's model), so an
editor completes and checks every key of every matcher, estimator, monitor and world preset,
installed plugins' registered names included (a `plugin = 'package.module:Class'` table is free)."""

from __future__ import annotations

from pydantic import BaseModel

import fusion
import fusion.monitors
import matcher
import worlds
from riverbench.plugins import PATH_PATTERN
from scenarios.spec.scenario import Scenario
from worlds.presets import PRESETS

_SET_ON_THE_ESTIMATOR = ("matcher", "monitor", "monitor_params", "seed")  # EstimatorSpec fields or the scenario seed, not params


def _add_model(defs: dict, model: type[BaseModel], drop: tuple[str, ...] = ()) -> dict:
    """Put `model`'s schema (and its sub-models) into `defs`; a $ref to it (a plugin's `Params` named by its full path)."""
    schema = model.model_json_schema(ref_template="#/$defs/{model}")
    defs.update(schema.pop("$defs", {}))
    for key in drop:
        schema["properties"].pop(key, None)
        if key in schema.get("required", []):
            schema["required"].remove(key)
    name = model.__name__ if model.__name__ not in defs else f"{model.__module__}.{model.__qualname__}"
    defs[name] = schema
    return {"$ref": f"#/$defs/{name}"}


def _kind_or_plugin(spec: dict, kinds: list[str]) -> None:
    """A matcher or estimator table names exactly one of kind (a registered name) and plugin (a class path)."""
    spec["properties"]["kind"] = {"enum": kinds, "description": spec["properties"]["kind"].get("description", "")}
    spec["properties"]["plugin"] = {"type": "string", "pattern": PATH_PATTERN, "description": spec["properties"]["plugin"].get("description", "")}
    spec["required"] = [key for key in spec.get("required", []) if key != "kind"]
    spec["oneOf"] = [{"required": ["kind"]}, {"required": ["plugin"]}]


def _by_kind(selector: str, table: str, models: dict[str, dict]) -> list[dict]:
    """if <selector> == kind then <table> follows that kind's model; one clause per kind."""
    return [
        {"if": {"properties": {selector: {"const": kind}}, "required": [selector]}, "then": {"properties": {table: ref}}}
        for kind, ref in models.items()
    ]


def scenario_json_schema() -> dict:
    """The scenario file's JSON Schema (draft 2020-12), every parameter table typed by its kind."""
    schema = Scenario.model_json_schema(ref_template="#/$defs/{model}")
    if "name" in schema.get("required", []):  # a file's name defaults to its stem (scenarios.spec.library.read)
        schema["required"].remove("name")
    defs = schema.setdefault("$defs", {})
    matchers = {k: _add_model(defs, matcher.params_model(k)) for k in matcher.available()}
    estimators = {k: _add_model(defs, fusion.params_model(k), _SET_ON_THE_ESTIMATOR) for k in fusion.available()}
    monitors = {k: _add_model(defs, fusion.monitors.params_model(k)) for k in fusion.monitors.available()}
    presets = {k: _add_model(defs, PRESETS[k][0]) for k in worlds.available()}

    spec = defs["MatcherSpec"]
    _kind_or_plugin(spec, list(matchers))
    spec["allOf"] = _by_kind("kind", "params", matchers)
    spec = defs["EstimatorSpec"]
    _kind_or_plugin(spec, list(estimators))
    spec["properties"]["monitor"] = {
        "anyOf": [{"enum": list(monitors)}, {"type": "string", "pattern": PATH_PATTERN}],
        "description": spec["properties"]["monitor"].get("description", ""),
    }
    spec["allOf"] = _by_kind("kind", "params", estimators) + _by_kind("monitor", "monitor_params", monitors)
    schema["allOf"] = _by_kind("world", "world_params", presets)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema
