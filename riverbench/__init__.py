"""riverbench's ground floor: what every package may import and that imports nothing of ours (version, errors, atomic writes, provenance)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("riverbench")
except PackageNotFoundError:  # run from a source tree without installing
    __version__ = "0+unknown"
