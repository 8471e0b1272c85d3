"""Turn any bad-input exception into the one line a user sees."""

from __future__ import annotations

from pydantic import ValidationError


def validation_message(exc: ValidationError, where: str) -> str:
    """A pydantic error as one line: '{where}: {key}: {message}', key the dotted path of the offending field.

    An extra (forbidden) key reads '{where}: unknown key '{key}''; an error of the model as a whole (no
    key) '{where}: {message}'. pydantic's 'Value error, ' prefix is dropped. When several fields are
    wrong, the line names the first and counts the others: ' (and N more)'.
    """
    errors = exc.errors()
    if not errors:  # pydantic never raises an empty ValidationError; keep a line anyway
        return f"{where}: {exc.title}: invalid"
    first = errors[0]
    key = ".".join(str(part) for part in first["loc"])
    if first["type"] == "extra_forbidden":
        line = f"{where}: unknown key '{key}'"
    else:
        message = " ".join(str(first["msg"]).removeprefix("Value error, ").splitlines())
        line = f"{where}: {key}: {message}" if key else f"{where}: {message}"
    return line + (f" (and {len(errors) - 1} more)" if len(errors) > 1 else "")


def one_line(exc: BaseException) -> str:
    """A single line naming what is wrong: a pydantic error as validation_message words it, where = the model's name."""
    if isinstance(exc, ValidationError):
        return validation_message(exc, exc.title)
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
