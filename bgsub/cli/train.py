"""``bgsub train``: train a gated RBM motion model with CD-k."""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

from bgsub.cli.common import check_distinct, note, warn
from bgsub.errors import InputError, OutputError

DOTS = ("dots-translation", "dots-rotation")
IMAGES = "shifted-images"

_DESCRIPTION = """\
Train a factored gated RBM (Memisevic & Hinton 2010) on patch pairs with contrastive divergence.

Data (--data):
  dots-translation   random dots (10% on) shifted by whole pixels, |dx|,|dy| <= --max-shift
                     (1: the paper's 9 classes). Binary units. Shifts > 1 px need fresh pairs
                     and a curriculum; a suitable one is used unless --curriculum is given.
  dots-rotation      random dots rotated about the patch centre within +-(--max-angle) degrees.
  shifted-images     photographs (scikit-image's sample images; pip install bgsub[train])
                     moved by sub-pixel shifts up to --max-shift plus a slight rotation/zoom.
                     Gaussian units, contrast-normalised, PCA-whitened by default.
  VIDEO ...          patch pairs from consecutive frames of your own videos / image folders
                     (unsupervised: the real motion of your footage). Settings as for
                     shifted-images.

For dots the summary reports held-out accuracy on 1,000 fresh pairs; for shifted-images the
fraction of held-out photo patches whose displacement is found within 1 px; for video nothing
(the true motion of its pairs is unknown).
"""

_EPILOG = """\
examples:
  bgsub train --data dots-translation -o dots.npz
        the paper's setup: 13x13, 200 factors, 100 mapping units, 9 one-pixel shifts
  bgsub train --data dots-translation --max-shift 3 -o dots3.npz
        shifts up to 3 px: 400 epochs, curriculum 100:1,200:2 and a linear lr decay by default
  bgsub train --data dots-rotation -o rot.npz
        the paper's rotation model, +-30 degrees
  bgsub train --data shifted-images --max-shift 4 --curriculum 50:1,100:2,150:3 \\
      --epochs 600 --lr-schedule linear -o natural.npz
        the shipped `natural` model (~7 min; photographs need pip install -e '.[train]')
  bgsub train --data samples/pan.mp4 --video-scale 0.5 -o mine.npz
        your own footage (here the bundled sample), unsupervised
"""


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "train",
        help="train a gated RBM motion model",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--data", nargs="+", required=True, metavar="KIND|VIDEO",
                        help="dots-translation, dots-rotation, shifted-images, or video paths")
    parser.add_argument("-o", "--output", required=True, metavar="MODEL.npz",
                        help="where to write the model")
    _add_model_options(parser)
    _add_training_options(parser)
    _add_data_options(parser)
    parser.add_argument("--overwrite", action="store_true", help="replace an existing model file")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar and no notes on stderr (the training summary); "
                             "warnings and errors are still printed")
    parser.set_defaults(handler=run)


def _add_model_options(parser: argparse.ArgumentParser) -> None:
    """The ``model`` group: sizes, output units, whitening."""
    model = parser.add_argument_group("model")
    model.add_argument("--patch-size", type=int, default=13, metavar="P", help="patch side (default 13)")
    model.add_argument("--factors", type=int, default=200, metavar="F", help="factors (default 200)")
    model.add_argument("--hidden", type=int, default=100, metavar="K", help="mapping units (default 100)")
    model.add_argument("--output-units", choices=("binary", "gaussian"), default=None,
                       help="default: binary for dots, gaussian for images and video (binary "
                            "units take dots only: image patches are contrast-normalised)")
    whiten = model.add_mutually_exclusive_group()
    whiten.add_argument("--whiten", dest="whiten", action="store_true", default=None,
                        help="PCA-whiten patches (default for images and video)")
    whiten.add_argument("--no-whiten", dest="whiten", action="store_false",
                        help="train on the pixels themselves, contrast-normalised for images and "
                             "video (default for dots)")
    model.add_argument("--normalize-filters", action="store_true",
                       help="keep input/output filters at a common norm (stabilises Gaussian units)")


