"""Where a live view goes: a rerun viewer (one already listening, else one spawned) and/or a recording file.

A headless machine cannot show a viewer: then the view is saved into the run directory (view.rrd) and
the command line says so in one line. A recording file (--view-save) is written under a temporary name
beside it and renamed when the run finishes, so a failed run leaves no half-written recording.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import socket
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import rerun as rr

from riverbench.atomic import FILE_MODE

DEFAULT_PORT = 9876
"""The gRPC port a rerun viewer listens on by default (`rerun` and rr.spawn use it)."""
FALLBACK_NAME = "view.rrd"
"""The recording in the run directory when --view finds no viewer to show."""
FLUSH_TIMEOUT_S = 30.0
"""How long closing waits for the sinks to take what is queued (a viewer closed mid-run must not hang the run)."""
APPLICATION_ID = "riverbench"
"""The rerun application id: the viewer keeps one layout per application."""


@dataclass(frozen=True)
class ViewTarget:
    """What the user asked for: `viewer` (--view) and/or a recording file `save` (--view-save)."""

    viewer: bool = False
    save: Path | None = None
    port: int = DEFAULT_PORT

    def __post_init__(self) -> None:
        if not self.viewer and self.save is None:
            raise ValueError("a live view needs a viewer or a file to save to")
        if self.save is not None and (Path(self.save).suffix != ".rrd" or Path(self.save).is_dir()):
            raise ValueError(f"--view-save {self.save}: expected a .rrd file name")


def listening(port: int, timeout_s: float = 0.2) -> bool:
    """Whether something accepts connections on 127.0.0.1:port (a viewer already running there)."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout_s):
            return True
    except OSError:
        return False


def viewer_executable() -> str | None:
    """The rerun viewer binary: the one rerun-sdk ships (package rerun_cli), else `rerun` on PATH."""
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        shipped = Path(spec.origin).parent / ("rerun.exe" if sys.platform == "win32" else "rerun")
        if shipped.is_file():
            return str(shipped)
    return shutil.which("rerun")


def no_display() -> bool:
    """True on Linux without an X11 or Wayland display (a native viewer window cannot open)."""
    return sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class ViewSink:
    """The recording stream of one run: `connect()` the viewer before the run, `attach(run_dir)` at its start, `close(keep)` at its end."""

    def __init__(self, target: ViewTarget) -> None:
        self.target = target
        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.viewer_url: str | None = None
        self.fallback = False  # --view found no viewer and no --view-save: the view goes into the run directory
        self._tmp: Path | None = None
        self._closed = False

    def connect(self) -> str | None:
        """Find or spawn the viewer when one was asked for; None when it is there, else why not (the view is then saved)."""
        if not self.target.viewer:
            return None
        port = self.target.port
        why = None
        if not listening(port):
            executable = viewer_executable()
            if executable is None:
                why = "no rerun viewer executable found"
            elif no_display():
                why = "no display: DISPLAY and WAYLAND_DISPLAY are unset"
            else:
                rr.spawn(port=port, connect=False, executable_path=executable)
                why = None if listening(port) else "the spawned viewer did not start"
        if why is None:
            self.viewer_url = f"rerun+http://127.0.0.1:{port}/proxy"
        else:
            self.fallback = self.target.save is None
        return why

    def attach(self, run_dir: Path) -> None:
        """Start the sinks: the viewer, the recording file (under a temporary name), or the run directory's view.rrd."""
        sinks: list = []
        if self.viewer_url is not None:
            sinks.append(rr.GrpcSink(self.viewer_url))
        if self.target.save is not None:
            save = Path(self.target.save)
            save.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{save.name}.", suffix=save.suffix, dir=save.parent)
            os.close(fd)
            self._tmp = Path(tmp)
            sinks.append(rr.FileSink(self._tmp))
        if self.fallback:
            sinks.append(rr.FileSink(Path(run_dir) / FALLBACK_NAME))
        self.rec.set_sinks(*sinks)

    def close(self, keep: bool) -> None:
        """Flush and close every sink; the recording file is renamed into place when `keep`, else deleted."""
        if self._closed:
            return
        self._closed = True
        self.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        self.rec.disconnect()
        if self._tmp is None or self.target.save is None:
            return
        try:
            if keep:
                os.chmod(self._tmp, FILE_MODE)  # mkstemp made it private; an output is for everyone to read
                os.replace(self._tmp, self.target.save)
        finally:
            if self._tmp.exists():
                self._tmp.unlink()
