"""Where a batch writes: one output per input, named after it, in the folders given.

``-o OUTDIR`` gets ``OUTDIR/NAME.mkv`` (or ``.avi``/``.mp4``, or a ``OUTDIR/NAME/`` folder of
``binNNNNNN.png`` masks); each side output's folder gets ``NAME.mp4`` (``--vis``,
``--flow-vis``), ``NAME.npy`` (``--motion``), ``NAME.jsonl`` (``--objects``) or ``NAME.csv``
(``--stats``). Completion records go to
``OUTDIR/.bgsub-batch/NAME.json`` (see :mod:`bgsub.batch.record`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Optional, Tuple

from bgsub.errors import OutputError

#: Mask formats of a batch: the extension of each input's mask video, or ``png`` for a folder.
MASK_FORMATS = ("mkv", "avi", "mp4", "mov", "png")

#: The folder of ``OUTDIR`` that holds the completion records.
RECORD_FOLDER = ".bgsub-batch"

#: Side outputs: option, and the extension of the file each input gets in its folder.
SIDE_OUTPUTS = (("vis", "--vis", ".mp4"), ("flow_vis", "--flow-vis", ".mp4"),
                ("motion", "--motion", ".npy"), ("objects", "--objects", ".jsonl"),
                ("stats", "--stats", ".csv"))

#: The option that names each kind of output (:data:`bgsub.io.pipeline.KINDS`), of a batch and
#: of a single run alike.
OPTIONS = {"masks": "-o", **{kind: flag for kind, flag, _ in SIDE_OUTPUTS}}


@dataclass(frozen=True)
class OutputLayout:
    """The output folders of a batch.

    Attributes
    ----------
    folder : str
        ``-o``: the masks of every input.
    mask_format : str
        One of :data:`MASK_FORMATS` (default ``mkv``: lossless FFV1).
    vis, flow_vis, motion, objects, stats : str, optional
        Folders of the side outputs (``None``: not written).
    """

    folder: str
    mask_format: str = "mkv"
    vis: Optional[str] = None
    flow_vis: Optional[str] = None
    motion: Optional[str] = None
    objects: Optional[str] = None
    stats: Optional[str] = None

    def __post_init__(self) -> None:
        if self.mask_format not in MASK_FORMATS:
            raise OutputError(f"unknown mask format {self.mask_format!r} (use one of "
                              f"{', '.join(MASK_FORMATS)})")

    def outputs(self, name: str) -> Dict[str, str]:
        """The outputs of the input named ``name``: ``{"masks": path, "vis": path, ...}``, the
        side outputs only when asked for."""
        suffix = "" if self.mask_format == "png" else f".{self.mask_format}"
        paths = {"masks": str(Path(self.folder) / f"{name}{suffix}")}
        for kind, _, extension in SIDE_OUTPUTS:
            folder = getattr(self, kind)
            if folder:
                paths[kind] = str(Path(folder) / f"{name}{extension}")
        return paths

    def flagged(self, name: str) -> Tuple[Tuple[str, str], ...]:
        """``(option, path)`` of each output of the input named ``name``, ``-o`` first."""
        return tuple((OPTIONS[kind], path) for kind, path in self.outputs(name).items())

    @property
    def record_folder(self) -> str:
        """The folder of the completion records (in ``-o``)."""
        return str(Path(self.folder) / RECORD_FOLDER)

    def record(self, name: str) -> str:
        """The completion record of the input named ``name``."""
        return str(Path(self.record_folder) / f"{name}.json")

    def extension(self, flag: str) -> str:
        """The extension of the files written to the folder of option ``flag``."""
        if flag == "-o":
            return f".{self.mask_format}"
        return next(extension for _, option, extension in SIDE_OUTPUTS if option == flag)

    def folders(self) -> Tuple[Tuple[str, str], ...]:
        """``(option, folder)`` of every output folder in use, ``-o`` first."""
        used = [("-o", self.folder)]
        used += [(flag, getattr(self, kind)) for kind, flag, _ in SIDE_OUTPUTS
                 if getattr(self, kind)]
        return tuple(used)

    def create_folders(self) -> None:
        """Create the output folders (and the record folder); :class:`OutputError` when one is
        a file or cannot be created."""
        for flag, folder in self.folders() + (("-o", self.record_folder),):
            path = Path(folder)
            if path.exists() and not path.is_dir():
                raise OutputError(f"{folder}: {flag} of several inputs must be a folder, not a "
                                  "file")
            try:
                path.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise OutputError(f"{folder}: cannot create the folder "
                                  f"({err.strerror or err})") from None