def _add_training_options(parser: argparse.ArgumentParser) -> None:
    """The ``training`` group: epochs, pairs, learning rate, CD-k settings, seed."""
    train = parser.add_argument_group("training")
    train.add_argument("--epochs", type=int, default=None, metavar="N",
                       help="passes (default: 150 for 1-px dots, 400 with --max-shift 3, "
                            "150 for rotations, 200 for images)")
    train.add_argument("--pairs", type=int, default=10_000, metavar="N", help="pairs per epoch (default 10000)")
    train.add_argument("--batch", type=int, default=100, metavar="N",
                       help="minibatch size (default 100; 20 diverges)")
    train.add_argument("--lr", type=float, default=None,
                       help="learning rate (default 0.05 for dots, 0.003 for images)")
    train.add_argument("--lr-schedule", choices=("constant", "linear"), default=None,
                       help="linear: decay to lr/10 over the second half (default: linear with a "
                            "curriculum, which dots-translation with --max-shift > 1 has by "
                            "default, else constant)")
    train.add_argument("--momentum", type=float, default=0.9, help="default 0.9")
    train.add_argument("--weight-decay", type=float, default=1e-4, help="default 1e-4")
    train.add_argument("--sparsity", type=float, default=0.02, metavar="P",
                       help="target mean activity of the mapping units (default 0.02)")
    train.add_argument("--sparsity-cost", type=float, default=1.0, metavar="C",
                       help="strength of the sparsity push on the mapping-unit biases (default 1)")
    train.add_argument("--cd-k", type=int, default=1, metavar="K", help="Gibbs steps of CD-k (default 1)")
    train.add_argument("--fixed-pairs", action="store_true",
                       help="one fixed training set (the paper) instead of fresh pairs every epoch")
    train.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _add_data_options(parser: argparse.ArgumentParser) -> None:
    """The ``data`` group: options some data kinds take (default None: "not given")."""
    data = parser.add_argument_group(
        "data", "options for some data kinds only; given with another kind, they are refused")
    data.add_argument("--max-shift", type=float, default=None, metavar="PX",
                      help="dots-translation, shifted-images: largest |dx|, |dy| trained on; "
                           "video: the range the model reads motion in. At most half of "
                           "--patch-size (default 1 for dots-translation, 3 for images and video)")
    data.add_argument("--max-angle", type=float, default=None, metavar="DEG",
                      help="dots-rotation: rotation range, up to 180 (default 30)")
    data.add_argument("--curriculum", default=None, metavar="E:L,...",
                      help="dots, shifted-images: grow the range, e.g. 100:1,200:2 = at most 1 "
                           "before epoch 100, 2 before 200, then all (default for "
                           "dots-translation with --max-shift > 1: one stage per extra pixel, "
                           "100:1,200:2 for --max-shift 3 and its default 400 epochs, scaled to "
                           "--epochs when that is given)")
    data.add_argument("--blur", default=None, metavar="S1,S2",
                      help="shifted-images: also train on the photos blurred by Gaussians of these "
                           "sigmas in px (soft or compressed footage), e.g. 1,2")
    data.add_argument("--motion-blur", type=int, default=None, metavar="PX",
                      help="shifted-images: also train on the photos box-blurred over PX pixels "
                           "horizontally and vertically (a shaking or panning camera)")
    data.add_argument("--video-step", type=int, default=None, metavar="N",
                      help="video: use every N-th frame (default 1)")
    data.add_argument("--video-scale", type=float, default=None, metavar="F",
                      help="video: resize the frames by this factor")
    data.add_argument("--eval-pairs", type=int, default=None, metavar="N",
                      help="dots, shifted-images: held-out pairs scored for the summary "
                           "(default 1000; 0 skips). Not for video: its motion is unknown")


