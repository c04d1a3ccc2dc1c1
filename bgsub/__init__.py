"""bgsub: moving-camera background subtraction with a factored gated RBM.

The public Python API; the ``bgsub`` command is a thin layer over it.
"""

__version__ = "0.1.0"

from bgsub.engines import Engine, Param, available_engines, create_engine, register_engine
from bgsub.errors import BgsubError, InputError, ModelError, OutputError, ProcessingError

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
