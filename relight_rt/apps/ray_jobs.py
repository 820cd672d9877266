"""Relight folders of photos and many video clips on a Ray cluster (optional extra ``ray``).

Photos go through Ray Data: a dataset of (input, output) paths, never decoded pixels, and
``map_batches`` with a callable class that holds one ``Relighter`` per actor (CUDA when the actor was
given a GPU, CPU otherwise). Each actor reads, relights and writes its photos atomically through
:func:`relight_rt.apps.batch.relight_file`, the very function the single-process ``relight-rt relight``
runs, so the outputs are the same files byte for byte. Videos run one clip per Ray task (the
stabiliser goes through a clip in order), each through relight_rt.video.job.relight_clip, the very function
``relight-rt video`` runs (:func:`relight_videos`). The command line's ``--ray`` is relight_rt.cli.ray.

Every photo or clip gives one row of a manifest, JSON lines appended by the driver as results come
back: ``input``, ``output``, ``status`` (ok | failed | skipped), ``error``, ``seconds`` (the work on
that file) and ``job`` (a hash of the settings that shape the output: light, models, mask,
background); photos also give ``worker`` (host:pid:device) and ``rss_mb`` (the actor's peak memory). A bad file is a
failed row, never the end of the job. A rerun skips every output that exists and is listed ok for
the same job; an output written but not yet listed when a job was killed is simply done again (the
atomic writer never leaves a half-written one).

Paths are read and written by the actors: on a cluster they must name shared storage that every node
sees, and relight_rt must be installed on every node (or shipped with ``runtime_env``). ``--ray local``
starts a private Ray on this machine whose workers import the same relight_rt as the driver; it ends with
the driver, also one killed by SIGKILL (a watcher process, relight_rt.apps.ray_reaper, ends what Ray's own fate
sharing leaves), and under an address-space limit (ulimit -v) its object store is sized to fit.

Python::

    from relight_rt.apps.ray_jobs import relight_folder
    report = relight_folder(["shoot/"], "relit/", light="studio", ray_address="auto", gpus_per_actor=1)
    print(report.written, report.failures)
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import socket
import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engine import environment
from ..engine.config import RuntimeConfig
from ..engine.errors import RelightError
from ..image.compositing import parse_background
from ..image.io import sibling_mask
from . import batch
from .ray_reaper import address_space_limit, limit_hint

log = logging.getLogger(__name__)

EXTRA_HINT = 'pip install "relight-rt[ray]"'
MANIFEST_NAME = "relight_manifest.jsonl"
STATUSES = ("ok", "failed", "skipped")


def import_ray():
    """The ray module, or a RelightError that says how to install it."""
    try:
        import ray
    except ImportError:
        raise RelightError(f"--ray needs Ray, which is not installed: {EXTRA_HINT}") from None
    return ray


# ------------------------------------------------------------------------------------------- Ray session


def worker_env() -> dict:
    """A runtime_env whose workers import this very relight_rt (the one the driver runs) first."""
    root = str(Path(__file__).resolve().parents[2])
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)
    return {"env_vars": {"PYTHONPATH": path}}


OBJECT_STORE_MIN_BYTES = 75 << 20  # Ray's own minimum
# below this address-space limit (ulimit -v) a local Ray hangs at start-up (1 GiB) or its driver dies in
# Ray's shared memory (2 GiB); measured with Ray 2.60 (at 3 GiB workers may still fail: one line each)
MIN_ADDRESS_SPACE = 3 << 30


def object_store_bytes() -> int | None:
    """The object store of a local Ray: under an address-space limit, an eighth of it (at least Ray's minimum,
    at most 2 GiB); None otherwise (Ray's default, 30 % of the memory). The raylet maps the whole store when
    it starts, and every process inherits the limit: with Ray's default the raylet dies at start-up under
    ``ulimit -v`` and the node never comes up. (The paths are only file names: the store holds none of
    the pixels.)"""
    limit = address_space_limit()
    return None if limit is None else max(OBJECT_STORE_MIN_BYTES, min(limit // 8, 2 << 30))


def _start_reaper():
    """The watcher that ends the local Ray if this process dies without shutting it down (relight_rt.apps.ray_reaper):
    its Popen, or None where it cannot run (not Linux)."""
    import subprocess

    if not sys.platform.startswith("linux"):
        return None
    from . import ray_reaper

    try:
        stderr = sys.stderr.fileno()  # the CLI's real stderr (its fd 2 may point at /dev/null meanwhile)
    except (AttributeError, OSError, ValueError):
        stderr = None
    try:
        return subprocess.Popen([sys.executable, "-I", ray_reaper.__file__], stdin=subprocess.PIPE, stderr=stderr,
                                start_new_session=True)  # fmt: skip
    except OSError as exc:
        log.warning("Ray: no watcher for the local Ray (%s); if this process is killed, end Ray with `ray stop`", exc)
        return None


def _stop_reaper(reaper, clean: bool = True) -> None:
    """Let the watcher go: after a clean ``ray.shutdown()`` it ends nothing; otherwise it ends what is left of
    the local Ray, quietly (this process reports the failure itself)."""
    if reaper is None:
        return
    with contextlib.suppress(OSError, ValueError):
        reaper.stdin.write(b"clean\n" if clean else b"quiet\n")
        reaper.stdin.close()
    with contextlib.suppress(Exception):
        reaper.wait(timeout=30)


def _start_local(ray, kwargs: dict):
    """``ray.init`` of a private local Ray, watched (see _start_reaper); every failure is one RelightError.
    Returns the watcher (for _stop_reaper)."""
    limit = address_space_limit()
    if limit is not None and limit < MIN_ADDRESS_SPACE:
        raise RelightError(f"--ray local: processes here may use {limit / 2**30:.1f} GiB of address space (ulimit "
                           f"-v); a local Ray needs {MIN_ADDRESS_SPACE >> 30} GiB or more per process: raise the "
                           "limit, or run without --ray")  # fmt: skip
    reaper = _start_reaper()
    store = object_store_bytes()
    if store is not None:
        kwargs = dict(kwargs, object_store_memory=store)
    try:
        ray.init(address="local", runtime_env=worker_env(), **kwargs)
    except Exception as exc:  # Ray raises plain Exception ("The current node timed out during startup")
        with contextlib.suppress(Exception):
            ray.shutdown()
        _stop_reaper(reaper, clean=False)  # ends what the failed start left behind
        text = str(exc).strip()
        reason = text.splitlines()[0] if text else type(exc).__name__
        raise RelightError(f"--ray local: Ray did not start: {reason}{limit_hint()}") from None
    except BaseException:  # Ctrl-C, SIGTERM during the start
        _stop_reaper(reaper, clean=False)
        raise
    return reaper


@contextlib.contextmanager
def ray_session(address: str | None) -> Iterator:
    """Ray, connected: an existing connection as it is (left open), else ``address`` (None or "local":
    a private Ray on this machine, shut down at the end, and by a watcher if this process is killed)."""
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    if address not in (None, "local", "auto") and ":" not in address and Path(address).exists():
        raise RelightError(f"--ray {address}: that is a file or folder, not a Ray address; put --ray after the "
                           "inputs, or write --ray local")  # fmt: skip
    kwargs = {"include_dashboard": False, "logging_level": logging.WARNING, "log_to_driver": False}
    reaper = None
    if address in (None, "local"):
        reaper = _start_local(ray, kwargs)
    else:
        try:
            ray.init(address=address, **kwargs)
        except (ConnectionError, ValueError, RuntimeError) as exc:
            raise RelightError(f"--ray {address}: cannot connect to a Ray cluster: {exc}") from None
    try:
        yield ray
    finally:
        clean = False
        try:
            ray.shutdown()
            clean = True
        finally:
            _stop_reaper(reaper, clean)


def check_resources(gpus, cpus, what: str) -> None:
    """Refuse, before any cluster starts, GPUs (None: chosen by the cluster) and CPUs per ``what`` that are not
    finite numbers with GPUs >= 0 and CPUs > 0 (NaN passed the cluster's own check; "1" or Inf failed in Ray)."""
    for name, value, least in (("GPUs", gpus, 0.0), ("CPUs", cpus, None)):
        if name == "GPUs" and value is None:
            continue
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
        try:
            finite = number and math.isfinite(value)
        except OverflowError:  # an integer of 400 digits (np.isfinite raised TypeError)
            finite = False
        if not finite or (value < least if least is not None else value <= 0):
            rule = ">= 0" if least is not None else "> 0"
            raise RelightError(f"Ray resources: {name} per {what}: expected a finite number {rule}, got {value!r:.40}")


def _resources(ray, gpus: float | None, cpus: float, device: str = "auto") -> tuple[float, float, dict]:
    """(GPUs, CPUs) per worker and the cluster's resources; by default one GPU per worker when the
    cluster has GPUs and the device is not "cpu"."""
    total = ray.cluster_resources()
    if gpus is None:
        gpus = 1.0 if total.get("GPU", 0) >= 1 and device != "cpu" else 0.0
    if gpus < 0 or cpus <= 0:
        raise RelightError(f"Ray resources: expected GPUs >= 0 and CPUs > 0 per worker, got {gpus} and {cpus}")
    return gpus, cpus, total


# ------------------------------------------------------------------------------------------- manifest


def job_key(**settings) -> str:
    """A short hash of the settings that shape the outputs (arrays by their bytes)."""
    h = hashlib.sha256()
    for key in sorted(settings):
        value = settings[key]
        h.update(key.encode())
        if isinstance(value, np.ndarray):
            h.update(str(value.dtype).encode() + str(value.shape).encode() + value.tobytes())
        else:
            h.update(repr(value).encode())
    return h.hexdigest()[:16]


def read_manifest(path: str | os.PathLike) -> list[dict]:
    """The rows of a manifest; lines that do not parse (a job killed mid-line) are left out."""
    path = Path(path)
    if not path.is_file():
        return []
    rows = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            try:
                row = json.loads(line)
            except (ValueError, RecursionError):  # not JSON, an integer of 5000 digits, "[" x 100000
                continue
            if isinstance(row, dict):
                rows.append(row)
    return rows


def done_outputs(manifest: str | os.PathLike, job: str) -> set[str]:
    """Outputs (resolved paths: files, or frame folders for videos) listed ok or skipped for ``job`` that
    still exist."""
    done = set()
    for row in read_manifest(manifest):
        if row.get("job") == job and row.get("status") in ("ok", "skipped") and isinstance(row.get("output"), str):
            if Path(row["output"]).exists():
                done.add(str(Path(row["output"]).resolve()))
    return done


class ManifestWriter:
    """Appends rows to a JSON-lines manifest: one write per row, flushed and synced per call, so a
    killed job leaves at most one torn last line (which :func:`read_manifest` skips)."""

    def __init__(self, path: str | os.PathLike, protect: Iterable[str | os.PathLike] = ()) -> None:
        from ..engine.files import check_target

        self.path = Path(path)
        check_target(self.path, protect)
        if self.path.exists() and not self.path.is_file():  # a FIFO would block the open below for ever
            raise RelightError(f"manifest {self.path}: exists and is not a regular file")
        if not self.path.parent.is_dir():
            raise RelightError(f"manifest {self.path}: folder {self.path.parent} does not exist")
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        if os.fstat(self._fd).st_size:  # a torn last line of a killed job: start on a fresh line
            with open(self.path, "rb") as f:
                f.seek(-1, os.SEEK_END)
                if f.read(1) != b"\n":
                    os.write(self._fd, b"\n")

    def write(self, rows: Iterable[dict]) -> None:
        data = b"".join(json.dumps(r, ensure_ascii=False).encode() + b"\n" for r in rows)
        view = memoryview(data)
        while view:  # a regular file takes it in one write; loop in case it does not
            view = view[os.write(self._fd, view) :]
        if data:
            os.fsync(self._fd)

    def close(self) -> None:
        os.close(self._fd)

    def __enter__(self) -> ManifestWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _row(src, target, status: str, error: str = "", seconds: float = 0.0, job: str = "") -> dict:
    return {"input": str(src), "output": str(target), "status": status, "error": error,
            "seconds": round(float(seconds), 4), "job": job}  # fmt: skip


@dataclass
class Report:
    """What a distributed job did: its manifest rows (this run) and the failures, in input order."""

    manifest: Path
    inputs: int = 0  # image files found
    rows: list[dict] = field(default_factory=list)
    failures: list[tuple[str, str]] = field(default_factory=list)

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.rows)

    @property
    def written(self) -> int:
        return self.count("ok")

    @property
    def skipped(self) -> int:
        return self.count("skipped")


# ------------------------------------------------------------------------------------------- photos


_ACTOR_FIELDS = ("input", "output", "status", "error", "seconds", "job", "worker", "rss_mb")


def _peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MiB (Linux and macOS; 0 where unknown)."""
    try:
        import resource
    except ImportError:
        return 0.0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)


class RelightActor:
    """Ray Data callable class: one Relighter per actor; each call relights a batch of (input, output)
    rows and returns their manifest rows. Every error is a failed row, never an exception."""

    def __init__(self, config: RuntimeConfig, cpus: float, light: np.ndarray, mask_arg, single: bool,
                 background, job: str, exposure="auto") -> None:  # fmt: skip
        import ray

        from ..builder import open as open_relighter

        device = config.device
        if device == "auto":
            device = "cuda" if ray.get_gpu_ids() else "cpu"
        if device == "cpu" and environment.threads() is None:
            os.environ[environment.THREADS] = str(max(1, int(cpus)))  # the CPUs Ray gave this actor
        self.relighter = open_relighter(config.replace(device=device))
        self.light = np.asarray(light, np.float32)
        self.mask_arg, self.single, self.background, self.job = mask_arg, single, background, job
        self.exposure = exposure
        self.worker = f"{socket.gethostname()}:{os.getpid()}:{device}"

    def __call__(self, rows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out: dict[str, list] = {k: [] for k in ("index", *_ACTOR_FIELDS)}
        for index, src, target, protect in zip(
            rows["index"], rows["input"], rows["output"], rows["protect"], strict=True
        ):
            start = time.perf_counter()
            try:
                batch.relight_file(
                    self.relighter,
                    Path(src),
                    Path(target),
                    self.light,
                    mask_arg=self.mask_arg,
                    single=self.single,
                    background=self.background,
                    exposure=self.exposure,
                    protect=json.loads(protect),
                )
                status, error = "ok", ""
            except (RelightError, OSError) as exc:  # what the single-process CLI reports
                status, error = "failed", str(exc)
            except Exception as exc:  # anything else: one failed row, the job goes on
                status, error = "failed", f"{type(exc).__name__}: {exc}"
            row = _row(src, target, status, error, time.perf_counter() - start, self.job)
            row.update(worker=self.worker, rss_mb=_peak_rss_mb())
            out["index"].append(int(index))
            for key, value in row.items():
                out[key].append(value)
        return {k: np.asarray(v) for k, v in out.items()}


def files_read(paths: Iterable[str | os.PathLike | None], models_dir: str | os.PathLike | None = None) -> list[Path]:
    """Every file a run reads, none of which an output (the manifest too) may replace: the files named, every
    file of a folder named (a --mask folder, a folder of frames), the NAME_mask.* beside each image, and the
    model graphs."""
    found: list[Path] = []
    for p in (Path(p) for p in paths if p):
        if p.is_dir():
            found.extend(f for f in p.iterdir() if f.is_file())
        elif p.exists():
            found.append(p)
    found.extend(m for m in map(sibling_mask, list(found)) if m)
    if models_dir is not None:
        found.extend(Path(models_dir).glob("*.onnx"))
    return found


def _protect_per_output(plan: batch.Plan, extra: Iterable) -> dict[Path, list[str]]:
    """For each output (resolved), the inputs it would replace: all an actor needs to refuse it."""
    protect = [*plan.inputs, *(p for p in extra if p), *(m for m in map(sibling_mask, plan.inputs) if m)]
    by_path: dict[Path, list[str]] = {}
    for p in protect:
        by_path.setdefault(Path(p).resolve(), []).append(str(p))
    return by_path


def relight_folder(
    inputs: str | os.PathLike | Iterable[str | os.PathLike],
    output: str | os.PathLike,
    light,
    *,
    ray_address: str | None = None,
    models: str | os.PathLike | None = None,
    mask: str | os.PathLike | None = None,
    background="original",
    device: str = "auto",
    actors: int | None = None,
    gpus_per_actor: float | None = None,
    cpus_per_actor: float = 1.0,
    batch_size: int = 8,
    manifest: str | os.PathLike | None = None,
    protect: Iterable[str | os.PathLike] = (),
    config: RuntimeConfig | None = None,
    exposure="auto",
) -> Report:
    """Relight photos (files and folders) on Ray: the work of ``relight-rt relight``, spread over actors.

    Args:
        inputs: image files and folders (as for the CLI; folders leave out ``*_relit``, ``*_mask`` and
            hidden files).
        output: output folder (NAME_relit.png per photo), or a file for one photo.
        light: a (9, 3) RGB SH light, or anything ``Relighter.resolve_light`` accepts (resolved here,
            once; the actors get the array).
        ray_address: None or "local" (a private Ray on this machine), "auto", "ray://HOST:PORT";
            ignored when Ray is already initialised in this process.
        models, device: as for ``Relighter`` ("auto": CUDA on actors given a GPU).
        mask: ``--mask``: a folder of NAME_mask.png (default: beside each photo, else its alpha).
        background: a Background or its shorthand ("original", "transparent", a colour, an image path).
        actors: actor pool size (default: one per GPU, else one per ``cpus_per_actor`` CPUs).
        gpus_per_actor: GPUs per actor (fractions share a GPU); default 1 when the cluster has GPUs.
        cpus_per_actor: CPUs per actor (and its onnxruntime threads on CPU).
        batch_size: photos per actor call.
        manifest: JSON-lines manifest, appended (default: ``relight_manifest.jsonl`` in the output folder).
        protect: more paths no output may replace (light files, ...).
        exposure: "auto", an EV offset or "physical" (relight_rt.light.exposure), for every photo.
        config: the rest of the runtime's settings (precision, preprocessing, detail) for every actor;
            ``models`` and ``device`` above win over its own.

    Returns:
        A Report: this run's manifest rows and the failures (planning ones first), in input order.

    Raises:
        RelightError: Ray missing or unreachable, bad options, a light that cannot be resolved.
    """
    import_ray()  # missing: say so before anything is written
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    if not isinstance(inputs, Iterable) or isinstance(inputs, (bytes, dict)):
        raise RelightError(f"inputs: expected image files and folders, got {type(inputs).__name__}")
    inputs = [str(i) for i in inputs]
    # what each actor would refuse photo by photo, refused here before a cluster starts (fuzz9)
    from ..light.exposure import parse_exposure

    parse_exposure(exposure)
    check_resources(gpus_per_actor, cpus_per_actor, "actor")
    if config is not None and not isinstance(config, RuntimeConfig):
        raise RelightError(f"config: expected a RuntimeConfig, got {type(config).__name__}")
    if mask is not None and str(mask) != "auto" and not Path(mask).exists():
        raise RelightError(f"--mask {mask}: not found (a mask file, a folder of NAME_mask.png, or auto)")
    if not isinstance(batch_size, int) or batch_size < 1:
        raise RelightError(f"batch size: expected a whole number >= 1, got {batch_size!r}")
    if actors is not None and (not isinstance(actors, int) or actors < 1):
        raise RelightError(f"actors: expected a whole number >= 1, got {actors!r}")
    background = parse_background(background)
    if background.kind == "image" and background.path is None:
        raise RelightError("background: an image array cannot be sent to a distributed job; give its path")
    bg_key = f"{background.kind}:{background.color}:{background.path}:{background.fit}"
    plan = batch.plan(inputs, output)
    out = Path(output)
    light = _resolve_light(light, models)
    from ..engine.session import find_models

    models_dir = find_models(models)
    mask_arg = None if mask is None else str(mask)
    config = (config or RuntimeConfig()).replace(models=str(models_dir.resolve()), device=device)
    job = job_key(light=light, models=str(models_dir.resolve()), mask=mask_arg, background=bg_key,
                  single=plan.single, precision=config.precision, preprocess=config.preprocess,
                  detail=config.detail, exposure=repr(exposure))  # fmt: skip
    if not plan.to_file and plan.pairs:
        out.mkdir(parents=True, exist_ok=True)
    manifest_path = Path(manifest) if manifest else (out.parent / f"{out.name}.manifest.jsonl" if plan.to_file
                                                      else out / MANIFEST_NAME)  # fmt: skip
    reads = files_read([*plan.inputs, mask_arg if mask_arg != "auto" else None, background.path,
                        *map(str, protect)], models_dir)  # fmt: skip
    by_path = _protect_per_output(plan, reads)
    report = Report(manifest_path, len(plan.inputs), failures=list(plan.failures))
    done = done_outputs(manifest_path, job)
    todo, rows = [], []
    for index, (src, target) in enumerate(plan.pairs):
        key = target.resolve()
        if str(key) in done:
            rows.append((index, _row(src, target, "skipped", job=job)))
        else:
            todo.append({"index": index, "input": str(src), "output": str(target),
                         "protect": json.dumps(by_path.get(key, []))})  # fmt: skip
    with ManifestWriter(manifest_path, protect=reads) as writer:
        writer.write(r for _, r in rows)
        if todo:
            with ray_session(ray_address) as ray:
                gpus, cpus, total = _resources(ray, gpus_per_actor, cpus_per_actor, device)
                # the actors find the models themselves: --models or $RELIGHT_RT_MODELS as given, else the
                # bundled models of their own install (the driver's path may not exist on another node)
                actor_kwargs = {"config": config, "cpus": cpus, "light": light, "mask_arg": mask_arg,
                                "single": plan.single, "background": background, "job": job,
                                "exposure": exposure}  # fmt: skip
                if actors is None:
                    actors = int(total.get("GPU", 0) // gpus) if gpus > 0 else int(total.get("CPU", 1) // cpus)
                    actors = max(1, min(actors, len(todo)))
                rows.extend(_run_actors(ray, todo, writer, actor_kwargs, actors, gpus, cpus, batch_size))
    rows.sort(key=lambda r: r[0])
    report.rows = [r for _, r in rows]
    report.failures.extend((r["input"], r["error"]) for r in report.rows if r["status"] == "failed")
    return report


def _resolve_light(light, models) -> np.ndarray:
    from ..light import sh

    if isinstance(light, np.ndarray) or (isinstance(light, (list, tuple)) and len(light) == 9):
        return sh.check_light(light, "light").astype(np.float32)  # the list itself: np.asarray reads True as 1.0
    from ..builder import open as open_relighter
    from ..engine.config import RuntimeConfig

    return open_relighter(RuntimeConfig(models=models, device="cpu")).resolve_light(light)


def _run_actors(ray, todo, writer, actor_kwargs, actors, gpus, cpus, batch_size) -> list[tuple[int, dict]]:
    """Run the Ray Data job; append each result batch to the manifest as it comes back."""
    remote = {"num_gpus": gpus} if gpus > 0 else {}
    ds = ray.data.from_items(todo, override_num_blocks=max(1, min(len(todo), actors * 4)))
    ds = ds.map_batches(
        RelightActor,
        fn_constructor_kwargs=actor_kwargs,
        batch_size=batch_size,
        batch_format="numpy",
        compute=ray.data.ActorPoolStrategy(size=actors),
        num_cpus=cpus,
        **remote,
    )  # fmt: skip
    log.info("Ray: %d photos on %d actor(s), %s GPU and %s CPU each", len(todo), actors, gpus, cpus)
    done: list[tuple[int, dict]] = []
    start = time.perf_counter()
    try:
        for part in ds.iter_batches(batch_size=None, batch_format="numpy"):
            rows = []
            for i in range(len(part["index"])):
                row = {k: _plain(part[k][i]) for k in _ACTOR_FIELDS}
                rows.append(row)
                done.append((int(part["index"][i]), row))
            writer.write(rows)
    except ray.exceptions.RayError as exc:  # an actor that cannot start (models, CUDA), a lost node, ...
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise RelightError(f"the Ray job stopped after {len(done)} of {len(todo)} photos (the manifest lists "
                           f"them; a rerun goes on): {reason}{limit_hint()}") from None  # fmt: skip
    seconds = time.perf_counter() - start
    log.info("Ray: %d photos in %.2f s (%.2f photos/s, actor start-up included)", len(done), seconds,
             len(done) / max(seconds, 1e-9))  # fmt: skip
    return done


def _plain(value):
    """A numpy scalar (or a str Ray gave back as is) → a plain Python value for JSON."""
    return value.item() if isinstance(value, np.generic) else value


# ------------------------------------------------------------------------------------------- videos

_PER_CLIP = ("src", "output", "frames_out", "lights_out", "metrics")  # what differs from clip to clip


def _video_clip(settings: dict, job: str, cpus: float) -> dict:
    """Ray task: one clip through relight_rt.video.job.relight_clip; every error is a failed row."""
    import ray

    from ..builder import open as open_relighter
    from ..builder import video_matter
    from ..video.job import relight_clip

    config = settings.get("config") or RuntimeConfig()
    if config.device == "auto":
        config = config.replace(device="cuda" if ray.get_gpu_ids() else "cpu")
    if config.device == "cpu" and environment.threads() is None:
        os.environ[environment.THREADS] = str(max(1, int(cpus)))
    start = time.perf_counter()
    try:
        relighter = None if settings.get("dvp") else open_relighter(config)
        relight_clip(**dict(settings, config=config, relighter=relighter, matter=video_matter(config)))
        status, error = "ok", ""
    except (RelightError, OSError) as exc:
        status, error = "failed", str(exc)
    except Exception as exc:
        status, error = "failed", f"{type(exc).__name__}: {exc}"
    return _row(settings["src"], settings.get("output") or settings.get("frames_out"), status, error,
                time.perf_counter() - start, job)  # fmt: skip


def _clip_reads(clips: list[dict]) -> list[Path]:
    """Every file the clips read: the clips, their masks, light files, the DVP, the background image and the
    model graphs (relight_rt.video.job.relight_clip's inputs)."""
    from ..engine.session import find_models
    from ..video.job import ClipLights

    paths: list = []
    models = set()
    for c in clips:
        lights = c["lights"] if isinstance(c["lights"], ClipLights) else ClipLights(spec=c["lights"])
        masks = c.get("masks")
        bg = c.get("background")
        bg_path = parse_background(bg).path if bg is not None else None
        paths += [c["src"], masks if masks != "auto" else None, *lights.paths, c.get("dvp"), bg_path]
        if not c.get("dvp"):
            models.add((c.get("config") or RuntimeConfig()).models)
    found = files_read(paths)
    for folder in models:
        found.extend(Path(find_models(folder)).glob("*.onnx"))
    return found


def relight_videos(
    clips: Iterable[dict],
    manifest: str | os.PathLike,
    *,
    ray_address: str | None = None,
    gpus_per_task: float | None = None,
    cpus_per_task: float = 1.0,
    failures: Iterable[tuple[str, str]] = (),
) -> Report:
    """Relight many clips on Ray, one task per clip (the stabiliser goes through a clip in order).

    Args:
        clips: per clip, the keyword arguments of relight_rt.video.job.relight_clip (``src``, ``lights``, the
            outputs, ``config``, ...); plain values that pickle.
        manifest: JSON-lines manifest, appended; a rerun of the same job skips the clips listed ok whose
            output exists.
        ray_address: None or "local" (a private Ray on this machine), "auto", "ray://HOST:PORT".
        gpus_per_task: GPUs per task (default 1 when the cluster has GPUs and the device is not "cpu").
        cpus_per_task: CPUs per task (and its onnxruntime threads on CPU).
        failures: failures found while planning (listed first in the report).

    Returns:
        A Report: this run's manifest rows and the failures, in clip order.
    """
    import_ray()
    if not isinstance(clips, Iterable) or isinstance(clips, (str, bytes, dict)):
        raise RelightError(f"clips: expected a list of relight_clip's settings, got {type(clips).__name__}")
    clips, failures = list(clips), list(failures)
    for c in clips:
        if not isinstance(c, dict) or not {"src", "lights"} <= c.keys() or not (c.get("output") or c.get("frames_out")):
            raise RelightError(f"clips: expected relight_clip's settings (src, lights, output or frames_out), got "
                               f"{str(c)[:120]}")  # fmt: skip
    check_resources(gpus_per_task, cpus_per_task, "task")
    shared = {k: v for k, v in (clips[0] if clips else {}).items() if k not in _PER_CLIP}
    job = job_key(**shared)  # the settings that shape every clip's output (the paths are per clip)
    report = Report(Path(manifest), len(clips) + len(failures), failures=failures)
    done = done_outputs(manifest, job)
    rows: list[tuple[int, dict]] = []
    reads = _clip_reads(clips)
    device = (shared.get("config") or RuntimeConfig()).device
    with ManifestWriter(manifest, protect=reads) as writer:
        todo = []
        for index, settings in enumerate(clips):
            target = settings.get("output") or settings.get("frames_out")
            if str(Path(target).resolve()) in done:
                rows.append((index, _row(settings["src"], target, "skipped", job=job)))
            else:
                todo.append((index, settings))
        writer.write(r for _, r in rows)
        if todo:
            with ray_session(ray_address) as ray:
                gpus, cpus, _ = _resources(ray, gpus_per_task, cpus_per_task, device)
                task = ray.remote(_video_clip).options(num_cpus=cpus, num_gpus=gpus, max_retries=0)
                pending = {task.remote(s, job, cpus): i for i, s in todo}
                clips_by_index = dict(todo)
                log.info("Ray: %d clip(s), one task each, %s GPU and %s CPU per task", len(todo), gpus, cpus)
                while pending:
                    ready, _ = ray.wait(list(pending), num_returns=1)
                    for ref in ready:
                        index = pending.pop(ref)
                        try:
                            row = ray.get(ref)
                        except ray.exceptions.RayError as exc:  # the worker died (memory, a lost node)
                            settings = clips_by_index[index]
                            reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
                            row = _row(settings["src"], settings.get("output") or settings.get("frames_out"),
                                       "failed", f"{settings['src']}: the Ray task failed: {reason}",
                                       job=job)  # fmt: skip
                        rows.append((index, row))
                        writer.write([row])
    rows.sort(key=lambda r: r[0])
    report.rows = [r for _, r in rows]
    report.failures.extend((r["input"], r["error"]) for r in report.rows if r["status"] == "failed")
    return report
