"""Speed benchmark: frames per second of each engine's per-frame step.

The clip is generated in memory before timing starts (a synthetic moving-camera scene from
:mod:`bgsub.samples`), so decoding and writing are excluded: only ``engine.apply(frame)`` is
timed. Each method runs ``repeats`` times on a fresh engine; the reported figure is the median.
The machine (CPU, cores, library versions, BLAS threads, date) is described with the figures,
since frames per second mean nothing without it.

Example::

    from bgsub.evaluation.bench import bench_methods
    report = bench_methods(methods=["mog2", "grbm"], width=320, height=240, frames=50)
    print(report.to_text())
"""

from __future__ import annotations

import ctypes
import datetime as _dt
import multiprocessing
import os
import platform
import resource
import statistics
import sys
import time
from dataclasses import asdict, dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.engines import available_engines, create_engine, get_engine_spec
from bgsub.errors import InputError, ProcessingError
from bgsub.samples import SceneSpec, render_frames

#: What the figures measure, printed with every report.
TIMING_NOTE = (
    "fps = frames / seconds spent inside engine.apply(); the clip is generated in memory "
    "beforehand, so decoding and writing are excluded. Median over repeats, each on a fresh "
    "engine after one untimed warm-up frame."
)


def _count(n: int, noun: str) -> str:
    """``"1 thread"``, ``"2 threads"``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


@dataclass(frozen=True)
class MachineInfo:
    """The machine a benchmark ran on."""

    cpu: str
    logical_cores: int
    usable_cores: int  # the cores this process may run on (affinity)
    platform: str
    python: str
    numpy: str
    opencv: str
    blas: str
    blas_threads: Optional[int]  # None when the BLAS library cannot be asked
    opencv_threads: int
    thread_env: Dict[str, str]  # OMP_NUM_THREADS & co. as set in the environment
    load_average: Optional[float]  # 1-minute load when the benchmark started (None: unknown)
    date: str  # ISO 8601, UTC

    def to_text(self) -> str:
        env = ", ".join(f"{k}={v}" for k, v in self.thread_env.items()) or "none set"
        blas_threads = "unknown threads" if self.blas_threads is None else \
            _count(self.blas_threads, "thread")
        load = "unknown" if self.load_average is None else \
            f"{self.load_average:.2f} (1-minute average at the start)"
        if self.load_average is not None and self.load_average > 0.5 * self.usable_cores:
            load += "; other programs were busy: expect lower, noisier figures"
        return "\n".join(
            [
                f"machine : {self.cpu}, {_count(self.logical_cores, 'logical core')} "
                f"({self.usable_cores} usable)",
                f"system  : {self.platform}, Python {self.python}",
                f"libs    : numpy {self.numpy} (BLAS {self.blas}, {blas_threads}), "
                f"OpenCV {self.opencv} ({_count(self.opencv_threads, 'thread')})",
                f"threads : {env}",
                f"load    : {load}",
                f"date    : {self.date}",
            ]
        )


@dataclass(frozen=True)
class BenchResult:
    """Speed of one method.

    ``fps_runs`` holds one figure per repeat; ``fps`` is their median. With memory measurement
    on, each method runs in its own child process: ``peak_rss_mib`` is that child's peak
    resident memory (``ru_maxrss``; it includes the interpreter and the clip, but not library
    pages the child never touched) and ``rss_growth_mib`` how much that peak rose above the
    child's resident memory at its start, i.e. what the method itself needed. ``None`` when
    not measured.
    """

    method: str
    fps: float
    fps_runs: List[float]
    ms_per_frame: float
    peak_rss_mib: Optional[float] = None
    rss_growth_mib: Optional[float] = None


@dataclass
class BenchReport:
    """All results of :func:`bench_methods` plus what is needed to interpret them."""

    width: int
    height: int
    frames: int
    repeats: int
    clip: str
    machine: MachineInfo
    results: List[BenchResult] = field(default_factory=list)
    note: str = TIMING_NOTE

    def to_dict(self) -> Dict[str, Any]:
        """A JSON-serialisable view of the report."""
        return asdict(self)

    def to_text(self) -> str:
        """The report as a small fixed-width table with the machine description."""
        has_mem = any(r.peak_rss_mib is not None for r in self.results)
        header = f"{'method':<14}{'fps (median)':>14}{'ms/frame':>10}  runs (fps)"
        if has_mem:
            header += "  | peak RSS MiB (growth)"
        lines = [
            f"bgsub bench: {_count(self.frames, 'frame')} of {self.width}x{self.height}, "
            f"{_count(self.repeats, 'run')} per method; clip: {self.clip}",
            self.note,
            "",
            header,
            "-" * len(header),
        ]
        for r in self.results:
            runs = " ".join(f"{f:.1f}" for f in r.fps_runs)
            line = f"{r.method:<14}{r.fps:>14.1f}{r.ms_per_frame:>10.2f}  {runs}"
            if has_mem:
                mem = "-" if r.peak_rss_mib is None else f"{r.peak_rss_mib:.0f}"
                if r.rss_growth_mib is not None:
                    mem += f" (+{r.rss_growth_mib:.0f})"
                line += f"  | {mem}"
            lines.append(line)
        lines += ["", self.machine.to_text()]
        return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# machine description


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def _blas_name() -> str:
    try:
        config = np.show_config(mode="dicts")
        blas = config["Build Dependencies"]["blas"]
        return f"{blas.get('name', '?')} {blas.get('version', '')}".strip()
    except Exception:  # older numpy has no mode="dicts"; the name is only informative
        return "unknown"


def _blas_threads() -> Optional[int]:
    """Threads the loaded OpenBLAS uses, asked through its C API; ``None`` if not found."""
    try:
        with open("/proc/self/maps", encoding="utf-8") as fh:
            libs = sorted(
                {
                    line.split()[-1]
                    for line in fh
                    if "openblas" in line.lower() and line.split()[-1].startswith("/")
                }
            )
    except OSError:
        return None
    names = (
        "scipy_openblas_get_num_threads64_",
        "scipy_openblas_get_num_threads",
        "openblas_get_num_threads64_",
        "openblas_get_num_threads",
    )
    for path in libs:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in names:
            func = getattr(lib, name, None)
            if func is not None:
                func.restype = ctypes.c_int
                return int(func())
    return None


def _load_average() -> Optional[float]:
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):  # not available on Windows
        return None


def machine_info() -> MachineInfo:
    """Describe this machine: CPU model, cores, library versions, thread settings, date."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count() or 1
    env_keys = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    return MachineInfo(
        cpu=_cpu_model(),
        logical_cores=os.cpu_count() or 1,
        usable_cores=usable,
        platform=platform.platform(),
        python=platform.python_version(),
        numpy=np.__version__,
        opencv=cv2.__version__,
        blas=_blas_name(),
        blas_threads=_blas_threads(),
        opencv_threads=cv2.getNumThreads(),
        thread_env={k: os.environ[k] for k in env_keys if k in os.environ},
        load_average=_load_average(),
        date=_dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
    )


