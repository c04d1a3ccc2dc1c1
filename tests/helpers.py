"""Helper functions and test doubles the tests import (``from helpers import ...``); the shared
fixtures are in conftest.py."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import pytest


def one_error_line(argv, capfd, *, code: int = 2) -> str:
    """Run ``bgsub argv``; check its exit status and that stderr (every writer, native libraries
    too: ``capfd`` captures the file descriptor) is exactly one ``bgsub: error:`` line; return
    that line."""
    from bgsub.cli import main

    rc = main([str(a) for a in argv])
    err = capfd.readouterr().err
    assert rc == code, err
    assert "Traceback" not in err
    assert err.startswith("bgsub: error:") and err.count("\n") == 1, err
    return err


def batch_results(capsys, argv) -> list:
    """Run the batch ``bgsub argv --json`` (it must succeed); ``(status, message)`` of each of
    its inputs, from its summary."""
    import json

    from bgsub.cli import main

    assert main(argv + ["--json"]) == 0
    return [(r["status"], r["message"]) for r in json.loads(capsys.readouterr().out)["results"]]


class OracleMatcher:
    """Exhaustive SSD block matching over integer shifts within +-max_disp (test double)."""

    patch_size = 13
    meta = {"max_disp": 3}

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        p = self.patch_size
        x = x_raw.reshape(-1, p, p)
        y = y_raw.reshape(-1, p, p)
        best = np.full(len(x), np.inf)
        disp = np.zeros((len(x), 2), np.float32)
        for dy in range(-max_disp, max_disp + 1):
            for dx in range(-max_disp, max_disp + 1):
                xs = x[:, max(0, -dy):p - max(0, dy), max(0, -dx):p - max(0, dx)]
                ys = y[:, max(0, dy):p - max(0, -dy), max(0, dx):p - max(0, -dx)]
                err = ((xs - ys) ** 2).mean(axis=(1, 2))
                better = err < best
                best[better] = err[better]
                disp[better] = (dx, dy)
        return disp, np.ones(len(x), np.float32), np.zeros(len(x), bool)


_NATURAL = {}


def model_path():
    """grbm needs a model file: the shipped natural model when installed, else skip."""
    from bgsub.errors import ModelError
    from bgsub.model.rbm import load_model

    if "m" not in _NATURAL:
        try:
            load_model("natural")
            _NATURAL["m"] = "natural"
        except ModelError as err:
            pytest.skip(f"shipped natural model not installed: {err}")
    return _NATURAL["m"]


def random_texture(h, w, seed=0):
    """A smooth random texture: ``(h + 8, w + 8) uint8`` (crop it to ``[:h, :w]``)."""
    import cv2

    rng = np.random.default_rng(seed)
    img = rng.random((h // 4 + 1, w // 4 + 1)).astype(np.float32)
    img = cv2.resize(img, (w + 8, h + 8), interpolation=cv2.INTER_CUBIC)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def shifted(img, dx, dy, h, w):
    """``img`` moved by ``(dx, dy)`` px (bilinear, edges reflected), cropped to ``(h, w)``."""
    import cv2

    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


# --------------------------------------------------------------------------------------------
# Small CDnet sequences and predictions on disk (evaluation and compare tests)
# --------------------------------------------------------------------------------------------


def write_gt_sequence(folder, gts, *, temporal_roi=None, roi=None):
    """A CDnet sequence folder holding ground truth only: ``groundtruth/gtNNNNNN.png`` for each
    ``{frame_number: (H, W) uint8 labels}`` of ``gts``, optional ``temporalROI.txt`` from
    ``(first, last)`` and ``ROI.bmp`` from an ``(H, W) uint8`` image. Returns ``folder``."""
    import cv2

    (folder / "groundtruth").mkdir(parents=True)
    for number, gt in gts.items():
        cv2.imwrite(str(folder / "groundtruth" / f"gt{number:06d}.png"), gt)
    if temporal_roi is not None:
        (folder / "temporalROI.txt").write_text(f"{temporal_roi[0]} {temporal_roi[1]}\n")
    if roi is not None:
        cv2.imwrite(str(folder / "ROI.bmp"), roi)
    return folder


def write_bins(folder, masks):
    """A folder of ``binNNNNNN.png`` masks from ``{frame_number: (H, W) uint8}``."""
    import cv2

    folder.mkdir(parents=True)
    for number, mask in masks.items():
        cv2.imwrite(str(folder / f"bin{number:06d}.png"), mask)
    return folder


def write_mask_video(path, masks):
    """A lossless mask video (FFV1 ``.mkv``) of ``masks``, ``(H, W) uint8`` each, in order."""
    from bgsub.io.sinks import open_mask_sink

    h, w = masks[0].shape
    with open_mask_sink(path, width=w, height=h, fps=25.0) as sink:
        for k, mask in enumerate(masks):
            sink.write(mask, k)
    return path


#: Frame size of :func:`write_input_sequence`.
SCENE_W, SCENE_H = 64, 48


def write_input_sequence(folder, *, n_frames=8, side=10, speed=4, seed=0, temporal_roi=None,
                         roi=None):
    """A tiny CDnet sequence with its input: static textured background, a bright square moving
    right by ``speed`` pixels a frame.

    ``input/inNNNNNN.png`` (lossless, so no test depends on JPEG), ``groundtruth/gtNNNNNN.png``
    (0/255), optional ``temporalROI.txt`` (the text ``"first last"``) and ``ROI.bmp``
    (``(SCENE_H, SCENE_W) uint8``); frames are ``SCENE_W x SCENE_H``.
    """
    import cv2

    rng = np.random.default_rng(seed)
    background = rng.integers(40, 120, size=(SCENE_H, SCENE_W), dtype=np.uint8)
    (folder / "input").mkdir(parents=True)
    (folder / "groundtruth").mkdir()
    for k in range(n_frames):
        frame = background.copy()
        gt = np.zeros((SCENE_H, SCENE_W), np.uint8)
        x, y = 2 + speed * k, 12 + seed
        frame[y:y + side, x:x + side] = 230
        gt[y:y + side, x:x + side] = 255
        cv2.imwrite(str(folder / "input" / f"in{k + 1:06d}.png"),
                    cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
        cv2.imwrite(str(folder / "groundtruth" / f"gt{k + 1:06d}.png"), gt)
    if temporal_roi is not None:
        (folder / "temporalROI.txt").write_text(temporal_roi + "\n")
    if roi is not None:
        cv2.imwrite(str(folder / "ROI.bmp"), roi)
    return folder


def write_box_clip(path, *, seed=0, n=12, width=64, height=48):
    """A small lossless FFV1 video (``n`` frames, ``(height, width, 3)``) of a bright box moving
    3 px a frame to the right over dark noise; returns ``path``."""
    return _write_box_video(path, "FFV1", speed=3, seed=seed, n=n, width=width, height=height)


def write_mp4_clip(path, *, seed=0, n=20, width=64, height=48):
    """A small MPEG-4 ``.mp4`` of ``write_box_clip``'s scene (lossy, the box moving 2 px a
    frame); returns ``path``."""
    return _write_box_video(path, "mp4v", speed=2, seed=seed, n=n, width=width, height=height)


def write_pan_clip(path, *, seed=0, n=30, width=320, height=240, fourcc="MJPG", burn_in=None):
    """An ``.avi`` (``fourcc``, Motion-JPEG by default) of ``n`` frames of the ``bgsub samples``
    pan scene (camera panning 2-5 px a frame, objects crossing), each frame passed through
    ``burn_in`` (image -> image: a logo, a watermark) when given; returns ``path``."""
    import cv2

    from bgsub.samples import SceneSpec, render_frames

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 25, (width, height))
    for frame in render_frames(SceneSpec("pan", seed=seed, width=width, height=height,
                                         n_frames=n)):
        writer.write(frame.image if burn_in is None else burn_in(frame.image))
    writer.release()
    return path


def _write_box_video(path, fourcc, *, speed, seed, n, width, height):
    import cv2

    rng = np.random.default_rng(seed)
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), 25.0,
                             (width, height), True)
    for k in range(n):
        frame = rng.integers(0, 40, (height, width, 3), dtype=np.uint8)
        frame[15:30, speed * k:speed * k + 12] = 230
        writer.write(frame)
    writer.release()
    return path


@contextlib.contextmanager
def serve_folder(folder, *, cut_at=None, hold=0.0):
    """Serve the files of ``folder`` over HTTP from 127.0.0.1 in a thread; yields the base URL
    (``http://127.0.0.1:PORT/``). Byte ranges are served, as video players ask for them (an
    ``.mp4`` keeps its index at its end). With ``cut_at`` (a fraction), every response sends
    only that part of the file, waits ``hold`` seconds, and closes: a stream that stalls
    (``hold`` longer than the reader's timeout) or drops (no ``hold``)."""
    import http.server
    import re
    import time

    root = Path(folder)

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            path = root / self.path.lstrip("/").split("?")[0]
            if not path.is_file():
                self.send_error(404)
                return
            data = path.read_bytes()
            found = re.match(r"bytes=(\d+)-(\d*)", self.headers.get("Range", ""))
            if cut_at is not None:
                self.send_response(200)
                body = data[:int(len(data) * cut_at)]
            elif found:
                first = int(found.group(1))
                last = int(found.group(2) or len(data) - 1)
                self.send_response(206)
                self.send_header("Content-Range", f"bytes {first}-{last}/{len(data)}")
                body = data[first:last + 1]
            else:
                self.send_response(200)
                body = data
            if cut_at is None:
                self.send_header("Accept-Ranges", "bytes")
                self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            try:
                self.wfile.write(body)
                self.wfile.flush()
                time.sleep(hold)
            except OSError:  # the reader went away
                pass

    with http_server(Handler) as url:
        yield url


@contextlib.contextmanager
def http_server(handler):
    """Serve with ``handler`` (a request handler class, or a factory of one) from 127.0.0.1
    in a thread; yields the base URL (``http://127.0.0.1:PORT/``)."""
    import http.server
    import threading

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def read_frames(path) -> list:
    """Every frame OpenCV decodes from the video file at ``path``, as ``(H, W, 3) uint8``."""
    import cv2

    capture = cv2.VideoCapture(str(path))
    frames = []
    ok, frame = capture.read()
    while ok:
        frames.append(frame)
        ok, frame = capture.read()
    capture.release()
    return frames
