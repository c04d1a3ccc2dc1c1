"""bgsub: moving-camera background subtraction with a factored gated RBM.

The public Python API; the ``bgsub`` command is a thin layer over it.
"""

__version__ = "0.1.0"

from typing import Any

from bgsub.errors import BgsubError, InputError, ModelError, OutputError, ProcessingError

_ENGINE_API = ("Engine", "Param", "available_engines", "create_engine", "register_engine")


def __getattr__(name: str) -> Any:
    # The engine API (numpy, OpenCV) loads on first use: `bgsub --help` starts fast, and a
    # Ctrl-C while the command starts is the CLI's clean "interrupted", not a traceback.
    if name in _ENGINE_API:
        from bgsub import engines

        return getattr(engines, name)
    raise AttributeError(f"module 'bgsub' has no attribute {name!r}")


def __dir__() -> list:
    # dir() and help() list the lazy engine API too (without importing it).
    return sorted(set(globals()) | set(_ENGINE_API))


__all__ = [
    "__version__",
    "Engine",
    "Param",
    "available_engines",
    "create_engine",
    "register_engine",
    "BgsubError",
    "InputError",
    "ModelError",
    "OutputError",
    "ProcessingError",
]
