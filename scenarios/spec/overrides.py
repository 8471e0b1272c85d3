"""`--set key=value` overrides: dotted keys into a scenario's raw TOML data, values typed as TOML."""

from __future__ import annotations

import copy
import json
import re
import tomllib


def parse_value(text: str):
    """A TOML value ('0.03', 'true', '[1, 2]', '"x"'); anything TOML cannot read is taken as a plain string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply(data: dict, assignments: list[str]) -> dict:
    """A copy of `data` with each 'dotted.key=value' set. In lists of tables (matchers, estimators)
    a key segment is an item's id or its index: `matchers.gicp.params.voxel_m=0.5`."""
    data = copy.deepcopy(data)
    for assignment in assignments:
        key, sep, raw = assignment.partition("=")
        key = key.strip()
        if not sep or not key or any(not part for part in key.split(".")):
            raise ValueError(f"--set {assignment!r}: write key=value, e.g. lidar.range_noise_m=0.03")
        _set(data, key.split("."), parse_value(raw.strip()), key)
    return data


def _set(node, parts: list[str], value, key: str) -> None:
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            index = _list_index(node, part, ".".join(parts[:i]), key)
            if last:
                node[index] = value
                return
            node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = value
                return
            node = node.setdefault(part, {})
        else:
            raise ValueError(f"--set {key}: {'.'.join(parts[:i])} is a value, not a table")


def _list_index(items: list, part: str, where: str, key: str) -> int:
    for index, item in enumerate(items):
        if isinstance(item, dict) and item.get("id") == part:
            return index
    if part.isdigit() and int(part) < len(items):
        return int(part)
    ids = [str(item.get("id")) for item in items if isinstance(item, dict)]
    raise ValueError(f"--set {key}: no entry {part!r} in {where} (ids: {', '.join(ids) or 'none'})")


def assignment(key: str, value) -> str:
    """The 'key=value' override that sets `key` to exactly `value` (floats round-trip through TOML)."""
    return f"{key}={to_toml(value)}"


def to_toml(value) -> str:
    """A value as one line of TOML: tables inline, floats in their shortest round-trip form."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_key(k)} = {to_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(to_toml(v) for v in value) + "]"
    import tomli_w

    return tomli_w.dumps({"v": value}).partition("=")[2].strip()


def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)
