"""The report folder of `bgsub compare`: creating it, recording what a run writes there, and
removing what an earlier run wrote (``overwrite``), nothing else.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import List, Optional, Sequence, Tuple, Union

from bgsub.engines import available_engines
from bgsub.errors import OutputError, given_path
from bgsub.evaluation.compare_report import HTML_REPORT, REPORT_FILES
from bgsub.io.outputs import MASK_NAME, PARTIAL_MASK_NAME, partial_path
from bgsub.io.sinks import names_a_folder

PathLike = Union[str, "Path"]

#: The side-by-side video of each input (in its sequence's folder for a dataset root).
SIDE_BY_SIDE = "side_by_side.mp4"

# Names that are files, not folders: `-o cmp.txt` most likely meant the report itself.
_FILE_SUFFIXES = {".txt", ".csv", ".json", ".md", ".html", ".htm", ".pdf", ".png", ".jpg",
                  ".mkv", ".avi", ".mp4", ".mov", ".webm"}


def check_report_dir(report_dir: PathLike, overwrite: bool) -> Optional[Path]:
    """Create ``report_dir`` or check that it may be filled; raise :class:`OutputError` when it
    holds results (without ``overwrite``), is a file, looks like a file name, or cannot be
    made. ``report_dir`` as given: a trailing slash marks a dotted name as a folder. Returns
    the outermost folder created here (``report_dir`` or a missing parent), or None."""
    given_path(report_dir, what="report folder", hint="a folder name such as cmp/",
               error=OutputError)
    if Path(report_dir).suffix.lower() in _FILE_SUFFIXES and not names_a_folder(report_dir):
        raise OutputError(
            f"{report_dir}: the report goes in a folder (report.txt, .csv and .json are written "
            "inside it); give a folder name such as cmp/")
    report_dir = Path(report_dir)
    created = None
    for folder in (report_dir, *report_dir.parents):
        if folder.exists():
            break
        created = folder
    if created is None:
        if not report_dir.is_dir():
            raise OutputError(f"report folder {report_dir} exists and is not a folder")
        if any(report_dir.iterdir()) and not overwrite:
            raise OutputError(f"report folder {report_dir} exists and is not empty "
                              "(use --overwrite to replace its results)")
    try:
        report_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create report folder {report_dir}: {err.strerror}") from None
    return created


def remove_if_no_files(folder: Path) -> None:
    """Remove ``folder`` (made by this run, with any parents it needed) when it holds no file,
    only empty folders: a run refused before writing anything leaves no trace."""
    if folder.is_dir() and not any(p.is_file() for p in folder.rglob("*")):
        shutil.rmtree(folder, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# The outputs of this run, and those of a previous one (overwrite)
# --------------------------------------------------------------------------------------------

# Deepest output below the report folder: CATEGORY/NAME/<method> for a dataset root.
_MAX_OUTPUT_DEPTH = 3


class RunOutputs:
    """What a run writes in the report folder, and the one-time removal of a previous run's.

    With ``overwrite``, :meth:`clear_previous` (called once the first input and its ground
    truth are accepted, before anything is written) removes the outputs of the compare run that
    filled the folder before, and nothing else: see :func:`remove_previous_outputs`.
    """

    def __init__(self, root: Optional[Path], *, overwrite: bool, methods: Sequence[str],
                 protect: Sequence[Path]) -> None:
        self.root = root
        self.overwrite = overwrite
        self.methods = list(methods)
        self.protect = list(protect)
        self.paths: List[str] = []
        self._cleared = False

    def clear_previous(self) -> None:
        if self._cleared or self.root is None or not self.overwrite:
            return
        self._cleared = True
        remove_previous_outputs(self.root, methods=self.methods, protect=self.protect)

    def add(self, path: Path) -> None:
        if self.root is not None:
            rel = path.relative_to(self.root).as_posix()
            if rel not in self.paths:
                self.paths.append(rel)


def _previous_report(root: Path) -> Tuple[Optional[List[str]], List[str]]:
    """``(outputs, methods)`` listed by ``root/report.json``; outputs ``None`` when it lists
    none (no report, an unreadable one, or one without an ``"outputs"`` list)."""
    try:
        data = json.loads((root / "report.json").read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None, []
    if not isinstance(data, dict):
        return None, []
    methods = data.get("methods")
    methods = [m for m in methods if isinstance(m, str) and m] if isinstance(methods, list) \
        else []
    outputs = data.get("outputs")
    if not isinstance(outputs, list) or not all(isinstance(p, str) for p in outputs):
        return None, methods
    return list(outputs), methods


def _names_an_output(rel: str, methods: Sequence[str]) -> bool:
    """Whether ``rel`` (relative to the report folder) is a path compare writes: a report file
    (or ``report.html``) at the top, or ``[SEQUENCE/]side_by_side.mp4``, ``<method>`` or ``<method>.mkv`` at most
    :data:`_MAX_OUTPUT_DEPTH` levels down."""
    parts = rel.split("/")
    if not rel or rel.startswith("/") or "\\" in rel or len(parts) > _MAX_OUTPUT_DEPTH \
            or any(part in ("", ".", "..") for part in parts):
        return False
    name = parts[-1]
    if name in REPORT_FILES or name == HTML_REPORT:
        return len(parts) == 1
    return name == SIDE_BY_SIDE or name in methods or \
        (name.endswith(".mkv") and name[:-len(".mkv")] in methods)


def _outputs_by_name(root: Path, methods: Sequence[str]) -> List[str]:
    """The paths compare's naming rules give, for a folder whose report does not list them:
    the report files, and ``side_by_side.mp4``, ``<method>/`` and ``<method>.mkv`` at the top
    (a single input) or in folders one or two levels down (``NAME/``, ``CATEGORY/NAME/`` of a
    dataset root). Folders named after a method are mask folders, not sequences."""
    found = [*REPORT_FILES, HTML_REPORT]
    per_input = [SIDE_BY_SIDE, *methods, *(f"{m}.mkv" for m in methods)]
    level = [""]
    for depth in range(_MAX_OUTPUT_DEPTH):
        found += [f"{prefix}{name}" for prefix in level for name in per_input]
        if depth == _MAX_OUTPUT_DEPTH - 1:
            break
        below = []
        for prefix in level:
            try:
                children = sorted((root / prefix).iterdir())
            except OSError:
                continue
            below += [f"{prefix}{child.name}/" for child in children
                      if child.is_dir() and not child.is_symlink()
                      and child.name not in methods and not child.name.startswith(".")]
        level = below
    return found


def remove_previous_outputs(root: PathLike, *, methods: Sequence[str] = (),
                            protect: Sequence[PathLike] = ()) -> List[str]:
    """Remove what an earlier compare run wrote in the report folder ``root``, nothing else.

    The outputs are those the earlier run's ``report.json`` lists (``"outputs"``); without
    that list (no report, e.g. after Ctrl-C, or one without it) compare's naming
    rules find them (:func:`_outputs_by_name`), for the methods the report names, the
    registered engines and ``methods``. Of a mask folder only its ``binNNNNNN.png`` files go
    (and the folder, once empty); of a video or report file, the file and the temporary file
    an interrupted writer may have left. Folders emptied this way are removed up to ``root``.
    Other files stay. Symbolic links are never followed nor removed.

    Parameters
    ----------
    root : path
        The report folder.
    methods : sequence of str
        Method names besides the registered engines (those of the run about to start).
    protect : sequence of path
        What the run about to start reads (its input, its ground truth): refused when an
        output to remove is, or holds, one of them.

    Returns
    -------
    list of str
        The removed paths, relative to ``root``.

    Raises
    ------
    OutputError
        A protected path would be removed, or a file cannot be.
    """
    root = Path(root)
    listed, report_methods = _previous_report(root)
    names = list(dict.fromkeys([*report_methods, *(spec.name for spec in available_engines()),
                                *methods]))
    if listed is None:
        candidates = _outputs_by_name(root, names)
    else:
        candidates = [rel for rel in listed if _names_an_output(rel, names)]
    # What goes is gathered before anything is removed, so a protected input stops it all.
    files, folders = _previous_files(root, candidates, names)
    _refuse_protected([*files, *folders], protect)
    return _remove(root, files, folders)


def _previous_files(root: Path, candidates: Sequence[str], names: Sequence[str]
                    ) -> Tuple[List[Path], List[Path]]:
    """``(files, mask folders)`` to remove among the ``candidates`` paths (relative to
    ``root``): a mask folder's ``binNNNNNN.png`` files, a video's or report's file and the
    temporary file an interrupted writer leaves. Symbolic links are left alone."""
    files: List[Path] = []
    folders: List[Path] = []  # mask folders, removed once empty
    for rel in dict.fromkeys(candidates):
        path = root / rel
        name = path.name
        if path.is_symlink():
            continue
        if name in names and path.is_dir():  # a mask folder
            try:
                entries = sorted(path.iterdir())
            except OSError as err:
                raise OutputError(f"cannot read {path}: {err.strerror}") from None
            files += [entry for entry in entries if not entry.is_symlink() and entry.is_file()
                      and (MASK_NAME.fullmatch(entry.name)
                           or PARTIAL_MASK_NAME.fullmatch(entry.name))]
            folders.append(path)
        elif name in REPORT_FILES or name in (HTML_REPORT, SIDE_BY_SIDE) \
                or (name.endswith(".mkv") and name[:-len(".mkv")] in names):
            # The file, and the one an interrupted video writer leaves.
            partial = partial_path(path)
            files += [p for p in (path, partial) if p.is_file() and not p.is_symlink()]
    return files, folders


def _refuse_protected(paths: Sequence[Path], protect: Sequence[PathLike]) -> None:
    """:class:`OutputError` when one of ``paths`` is, or holds, one of ``protect``."""
    guarded = {Path(p).resolve() for p in protect}
    for path in paths:
        resolved = path.resolve()
        if resolved in guarded or any(parent in guarded for parent in resolved.parents):
            raise OutputError(f"{path} was written by an earlier bgsub compare but is part of "
                              "this run's input: --overwrite will not remove it; write the "
                              "report elsewhere")


def _remove(root: Path, files: Sequence[Path], folders: Sequence[Path]) -> List[str]:
    """Remove ``files``, then the folders left empty (``folders`` and the files' own) up to
    ``root``; returns the removed paths relative to ``root`` (folders end in ``/``)."""
    removed: List[str] = []
    emptied = set()
    for path in files:
        try:
            path.unlink()
        except FileNotFoundError:
            continue
        except OSError as err:
            raise OutputError(f"cannot remove {path} (left by an earlier bgsub compare): "
                              f"{err.strerror}") from None
        removed.append(path.relative_to(root).as_posix())
        emptied.add(path.parent)
    emptied.update(folders)
    # Deepest first, so a sequence folder is looked at after its mask folders.
    for folder in sorted(emptied, key=lambda p: len(p.parts), reverse=True):
        while folder != root and root in folder.parents:
            try:
                folder.rmdir()  # only when empty
            except OSError:
                break
            removed.append(folder.relative_to(root).as_posix() + "/")
            folder = folder.parent
    return removed
