"""The scenario library (scenarios/spec/library/*.toml) and `scenarios.load`: a name or a TOML path,
`--set` overrides and a seed, validated into a Scenario; any problem is one line naming the file."""

from __future__ import annotations

import tomllib
from pathlib import Path

from pydantic import ValidationError

from riverbench.errors import validation_message
from scenarios.spec import overrides
from scenarios.spec.scenario import Scenario, default_lists

LIBRARY = Path(__file__).resolve().parent / "library"


def available() -> list[str]:
    """Names of the library's scenarios, sorted."""
    return sorted(p.stem for p in LIBRARY.glob("*.toml"))


def path_of(name_or_path: str | Path) -> Path:
    """The TOML file of a library name or a path (ValueError naming it when neither exists)."""
    text = str(name_or_path)
    if text in available():
        return LIBRARY / f"{text}.toml"
    path = Path(text)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ValueError(f"scenario file {text} does not exist")
        return path
    raise ValueError(f"unknown scenario {text!r}; the library has: {', '.join(available())} (or give a .toml path)")


def read(name_or_path: str | Path) -> dict:
    """The raw TOML data of a scenario, mesh-file worlds made absolute (relative to the file)."""
    path = path_of(name_or_path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path.name}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path.name}: cannot read: {exc}") from None
    world = data.get("world")
    if isinstance(world, str) and Path(world).suffix and not Path(world).is_absolute():
        data["world"] = str((path.parent / world).resolve())
    data.setdefault("name", path.stem)
    return data


def load(name_or_path: str | Path, set: list[str] | None = None, seed: int | None = None) -> Scenario:
    """A validated Scenario from a library name or a TOML path, with `--set` overrides and a seed."""
    data = read(name_or_path)
    if set:
        data = {**default_lists(), **data}  # so that --set can reach into the default matchers and estimators
    data = overrides.apply(data, list(set or []))
    if seed is not None:
        data["seed"] = seed
    return validate(data, path_of(name_or_path).name)


FAST_REPLACES = ("stretch", "expect", "goals")
"""What a [fast] table replaces: a --set of these would be silently undone by --fast."""


def load_fast(name_or_path: str | Path, set: list[str] | None = None, seed: int | None = None) -> Scenario:
    """The [fast] variant of a scenario (`run --fast`, `sweep --fast`), ValueError naming the scenario when it has
    none: a full run where a short one was asked for would pass for one. Also refused: a --set of the stretch or
    the expectations, which the [fast] table replaces (set fast.stretch or fast.expect instead). `suite --fast`
    alone runs a scenario without one in full, as the library's baseline was measured."""
    scenario = load(name_or_path, set, seed)
    if scenario.fast is None:
        raise ValueError(f"{scenario.name}: no [fast] variant (its file has no [fast] table); run it without --fast, or add one")
    for assignment in set or []:
        key = assignment.partition("=")[0].strip()
        if key.split(".")[0] in FAST_REPLACES:
            raise ValueError(f"{key}: overridden, but --fast runs the [fast] table's stretch and expectations; override fast.{key} instead")
    return scenario.fast_variant()


def validate(data: dict, source: str = "scenario") -> Scenario:
    """Scenario.model_validate with its errors as one line: 'file: key: message'."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, source)) from None