def _sigmas(text: str) -> tuple:
    """``"1,2"`` -> ``(1.0, 2.0)``: positive blur sigmas for ``--blur``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise InputError(f"--blur takes sigmas like 1,2, not {text!r}") from None
    # Written so that NaN fails too (every comparison with NaN is false).
    if not values or not all(0 < v < math.inf for v in values):
        raise InputError(f"--blur: blur sigmas must be positive numbers, not {text!r}")
    return values


def _default_curriculum(max_range: float, step_epochs: int = 100) -> str:
    """|d| <= 1 for 100 epochs, <= 2 for the next 100, ... up to the full range."""
    stages = [f"{step_epochs * k}:{k}" for k in range(1, int(math.ceil(max_range)))]
    return ",".join(stages)


def _default_epochs(kind: str, max_shift: float) -> int:
    """--epochs when not given."""
    if kind == "dots-translation":
        # One curriculum stage of 100 epochs per extra pixel, then 200 on the full range.
        return 150 if max_shift <= 1 else 100 * (int(math.ceil(max_shift)) - 1) + 200
    return 150 if kind == "dots-rotation" else 200


def _fit_curriculum(curriculum: Any, args: argparse.Namespace, kind: str, *, max_shift: float,
                    epochs: int, default_epochs: int) -> Any:
    """The curriculum to train with, fitted to the epoch count.

    The default stages (``args.curriculum`` None) are laid out for the default epoch count:
    for other counts they are spread over the epochs asked for, so that every range, the full
    one last, is trained (the default epoch count keeps them as they are). A curriculum the user
    gave is kept, with a warning when part of it lies beyond the last epoch.
    """
    if not curriculum.stages:
        return curriculum
    if args.curriculum is None:
        if epochs == default_epochs:
            return curriculum
        scaled = curriculum.scaled(epochs / default_epochs, epochs=epochs)
        note(f"default curriculum {curriculum} (for {default_epochs} epochs) scaled to --epochs "
             f"{epochs}: {str(scaled) or 'none (the full range from the start)'}",
             quiet=args.quiet)
        return scaled
    rotation = kind == "dots-rotation"
    full = args.max_angle if rotation else max_shift
    idle, last = curriculum.unreached(epochs, full)
    problems = []
    if last is not None:
        problems.append(f"the range stays at {last:g} to the end and never reaches the full "
                        f"{'--max-angle' if rotation else '--max-shift'} {full:g}")
    if idle:
        problems.append(f"{'stage' if len(idle) == 1 else 'stages'} "
                        f"{','.join(f'{u}:{l:g}' for u, l in idle)} never "
                        f"{'runs' if len(idle) == 1 else 'run'}")
    if problems:
        warn(f"--curriculum {curriculum} reaches beyond --epochs {epochs}: " + "; ".join(problems))
    return curriculum


def _imagedata():
    try:
        import bgsub.model.imagedata as imagedata
    except ImportError as err:
        raise InputError(f"training on images needs bgsub.model.imagedata, which cannot be imported ({err})") from None
    return imagedata


# ---------------------------------------------------------------------------- checks up front

# (option, test, what the value must be). Every test is a comparison that NaN fails, and the
# float ones have a finite upper bound, so NaN and inf are refused along with the out-of-range.
_OPTION_RULES: Tuple[Tuple[str, Callable[[float], bool], str], ...] = (
    ("--patch-size", lambda v: v >= 3, "at least 3 (smaller patches cannot show motion)"),
    ("--factors", lambda v: v >= 1, "at least 1"),
    ("--hidden", lambda v: v >= 1, "at least 1"),
    ("--epochs", lambda v: v >= 1, "at least 1"),
    ("--pairs", lambda v: v >= 1, "at least 1"),
    ("--batch", lambda v: v >= 1, "at least 1"),
    ("--cd-k", lambda v: v >= 1, "at least 1"),
    ("--lr", lambda v: 0 < v < math.inf, "a number > 0"),
    ("--momentum", lambda v: 0 <= v < 1, "in [0, 1)"),
    ("--weight-decay", lambda v: 0 <= v < math.inf, "a number >= 0"),
    ("--sparsity", lambda v: 0 < v < 1, "in (0, 1)"),
    ("--sparsity-cost", lambda v: 0 <= v < math.inf, "a number >= 0"),
    ("--seed", lambda v: v >= 0, "a whole number >= 0"),
    # 0 would train on pairs that do not move at all: a motion model that has seen no motion.
    ("--max-shift", lambda v: 1 <= v < math.inf, "a number of pixels >= 1"),
    ("--max-angle", lambda v: 0 < v <= 180, "in (0, 180] degrees (+-180 covers every rotation)"),
    ("--motion-blur", lambda v: v >= 0, "a number of pixels >= 0 (0 or 1: no motion blur)"),
    ("--video-step", lambda v: v >= 1, "at least 1"),
    ("--video-scale", lambda v: 0 < v < math.inf, "a number > 0, e.g. 0.5"),
    ("--eval-pairs", lambda v: v >= 0, "at least 0 (0 skips the held-out evaluation)"),
)


def _check_options(args: argparse.Namespace) -> None:
    """Refuse numeric options that cannot work, naming the option, before any data is made."""
    for option, ok, rule in _OPTION_RULES:
        value = getattr(args, option[2:].replace("-", "_"))
        if value is not None and not ok(value):
            raise InputError(f"{option} must be {rule}, not {value:g}")
    if args.batch > args.pairs:
        raise InputError(f"--batch {args.batch} is larger than --pairs {args.pairs}: "
                         "an epoch must hold at least one minibatch")


# Options that only some data kinds use: (flag, the kinds that take it, what to say instead).
# Their defaults are None, so that an option given with another kind is refused rather than
# silently ignored.
_KIND_OPTIONS: Tuple[Tuple[str, Tuple[str, ...], str], ...] = (
    ("--max-shift", ("dots-translation", IMAGES, "video"), "dots-rotation takes --max-angle"),
    ("--max-angle", ("dots-rotation",), ""),
    ("--curriculum", DOTS + (IMAGES,), "video pairs have no range to grow"),
    ("--blur", (IMAGES,), ""),
    ("--motion-blur", (IMAGES,), ""),
    ("--video-step", ("video",), ""),
    ("--video-scale", ("video",), ""),
)


def _kind_name(kind: str) -> str:
    return "video data" if kind == "video" else kind


def _kinds_text(kinds: Tuple[str, ...]) -> str:
    names = [_kind_name(k) for k in kinds]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _check_kind_options(args: argparse.Namespace, kind: str) -> None:
    """Refuse options the data kind does not use (they would be silently ignored)."""
    for flag, kinds, hint in _KIND_OPTIONS:
        if getattr(args, flag[2:].replace("-", "_")) is not None and kind not in kinds:
            only = " only" if len(kinds) == 1 else ""
            raise InputError(f"{flag} applies to {_kinds_text(kinds)}{only}, not to "
                             f"{_kind_name(kind)}" + (f" ({hint})" if hint else ""))
    if args.output_units == "binary" and kind not in DOTS:
        raise InputError(f"--output-units binary applies to dots data ({_kinds_text(DOTS)}) only, "
                         f"not to {_kind_name(kind)}: its patches are contrast-normalised real "
                         "values, which need gaussian units (the default)")
    if kind == "video" and args.eval_pairs:  # 0 asks for what video gets anyway: nothing
        raise InputError("--eval-pairs applies to generated data (dots-translation, dots-rotation "
                         "and shifted-images) only, not to video data: the true motion of video "
                         "pairs is unknown, so there is nothing to score")


def _max_shift(args: argparse.Namespace, kind: str) -> float:
    """``--max-shift`` or its default for ``kind``, checked against the patch size.

    The readout that scores the held-out pairs (and later reads motion with the model's
    ``max_shift`` as its range) compares pixels that stay inside the patch after the shift,
    and the held-out pixel accuracy counts pixels at least ``max_shift`` from the border: both
    need shifts of at most half the patch. (dots-rotation does not use it.)
    """
    dots = kind in DOTS
    max_shift = args.max_shift if args.max_shift is not None else (1.0 if dots else 3.0)
    if dots and max_shift != int(max_shift):
        raise InputError(f"--max-shift for dots must be a whole number of pixels, not {max_shift:g}")
    p = args.patch_size
    limit = (p - 1) // 2
    if kind != "dots-rotation" and max_shift > limit:
        raise InputError(
            f"--max-shift {max_shift:g} is too large for {p}x{p} patches: at most {limit} "
            f"(half the patch); lower --max-shift or raise --patch-size to {2 * math.ceil(max_shift) + 1}"
        )
    return max_shift


def _data_kind(data: List[str]) -> str:
    """One of :data:`DOTS`, :data:`IMAGES`, or ``"video"`` for a list of existing video paths."""
    kinds = [d for d in data if d in DOTS + (IMAGES,)]
    if not kinds:
        for path in data:
            if not Path(path).exists() and not any(ch in path for ch in "*?["):
                raise InputError(
                    f"--data {path}: no such file (kinds: {', '.join(DOTS + (IMAGES,))}, or video paths)"
                )
        return "video"
    if len(data) > 1:
        others = ", ".join(d for d in data if d != kinds[0])
        raise InputError(
            f"--data {kinds[0]} is a built-in data kind and must be given alone (also got {others}); "
            "to train on your own footage, give only video paths"
        )
    return kinds[0]


def _check_output(args: argparse.Namespace, kind: str) -> Path:
    """The model path, checked before any work: a file (not a folder) whose folder can be
    written, new unless ``--overwrite``, and not one of the videos being read."""
    from bgsub.io.sinks import check_file_output  # the output check of eval, flow and analogy

    out = Path(args.output)
    # A trailing slash means a folder even if it does not exist yet (Path would drop it).
    if out.is_dir() or args.output.endswith(("/", os.sep)):
        raise OutputError(f"{args.output}: {'is' if out.is_dir() else 'names'} a folder, not a "
                          f"model file (give a file name, e.g. {out / 'model.npz'})")
    if out.exists() and not out.is_file():
        raise OutputError(f"{out}: is not a regular file")  # e.g. /dev/null: never replace it
    if out.suffix.lower() != ".npz":
        # load_model() reads .npz files; a model saved as mine.txt would be hard to find again.
        raise OutputError(f"{out}: a model file ends in .npz (e.g. {out.with_suffix('.npz')})")
    check_file_output(out, overwrite=args.overwrite)
    if kind == "video":
        check_distinct(args.data, [("-o", out)])
    return out


def _save(model: Any, out: Path) -> None:
    """Write ``model`` to ``out`` (atomically: :meth:`GatedRBM.save` renames a temporary file)."""
    try:
        model.save(out, overwrite=True)  # _check_output refused an existing file without --overwrite
    except OSError as err:  # e.g. the disk filled up or the folder turned read-only meanwhile
        raise OutputError(f"cannot write the model to {out}: {err.strerror or err}") from None


def _save_interrupted(model: Any, out: Path, when: str, what: str = "the model so far") -> int:
    """Ctrl-C with a usable model: keep it, say so, and exit as interrupted (130)."""
    try:
        _save(model, out)
    except OutputError as err:
        note(f"interrupted {when}; {what} was not saved ({err})")
    else:
        note(f"interrupted {when}; saved {what} to {out}")
    return 130


# ---------------------------------------------------------------------------------- command


@dataclass(frozen=True)
class _Plan:
    """What ``run`` trains, settled from the options before any data is made."""

    kind: str  # one of DOTS, IMAGES or "video"
    out: Path  # the model file, checked writable
    max_shift: float
    blur: Tuple[float, ...]  # --blur sigmas, () for none
    eval_pairs: int
    epochs: int
    curriculum: Any  # training.Curriculum, fitted to the epochs
    has_curriculum: bool  # whether one was asked for (scaling may leave no stage)


def _plan(args: argparse.Namespace) -> _Plan:
    """Every check first (a mistake must not cost a training run), and the defaults that depend
    on the data kind; sets the defaults of the kind-only options on ``args``."""
    from bgsub.model.training import Curriculum

    kind = _data_kind(args.data)
    _check_options(args)
    _check_kind_options(args, kind)
    # The defaults of the options only some kinds take (None above: "not given").
    args.max_angle = 30.0 if args.max_angle is None else args.max_angle
    args.motion_blur = args.motion_blur or 0
    args.video_step = args.video_step or 1
    eval_pairs = 1000 if args.eval_pairs is None else args.eval_pairs
    max_shift = _max_shift(args, kind)
    blur = _sigmas(args.blur) if args.blur else ()
    out = _check_output(args, kind)

    default_epochs = _default_epochs(kind, max_shift)
    epochs = args.epochs if args.epochs is not None else default_epochs
    curriculum_text = args.curriculum
    if curriculum_text is None and kind == "dots-translation" and max_shift > 1:
        curriculum_text = _default_curriculum(max_shift)
    curriculum = Curriculum.parse(curriculum_text)
    has_curriculum = bool(curriculum.stages)  # before scaling, which may leave no stage
    curriculum = _fit_curriculum(curriculum, args, kind, max_shift=max_shift, epochs=epochs,
                                 default_epochs=default_epochs)
    return _Plan(kind=kind, out=out, max_shift=max_shift, blur=blur, eval_pairs=eval_pairs,
                 epochs=epochs, curriculum=curriculum, has_curriculum=has_curriculum)


def _train_config(args: argparse.Namespace, plan: _Plan) -> Any:
    """The :class:`~bgsub.model.training.TrainConfig` of the options, checked."""
    from bgsub.model.training import TrainConfig

    dots = plan.kind in DOTS
    config = TrainConfig(
        patch_size=args.patch_size,
        n_factors=args.factors,
        n_hidden=args.hidden,
        output_units=args.output_units or ("binary" if dots else "gaussian"),
        normalization="none" if dots else "contrast",
        whiten=bool(args.whiten) if args.whiten is not None else not dots,
        normalize_filters=args.normalize_filters,
        epochs=plan.epochs,
        n_pairs=args.pairs,
        batch_size=args.batch,
        cd_k=args.cd_k,
        lr=args.lr if args.lr is not None else (0.05 if dots else 0.003),
        lr_schedule=args.lr_schedule or ("linear" if plan.has_curriculum else "constant"),
        momentum=args.momentum,
        weight_decay=args.weight_decay,
        sparsity_target=args.sparsity,
        sparsity_cost=args.sparsity_cost,
        fresh_pairs=not args.fixed_pairs,
        seed=args.seed,
    )
    config.check()  # the library's own guard, before the data: collecting video pairs takes a while
    return config


def _describe(model: Any, args: argparse.Namespace, plan: _Plan) -> Any:
    """Record the data kind, curriculum and motion range in ``model.meta``; returns ``model``."""
    model.meta["curriculum"] = str(plan.curriculum)
    model.meta["data_kind"] = plan.kind
    if plan.kind != "dots-rotation":
        model.meta["max_shift"] = plan.max_shift
    else:
        model.meta["max_angle"] = args.max_angle
    return model


def _summarise(result: Any, scores: Dict[str, float], args: argparse.Namespace, plan: _Plan) -> None:
    """The training summary on stderr (unless ``--quiet``)."""
    note(f"trained {plan.epochs} epochs of {args.pairs} pairs in {result.seconds:.1f} s "
         f"({result.seconds / max(1, result.epochs_run):.2f} s/epoch)", quiet=args.quiet)
    note(f"final reconstruction error {result.errors[-1]:.4f} per pixel", quiet=args.quiet)
    for key, value in scores.items():
        note(f"held-out {key.replace('_', ' ')}: {_fmt(value)}", quiet=args.quiet)
    note(f"model written to {plan.out}", quiet=args.quiet)


def run(args: argparse.Namespace) -> int:
    from bgsub.model import training

    plan = _plan(args)
    config = _train_config(args, plan)
    kind, out = plan.kind, plan.out
    try:
        source, description = _source(kind, args, max_shift=plan.max_shift,
                                      curriculum=plan.curriculum, blur=plan.blur)
        if kind == "dots-translation" and plan.max_shift > 1 and args.fixed_pairs:
            note("shifts > 1 px rarely learn from a fixed training set; consider dropping --fixed-pairs",
                 quiet=args.quiet)
        result = _train(source, config, description, quiet=args.quiet)
    except training.TrainingInterrupted as stop:
        done = stop.result.epochs_run
        return _save_interrupted(_describe(stop.result.model, args, plan), out,
                                 f"after {done} of {plan.epochs} epochs")
    except KeyboardInterrupt:
        note(f"interrupted before the first epoch finished; no model was written to {out}")
        return 130
    model = _describe(result.model, args, plan)

    try:
        scores = _evaluate(kind, model, max_shift=plan.max_shift, max_angle=args.max_angle,
                           n=plan.eval_pairs)
    except KeyboardInterrupt:  # training is complete: keep it, without the held-out scores
        return _save_interrupted(model, out, "during the held-out evaluation",
                                 "the fully trained model (without held-out scores)")
    if scores:
        model.meta["held_out"] = scores
    _save(model, out)
    _summarise(result, scores, args, plan)
    return 0


def _source(kind: str, args: argparse.Namespace, *, max_shift: float, curriculum: Any,
            blur: Tuple[float, ...]) -> Tuple[Any, str]:
    """The pair source for ``kind`` and a one-line description of it for the model's meta."""
    from bgsub.model import training

    p = args.patch_size
    if kind == "dots-translation":
        source = training.TranslatedDots(patch_size=p, max_shift=int(max_shift), curriculum=curriculum)
        return source, f"random dots, integer shifts |dx|,|dy| <= {int(max_shift)}"
    if kind == "dots-rotation":
        source = training.RotatedDots(patch_size=p, max_angle=args.max_angle, curriculum=curriculum)
        return source, f"random dots, rotations within +-{args.max_angle:g} deg"
    if kind == IMAGES:
        source = _imagedata().shifted_image_pairs(max_shift=max_shift, curriculum=curriculum,
                                                  patch_size=p, blur=blur,
                                                  motion_blur=args.motion_blur)
        description = f"shifted photographs, shifts up to {max_shift:g} px"
        if blur or args.motion_blur > 1:
            description += " (with blurred copies)"
        return source, description
    note("collecting patch pairs from the videos ...", quiet=args.quiet)
    source = _imagedata().video_frame_pairs(
        args.data, patch_size=p, step=args.video_step, scale=args.video_scale, seed=args.seed
    )
    return source, "video frame pairs: " + ", ".join(Path(a).name for a in args.data)


