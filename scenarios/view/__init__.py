"""The live view: `riverbench run SCENARIO --view` streams the run to the rerun viewer as it happens.

Rerun (rerun-sdk, the optional `view` extra) rather than Foxglove's WebSocket bridge: a rerun recording
is a file (.rrd) that the same SDK reads back, so tests check what a view carries; it has a native
viewer and a web viewer, a time line to scrub, and needs no server of ours.

Modules: sink (where the view goes: a spawned or running viewer, or a file), world_mesh (the world as
the viewer draws it), layout (the viewer's panels), live (the observer the run calls per scan and fix).
This package imports rerun only when `import_rerun()` or one of its modules is imported, so a run
without --view never loads it.
"""

from __future__ import annotations

from types import ModuleType

INSTALL_HINT = "pip install 'riverbench[view]'"


def import_rerun() -> ModuleType:
    """The rerun module, or a one-line ValueError saying which extra installs it."""
    try:
        import rerun
    except ImportError:
        raise ValueError(f"--view needs the rerun SDK, which is not installed: {INSTALL_HINT}") from None
    return rerun
