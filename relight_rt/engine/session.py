"""ONNX Runtime sessions: device choice, contract checks at load, and where the models live.

``create_session`` opens a graph on the requested device and checks, after creation, that the
provider asked for is the one really running it. ``load_model`` also checks the graph against the
contract (DESIGN.md §5, ``relight_rt.engine.contract``) and wraps it as a :class:`Model`. onnxruntime's
global logging is never touched; ``RELIGHT_RT_THREADS`` sets the intra-op thread count.

Performance settings (docs/BENCHMARKS.md has the figures):

- CPU (``cpu_session_options``): all graph optimisations (with the NCHWc layout transform that suits
  these convolution-heavy graphs), a memory arena and memory patterns (fixed shapes), sequential
  execution, intra-op threads = cores (``RELIGHT_RT_THREADS`` to change), and no spin-waiting of the
  intra-op threads: stage 1 and stage 2 are two sessions with a thread pool each, and the threads of
  the one that just finished kept spinning on the cores the other needed (2 cores, bundled 256²
  models: ``relight`` 73 → 44 ms; no change at 1024², where each call runs for seconds).
- CUDA (``cuda_provider_options``) — UNTESTED ON A GPU so far: exhaustive cuDNN algorithm search (these
  graphs run at fixed shapes, so the one-off search at warm-up pays back), the largest cuDNN workspace,
  copies on the default stream, an arena that grows by what is asked. CUDA graphs are not switched on:
  onnxruntime replays a captured graph on the device addresses of its first run, and the chain in
  relight_rt.engine.device_chain binds fresh buffers per run (docs/BENCHMARKS.md says what that needs).
- TensorRT, opt-in and UNTESTED ON A GPU so far: ``RELIGHT_RT_TENSORRT=CACHE_DIR`` puts
  TensorrtExecutionProvider first (fp16, engines and timing cache kept in CACHE_DIR: the first load
  builds them, minutes; later loads read them), CUDA and CPU after it for what TensorRT does not take.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnxruntime as ort

from . import environment
from .contract import KINDS, ModelConfig, config_from_metadata, kind_spec
from .errors import RelightError
from .graph_cache import open_session

log = logging.getLogger(__name__)

DEVICES = ("auto", "cuda", "cpu")
CUDA = "CUDAExecutionProvider"
CPU = "CPUExecutionProvider"
ENV_MODELS = environment.MODELS
ENV_THREADS = environment.THREADS
ENV_TENSORRT = environment.TENSORRT
TENSORRT = "TensorrtExecutionProvider"
_CUDA_HELP = (
    "likely causes: both 'onnxruntime' and 'onnxruntime-gpu' are installed (uninstall both, then install "
    "onnxruntime-gpu only), or the CUDA / cuDNN libraries that this onnxruntime-gpu build needs are missing "
    "(see `relight-rt doctor`)"
)


def thread_count() -> int:
    """Intra-op threads from $RELIGHT_RT_THREADS (0 = onnxruntime's default), checked by its one reader
    (relight_rt.engine.environment.threads: a whole number up to four per core)."""
    return environment.threads() or 0


def cpu_session_options() -> ort.SessionOptions:
    """SessionOptions for these graphs on CPU (module docstring); intra-op threads from $RELIGHT_RT_THREADS."""
    opts = ort.SessionOptions()
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.enable_cpu_mem_arena = True
    opts.enable_mem_pattern = True
    opts.intra_op_num_threads = thread_count()
    # two sessions run in turn (module docstring): idle threads must sleep, not spin on the shared cores
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return opts


def cuda_provider_options(device_id: int = 0) -> dict[str, str]:
    """CUDAExecutionProvider options for fixed-shape convolution graphs. UNTESTED ON A GPU so far."""
    return {
        "device_id": str(int(device_id)),
        "cudnn_conv_algo_search": "EXHAUSTIVE",
        "cudnn_conv_use_max_workspace": "1",
        "do_copy_in_default_stream": "1",
        "arena_extend_strategy": "kSameAsRequested",
    }


def tensorrt_provider_options(device_id: int, cache: str | os.PathLike) -> dict[str, str]:
    """TensorrtExecutionProvider options: fp16, engine + timing cache in ``cache``. UNTESTED ON A GPU so far."""
    return {
        "device_id": str(int(device_id)),
        "trt_fp16_enable": "True",
        "trt_engine_cache_enable": "True",
        "trt_engine_cache_path": str(cache),
        "trt_timing_cache_enable": "True",
        "trt_timing_cache_path": str(cache),
        "trt_max_workspace_size": str(8 << 30),
        "trt_builder_optimization_level": "3",
    }


def _providers_for(device: str, device_id: int) -> list:
    if device not in DEVICES:
        raise RelightError(f"device is {device!r}, expected one of {list(DEVICES)}")
    available = ort.get_available_providers()
    if device == "cpu":
        return [CPU]
    if CUDA in available:
        chain: list = [(CUDA, cuda_provider_options(device_id)), CPU]
        cache = environment.tensorrt_cache()
        if cache and TENSORRT in available:  # opt-in, untested on a GPU so far
            Path(cache).mkdir(parents=True, exist_ok=True)
            chain.insert(0, (TENSORRT, tensorrt_provider_options(device_id, cache)))
        elif cache:
            log.warning("$%s is set but this onnxruntime offers no %s; using CUDA", ENV_TENSORRT, TENSORRT)
        return chain
    if device == "cuda":
        raise RelightError(
            f"device 'cuda' asked for, but this onnxruntime {ort.__version__} offers only {available}; {_CUDA_HELP}"
        )
    return [CPU]


def _warmup_feeds(session: ort.InferenceSession, config: ModelConfig) -> dict[str, np.ndarray]:
    """Zeros for every input of the graph, shaped by its kind's spec (batch 1, the native or a 64 px size)."""
    spec = config.spec
    size = config.resolution or 64
    feeds = {}
    for inp in session.get_inputs():
        shape = list(spec.tensor(inp.name).zeros_shape(size))
        fixed = [d if isinstance(d, int) and d > 0 else None for d in inp.shape]
        shape = [f or d for f, d in zip(fixed, shape, strict=False)]
        feeds[inp.name] = np.zeros(shape, np.float32)
    return feeds


def create_session(
    model: str | os.PathLike | ort.InferenceSession,
    *,
    device: str = "auto",
    device_id: int = 0,
    providers: Sequence | None = None,
    sess_options: ort.SessionOptions | None = None,
    warmup: bool = True,
    kind: str | None = None,
) -> ort.InferenceSession:
    """Open an ONNX graph with onnxruntime on the requested device, checked against the contract.

    Args:
        model: path of a .onnx file, or an existing InferenceSession (checked and returned as is).
        device: "auto" (CUDA when onnxruntime offers it, else CPU), "cuda" or "cpu".
        device_id: CUDA device index.
        providers: explicit onnxruntime providers; they win over ``device``.
        sess_options: onnxruntime SessionOptions; by default new ones with $RELIGHT_RT_THREADS threads.
        warmup: run the graph once on zeros (CUDA: allocates memory and picks kernels up front).
        kind: the contract kind expected ("stage1", ...); a graph whose metadata names another kind is
            reported as the wrong kind before its inputs and outputs are compared.

    Raises:
        RelightError: missing, unreadable or corrupt file; a graph that breaks the contract; CUDA asked for
            but not active (with the likely causes). With ``device="auto"`` a CPU fallback is only logged.
    """
    if isinstance(model, ort.InferenceSession):
        validate_session(model, "session", kind)
        return model
    path = Path(model)
    if not path.is_file():
        raise RelightError(f"model file {path} {'is not a regular file' if path.exists() else 'not found'}")
    wanted = list(providers) if providers is not None else _providers_for(device, device_id)
    if sess_options is None:
        sess_options = cpu_session_options()
    try:
        session = open_session(path, sess_options, wanted)  # an optimised graph kept from an earlier run
    except Exception as exc:  # onnxruntime raises its own classes (InvalidProtobuf, Fail, ...)
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RelightError(f"model {path}: not a readable ONNX graph ({first})") from None
    active = session.get_providers()
    asked_cuda = any((p[0] if isinstance(p, tuple) else p) in (CUDA, TENSORRT) for p in wanted)
    if asked_cuda and CUDA not in active:
        if device == "cuda" or providers is not None:
            raise RelightError(f"model {path}: CUDA was asked for but onnxruntime runs it on {active}; {_CUDA_HELP}")
        log.warning("%s: CUDA is offered but not active (running on %s); %s", path, active, _CUDA_HELP)
    config = validate_session(session, str(path), kind)
    log.debug("%s: %s on %s", path, config, active)
    if warmup:
        session.run(None, _warmup_feeds(session, config))
    return session


def validate_session(session: ort.InferenceSession, name: str, kind: str | None = None) -> ModelConfig:
    """Check a session's metadata and inputs/outputs against the contract; return its ModelConfig.

    Checks names (exact set), ranks, element type float32 and the fixed dimensions (channels; for stage 1
    the spatial size equals the metadata resolution). Symbolic dimensions are accepted.

    Raises:
        RelightError: naming the graph and the field that is wrong.
    """
    meta = session.get_modelmeta().custom_metadata_map
    config = config_from_metadata(meta, name)
    if kind is not None and config.kind != kind:
        raise RelightError(f"{name}: metadata relight_rt.kind is {config.kind!r}, expected {kind!r} here")
    spec = kind_spec(config.kind)
    sides = (("input", session.get_inputs(), spec.inputs), ("output", session.get_outputs(), spec.outputs))
    for role, args, specs in sides:
        got = {a.name: a for a in args}
        want = [s.name for s in specs]
        if sorted(got) != sorted(want):
            raise RelightError(f"{name}: {config.kind} graph {role}s are {sorted(got)}, expected {want}")
        for s in specs:
            arg = got[s.name]
            if arg.type != "tensor(float)":
                raise RelightError(f"{name}: {role} {s.name!r} has type {arg.type}, expected tensor(float) (float32)")
            if len(arg.shape) != s.rank:
                rank = len(arg.shape)
                raise RelightError(f"{name}: {role} {s.name!r} has rank {rank} ({arg.shape}), expected {s.rank}")
            expect = s.fixed_dims(config.resolution if spec.fixed_size else None)
            for axis, (have, need) in enumerate(zip(arg.shape, expect, strict=False)):
                if need is not None and isinstance(have, int) and have != need:
                    raise RelightError(
                        f"{name}: {role} {s.name!r} has shape {arg.shape}, expected size {need} on axis {axis}"
                    )
    return config


@dataclass(frozen=True)
class Model:
    """One checked graph: its session, its contract settings and what to call it."""

    session: ort.InferenceSession
    config: ModelConfig
    name: str

    @property
    def on_cuda(self) -> bool:
        """True when CUDA (or TensorRT on CUDA) runs this graph."""
        return self.session.get_providers()[0] in (CUDA, TENSORRT)

    def warm_up(self) -> None:
        """Run the graph once on zeros (allocates memory, picks CUDA kernels)."""
        self.session.run(None, _warmup_feeds(self.session, self.config))

    def run(self, feeds: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Run on host arrays (float32, NCHW); returns every output by name.

        Raises:
            RelightError: an output holds NaN or Inf (naming this model and the output).
        """
        names = [o.name for o in self.session.get_outputs()]
        values = self.session.run(names, {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in feeds.items()})
        out = dict(zip(names, values, strict=True))
        check_finite(out, self.name)
        return out


def check_finite(outputs: Mapping[str, np.ndarray], model: str) -> None:
    """Raise RelightError when a network output holds NaN or Inf (a broken graph or inputs it cannot take)."""
    for key, value in outputs.items():
        if not np.isfinite(value).all():
            raise RelightError(f"model {model}: output {key!r} holds NaN or Inf (a broken or mis-exported graph?)")


def load_model(
    path: str | os.PathLike | ort.InferenceSession,
    kind: str,
    *,
    device: str = "auto",
    device_id: int = 0,
    providers: Sequence | None = None,
    sess_options: ort.SessionOptions | None = None,
    warmup: bool = True,
) -> Model:
    """``create_session`` plus a check that the graph is of ``kind``; see there for the arguments."""
    name = "session" if isinstance(path, ort.InferenceSession) else str(path)
    session = create_session(
        path, device=device, device_id=device_id, providers=providers, sess_options=sess_options, warmup=False,
        kind=kind,
    )
    model = Model(session, validate_session(session, name, kind), name)
    if warmup:
        model.warm_up()
    return model


def bundled_models_dir() -> Path:
    """relight_rt/models inside the installed package."""
    return Path(__file__).resolve().parents[1] / "models"


def find_models(models: str | os.PathLike | None = None) -> Path:
    """The folder holding the stage-1 graph: ``models`` if given, else $RELIGHT_RT_MODELS, else the bundled models.

    Raises:
        RelightError: nothing found; the message lists every place looked.
    """
    required = KINDS["stage1"].filename
    if models is not None:
        places = [Path(models)]
    else:
        env = environment.models()
        # A $RELIGHT_RT_MODELS that holds no models is a mistake to report, not a reason to fall back
        # silently to the bundled models.
        places = [Path(env)] if env else [bundled_models_dir()]
    for place in places:
        if (place / required).is_file():
            return place
    looked = "; ".join(f"{p} ({'no ' + required if p.is_dir() else 'no such folder'})" for p in places)
    if models is not None:
        hint = ""
    elif environment.models():
        hint = f" (from ${ENV_MODELS}; unset it to use the bundled models)"
    else:
        hint = f"; pass --models DIR / models=DIR or set ${ENV_MODELS}"
    raise RelightError(f"no relight_rt models found, looked in: {looked}{hint}")
