"""Parameter validation that ends in one clear line naming the offending key."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from riverbench.errors import validation_message

ModelT = TypeVar("ModelT", bound=BaseModel)


def validate(model: type[ModelT], data: Any, where: str) -> ModelT:
    """`model.model_validate(data)`, re-raising a pydantic error as a one-line ValueError."""
    if isinstance(data, model):
        return data
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, where)) from None
