"""UNIX time of the bench's clock, one conversion for every file handed to other tools (TUM, ROS bags, pcaps).

Inside the code time is float64 seconds since the scenario's time 0. The scenario's `[gnss] epoch_utc`
is the UTC date and time of that time 0: civil UTC, as NMEA's GGA/RMC times are, not GPS time. UNIX
(POSIX) time counts UTC seconds since 1970-01-01T00:00:00Z as if every day had 86,400 s, i.e. without
leap seconds, and so does Python's datetime arithmetic: the UNIX time of an aware UTC datetime is its
difference to `UNIX_EPOCH`, with no leap-second table needed. GPS time has no leap seconds either but
started on 1980-01-06 UTC and has run ahead of UTC by every leap second since (`GPS_MINUS_UTC_S`, 18 s
since 2017-01-01): an epoch read off a receiver in GPS time must lose those 18 s before it is a UTC
`epoch_utc`, else every UNIX stamp would be 18 s late. A run never crosses a leap second's insertion
(the bench's epochs lie in 2024, the last leap second was 2016-12-31) so seconds since time 0 simply add.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np

UNIX_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
"""Time 0 of UNIX time."""
GPS_MINUS_UTC_S = 18
"""GPS time minus UTC since 2017-01-01 (IERS Bulletin C 52; no leap second announced since): GPS time = UTC + 18 s."""
NS_PER_S = 1_000_000_000


def unix_ns(when: datetime) -> int:
    """Integer nanoseconds since the UNIX epoch of an aware datetime (datetimes carry microseconds, so exact)."""
    if when.tzinfo is None:
        raise ValueError(f"time {when.isoformat()} has no time zone (give UTC, e.g. {when.isoformat()}Z)")
    return (when - UNIX_EPOCH) // timedelta(microseconds=1) * 1000


def scenario_unix_ns(epoch_utc: datetime, seconds: float) -> int:
    """UNIX nanoseconds of scenario time `seconds` (since the scenario's time 0, whose UTC time is `epoch_utc`)."""
    return unix_ns(epoch_utc) + round(seconds * 1e9)


def on_ns_grid(seconds: np.ndarray) -> np.ndarray:
    """Scenario seconds rounded to whole nanoseconds (`k / 1e9`), the float a ROS stamp or TUM line gives back exactly.

    A run's scan and fix times are put on this grid so that a run exported to a bag (integer ns) and replayed sees
    bit-identical times: off the grid they differ by up to 0.5 ns, which pf resampling and gicp's thresholds
    amplify to metres (issue 22).
    """
    return np.round(np.asarray(seconds, dtype=np.float64) * 1e9) / 1e9


def seconds_text(ns: int) -> str:
    """UNIX nanoseconds as exact decimal seconds with 9 digits ('1718460000.123456789'), for text files."""
    sign = "-" if ns < 0 else ""
    whole, fraction = divmod(abs(int(ns)), NS_PER_S)
    return f"{sign}{whole}.{fraction:09d}"


def parse_seconds_ns(text: str) -> int:
    """Decimal seconds as written by `seconds_text` (or any '[-]digits[.digits]') as integer nanoseconds, exactly."""
    body = text.strip()
    sign = -1 if body.startswith("-") else 1
    whole, _, fraction = body.lstrip("+-").partition(".")
    if not (whole or fraction) or not (whole or "0").isdigit() or (fraction and not fraction.isdigit()):
        raise ValueError(f"{text!r} is not a decimal number of seconds")
    digits = (fraction + "0" * 9)[:9]
    ns = int(whole or "0") * NS_PER_S + int(digits)
    if len(fraction) > 9 and int(fraction[9]) >= 5:
        ns += 1
    return sign * ns
