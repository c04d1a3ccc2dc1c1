"""Output paths: the checks every command runs before writing, and the names outputs are
written under.

* ``check_*_output`` refuse, before any frame is processed, an output that exists (without
  ``overwrite``), has an extension nothing can write, is a folder where a file is meant (or the
  reverse), or whose folder is missing or read-only; nothing is written.
* :func:`partial_path` is the hidden temporary name a video or motion file is written under
  before it is renamed to its final name; :class:`OutputClaim` makes sure only one run writes it.
* :func:`write_atomically` writes a small file (a report, a model) under a temporary name and
  renames it.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import sys
import uuid
from pathlib import Path
from typing import Optional, Union

from bgsub.errors import BgsubError, OutputError, ProcessingError, given_path

try:
    import fcntl
except ImportError:  # (Windows: outputs are not claimed)
    fcntl = None  # type: ignore[assignment]

PathLike = Union[str, "os.PathLike[str]"]

#: Mask video codecs by extension: FFV1 is lossless, mp4v is not (masks come back blurred).
MASK_VIDEO_CODECS = {".mkv": "FFV1", ".avi": "FFV1", ".mp4": "mp4v", ".mov": "mp4v"}

#: Picture video codecs by extension, chosen to play in common players.
PICTURE_VIDEO_CODECS = {".mp4": "mp4v", ".mov": "mp4v", ".avi": "MJPG", ".mkv": "FFV1"}

LOSSY_CODECS = {"mp4v", "MJPG"}

MASK_NAME = re.compile(r"bin\d{6}\.png")
PARTIAL_MASK_NAME = re.compile(r"\.bin\d{6}\.partial\.png")


def say(message: str) -> None:
    """``bgsub: message`` on stderr, at once (a run's progress bar shares the line)."""
    print(f"bgsub: {message}", file=sys.stderr, flush=True)


def frames_text(n: int) -> str:
    """``"1 frame"``, ``"3 frames"``."""
    return f"{n} frame{'s' * (n != 1)}"


def is_video_path(path: PathLike) -> bool:
    """True when ``path``'s extension makes :func:`open_mask_sink` write a video."""
    return Path(path).suffix.lower() in MASK_VIDEO_CODECS


def write_error(path: Path, what: str, err: OSError) -> BgsubError:
    """The error for a failed write of ``what`` to ``path``: a full disk (or quota) is a
    :class:`ProcessingError`, as for videos; any other cause an :class:`OutputError`."""
    if err.errno == errno.ENOSPC:
        return ProcessingError(f"{path}: the disk is full, cannot write {what}")
    if err.errno == getattr(errno, "EDQUOT", None):
        return ProcessingError(f"{path}: the disk quota is exceeded, cannot write {what}")
    return OutputError(f"{path}: cannot write {what} ({err.strerror or err})")


def partial_path(path: Path) -> Path:
    # Same folder (so the final rename is atomic) and same extension (OpenCV picks the container
    # from it); the leading dot hides it from most file listings while it is being written.
    return path.with_name(f".{path.stem}.partial{path.suffix}")


class OutputClaim:
    """This run's exclusive claim on a file or folder it writes an output through.

    Two runs writing the same output at once would each delete or overwrite the other's
    temporary file and lose both outputs; the second is refused instead, before it writes
    anything. The claim is an advisory lock (``flock``) on the temporary file itself (created if
    missing, emptied once claimed) or on the mask folder. A lock ends with :meth:`release` or
    with the process, so a file a killed run left behind is claimed again (stale), and nothing
    is left behind for the claim itself. Where the system or file system has no such locks,
    nothing is locked.

    Parameters
    ----------
    path : Path
        The temporary file (or, with ``folder``, the existing folder) to claim.
    output : Path
        The output it is for, as errors name it.
    overwrite : bool
        Without it, an ``output`` that exists once the claim is held is refused: another run
        finished it in the meantime.
    folder : bool
        ``path`` is a folder (nothing is created or emptied).

    Raises
    ------
    OutputError
        Another run holds the claim, the output appeared meanwhile, or ``path`` cannot be
        created.
    """

    def __init__(self, path: Path, *, output: Path, overwrite: bool = False,
                 folder: bool = False) -> None:
        self.path = path
        self._fd = _lock(path, output=output, folder=folder)
        if not overwrite and not folder and output.exists():
            self.release()
            raise OutputError(f"{output}: already exists: another run finished it meanwhile "
                              "(--overwrite, or overwrite=True, replaces it)")
        if self._fd is not None and not folder:
            os.ftruncate(self._fd, 0)  # what a killed run left

    @property
    def held(self) -> bool:
        """Whether this claim still holds its lock (False where locks are not available)."""
        return self._fd is not None

    def release(self) -> None:
        """End the claim (the file or folder stays)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)  # (closing the only descriptor of the lock releases it)


def _lock(path: Path, *, output: Path, folder: bool) -> Optional[int]:
    """A descriptor of ``path`` holding its exclusive ``flock``, or None where locks are not
    available; :class:`OutputError` when another process holds it."""
    if fcntl is None:
        return None
    flags = (os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)) if folder else (os.O_RDWR | os.O_CREAT)
    for _ in range(5):  # (the name moved to another file between open and lock: again)
        try:
            fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0), 0o666)
        except OSError as err:
            raise OutputError(f"{output}: cannot create a file there "
                              f"({err.strerror or err})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(fd)
            if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise OutputError(f"{output}: another run is writing it now; wait for it to "
                                  "end or choose another name") from None
            return None  # a file system without locks (ENOLCK, EOPNOTSUPP)
        if _same_file(fd, path):
            return fd
        os.close(fd)
    raise OutputError(f"{output}: another run is writing it now; wait for it to end or choose "
                      "another name")


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except OSError:
        return False


def why_not_writable(path: Path) -> str:
    """``"cannot create a file there (reason); "`` when the system refuses a new file at
    ``path`` (which must not exist), else ``""``: a writer library's failure names no cause,
    and a folder can refuse files although it looks writable (``/proc``)."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as err:
        return f"cannot create a file there ({err.strerror or err}); "
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(path)
    return ""


def output_path(path: PathLike) -> Path:
    return Path(given_path(path, what="output", hint="a file or folder name", error=OutputError))


def check_writable_folder(folder: Path, output: Path) -> None:
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if existing.exists() and not existing.is_dir():  # afile/sub/m.mkv: name the file
        raise OutputError(f"{output}: {existing} is not a folder")
    if not folder.is_dir():
        raise OutputError(f"{output}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        read_only = getattr(os, "ST_RDONLY", None)  # POSIX only
        reason = ("on a read-only file system"
                  if read_only is not None and os.statvfs(folder).f_flag & read_only
                  else "not writable (permission denied)")
        raise OutputError(f"{output}: cannot write there, the folder {folder} is {reason}")


def check_file_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that a file (a report, a model) can be written at ``path``; return it as a
    :class:`Path`. :class:`OutputError` when it is a folder, exists (without ``overwrite``),
    or its folder is missing or read-only. Nothing is written."""
    output = output_path(path)
    if output.is_dir():
        raise OutputError(f"{output}: is a folder; give a file name")
    if output.exists() and not overwrite:
        raise OutputError(f"{output}: already exists (--overwrite, or overwrite=True, replaces "
                          "it)")
    check_writable_folder(output.parent, output)  # Path("x").parent is Path(".")
    return output


def write_atomically(path: Path, data: bytes, *, what: str) -> None:
    """Write ``data`` under a temporary name in the same folder, then rename it to ``path``.

    A failed write (disk full, read-only folder) never leaves a partial file, nor destroys the
    file it was to replace; the error names the system's reason. The file gets the usual
    permissions (``0o666`` less the umask), not the ``0o600`` of ``tempfile.mkstemp``.
    """
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.part")
    try:
        # O_EXCL: a fresh file of our own; mode 0o666 is reduced by the umask, as for open().
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as err:
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None


def names_a_folder(path: PathLike) -> bool:
    """True when ``path`` is an existing folder or ends in a path separator (``out.v2/``):
    :class:`Path` drops a trailing slash, so look at the text as given."""
    text = os.fspath(path)
    return Path(text).is_dir() or text.endswith(tuple(filter(None, (os.sep, os.altsep))))


def check_video_output(path: PathLike, *, overwrite: bool = False,
                       codecs: Optional[dict] = None) -> Path:
    """Check that a video can be written at ``path``; return it as a :class:`Path`.

    Raises :class:`OutputError` when it exists (without ``overwrite``), is a folder, has an
    extension with no codec in ``codecs`` (default: :data:`PICTURE_VIDEO_CODECS`), or its folder
    is missing or read-only. Nothing is written.
    """
    codecs = PICTURE_VIDEO_CODECS if codecs is None else codecs
    output = output_path(path)
    if output.suffix.lower() not in codecs:
        known = ", ".join(sorted(codecs))
        raise OutputError(f"{output}: cannot write a video with this extension (use {known})")
    if output.is_dir():
        raise OutputError(f"{output}: is a folder, not a video file")
    return check_file_output(output, overwrite=overwrite)


def check_mask_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that :func:`open_mask_sink` can write masks at ``path``; nothing is written.

    A name with a mask video extension (:data:`MASK_VIDEO_CODECS`) is a video; a name without an
    extension, an existing folder, or a name ending in a slash is a folder of PNGs; any other
    extension is refused. A mask folder "exists" when it already holds ``binNNNNNN.png`` masks;
    an empty or unrelated folder is fine. Raises :class:`OutputError` otherwise (see
    :func:`check_video_output`).
    """
    output = output_path(path)
    suffix = output.suffix.lower()
    if suffix in MASK_VIDEO_CODECS:
        return check_video_output(output, overwrite=overwrite, codecs=MASK_VIDEO_CODECS)
    if suffix and not names_a_folder(path):
        # masks.txt, mask.png, masks.webm: a file was meant, and a folder of that name would
        # surprise. A dotted folder name is still fine when it exists or ends in a slash.
        raise OutputError(
            f"{output}: cannot write masks to a {suffix} file; give a video ending in .mkv or "
            ".avi (lossless) or .mp4 or .mov (lossy), or a folder for binNNNNNN.png masks: a "
            f"name without an extension, or one ending in a slash ({output.name}/)"
        )
    if output.exists() and not output.is_dir():
        raise OutputError(f"{output}: is a file, not a folder for masks")
    if output.is_dir():
        if not overwrite and any(MASK_NAME.fullmatch(p.name) for p in output.iterdir()):
            raise OutputError(f"{output}: already holds masks (binNNNNNN.png); use --overwrite "
                              "to replace them")
        check_writable_folder(output, output)
    else:
        check_new_folder(output, output)
    return output


def check_new_folder(folder: Path, output: Path) -> None:
    """Check that the missing ``folder`` can be created for ``output``: its nearest existing
    ancestor is a writable folder (:class:`OutputError` naming ``output`` otherwise)."""
    ancestor = folder.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    check_writable_folder(ancestor, output)


def check_motion_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that a motion file (``.npy``) can be written at ``path``; nothing is written."""
    output = check_file_output(path, overwrite=overwrite)
    if output.suffix.lower() != ".npy":
        raise OutputError(f"{output}: a motion file is a .npy array; give a name ending in .npy")
    return output
