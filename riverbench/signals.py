"""SIGINT (Ctrl-C) and SIGTERM (`kill`) stop a command the same way: it unwinds, removing its temporaries, and
exits 128 + the signal's number (130, 143: the shells' convention), so nothing hidden or half-written is left.

Python's default SIGTERM ends the process at once, before any `finally` runs: a run killed so used to
leave its hidden temporary run directory behind.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType, TracebackType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """Context manager: the first SIGINT or SIGTERM raises KeyboardInterrupt (so code written for Ctrl-C unwinds as
    it does for Ctrl-C); the ones after it are ignored while the command cleans up (SIGKILL still ends it at once).

    A SIGINT ignored on entry (a background job of a shell without job control) stays ignored. The previous handlers
    come back on exit. Outside the main thread (where Python allows no handlers) it changes nothing.
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    @property
    def exit_code(self) -> int:
        """128 + the signal's number; 130 (Ctrl-C) when the KeyboardInterrupt came from elsewhere."""
        return 128 + (self.signum if self.signum is not None else signal.SIGINT)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum is not None else "SIGINT"

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is None:
            self.signum = signum
            raise KeyboardInterrupt

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is not threading.main_thread():
            return self  # only the main thread may set handlers; there, Python's own behaviour stays
        for sig in STOP_SIGNALS:
            current = signal.getsignal(sig)
            if sig == signal.SIGINT and current == signal.SIG_IGN:
                continue
            self._previous[sig] = current
            signal.signal(sig, self._handle)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
