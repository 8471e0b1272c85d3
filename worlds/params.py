"""Parameter validation that ends in one clear line naming the offending key."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)


def validate(model: type[ModelT], data: Any, where: str) -> ModelT:
    """`model.model_validate(data)`, re-raising a pydantic error as a one-line ValueError."""
    if isinstance(data, model):
        return data
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(p) for p in err["loc"]) or "(root)"
        if err["type"] == "extra_forbidden":
            raise ValueError(f"{where}: unknown parameter {key!r}") from None
        raise ValueError(f"{where}: {key}: {err['msg']} (got {err.get('input')!r})") from None
