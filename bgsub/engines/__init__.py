"""Engines: every background subtractor behind OpenCV's ``BackgroundSubtractor`` shape, and the
registry that names them (``bgsub methods`` lists it)."""

from bgsub.engines.base import (  # noqa: F401
    CAPABILITIES,
    DEFAULT_METHOD,
    LEARNING_RATE,
    Engine,
    EngineSpec,
    Param,
    available_engines,
    check_fgmask,
    check_frame,
    check_learning_rate,
    create_engine,
    default_method,
    get_engine_spec,
    opencv_keywords,
    parse_params,
    register_engine,
    supports,
)
