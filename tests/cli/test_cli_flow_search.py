"""``bgsub flow`` plans its coarsest-level search and says its reach as ``estimate_flow`` reads.

The CLI widens ``search`` until the pyramid reaches ``--max-motion`` and warns in its own words
(``warn_range=False``) when even the widest does not: its search and reach must be those of the
pyramid ``estimate_flow`` builds for the same frame, or it would stay silent about misread
motions, or warn about motions that are read.
"""

from __future__ import annotations

import argparse
import re
import warnings

import numpy as np
import pytest

from bgsub.cli.flow import _MAX_SEARCH, _search_for
from bgsub.motion import FlowConfig
from bgsub.motion.flowfield import MotionRangeWarning, estimate_flow


class _StillModel:
    """Reads no motion anywhere (test double): only the pyramid planning matters here."""

    def __init__(self, max_disp: int) -> None:
        self.patch_size = 13
        self.meta = {"max_disp": max_disp}

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        n = len(x_raw)
        return np.zeros((n, 2), np.float32), np.ones(n, np.float32), np.zeros(n, bool)


def _flow_reach(frame: np.ndarray, model: _StillModel, max_motion: float, search: int):
    """``estimate_flow``'s (levels, reach when max_motion is beyond it, else None)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MotionRangeWarning)
        config = FlowConfig(max_motion=max_motion, search=search, stride=32, max_patches=8)
        flow = estimate_flow(frame, frame, config, model=model)
    said = [str(w.message) for w in caught if issubclass(w.category, MotionRangeWarning)]
    assert len(said) <= 1
    reach = int(re.search(r"up to about (\d+) px", said[0]).group(1)) if said else None
    return flow.levels, reach


def _cli_search(shape, model: _StillModel, max_motion: float, capsys):
    """``bgsub flow``'s (search, reach when --max-motion is beyond it, else None)."""
    args = argparse.Namespace(levels=None, max_motion=max_motion)
    search = _search_for(shape, model, args)
    said = capsys.readouterr().err
    match = re.search(r"motions above about (\d+) px are misread", said)
    assert bool(match) == bool(said), said
    return search, int(match.group(1)) if match else None


@pytest.mark.parametrize("shape", [(60, 80), (120, 160), (240, 320), (480, 640), (90, 1000)])
@pytest.mark.parametrize("max_disp", [3, 4])
def test_the_cli_search_and_reach_are_those_of_estimate_flow(shape, max_disp, capsys):
    model = _StillModel(max_disp)
    frame = np.random.default_rng(0).integers(0, 256, shape, dtype=np.uint8)
    for max_motion in (1, 2.5, 4, 7, 12, 20, 24, 60, 400):
        search, cli_reach = _cli_search(shape, model, max_motion, capsys)
        levels, flow_reach = _flow_reach(frame, model, max_motion, search)
        where = (shape, max_disp, max_motion, search)
        # The same reach out of range (the CLI's warning names the number estimate_flow's does),
        # and none where estimate_flow reads the whole range.
        assert cli_reach == flow_reach, where
        assert search <= _MAX_SEARCH and (search == 0 or levels > 1), where
        if search > FlowConfig().search and cli_reach is None:
            # The smallest search that reaches: one ring less is out of reach for estimate_flow.
            assert _flow_reach(frame, model, max_motion, search - 1)[1] is not None, where
        if search < _MAX_SEARCH and cli_reach is not None and levels > 1:
            # Out of reach only at the widest search the CLI allows.
            pytest.fail(f"the CLI stopped short of its widest search: {where}")
