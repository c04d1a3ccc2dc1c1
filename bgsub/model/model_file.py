"""The ``.npz`` file format of gated RBM models, and loading the shipped ones by name.

A model file is an ``.npz`` archive holding ``format_version`` (int64 scalar), ``header`` (a JSON
string: ``patch_size``, ``output_units``, ``normalization``, ``contrast_floor``, ``meta``) and
the float32 arrays ``wxf, wyf, whf, bh, by`` (plus ``wyf_gen`` when the model has one). It is
read with ``allow_pickle=False`` (a pickle can run code); anything malformed raises
:class:`~bgsub.errors.ModelError` naming the file and the problem.

:meth:`GatedRBM.save <bgsub.model.rbm.GatedRBM.save>`, :meth:`GatedRBM.load
<bgsub.model.rbm.GatedRBM.load>` and :func:`bgsub.model.rbm.load_model` call into this module.
"""

from __future__ import annotations

import io
import json
import zipfile
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, Type, Union

import numpy as np

from bgsub.errors import ModelError, OutputError

if TYPE_CHECKING:  # rbm imports this module; the class is only needed at run time in load_model
    from bgsub.model.rbm import GatedRBM

__all__ = [
    "ARRAY_NAMES",
    "FORMAT_VERSION",
    "RANGE_KEYS",
    "SHIPPED_MODELS",
    "load_model",
    "read_model",
    "write_model",
]

#: Version of the ``.npz`` layout written by :func:`write_model`.
FORMAT_VERSION = 1

#: Models that can be loaded by name (installed as package data ``bgsub.models``).
SHIPPED_MODELS = ("natural", "dots-translation", "dots-translation-3px", "dots-rotation")

#: The weight arrays every model has (:class:`~bgsub.model.rbm.GatedRBM` fields of those names).
ARRAY_NAMES = ("wxf", "wyf", "whf", "bh", "by")

#: The ``meta`` entries the motion readers take as the model's displacement range (pixels).
RANGE_KEYS = ("max_disp", "max_shift", "max_displacement")


# ---------------------------------------------------------------------------------- writing


def write_model(model: "GatedRBM", path: Union[str, Path], *, overwrite: bool = True) -> Path:
    """Write ``model`` as an ``.npz`` archive (float32 arrays + a JSON header), atomically.

    Raises
    ------
    OutputError
        ``path`` exists and ``overwrite`` is false.

    Returns
    -------
    Path written.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputError(f"{path}: already exists (--overwrite, or overwrite=True, "
                          "replaces it)")
    header = {
        "patch_size": model.patch_size,
        "output_units": model.output_units,
        "normalization": model.normalization,
        "contrast_floor": model.contrast_floor,
        "meta": model.meta,
    }
    arrays = {name: getattr(model, name) for name in ARRAY_NAMES}
    if model.wyf_gen is not None:
        arrays["wyf_gen"] = model.wyf_gen
    from bgsub.io.sinks import write_atomically  # (sinks imports OpenCV; models do not need it)

    archive = io.BytesIO()  # a model is a few hundred KB: written whole, then renamed
    np.savez_compressed(archive, format_version=np.array(FORMAT_VERSION, np.int64),
                        header=np.array(json.dumps(header)), **arrays)
    write_atomically(path, archive.getvalue(), what="model")
    return path


# ---------------------------------------------------------------------------------- reading


def read_model(path: Union[str, Path], *, model_class: Type["GatedRBM"]) -> "GatedRBM":
    """Read a model written by :func:`write_model` as a ``model_class``.

    Raises
    ------
    ModelError
        Missing file, not an ``.npz`` archive, pickled content, wrong format version, malformed
        header, non-numeric or inconsistent arrays, or a displacement range in ``meta`` the
        model's patches cannot show.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"model file {path} does not exist")
    data = _read_archive(path)
    missing = [n for n in ("format_version", "header") + ARRAY_NAMES if n not in data]
    if missing:
        raise ModelError(f"{path} is not a bgsub model (missing {', '.join(missing)})")
    _check_version(path, data["format_version"])
    settings = _read_header(path, data["header"])
    arrays = _numeric_arrays(path, data)
    try:
        model = model_class(**arrays, **settings)
    except ModelError as err:
        raise ModelError(f"{path}: {err}") from None
    problem = _range_problem(model.meta, model.patch_size)
    if problem:
        raise ModelError(f"{path}: inconsistent gated RBM: {problem}")
    model.meta.setdefault("source", str(path))
    return model


