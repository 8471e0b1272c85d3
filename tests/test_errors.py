"""riverbench.errors: the one wording of a pydantic validation error."""

from __future__ import annotations

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from riverbench.errors import one_line, validation_message


class Inner(BaseModel):
    model_config = ConfigDict(extra="forbid")
    rate_hz: float = Field(1.0, gt=0)

    @field_validator("rate_hz")
    @classmethod
    def _not_seven(cls, value: float) -> float:
        if value == 7:
            raise ValueError("seven is unlucky")
        return value


class Outer(BaseModel):
    model_config = ConfigDict(extra="forbid")
    inner: Inner = Inner()
    n: int = 0

    @model_validator(mode="after")
    def _whole(self) -> Outer:
        if self.n == 13:
            raise ValueError("n and inner disagree")
        return self


def _error(data: dict) -> ValidationError:
    with pytest.raises(ValidationError) as info:
        Outer.model_validate(data)
    return info.value


@pytest.mark.parametrize(
    ("data", "line"),
    [
        ({"inner": {"rate_hz": -1}}, "f.toml: inner.rate_hz: Input should be greater than 0"),
        ({"inner": {"bogus": 1}}, "f.toml: unknown key 'inner.bogus'"),
        ({"inner": {"rate_hz": 7}}, "f.toml: inner.rate_hz: seven is unlucky"),
        ({"n": 13}, "f.toml: n and inner disagree"),
        ({"inner": {"rate_hz": -1}, "n": "x", "extra": 1}, "f.toml: inner.rate_hz: Input should be greater than 0 (and 2 more)"),
    ],
)
def test_a_validation_error_is_one_line_naming_where_the_key_and_the_problem(data, line):
    assert validation_message(_error(data), "f.toml") == line


def test_one_line_words_a_validation_error_the_same_way_with_the_models_name():
    assert one_line(_error({"inner": {"bogus": 1}})) == "Outer: unknown key 'inner.bogus'"
    assert one_line(ValueError("bad\nsecond line")) == "bad"
