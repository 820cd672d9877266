"""The ONNX model contract, format version 1 (DESIGN.md §5).

One place that says what a relight_rt graph must look like: the metadata keys, the kinds, and
the names and ranks of every input and output. The exporter writes graphs from these constants
and the runtime checks graphs against them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ._errors import RelightError

FORMAT_VERSION = "1"

META_FORMAT = "relight_rt.format"
META_KIND = "relight_rt.kind"
META_RESOLUTION = "relight_rt.resolution"
META_COLOR = "relight_rt.color"
META_SH_DEGREE = "relight_rt.sh_degree"
META_NORM = "relight_rt.norm"
META_SOURCE = "relight_rt.source"
# Informational, stage2/dvp graphs written by this project: the network's output activation ("none" as the
# reference's, or "tanh", a training option). The graph computes it; the runtime does not read this key.
META_OUTPUT_ACTIVATION = "relight_rt.output_activation"

NORMS = ("batch", "instance")
OUTPUT_ACTIVATIONS = ("none", "tanh")


@dataclass(frozen=True)
class TensorSpec:
    """One graph input or output: its name and rank (all are float32, NCHW or N×9×3)."""

    name: str
    rank: int


@dataclass(frozen=True)
class KindSpec:
    """The inputs and outputs, in order, of one kind of graph."""

    inputs: tuple[TensorSpec, ...]
    outputs: tuple[TensorSpec, ...]
    fixed_size: bool  # True: H = W = resolution; False: any H, W divisible by 64


KINDS: dict[str, KindSpec] = {
    "stage1": KindSpec(
        inputs=(TensorSpec("image", 4), TensorSpec("mask", 4)),
        outputs=(TensorSpec("albedo", 4), TensorSpec("skin", 4), TensorSpec("transport", 4), TensorSpec("light", 3)),
        fixed_size=True,
    ),
    "stage2": KindSpec(
        inputs=(TensorSpec("diffuse", 4), TensorSpec("mask", 4)),
        outputs=(TensorSpec("residual", 4), TensorSpec("relit", 4)),
        fixed_size=False,
    ),
    "dvp": KindSpec(
        inputs=(TensorSpec("frame", 4), TensorSpec("mask", 4), TensorSpec("light", 3)),
        outputs=(TensorSpec("relit", 4),),
        fixed_size=False,
    ),
}


@dataclass(frozen=True)
class ModelConfig:
    """Per-model settings read from a graph's metadata_props.

    Attributes:
        kind: "stage1", "stage2" or "dvp".
        resolution: native square size in pixels; 0 means any size divisible by 64.
        norm: "batch" (running statistics) or "instance" (per-sample statistics).
        source: free text, what the graph was trained or converted from.
    """

    kind: str
    resolution: int
    norm: str
    source: str
    color: str = "RGB"
    sh_degree: int = 2
    format: str = FORMAT_VERSION

    def metadata(self) -> dict[str, str]:
        """The metadata_props that describe this model, as strings."""
        return {
            META_FORMAT: self.format,
            META_KIND: self.kind,
            META_RESOLUTION: str(self.resolution),
            META_COLOR: self.color,
            META_SH_DEGREE: str(self.sh_degree),
            META_NORM: self.norm,
            META_SOURCE: self.source,
        }


def config_from_metadata(meta: Mapping[str, str], name: str = "model") -> ModelConfig:
    """Parse and check a graph's metadata_props.

    Args:
        meta: the graph's custom metadata (``InferenceSession.get_modelmeta().custom_metadata_map``).
        name: what to call the graph in error messages (usually its path).

    Raises:
        RelightError: a key is missing or holds a value the contract does not allow.
    """

    def need(key: str) -> str:
        if key not in meta:
            raise RelightError(f"{name}: metadata {key!r} is missing; not a relight_rt graph (format {FORMAT_VERSION})")
        return str(meta[key])

    fmt = need(META_FORMAT)
    if fmt != FORMAT_VERSION:
        raise RelightError(f"{name}: metadata {META_FORMAT} is {fmt!r}, this runtime reads format {FORMAT_VERSION!r}")
    kind = need(META_KIND)
    if kind not in KINDS:
        raise RelightError(f"{name}: metadata {META_KIND} is {kind!r}, expected one of {sorted(KINDS)}")
    res_text = need(META_RESOLUTION)
    try:
        resolution = int(res_text)
    except ValueError:
        raise RelightError(f"{name}: metadata {META_RESOLUTION} is {res_text!r}, expected an integer") from None
    if resolution < 0 or (resolution and resolution % 64):
        raise RelightError(f"{name}: metadata {META_RESOLUTION} is {resolution}, expected 0 or a multiple of 64")
    if kind == "stage1" and resolution == 0:
        raise RelightError(f"{name}: a stage1 graph needs a fixed resolution, metadata {META_RESOLUTION} is 0")
    color = need(META_COLOR)
    if color != "RGB":
        raise RelightError(f"{name}: metadata {META_COLOR} is {color!r}, expected 'RGB'")
    degree = need(META_SH_DEGREE)
    if degree != "2":
        raise RelightError(f"{name}: metadata {META_SH_DEGREE} is {degree!r}, expected '2'")
    norm = need(META_NORM)
    if norm not in NORMS:
        raise RelightError(f"{name}: metadata {META_NORM} is {norm!r}, expected one of {list(NORMS)}")
    source = str(meta.get(META_SOURCE, ""))
    return ModelConfig(kind=kind, resolution=resolution, norm=norm, source=source)