def _train(source: Any, config: Any, description: str, *, quiet: bool) -> Any:
    """:func:`bgsub.model.training.train` with a progress bar, closed before any message is printed."""
    from bgsub.model import training

    bar = _progress(config.epochs, quiet=quiet)

    def on_epoch(epoch: int, error: float, _get_model: Any) -> None:
        if bar is not None:
            bar.set_postfix_str(f"recon err {error:.4f}")
            bar.update(1)

    try:
        return training.train(source, config, on_epoch=on_epoch, data_description=description)
    finally:
        if bar is not None:
            bar.close()


def _evaluate(kind: str, model: Any, *, max_shift: float, max_angle: float, n: int) -> Dict[str, float]:
    from bgsub.model import training

    if n <= 0:
        return {}
    if kind == "dots-translation":
        r = training.evaluate_translation(model, max_shift=int(max_shift), n=n, radius=int(max_shift))
        return {"patch_accuracy": r["patch_accuracy"], "pixel_accuracy": r["pixel_accuracy"]}
    if kind == "dots-rotation":
        r = training.evaluate_rotation(model, max_angle=max_angle, n=n)
        return {"median_angle_error_deg": r["median_angle_error"], "within_5deg": r["within_5deg"]}
    if kind == IMAGES:
        test = _imagedata().shifted_image_pairs(split="test", max_shift=max_shift, patch_size=model.patch_size)
        return training.evaluate_shifted(model, test, n=n, max_disp=int(math.ceil(max_shift)))
    return {}


def _progress(total: int, *, quiet: bool) -> Optional[Any]:
    from tqdm import tqdm

    if quiet or not sys.stderr.isatty():
        return None
    return tqdm(total=total, desc="training", unit="epoch", file=sys.stderr, dynamic_ncols=True, leave=False)


def _fmt(value: float) -> str:
    return f"{value:.4f}" if isinstance(value, float) else str(value)
