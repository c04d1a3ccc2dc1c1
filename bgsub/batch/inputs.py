"""What a batch reads: the command line's inputs expanded into one item per video or sequence.

An argument becomes:

* a camera index, video device or URL (``0``, ``/dev/video0``, ``rtsp://...``) -- one live
  source, never globbed (a URL's ``?`` is a query), named ``camera0``, ``video0`` or after
  the URL's last path part;
* an existing file -- one video;
* a folder holding images (or a CDnet sequence folder, which holds ``input/``) -- one image
  sequence; a folder holding no images but video files -- each of those videos;
* a glob pattern -- one image sequence when it matches only images (``'frames/*.png'``), else
  each video file and folder it matches (``'flights/*.mp4'``, ``'cdnet/*/*'``);
* anything else (a missing file) -- one item, which then fails on its own with the reason, so
  a typo in one name does not stop the rest of the batch.

Each item is named after its input (``v1`` for ``v1.mp4``, ``traffic`` for the sequence folder
``traffic/``, ``frames`` for ``'frames/*.png'``); the outputs carry that name.
"""

from __future__ import annotations

import glob
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterable, List

from bgsub.errors import InputError
from bgsub.io.sources import IMAGE_EXTENSIONS, VIDEO_SUFFIXES, natural_key
from bgsub.io.streams import stream_kind, stream_name


@dataclass(frozen=True)
class BatchInput:
    """One input of a batch: ``path`` as given to :func:`bgsub.io.sources.open_source`, and the
    ``name`` its outputs are given."""

    path: str
    name: str


def _is_image(path: Path) -> bool:
    return path.suffix.lower() in IMAGE_EXTENSIONS and not path.name.startswith(".")


def _is_video(path: Path) -> bool:
    return path.suffix.lower() in VIDEO_SUFFIXES and not path.name.startswith(".") \
        and path.is_file()


def _holds_images(folder: Path) -> bool:
    if (folder / "input").is_dir():
        return True
    try:
        return any(_is_image(p) and p.is_file() for p in folder.iterdir())
    except OSError:
        return True  # open_source names the reason the folder cannot be listed


def _videos_in(folder: Path) -> List[Path]:
    return sorted((p for p in folder.iterdir() if _is_video(p)), key=lambda p: natural_key(p.name))


def _from_folder(text: str) -> List[BatchInput]:
    folder = Path(text)
    videos = [] if _holds_images(folder) else _videos_in(folder)
    if not videos:  # an image sequence (or a folder run then calls empty)
        return [BatchInput(text, folder.resolve().name)]
    return [BatchInput(str(p), p.stem) for p in videos]


def _from_glob(pattern: str) -> List[BatchInput]:
    matches = sorted((Path(p) for p in glob.glob(pattern)), key=lambda p: natural_key(str(p)))
    if matches and all(_is_image(p) for p in matches if p.is_file()) \
            and not any(p.is_dir() for p in matches):
        return [BatchInput(pattern, Path(pattern).parent.resolve().name or "frames")]
    found = [p for p in matches if _is_video(p) or p.is_dir()]
    if not found:
        return [BatchInput(pattern, "nothing")]  # "nothing matches this pattern" when run
    return [BatchInput(str(p), p.stem if p.is_file() else p.resolve().name) for p in found]


def expand(arguments: Iterable[str]) -> List[BatchInput]:
    """The batch items of the command line's input arguments, in the order given (a folder's or
    a pattern's videos in natural order). Raises :class:`InputError` when two items would get
    the same name, and so write the same outputs."""
    items: List[BatchInput] = []
    for text in arguments:
        path = Path(text)
        if stream_kind(text) is not None:
            items.append(BatchInput(text, stream_name(text)))
        elif path.is_dir():
            items += _from_folder(text)
        elif not path.exists() and glob.has_magic(text):
            items += _from_glob(text)
        else:
            items.append(BatchInput(text, path.stem or text))
    _check_names(items)
    return items


def is_batch(arguments: List[str]) -> bool:
    """Whether the command line's inputs make a batch (several items, or a folder or pattern of
    videos) rather than the one input of a single run."""
    if len(arguments) != 1:
        return True
    items = expand(arguments)
    return len(items) != 1 or os.fspath(items[0].path) != arguments[0]


def _check_names(items: List[BatchInput]) -> None:
    seen: Dict[str, BatchInput] = {}
    for item in items:
        other = seen.get(item.name)
        if other is not None and Path(other.path).resolve() == Path(item.path).resolve():
            raise InputError(f"{item.path} is given twice")
        if other is not None:
            raise InputError(f"{other.path} and {item.path} would both write outputs named "
                             f"{item.name!r}; give them in separate batches (each with its "
                             "own -o folder)")
        seen[item.name] = item
