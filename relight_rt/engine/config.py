"""One runtime configuration: which models, where they run and how photos are prepared for them.

A :class:`RuntimeConfig` is a frozen, picklable value: the CLI builds one from its options
(``relight_rt.cli.options.add_runtime_options``), an application or a Ray worker builds one in code, and
``relight_rt.open(config)`` loads the models it names. It holds no sessions and no arrays, so
it can be sent to another process and compared for equality.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass

from .errors import RelightError

DEVICES = ("auto", "cuda", "cpu")
PRECISIONS = ("fp32", "fp16", "int8")
PREPROCESS = ("quality", "reference")
MATTING = ("auto", "all", "off")


@dataclass(frozen=True)
class RuntimeConfig:
    """How a :class:`relight_rt.Relighter` is set up.

    Attributes:
        models: folder with ``stage1.onnx`` [``stage2.onnx``, ``dvp.onnx``]; None: $RELIGHT_RT_MODELS, then
            the bundled models.
        device: "auto" (CUDA when onnxruntime offers it), "cuda" or "cpu".
        device_id: CUDA device index.
        precision: "fp32", "fp16" or "int8": which graphs of the folder run (see ``Relighter``).
        preprocess: "quality" (INTER_AREA when shrinking) or "reference" (the reference's resize, bit for bit).
        detail: carry the input's full-resolution detail into results larger than the network's square.
        warmup: run each graph once at load; None: only on CUDA.
        matting: "auto": a photo with neither a mask nor an alpha channel gets an automatic person matte of
            its largest person and the people who stand with them, as tall and seen whole (a group posing
            together, relit person by person; when a matting model is installed); "all": of everyone the matte
            finds (a group photo relit whole, person by person, each with their share of the matte;
            relight_rt.person.matting ``person="all"``, ``PersonMatter.parts``); "off": such a photo is an error.
    """

    models: str | None = None
    device: str = "auto"
    device_id: int = 0
    precision: str = "fp32"
    preprocess: str = "quality"
    detail: bool = True
    warmup: bool | None = None
    matting: str = "auto"

    def __post_init__(self) -> None:
        if self.models is not None:
            if not isinstance(self.models, (str, os.PathLike)):
                raise RelightError(f"models: expected a folder path or None, got {type(self.models).__name__}")
            object.__setattr__(self, "models", os.fspath(self.models))
        for field, value, allowed in (
            ("device", self.device, DEVICES),
            ("precision", self.precision, PRECISIONS),
            ("preprocess", self.preprocess, PREPROCESS),
            ("matting", self.matting, MATTING),
        ):
            if value not in allowed:
                raise RelightError(f"{field} is {value!r}, expected one of {list(allowed)}")
        if not isinstance(self.device_id, int) or isinstance(self.device_id, bool) or self.device_id < 0:
            raise RelightError(f"device_id is {self.device_id!r}, expected a whole number >= 0")
        if not isinstance(self.detail, bool):
            raise RelightError(f"detail is {self.detail!r}, expected True or False")
        if self.warmup is not None and not isinstance(self.warmup, bool):
            raise RelightError(f"warmup is {self.warmup!r}, expected True, False or None")

    def replace(self, **changes) -> RuntimeConfig:
        """A copy with some fields changed (checked like a new one)."""
        return RuntimeConfig(**{**asdict(self), **changes})
