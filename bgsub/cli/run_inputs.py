"""Options of ``bgsub run`` about what goes in: how much of a live source (``--max-frames``,
``--stall-timeout``), where to look (``--roi``), the camera motion when it is known
(``--motion-in``) and the grbm model (``--model``). Each is checked before any frame is read."""

from __future__ import annotations

import argparse
import os
from typing import Any, Dict, List, Optional

from bgsub.errors import InputError


def add_options(parser: argparse.ArgumentParser) -> None:
    from bgsub.io.streams import DEFAULT_STALL_SECONDS

    parser.add_argument("--model", default=None, metavar="M",
                        help="grbm's model: a shipped name or an .npz path")
    parser.add_argument("--roi", metavar="MASK.png", default=None,
                        help="no foreground outside the mask's white pixels")
    parser.add_argument("--motion-in", metavar="FILE.npy", default=None,
                        help="a known camera motion, as --motion writes it")
    group = next(g for g in parser._action_groups if g.title == "input frames")
    group.add_argument("--max-frames", type=int, default=None, metavar="N",
                       help="process at most N frames")
    group.add_argument("--stall-timeout", type=float, default=None, metavar="S",
                       help=f"stop a live source silent for S s (default: "
                            f"{DEFAULT_STALL_SECONDS:g})")


def apply_max_frames(args: argparse.Namespace) -> None:
    """Fold ``--max-frames`` into ``--stop`` (the frame range every input takes)."""
    if args.max_frames is None:
        return
    if args.max_frames < 1:
        raise InputError(f"--max-frames takes a number >= 1, not {args.max_frames}")
    stop = args.start + args.max_frames * max(args.step, 1)
    args.stop = stop if args.stop is None else min(args.stop, stop)


def engine_params(args: argparse.Namespace, method: str, params: Dict[str, Any]) -> Dict[str, Any]:
    """``params`` with ``--model``, ``--roi`` and ``--motion-in`` added as the engine
    parameters they stand for (``model``, ``roi``, ``known_motion``); each refused for a method
    without that parameter, or when ``--param`` gives it too."""
    from bgsub.engines import get_engine_spec

    spec = get_engine_spec(method)
    params = dict(params)
    for flag, name, value in (("--model", "model", args.model), ("--roi", "roi", args.roi),
                              ("--motion-in", "known_motion", args.motion_in)):
        if value is None:
            continue
        if name not in spec.params:
            raise InputError(f"{flag}: method {method!r} has no {name} (use a moving-camera "
                             "method such as grbm)" if flag != "--model" else
                             f"--model: method {method!r} takes no model (grbm does)")
        if name in params:
            raise InputError(f"{flag} and --param {name}= (or --config) both set it; give one")
        params[name] = spec.params[name].parse(name, value)
    return params


def input_files(args: argparse.Namespace, params: Dict[str, Any]) -> List[str]:
    """The files a run reads besides its input (``--config``, and the model, region of
    interest and known camera motion when given as files): no output may replace them."""
    from bgsub.cli.common import model_files

    files = [args.config] if args.config else []
    model = params.get("model")
    if isinstance(model, str):
        files += model_files(model)
    files += [params[name] for name in ("roi", "known_motion")
              if isinstance(params.get(name), (str, os.PathLike))]
    return files


def check_inputs(params: Dict[str, Any], *, width: int, height: int) -> Dict[str, Any]:
    """``params`` with the region of interest and the known camera motion read now (the region
    also scaled to ``width`` x ``height`` frames), so a bad file stops the run before any frame
    is processed."""
    from bgsub.engines.roi import RegionOfInterest

    params = dict(params)
    if params.get("roi"):
        region = RegionOfInterest.from_value(params["roi"])
        region.at((height, width))
        params["roi"] = region
    if params.get("known_motion"):
        from bgsub.camera.known import KnownMotion  # (a moving-camera engine's)

        params["known_motion"] = KnownMotion.from_value(params["known_motion"])
        check_motion_size(params["known_motion"], width=width, height=height)
    return params


def check_motion_size(known: Any, *, width: int, height: int) -> None:
    """Refuse a known camera motion (a :class:`~bgsub.camera.KnownMotion`) with an entry
    that moves a corner of ``width`` x ``height`` frames by more than the frame's size: no
    camera moves that far between two frames, and every mask would be empty."""
    import numpy as np

    corners = np.array([[0, 0, 1], [width - 1, 0, 1], [0, height - 1, 1],
                        [width - 1, height - 1, 1]], np.float64).T
    with np.errstate(all="ignore"):
        moved = np.einsum("nij,jk->nik", np.nan_to_num(known.matrices), corners)
        shift = np.abs(moved[:, :2] / moved[:, 2:] - corners[None, :2])
    fits = (shift[:, 0] <= width).all(axis=1) & (shift[:, 1] <= height).all(axis=1)
    unknown = np.isnan(known.matrices).all(axis=(1, 2))
    bad = np.flatnonzero(~fits & ~unknown)
    if len(bad):
        entry = int(bad[0])
        largest = float(np.nanmax(np.where(np.isfinite(shift[entry]), shift[entry], np.inf)))
        raise InputError(f"{known.name}: entry {entry} moves a corner of the {width}x{height} "
                         f"frame by {largest:.4g} px, more than the frame's size: not a camera "
                         "motion between two frames (give --motion-in an (N, 3, 3) array of "
                         "frame-to-frame motions, as --motion writes it)")


def motion_note(engine: Any) -> Optional[str]:
    """A line when ``--motion-in`` ended before the input: the frames after were estimated."""
    known = getattr(engine, "known_motion", None)
    if known is None or not known.frames_past_end:
        return None
    return (f"{known.name} holds the camera motion of {len(known.matrices)} frames; the "
            f"{known.frames_past_end} after them were estimated")