def _read_archive(path: Path) -> Dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path``, read without pickle."""
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):  # a plain .npy array
            raise ModelError(f"{path} is not a readable bgsub model (a single .npy array, "
                             "not an .npz archive)")
        data = {}
        with loaded as npz:
            for name in npz.files:
                try:
                    data[name] = npz[name]
                except ValueError as err:
                    if "pickle" not in str(err):
                        raise
                    raise ModelError(f"{path}: array {name!r} holds Python objects, which "
                                     "only pickle can read, and bgsub never loads pickles "
                                     "(they can run code); save numbers and text only"
                                     ) from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as err:
        # numpy's own message for a non-npz file suggests loading it with allow_pickle, which
        # bgsub never does (a pickle can run code): name the problem without that advice.
        reason = "not an .npz archive" if "pickle" in str(err) else f"corrupt or truncated: {err}"
        raise ModelError(f"{path} is not a readable bgsub model ({reason})") from None
    return data


def _check_version(path: Path, stored: np.ndarray) -> None:
    """``ModelError`` unless ``stored`` is the whole number :data:`FORMAT_VERSION`."""
    if stored.dtype.kind not in "iu" or stored.size != 1:
        shown = repr(stored.item()) if stored.size == 1 else f"of shape {stored.shape}"
        raise ModelError(f"{path}: format version {shown} is not stored as a whole number "
                         f"(bgsub models store {FORMAT_VERSION}); save the model again with "
                         "bgsub")
    version = int(stored.item())
    if version != FORMAT_VERSION:
        raise ModelError(
            f"{path} has model format version {version}; this bgsub reads version {FORMAT_VERSION}"
        )


def _read_header(path: Path, stored: np.ndarray) -> Dict[str, Any]:
    """The JSON header as the model's keyword arguments (all but the arrays)."""
    try:
        header = json.loads(str(stored[()]))
        if type(header["patch_size"]) is not int:  # not 13.7, "13" or true
            raise ValueError(f"patch_size {header['patch_size']!r} is not a whole number")
        return dict(
            patch_size=header["patch_size"],
            output_units=str(header["output_units"]),
            normalization=str(header.get("normalization", "none")),
            contrast_floor=float(header.get("contrast_floor", 0.02)),
            meta=dict(header.get("meta", {})),
        )
    except (ValueError, KeyError, TypeError) as err:
        raise ModelError(f"{path}: malformed model header ({err})") from None


def _numeric_arrays(path: Path, data: Dict[str, np.ndarray]) -> Dict[str, Any]:
    """The weight arrays of ``data`` (``wyf_gen`` None when absent); ``ModelError`` for any
    that does not hold numbers."""
    arrays: Dict[str, Any] = {}
    for name in ARRAY_NAMES + ("wyf_gen",):
        if name in data:
            arr = data[name]
            if arr.dtype.kind not in "fiu":
                raise ModelError(f"{path}: array {name} has non-numeric type {arr.dtype}")
            arrays[name] = arr
    arrays.setdefault("wyf_gen", None)
    return arrays


def _range_problem(meta: Dict[str, Any], p: int) -> str:
    """Why the displacement range a model's ``meta`` states (:data:`RANGE_KEYS`) cannot be
    read with its ``p x p`` patches ("" when it can): the readouts compare pixels that stay in
    the patch after the shift, so the range is a number of pixels from 0 to half the patch
    (as ``bgsub train --max-shift`` requires)."""
    limit = (p - 1) // 2
    for key in RANGE_KEYS:
        if key not in meta:
            continue
        value = meta[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not 0 <= value <= limit:
            return (f"meta {key} {value!r} is not a displacement its {p}x{p} patches can show "
                    f"(a number of pixels from 0 to {limit})")
    return ""


# ---------------------------------------------------------------------------------- by name


def _shipped_path(name: str):
    try:
        folder = resources.files("bgsub.models")
    except ModuleNotFoundError:
        # Run from a source checkout that was never pip-installed: models/ sits beside bgsub/.
        folder = Path(__file__).resolve().parents[2] / "models"
    return folder.joinpath(f"{name}.npz")


def load_model(name_or_path: Union[str, Path, "GatedRBM"]) -> "GatedRBM":
    """A shipped model by name, or a model file by path.

    Parameters
    ----------
    name_or_path : str, Path or GatedRBM
        ``"natural"``, ``"dots-translation"``, ``"dots-translation-3px"``, ``"dots-rotation"``, or
        the path of an ``.npz`` written by :func:`write_model`. A ``GatedRBM`` is returned as is.

    Raises
    ------
    ModelError
        Unknown name (the message lists the shipped ones), missing or invalid file.
    """
    from bgsub.model.rbm import GatedRBM  # (rbm imports this module)

    if isinstance(name_or_path, GatedRBM):
        return name_or_path
    text = str(name_or_path)
    if text in SHIPPED_MODELS:
        ref = _shipped_path(text)
        if not ref.is_file():
            raise ModelError(f"shipped model {text!r} is not installed (no {text}.npz in bgsub.models)")
        with resources.as_file(ref) as real:
            return GatedRBM.load(real)
    path = Path(text).expanduser()
    if path.is_file():
        return GatedRBM.load(path)
    shipped = ", ".join(SHIPPED_MODELS)
    raise ModelError(f"no model file {text!r} and no shipped model of that name (shipped: {shipped})")
