"""Plugins: matcher, estimator and monitor classes from outside riverbench, by path or entry point.

A plugin is named 'package.module:Class' (importable: installed or on PYTHONPATH) or by the name an
installed package registers in an entry-point group (riverbench.matchers, riverbench.estimators,
riverbench.monitors). Its class carries its parameter model as the pydantic class attribute
`Params`. Loading checks the class; anything wrong (it does not import, is not a class, lacks a
method, has no Params) is one ValueError line naming the plugin. Entry points are looked up on
every call, never cached, so a package installed meanwhile is seen.
"""

from __future__ import annotations

import inspect
from importlib import import_module
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from pydantic import BaseModel

PATH_PATTERN = r"^[A-Za-z_][A-Za-z0-9_.]*:[A-Za-z_][A-Za-z0-9_.]*$"
"""A 'package.module:Class' reference (for the JSON Schema)."""


def is_path(ref: str) -> bool:
    """True for a 'package.module:Class' reference, False for a plain name."""
    return ":" in ref


def names(group: str) -> list[str]:
    """The names installed packages register in entry-point group `group`, sorted."""
    return sorted({ep.name for ep in entry_points(group=group)})


def load(
    ref: str, group: str, what: str, methods: tuple[str, ...], properties: tuple[str, ...] = (), params: type[BaseModel] = BaseModel
) -> type[Any]:
    """The class `ref` names ('package.module:Class' or an entry-point name in `group`), checked to have
    every method and property listed and a `Params` model subclassing `params`."""
    where = f"{what} plugin {ref!r}"
    cls = _import_path(ref, where) if is_path(ref) else _import_entry_point(ref, group, where)
    if not inspect.isclass(cls):
        raise ValueError(f"{where}: is not a class but a {type(cls).__name__}")
    missing = [f"method {m!r}" for m in methods if not callable(getattr(cls, m, None))]
    missing += [f"property {p!r}" for p in properties if not hasattr(cls, p)]
    if missing:
        raise ValueError(f"{where}: class {cls.__name__} lacks {', '.join(missing)}")
    if inspect.isabstract(cls):
        abstract = sorted(getattr(cls, "__abstractmethods__", ()))
        raise ValueError(f"{where}: class {cls.__name__} is abstract: it does not implement {', '.join(abstract)}")
    model = getattr(cls, "Params", None)
    if not (inspect.isclass(model) and issubclass(model, params)):
        raise ValueError(f"{where}: class {cls.__name__} lacks a parameter model: a class attribute Params subclassing {params.__name__}")
    return cls


def _import_path(ref: str, where: str) -> Any:
    """What 'package.module:Class' names (nested names with dots)."""
    module_name, _, qualname = ref.partition(":")
    try:
        found = import_module(module_name)
    except Exception as exc:  # a plugin's import may raise anything: report it as one line
        raise ValueError(
            f"{where}: cannot import {module_name!r}: {type(exc).__name__}: {exc} (a plugin must be installed or on PYTHONPATH)"
        ) from None
    for part in qualname.split("."):
        if not hasattr(found, part):
            raise ValueError(f"{where}: module {module_name!r} has no {qualname!r}")
        found = getattr(found, part)
    return found


def _import_entry_point(name: str, group: str, where: str) -> Any:
    """What the entry point `name` of `group` names; two packages registering it differently is an error."""
    found: dict[str, EntryPoint] = {ep.value: ep for ep in entry_points(group=group, name=name)}
    if not found:
        raise ValueError(f"{where}: no installed package registers {name!r} in entry-point group {group!r}")
    if len(found) > 1:
        raise ValueError(f"{where}: registered more than once in {group!r}: {', '.join(sorted(found))}")
    (entry,) = found.values()
    try:
        return entry.load()
    except Exception as exc:  # a plugin's import may raise anything: report it as one line
        raise ValueError(f"{where}: cannot import {entry.value!r}: {type(exc).__name__}: {exc}") from None
