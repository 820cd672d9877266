"""The ONNX model contract, format version 1 (DESIGN.md §5), with every model kind declared once.

One place that says what a relight_rt graph must look like: the metadata keys, and for each kind
(a :class:`KindSpec` in the :data:`KINDS` registry) the names, ranks and channel counts of its inputs
and outputs, the file name it has in a models folder, and the metadata it must carry. The exporter
writes graphs from these specs; the runtime's session validation, warm-up and model discovery read
only them. A new kind is one :func:`register_kind` call::

    register_kind(KindSpec("matte", inputs=(TensorSpec("image", 4, 3),), outputs=(TensorSpec("alpha", 4, 1),),
                           fixed_size=True, filename="matte.onnx", metadata=()))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .errors import RelightError

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
LIGHT_SHAPE = (9, 3)  # an SH light input or output: (N, 9, 3), DESIGN.md §3
OUTPUT_ACTIVATIONS = ("none", "tanh")


@dataclass(frozen=True)
class TensorSpec:
    """One graph input or output, float32.

    Attributes:
        name: the tensor's name in the graph.
        rank: 4 for images (N, C, H, W); 3 for SH lights (N, 9, 3); 2 for per-image scores (N, C).
        channels: C of a rank-4 tensor (None: any); unused for lights.
        stride: a rank-4 output on a coarser grid than the input: H = W = resolution / stride (a detector's
            per-cell predictions).
    """

    name: str
    rank: int
    channels: int | None = None
    stride: int = 1

    def fixed_dims(self, resolution: int | None) -> list[int | None]:
        """The sizes every axis must have (None where any size goes); ``resolution`` for fixed-size kinds."""
        if self.rank == 3:
            return [None, *LIGHT_SHAPE]
        side = resolution // self.stride if resolution is not None else None
        return [None, self.channels, side, side][: self.rank]

    def zeros_shape(self, size: int) -> tuple[int, ...]:
        """A batch-of-one shape for this tensor at spatial ``size`` (warm-up feeds, sample inputs)."""
        if self.rank == 3:
            return (1, *LIGHT_SHAPE)
        return (1, self.channels or 3, size, size)


@dataclass(frozen=True)
class KindSpec:
    """Everything the contract says about one kind of graph.

    Attributes:
        name: the value of ``relight_rt.kind``.
        inputs, outputs: in order.
        fixed_size: True: H = W = the metadata resolution; False: any H, W divisible by 64.
        filename: the graph's file name in a models folder (precision variants add ``_fp16`` / ``_int8``).
        metadata: keys this kind must carry beyond format, kind, resolution, color and source
            (relighting kinds: sh_degree and norm; a person-matting graph needs neither).
    """

    name: str
    inputs: tuple[TensorSpec, ...]
    outputs: tuple[TensorSpec, ...]
    fixed_size: bool
    filename: str
    metadata: tuple[str, ...] = (META_SH_DEGREE, META_NORM)

    def tensor(self, name: str) -> TensorSpec:
        """The input or output called ``name``."""
        for t in (*self.inputs, *self.outputs):
            if t.name == name:
                return t
        raise RelightError(f"kind {self.name!r} has no tensor {name!r}")


KINDS: dict[str, KindSpec] = {}


def register_kind(spec: KindSpec) -> KindSpec:
    """Add a kind to :data:`KINDS` (session validation, warm-up, discovery and export read it from there)."""
    if spec.name in KINDS and KINDS[spec.name] != spec:
        raise RelightError(f"model kind {spec.name!r} is already registered with another spec")
    KINDS[spec.name] = spec
    return spec


def kind_spec(kind: str) -> KindSpec:
    """The spec of ``kind``; an unknown kind raises and lists the known ones."""
    try:
        return KINDS[kind]
    except KeyError:
        raise RelightError(f"model kind {kind!r} is unknown; known kinds: {sorted(KINDS)}") from None


register_kind(KindSpec(
    "stage1",
    inputs=(TensorSpec("image", 4, 3), TensorSpec("mask", 4, 1)),
    outputs=(TensorSpec("albedo", 4, 3), TensorSpec("skin", 4, 1), TensorSpec("transport", 4, 9),
             TensorSpec("light", 3)),
    fixed_size=True,
    filename="stage1.onnx",
))
register_kind(KindSpec(
    "stage2",
    inputs=(TensorSpec("diffuse", 4, 3), TensorSpec("mask", 4, 1)),
    outputs=(TensorSpec("residual", 4, 3), TensorSpec("relit", 4, 3)),
    fixed_size=False,
    filename="stage2.onnx",
))
register_kind(KindSpec(
    "dvp",
    inputs=(TensorSpec("frame", 4, 3), TensorSpec("mask", 4, 1), TensorSpec("light", 3)),
    outputs=(TensorSpec("relit", 4, 3),),
    fixed_size=False,
    filename="dvp.onnx",
))
# Person matting (issue 20, relight_rt.person.matting), converted from MediaPipe by export/mask_models.py. Neither
# carries SH degree or norm: they are not relighting networks.
register_kind(KindSpec(  # a square person region -> person logits and a pose-presence probability
    "matte_pose",
    inputs=(TensorSpec("image", 4, 3),),
    outputs=(TensorSpec("segmentation", 4, 1), TensorSpec("presence", 2, 1)),
    fixed_size=True,
    filename="matte_pose.onnx",
    metadata=(),
))
register_kind(KindSpec(  # the whole letterboxed image -> person probability (finds the region)
    "matte_roi",
    inputs=(TensorSpec("image", 4, 3),),
    outputs=(TensorSpec("segmentation", 4, 1),),
    fixed_size=True,
    filename="matte_roi.onnx",
    metadata=(),
))
register_kind(KindSpec(  # issue 33: the whole letterboxed image -> face boxes, where the pose graph finds nobody
    "matte_face",
    inputs=(TensorSpec("image", 4, 3),),
    outputs=(TensorSpec("boxes", 4, 16, stride=4), TensorSpec("scores", 4, 1, stride=4)),
    fixed_size=True,
    filename="matte_face.onnx",
    metadata=(),
))


@dataclass(frozen=True)
class ModelConfig:
    """Per-model settings read from a graph's metadata_props.

    Attributes:
        kind: a registered kind ("stage1", "stage2", "dvp", ...).
        resolution: native square size in pixels; 0 means any size divisible by 64.
        norm: "batch" (running statistics) or "instance" (per-sample statistics); "" for a kind without it.
        source: free text, what the graph was trained or converted from (and under which licence).
    """

    kind: str
    resolution: int
    norm: str
    source: str
    color: str = "RGB"
    sh_degree: int = 2
    format: str = FORMAT_VERSION

    @property
    def spec(self) -> KindSpec:
        """The kind's contract spec."""
        return kind_spec(self.kind)

    def metadata(self) -> dict[str, str]:
        """The metadata_props that describe this model, as strings (only the keys its kind carries)."""
        meta = {
            META_FORMAT: self.format,
            META_KIND: self.kind,
            META_RESOLUTION: str(self.resolution),
            META_COLOR: self.color,
            META_SH_DEGREE: str(self.sh_degree),
            META_NORM: self.norm,
            META_SOURCE: self.source,
        }
        optional = {META_SH_DEGREE, META_NORM} - set(self.spec.metadata)
        return {k: v for k, v in meta.items() if k not in optional}


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
    spec = KINDS[kind]
    res_text = need(META_RESOLUTION)
    try:
        resolution = int(res_text)
    except ValueError:
        raise RelightError(f"{name}: metadata {META_RESOLUTION} is {res_text!r}, expected an integer") from None
    # relighting kinds (those with SH metadata) work at multiples of 64: six stride-2 convolutions
    if resolution < 0 or (resolution % 64 and META_SH_DEGREE in spec.metadata):
        raise RelightError(f"{name}: metadata {META_RESOLUTION} is {resolution}, expected 0 or a multiple of 64")
    if spec.fixed_size and resolution == 0:
        raise RelightError(f"{name}: a {kind} graph needs a fixed resolution, metadata {META_RESOLUTION} is 0")
    color = need(META_COLOR)
    if color != "RGB":
        raise RelightError(f"{name}: metadata {META_COLOR} is {color!r}, expected 'RGB'")
    sh_degree, norm = 2, ""
    if META_SH_DEGREE in spec.metadata:
        degree = need(META_SH_DEGREE)
        if degree != "2":
            raise RelightError(f"{name}: metadata {META_SH_DEGREE} is {degree!r}, expected '2'")
    if META_NORM in spec.metadata:
        norm = need(META_NORM)
        if norm not in NORMS:
            raise RelightError(f"{name}: metadata {META_NORM} is {norm!r}, expected one of {list(NORMS)}")
    source = str(meta.get(META_SOURCE, ""))
    return ModelConfig(kind=kind, resolution=resolution, norm=norm, source=source, sh_degree=sh_degree)