# --------------------------------------------------------------------------------------------
# the clip

# The smallest frames bgsub.samples renders (SceneSpec refuses smaller ones).
_SCENE_MIN_SIZE = (64, 48)


def _panning_texture(width: int, height: int, n_frames: int, seed: int) -> np.ndarray:
    """Fallback clip: a smooth random texture panned 2 px/frame with a square moving across.

    Returns ``(n_frames, height, width, 3) uint8``.
    """
    rng = np.random.default_rng(seed)
    margin = 2 * n_frames + 4
    noise = rng.random((height + margin, width + margin), dtype=np.float32)
    texture = cv2.GaussianBlur(noise, (0, 0), 2.0)
    texture = cv2.normalize(texture, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    side = max(4, min(width, height) // 6)
    frames = np.empty((n_frames, height, width, 3), np.uint8)
    for k in range(n_frames):
        view = texture[k : k + height, 2 * k : 2 * k + width].copy()
        x = (5 * k) % max(1, width - side)
        view[height // 3 : height // 3 + side, x : x + side] = 255
        frames[k] = cv2.cvtColor(view, cv2.COLOR_GRAY2BGR)
    return frames


def make_clip(*, width: int, height: int, n_frames: int,
              seed: int = 0) -> Tuple[np.ndarray, str]:
    """The benchmark clip, held in memory.

    A panning scene from :mod:`bgsub.samples` (camera moving 2-5 px/frame, objects crossing);
    frames smaller than those scenes allow (64x48) get a panning random texture instead.

    Returns
    -------
    frames : (n_frames, height, width, 3) uint8 BGR array
    description : str
        What the clip is, for the report.
    """
    if width < _SCENE_MIN_SIZE[0] or height < _SCENE_MIN_SIZE[1]:
        return (_panning_texture(width, height, n_frames, seed),
                f"panning random texture with a moving square (seed {seed})")
    # Frames render lazily, so a long scene costs only the frames taken; scenes of 100 frames
    # or more let objects cross the view at a natural pace.
    spec = SceneSpec("pan", seed=seed, width=width, height=height, n_frames=max(100, n_frames))
    frames = np.empty((n_frames, height, width, 3), np.uint8)
    for k, scene_frame in zip(range(n_frames), render_frames(spec)):
        frames[k] = scene_frame.image
    return frames, (f"bgsub.samples 'pan' scene, seed {seed} (camera panning 2-5 px/frame, "
                    "moving objects)")


# --------------------------------------------------------------------------------------------
# timing


def time_engine(method: str, params: Mapping[str, Any], frames: np.ndarray) -> float:
    """Seconds spent in ``apply`` over ``frames[1:]``, on a fresh engine warmed on ``frames[0]``."""
    engine = create_engine(method, **params)
    engine.apply(frames[0])  # untimed: first frames often only store state
    elapsed = 0.0
    for frame in frames[1:]:
        t0 = time.perf_counter()
        engine.apply(frame)
        elapsed += time.perf_counter() - t0
    return elapsed


def _run_method(method: str, params: Mapping[str, Any], frames: np.ndarray,
                repeats: int) -> List[float]:
    """Frames per second of each of ``repeats`` runs, each on a fresh engine."""
    n = len(frames) - 1
    return [n / max(time_engine(method, params, frames), 1e-9) for _ in range(repeats)]


def _peak_rss_mib() -> float:
    # ru_maxrss is KiB on Linux, bytes on macOS.
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def _child(conn: Any, method: str, params: Mapping[str, Any], frames: np.ndarray,
           repeats: int) -> None:
    """Body of the child process: run one method, send back fps and memory figures."""
    try:
        start = _peak_rss_mib()
        runs = _run_method(method, params, frames, repeats)
        peak = _peak_rss_mib()
        conn.send(("ok", runs, (peak, peak - start)))
    except BaseException as err:  # reported in the parent
        conn.send(("error", f"{type(err).__name__}: {err}", None))
    finally:
        conn.close()


def _run_in_child(method: str, params: Mapping[str, Any], frames: np.ndarray, repeats: int):
    """Run one method in a child process so its peak memory is its own."""
    # "spawn", a fresh interpreter, not "fork": a child forked after OpenCV started its worker
    # threads inherits the thread pool's lock but not its threads, and cv2.setNumThreads()
    # (limited_threads, every grbm/compensated frame) then waits on it forever.
    ctx = multiprocessing.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, method, params, frames, repeats))
    proc.start()
    child.close()
    try:
        status, payload, peak = parent.recv()
    except EOFError:
        status, payload, peak = "error", f"child process died (exit code {proc.exitcode})", None
    proc.join()
    if status != "ok":
        raise ProcessingError(f"bench: method {method!r} failed: {payload}")
    return payload, peak


def bench_methods(
    *,
    methods: Optional[Sequence[str]] = None,
    width: int = 320,
    height: int = 240,
    frames: int = 50,
    repeats: int = 3,
    params: Optional[Mapping[str, Mapping[str, Any]]] = None,
    memory: bool = False,
    seed: int = 0,
    progress: Any = None,
) -> BenchReport:
    """Measure frames per second of each engine's ``apply`` on a generated clip.

    Parameters
    ----------
    methods : names of registered engines; default all registered engines.
    width, height : frame size in pixels, at least 16 x 16, odd or even (nothing is written).
        From 64 x 48 the clip is a :mod:`bgsub.samples` scene, below it a panning texture.
    frames : timed frames per run (one more, untimed, warms each engine up).
    repeats : runs per method; the median fps is reported.
    params : ``{method: {param: value}}`` engine parameters.
    memory : measure each method's peak RSS in its own child process (Linux/macOS).
    seed : seed of the generated clip.
    progress : optional ``callable(iterable, total=, desc=)`` wrapping the method loop (a bar).

    Returns
    -------
    BenchReport
    """
    if width < 16 or height < 16:
        raise InputError(f"bench: frame size {width}x{height} is too small (at least 16x16; "
                         f"below {_SCENE_MIN_SIZE[0]}x{_SCENE_MIN_SIZE[1]}, the smallest sample "
                         "scene, the clip is a panning random texture)")
    if frames < 1 or repeats < 1:
        raise InputError("bench: --max-frames and --repeats must be at least 1")
    if seed < 0:
        raise InputError(f"bench: the seed must be >= 0, not {seed}")
    names = list(methods) if methods else [spec.name for spec in available_engines()]
    if not names:
        raise InputError("bench: no engines are registered")
    params = dict(params or {})
    unknown = sorted(set(params) - set(names))
    if unknown:
        raise InputError(f"bench: --param for {unknown[0]!r}, which is not among the methods")
    for name in names:
        # Unknown names, bad parameters and missing model files fail before any timing.
        get_engine_spec(name).create(**params.get(name, {}))

    clip, description = make_clip(width=width, height=height, n_frames=frames + 1, seed=seed)
    report = BenchReport(
        width=width, height=height, frames=frames, repeats=repeats, clip=description,
        machine=machine_info(),
    )
    in_child = memory and sys.platform != "win32"  # ru_maxrss is POSIX
    iterator = progress(names, total=len(names), desc="bench") if progress else names
    for name in iterator:
        method_params = params.get(name, {})
        peak: Optional[float] = None
        growth: Optional[float] = None
        if in_child:
            runs, (peak, growth) = _run_in_child(name, method_params, clip, repeats)
        else:
            runs = _run_method(name, method_params, clip, repeats)
            if memory:
                peak = _peak_rss_mib()  # whole-process peak so far: an upper bound
        fps = float(statistics.median(runs))
        report.results.append(
            BenchResult(method=name, fps=fps, fps_runs=[float(f) for f in runs],
                        ms_per_frame=1000.0 / fps, peak_rss_mib=peak,
                        rss_growth_mib=growth)
        )
    return report
