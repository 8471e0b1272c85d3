"""Turn any bad-input exception into the one line a user sees."""

from __future__ import annotations

from pydantic import ValidationError


def one_line(exc: BaseException) -> str:
    """A single line naming what is wrong: pydantic errors as 'key: message; ...'."""
    if isinstance(exc, ValidationError):
        parts = []
        for err in exc.errors():
            key = ".".join(str(p) for p in err["loc"]) or exc.title
            parts.append(f"{key}: {err['msg']}")
        return f"{exc.title}: " + "; ".join(parts)
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
