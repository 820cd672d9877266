"""Streaming video relighting: frame sources, per-frame lights, stabiliser, DVP, sinks.

A video flows through in batches of ``batch_size`` frames; only that batch, one frame of
stabiliser history and the writer's buffer are ever held, so memory does not grow with the
video's length.

    source ──► batch of (frame, mask) ──► engine.decompose ──► Stabilizer ──► engine.render(light_t)
                                       └─► (with a fitted DVP) dvp(frame, mask, light_t) ───────────┴─► sink

- Sources (relight_rt.video.frames, re-exported here): a video file (``cv2.VideoCapture``) or a folder
  of frames. Masks: a folder (same stem, or ``STEM_mask``), per-frame ``STEM_mask.EXT`` files beside
  the frames (the reference layout), the alpha channel of RGBA frames, or a mask video.
- Lights per frame (:class:`LightSchedule`): one light, an (N, 9, 3) sequence, a rotation about
  +z at a number of turns per second, or an interpolation between keyframe lights.
- Engines: :class:`RelighterEngine` (the runtime's stage 1 + stage 2, batched stage 1) or a fitted
  DVP graph (:class:`DVPModel`).
- Sinks (relight_rt.video.frames): a video file (``cv2.VideoWriter``, written to a temporary file and
  renamed when complete) and/or a folder of PNG frames (each written atomically).

Frames are RGB float32 in [0, 1], (H, W, 3); masks float32 (H, W) in [0, 1]; lights (9, 3) RGB SH
(DESIGN.md §3).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.compositing import Background, clean_edge_colour, over_premultiplied, parse_background
from ..light import sh
from ..light.spec import LightSpec
from .frames import (  # noqa: F401  (re-exported: the video API in one place)
    IMAGE_SUFFIXES,
    MAX_FPS,
    VIDEO_SUFFIXES,
    Frame,
    FrameSink,
    FrameSource,
    batched,
    empty_clip,
    read_frame,
    read_mask_file,
)
from .stabilize import Stabilizer

logger = logging.getLogger(__name__)

# ---------------------------------------------------------------------------------------------
# lights


def resolve_light(spec, relighter=None) -> np.ndarray:
    """One light, by the rule of relight_rt.light.spec (light file, environment map, photo, preset name).

    Args:
        spec: a :class:`relight_rt.light.spec.LightSpec`, a (9, 3) array, or a string / path.
        relighter: estimates the light of a photo of a person (None: a photo is an error).

    Returns:
        (9, 3) float64 RGB SH coefficients.
    """
    if relighter is not None:
        return relighter.resolve_light(spec, dtype=np.float64)
    return LightSpec.of(spec).resolve(dtype=np.float64)


class LightSchedule:
    """The light of each frame. Build with one of the class methods; call ``schedule(index, fps)``."""

    def __init__(self, fn: Callable[[int, float], np.ndarray], description: str, length: int | None = None):
        self._fn = fn
        self.description = description
        self.length = length  # frames covered, None = unbounded

    def __call__(self, index: int, fps: float) -> np.ndarray:
        """(9, 3) float32 RGB light of frame ``index`` (0-based) of a video at ``fps`` frames per second."""
        if self.length is not None and index >= self.length:
            raise RelightError(f"lights: {self.description} covers {self.length} frames, frame {index} needs one")
        return np.asarray(self._fn(index, fps), np.float32)

    @classmethod
    def constant(cls, light: np.ndarray) -> LightSchedule:
        fixed = sh.check_light(light, "light")
        return cls(lambda i, fps: fixed, "one light")

    @classmethod
    def sequence(cls, lights: np.ndarray) -> LightSchedule:
        """One light per frame from an (N, 9, 3) RGB array."""
        arr = np.asarray(lights, np.float64)
        if arr.ndim != 3 or arr.shape[1:] != (9, 3) or not np.isfinite(arr).all():
            raise RelightError(f"lights: expected a finite (N, 9, 3) light sequence, got {np.asarray(lights).shape}")
        arr = sh.check_lights(arr, "lights")  # a copy; too large for float32: RelightError
        return cls(lambda i, fps: arr[i], f"a sequence of {len(arr)} lights", len(arr))

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> LightSchedule:
        """An (N, 9, 3) RGB .npy light sequence (its header checked before anything is allocated)."""
        from ..engine.limits import load_npy

        if Path(path).suffix.lower() == ".json":
            raise RelightError(f"{path}: --lights takes an (N, 9, 3) .npy sequence, one light per frame; "
                               "for one light from a .json file use --light")
        arr = load_npy(path, "light sequence")
        try:
            return cls.sequence(arr)
        except RelightError as exc:
            raise RelightError(f"{path}: {exc}") from None

    @classmethod
    def rotating(cls, light: np.ndarray, turns_per_second: float) -> LightSchedule:
        """``light`` turned about +z (DESIGN.md §3 rotate_z) by ``2π · turns_per_second · index / fps``."""
        base = sh.check_light(light, "light")
        rate = float(turns_per_second)
        return cls(lambda i, fps: sh.rotate_z(base, 2.0 * np.pi * rate * i / fps), f"{rate} turns per second")

    @classmethod
    def interpolated(cls, keys: Sequence[np.ndarray], n_frames: int) -> LightSchedule:
        """Interpolate between keyframe lights over ``n_frames`` (relight_rt.light.presets.interpolate)."""
        from ..light import presets

        if len(keys) < 2 or n_frames < 1:
            raise RelightError(f"lights: expected at least two keyframe lights and frames, got {len(keys)}, {n_frames}")
        arr = np.asarray(presets.interpolate([sh.check_light(k, f"key light {j}") for j, k in enumerate(keys)],
                                             n_frames), np.float64)
        return cls(lambda i, fps: arr[i], f"an interpolation over {n_frames} frames", n_frames)


# ---------------------------------------------------------------------------------------------
# engines


@dataclass(frozen=True)
class FrameLayers:
    """One frame's intrinsic layers in the engine's working frame (what the stabiliser filters).

    Attributes:
        image: (h, w, 3) the input frame in the working frame, RGB [0, 1] (the optical-flow source).
        mask: (h, w) person mask in [0, 1].
        albedo: (h, w, 3) RGB [0, 1]; transport: (h, w, 9) (DESIGN.md §3).
        light: (9, 3) the original frame's estimated light, or None.
        state: engine-specific data (e.g. the runtime's Decomposition).
    """

    image: np.ndarray
    mask: np.ndarray
    albedo: np.ndarray
    transport: np.ndarray
    light: np.ndarray | None = None
    state: object = None


class Engine(Protocol):
    """What the pipeline needs from a relighting runtime (see :class:`RelighterEngine`).

    ``decompose`` gets a batch of full frames (H, W, 3) and masks (H, W), and per frame whether its mask is the
    automatic matte (``Frame.automatic``; None: none is), and returns FrameLayers per frame. ``render`` puts a
    frame's (stabilised) albedo/transport back into its FrameLayers, applies ``light`` (9, 3) and returns the full
    output frame (H, W, 3|4) RGB[A] [0, 1], composited over ``background`` (a relight_rt.image.compositing.Background).
    ``to_input`` maps a working-frame layer to the input frame.
    """

    def decompose(self, images: Sequence[np.ndarray], masks: Sequence[np.ndarray],
                  automatic: Sequence[bool] | None = None) -> list[FrameLayers]: ...

    def render(self, layers: FrameLayers, albedo: np.ndarray, transport: np.ndarray, own_light: np.ndarray | None,
               light: np.ndarray, background: Background) -> np.ndarray: ...

    def to_input(self, layers: FrameLayers, layer: np.ndarray) -> np.ndarray: ...


class RelighterEngine:
    """Adapter of :class:`relight_rt.relight.relighter.Relighter` for video: batched stage 1 in the network frame.

    The working frame is each frame's network square (R x R crop of the person); the stabiliser's
    optical flow runs between consecutive network-frame images, so it also absorbs the small
    shift and scale of the crop box from one frame to the next.

    Args:
        relighter: a loaded Relighter (stage 1, optional stage 2).
        exposure: "auto" (each frame keeps its person's mean luminance), an EV offset or "physical"
            (relight_rt.light.exposure).
    """

    def __init__(self, relighter, exposure="auto"):
        from ..light.exposure import parse_exposure

        self.relighter = relighter
        self.exposure = parse_exposure(exposure)

    def decompose(self, images: Sequence[np.ndarray], masks: Sequence[np.ndarray],
                  automatic: Sequence[bool] | None = None) -> list[FrameLayers]:
        # the automatic matte's frames may keep the background's rim over their own background (compose FRAME_RIM)
        decs = self.relighter.decompose_batch(images, masks, allow_full=True, automatic=automatic)
        return [FrameLayers(d.network_image, d.network_mask, np.array(d.albedo), np.array(d.transport),
                            np.array(d.light), d) for d in decs]

    def render(self, layers: FrameLayers, albedo: np.ndarray, transport: np.ndarray, own_light: np.ndarray | None,
               light: np.ndarray, background: Background) -> np.ndarray:
        dec = layers.state
        stab = replace(dec, albedo_chw=albedo.transpose(2, 0, 1), transport_chw=transport.transpose(2, 0, 1),
                       light=dec.light if own_light is None else own_light)
        return self.relighter.relight(stab, light, background=background, exposure=self.exposure)

    def to_input(self, layers: FrameLayers, layer: np.ndarray) -> np.ndarray:
        return layers.state.to_input(layer)


class DVPModel:
    """A fitted deep video prior graph (contract kind "dvp"), run on batches of frames.

    Args:
        path: the .onnx file.
        device: "auto", "cuda" or "cpu" (relight_rt.engine.session).
        size: working size of the long side (the size it was fitted at, see ``python -m export fit-dvp
            --size``); None: the frames' own size. Frames are zero-padded to multiples of 64.
    """

    def __init__(self, path: str | os.PathLike, device: str = "auto", size: int | None = None):
        from ..engine.session import load_model

        self.path = Path(path)
        if not self.path.is_file():
            raise RelightError(f"{self.path}: DVP model file does not exist")
        self.model = load_model(self.path, "dvp", device=device, warmup=False)
        self.size = size

    def __call__(self, images: Sequence[np.ndarray], masks: Sequence[np.ndarray],
                 lights: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Relit frames (H, W, 3) float32 RGB [0, 1], masked, at the frames' own size."""
        h0, w0 = images[0].shape[:2]
        h, w = h0, w0
        if self.size is not None and max(h0, w0) != self.size:
            scale = self.size / max(h0, w0)
            h, w = max(1, round(h0 * scale)), max(1, round(w0 * scale))
        ph, pw = -h % 64, -w % 64
        x = np.zeros((len(images), 3, h + ph, w + pw), np.float32)
        m = np.zeros((len(images), 1, h + ph, w + pw), np.float32)
        for b, (img, mask) in enumerate(zip(images, masks, strict=True)):
            if (h, w) != (h0, w0):
                img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
                mask = cv2.resize(mask, (w, h), interpolation=cv2.INTER_LINEAR)
            x[b, :, :h, :w] = img.transpose(2, 0, 1)
            m[b, 0, :h, :w] = mask
        light = np.stack([np.asarray(v, np.float32) for v in lights])
        relit = self.model.run({"frame": x, "mask": m, "light": light})["relit"]
        outs = [np.ascontiguousarray(r[:, :h, :w].transpose(1, 2, 0)) for r in relit]
        if (h, w) != (h0, w0):
            outs = [cv2.resize(o, (w0, h0), interpolation=cv2.INTER_LINEAR) for o in outs]
        return outs


# ---------------------------------------------------------------------------------------------
# pipeline


@dataclass(frozen=True)
class VideoReport:
    """What :func:`relight_video` did: frames written and seconds per frame (processing only)."""

    frames: int
    seconds_per_frame: float


def composite(relit: np.ndarray, image: np.ndarray, mask: np.ndarray, background="original",
              premultiplied: bool = False) -> np.ndarray:
    """Put a relit person over a frame's background (relight_rt.image.compositing).

    Args:
        relit: (H, W, 3) RGB [0, 1]; already multiplied by the mask when ``premultiplied`` (a DVP output).
        image: (H, W, 3) the original frame; mask: (H, W) in [0, 1].
        background: a Background or its shorthand ("original", "transparent", "black", "#RRGGBB", an image).

    Returns:
        (H, W, 3) float32, or (H, W, 4) RGBA for a transparent background.
    """
    bg = parse_background(background)
    person = relit if premultiplied else relit * mask[..., None]
    if bg.kind != "original":  # a new backdrop: the soft edge loses the frame's old background first
        from ..image.foreground import estimate_foreground

        m = mask[..., None]
        colour = np.divide(person, m, out=np.zeros_like(person), where=m > 1e-3)
        photo = np.ascontiguousarray(image[..., :3], dtype=np.float32)
        colour = clean_edge_colour(colour, photo, estimate_foreground(photo, mask), mask)
        person = colour * m
    return over_premultiplied(person, mask, bg.backdrop(image))


GRADE_SECONDS = 0.5  # --grade-background over a clip: the person's change followed with this time constant


class BackgroundGrade:
    """The original background following the light over a clip (``Background.original(grade=True)``): the still
    photo's global grade (relight_rt.image.compositing; the person's change in light per channel, put on the backdrop's
    values with the exposure's 1 / 2.2 power), measured on every frame and followed over time.

    One frame's grade is measured where the frame is opaque person (alpha >= 1 - 1/255: there the relit frame is
    the person's relit colour and the frame their own colour; relight_rt.relight.compose ``light_sums``, on an
    even sample of them); the soft edge, a few pixels of it, is left out. Measured afresh on each frame it
    would move with the person's pose, the matte and the stage-1 estimate (the reference clip under night: 0.008 EV
    from frame to frame at the median, 0.022 at most; benchmarks/background_grade.py --clip), and every pixel of a
    still background would flicker with it; so the log of the grade follows the frames' with an exponential time
    constant of
    ``GRADE_SECONDS`` (a light changing over seconds, a schedule's or a rotation's, is followed within that). The
    first frame with a person takes its own grade; a frame without one keeps the grade the clip had (none before
    any person: the background as it is).
    """

    def __init__(self, fps: float) -> None:
        self.keep = float(np.exp(-1.0 / (max(fps, 1e-3) * GRADE_SECONDS)))
        self.log: np.ndarray | None = None

    def update(self, relit: np.ndarray, image: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The clip's grade (3,) after this frame (``relit``: the frame relit over its own background)."""
        from ..relight.compose import grade_of_sums, light_sums

        opaque = mask >= 1 - 1 / 255
        if opaque.any():
            now = np.log(np.maximum(grade_of_sums(*light_sums(relit, image, opaque)), 1e-6))
            self.log = now if self.log is None else self.keep * self.log + (1 - self.keep) * now
        return np.ones(3, np.float32) if self.log is None else np.exp(self.log).astype(np.float32)

    @staticmethod
    def apply(relit: np.ndarray, image: np.ndarray, mask: np.ndarray, gain: np.ndarray) -> np.ndarray:
        """``relit`` (over the frame's own background) with that background graded by ``gain``: outside the matte
        and behind the soft edge (the colour behind it as the frame's relighting took it: the solid colours beside
        it, relight_rt.image.foreground ``nearest_colours``), clipped to [0, 1]."""
        from ..image.foreground import nearest_colours

        behind = nearest_colours(np.ascontiguousarray(image[..., :3], np.float32), mask)[1]
        change = np.minimum(behind * gain, 1, dtype=np.float32)  # the backdrop graded, clipped at white ...
        change -= behind  # ... less what the frame shows of it, by the share it shows
        change *= (1 - mask)[..., None]
        change += relit[..., :3]
        return np.clip(change, 0, 1, out=change)


def relight_frames(source: Iterator[Frame] | FrameSource, lights: LightSchedule, *, fps: float | None = None,
                   engine: Engine | None = None, dvp: DVPModel | None = None, stabilizer: Stabilizer | None = None,
                   batch_size: int = 4, background: Background | str = "original",
                   with_layers: bool = False) -> Iterator[tuple[Frame, np.ndarray, dict]]:
    """Relight a stream of frames; yields (frame, output (H, W, 3|4) RGB[A] [0, 1], extras) in order.

    ``fps`` (for light schedules that depend on time) defaults to the source's; ``background`` is a
    relight_rt.image.compositing.Background or its shorthand ("original", "transparent", "black", an image).

    With ``dvp`` the fitted network maps each frame and its light straight to the relit frame.
    Otherwise ``engine`` decomposes each batch, ``stabilizer`` (None = off) filters the layers (and
    the original video's estimated light), and ``engine.render`` applies each frame's own light.
    Frames whose mask is empty pass through unchanged.

    ``extras`` holds "light" (9, 3) and, on the engine path with ``with_layers``, the stabilised
    "albedo" (H, W, 3) and "transport" (H, W, 9) in the input frame (what the light-following
    metric needs).
    """
    if (engine is None) == (dvp is None):
        raise RelightError("video: expected exactly one of an engine (stage 1/2 models) or a DVP model")
    bg = parse_background(background)  # checked before any work
    if fps is None:
        fps = getattr(source, "fps", None)
        if fps is None:
            raise RelightError("video: fps is needed for a stream of frames without one")
    fitted: dict[tuple[int, int], Background] = {}
    grade = BackgroundGrade(fps) if bg.graded else None  # the grade follows the clip's frames (no flicker)
    if grade is not None:
        bg = Background.original()  # each frame relit over its own background, then graded by the clip's grade

    def backdrop_for(frame: Frame) -> Background:  # an image background is read and fitted once per frame size
        if bg.kind != "image":
            return bg
        shape = frame.image.shape[:2]
        if shape not in fitted:
            fitted[shape] = Background.from_image(bg.backdrop(frame.image), fit="exact")
        return fitted[shape]

    for batch in batched(source, batch_size):
        batch_lights = [lights(f.index, fps) for f in batch]
        people = [i for i, f in enumerate(batch) if (f.mask >= 0.5).any()]
        outs: list = [None] * len(batch)
        extras: list[dict] = [{"light": light} for light in batch_lights]
        if dvp is not None and people:
            relit = dvp([batch[i].image for i in people], [batch[i].mask for i in people],
                        [batch_lights[i] for i in people])
            for i, out in zip(people, relit, strict=True):
                outs[i] = composite(out, batch[i].image, batch[i].mask, backdrop_for(batch[i]), premultiplied=True)
        elif people:
            layers = engine.decompose([batch[i].image for i in people], [batch[i].mask for i in people],
                                      [batch[i].automatic for i in people])
            for i, lay in zip(people, layers, strict=True):
                albedo, transport, own = lay.albedo, lay.transport, lay.light
                if stabilizer is not None:
                    albedo, transport = stabilizer.update(lay.image, lay.mask, albedo, transport)
                    own = None if own is None else stabilizer.smooth_light(own)
                outs[i] = engine.render(lay, albedo, transport, own, batch_lights[i], backdrop_for(batch[i]))
                if with_layers:
                    extras[i]["albedo"] = engine.to_input(lay, albedo)
                    extras[i]["transport"] = engine.to_input(lay, transport)
        for i, f in enumerate(batch):
            if outs[i] is None:  # nobody in this frame
                logger.debug("frame %s: empty mask, passed through", f.name)
                outs[i] = composite(f.image, f.image, f.mask, backdrop_for(f))
                if with_layers and engine is not None:
                    extras[i]["albedo"] = np.zeros_like(f.image)
                    extras[i]["transport"] = np.zeros((*f.image.shape[:2], 9), np.float32)
            if grade is not None:  # in frame order: the clip's grade after this frame
                gain = grade.update(outs[i], f.image, f.mask)
                outs[i] = grade.apply(outs[i], f.image, f.mask, gain)
                extras[i]["background_grade"] = gain
            yield f, outs[i], extras[i]


def relight_video(source: FrameSource, lights: LightSchedule, sink: FrameSink, *, engine: Engine | None = None,
                  dvp: DVPModel | None = None, stabilizer: Stabilizer | None = None, batch_size: int = 4,
                  background: Background | str = "original",
                  on_frame: Callable[[Frame, np.ndarray, dict], None] | None = None,
                  with_layers: bool = False) -> VideoReport:
    """Relight a whole video from ``source`` into ``sink`` in bounded memory.

    Args:
        source: frames and masks; lights: the light of each frame.
        sink: where frames go (closed here: the video is renamed into place only on success).
        engine / dvp: exactly one (see :func:`relight_frames`).
        stabilizer: a fresh :class:`Stabilizer` (on by default in the CLI) or None.
        batch_size: frames decomposed together.
        on_frame: called with (frame, output, extras) after each frame is written (metrics, progress).
        with_layers: put the input-frame layers into ``extras`` (see :func:`relight_frames`).

    Returns:
        VideoReport with the number of frames and the mean seconds per frame (reading and writing
        included, ``on_frame`` excluded).
    """
    start = time.perf_counter()
    n = 0
    anyone = False  # a person in some frame (relight_frames' own test: some mask value >= 0.5)
    callback = 0.0  # time spent in on_frame (metrics, progress): not the pipeline's
    try:
        frames = relight_frames(source, lights, fps=source.fps, engine=engine, dvp=dvp, stabilizer=stabilizer,
                                batch_size=batch_size, background=background, with_layers=with_layers)
        for frame, out, extras in frames:
            sink.write(frame.name, out)
            n += 1
            anyone = anyone or bool((frame.mask >= 0.5).any())
            if on_frame is not None:
                t0 = time.perf_counter()
                on_frame(frame, out, extras)
                callback += time.perf_counter() - t0
    except BaseException:
        sink.close(ok=False)
        raise
    empty = empty_clip(source.path, n, anyone, " (nothing to relight); give masks with --masks if there is one")
    if empty is None and sink.count != n:  # frames written must equal frames read
        empty = RelightError(f"{source.path}: {n} frames relit but {sink.count} written")
    if empty is not None:  # nothing is written
        sink.close(ok=False)
        raise empty
    sink.close(ok=True)
    spf = (time.perf_counter() - start - callback) / n
    logger.debug("relit %d frames, %.3f s per frame", n, spf)  # the CLI says it once, with the lights
    return VideoReport(n, spf)


# ---------------------------------------------------------------------------------------------
# one clip, start to end (relight-rt video, and each Ray task of relight_rt.apps.ray_jobs)


@dataclass(frozen=True)
class ClipLights:
    """How a clip is lit, as given; :meth:`schedule` resolves it once the clip is open (an interpolation needs
    its frame count, the light of a photo the models).

    Exactly one of: ``spec`` (one light: a LightSpec, or any light ``LightSpec.of`` takes, turning at
    ``rotate_per_second`` revolutions per second when given), ``per_frame`` (an (N, 9, 3) RGB .npy, one light per
    frame) or ``keys`` (two or more key lights: LightSpecs, light files, environment maps or preset names,
    interpolated over the whole clip).
    """

    spec: LightSpec | None = None
    rotate_per_second: float | None = None
    per_frame: str | None = None
    keys: tuple = ()

    def __post_init__(self) -> None:
        given = (self.spec is not None) + (self.per_frame is not None) + bool(self.keys)
        if given != 1:
            raise RelightError("clip lights: expected exactly one of a light, a per-frame light file or key lights")
        if self.rotate_per_second is not None and self.spec is None:
            raise RelightError("clip lights: rotate_per_second turns one light; give a light, not a schedule")
        if self.keys and len(self.keys) < 2:
            raise RelightError("--interpolate: expected at least two key lights")
        object.__setattr__(self, "keys", tuple(self.keys))
        if self.spec is not None:  # any light argument (a (9, 3) array, a preset name, a path) as its LightSpec
            object.__setattr__(self, "spec", LightSpec.of(self.spec))
        if self.per_frame is not None:
            object.__setattr__(self, "per_frame", os.fspath(self.per_frame))

    @property
    def paths(self) -> tuple[str, ...]:
        """The files these lights read (to protect them from being overwritten)."""
        keys = (k.paths if isinstance(k, LightSpec) else (os.fspath(k),) for k in self.keys)
        found = [*(self.spec.paths if self.spec is not None else ()), *(p for k in keys for p in k)]
        return tuple(p for p in (self.per_frame, *found) if p)

    def schedule(self, frame_count: int, relighter=None, name: str = "clip") -> LightSchedule:
        """The light of each frame of a clip of ``frame_count`` frames (< 1: unknown)."""
        if self.per_frame is not None:
            return LightSchedule.from_file(self.per_frame)
        if self.keys:
            if frame_count < 1:
                raise RelightError(f"{name}: the frame count is unknown; --interpolate needs it, use --lights")
            return LightSchedule.interpolated([resolve_light(k, relighter) for k in self.keys], frame_count)
        base = resolve_light(self.spec, relighter)
        if self.rotate_per_second is not None:
            return LightSchedule.rotating(base, self.rotate_per_second)
        return LightSchedule.constant(base)


@dataclass(frozen=True)
class ClipReport:
    """What :func:`relight_clip` did: frames written, seconds per frame, the lights' description, and the
    frames left out (``skip_bad_frames``: one message each, and how many)."""

    frames: int
    seconds_per_frame: float
    lights: str
    skipped: tuple[str, ...] = ()
    lost: int = 0


def relight_clip(
    src: str | os.PathLike,
    lights: ClipLights | LightSpec,
    *,
    output: str | os.PathLike | None = None,
    frames_out: str | os.PathLike | None = None,
    masks: str | os.PathLike | None = None,
    fps: float | None = None,
    skip_bad_frames: bool = False,
    background: Background | str = "original",
    exposure="auto",
    config=None,
    relighter=None,
    matter=None,
    dvp: str | os.PathLike | None = None,
    dvp_size: int | None = None,
    stabilize: bool = True,
    stabilize_strength: float = 0.8,
    batch_size: int = 4,
    lights_out: str | os.PathLike | None = None,
    metrics: str | os.PathLike | None = None,
    progress=None,
) -> ClipReport:
    """Relight one clip (a video file or a folder of frames) into a video file and/or PNG frames: the work of
    ``relight-rt video``, in bounded memory.

    Args:
        src: video file (OpenCV) or folder of frames.
        lights: the light of each frame (:class:`ClipLights`), or one LightSpec.
        output: video file to write (.mp4, .avi, .mkv); frames_out: folder for the relit frames as PNGs. One or
            both.
        masks: mask folder, mask video or "auto" (default: STEM_mask files beside the frames, else the alpha of
            RGBA frames, else the automatic matte, steady over time, when installed).
        fps: frame rate of a frame folder (default 25), or one that overrides the video's; in (0, MAX_FPS].
        skip_bad_frames: leave out frames that cannot be decoded or differ in size (listed in the report)
            instead of failing.
        background: a Background or its shorthand; "transparent" needs ``frames_out`` only.
        exposure: "auto", an EV offset or "physical" (relight_rt.light.exposure).
        config: a RuntimeConfig (models, device, precision, ...); default RuntimeConfig().
        relighter: the Relighter to relight with (``relight_rt.open(config)`` gives one whose matte can read a
            light from a photo without a mask); None: ``Relighter(config)``.
        matter: the automatic matte for frames without a mask (relight_rt.builder.video_matter: steady over
            time); None: such frames are refused.
        dvp: a fitted dvp.onnx used instead of stage 1/2; dvp_size: the long side it was fitted at.
        stabilize: the training-free stabiliser (not with a DVP); stabilize_strength: its weight in [0, 1).
        batch_size: frames per stage-1 / DVP run.
        lights_out: write the (N, 9, 3) RGB light of every frame to this .npy.
        metrics: write temporal error, warping error and light-following to this JSON file.
        progress: called with the frame count (None when unknown) and returning a context manager whose
            ``update()`` is called once per frame written (the CLI's progress bar); None: nothing.

    Returns:
        A ClipReport. Outputs are written atomically and never over a file the run reads.

    Raises:
        RelightError: bad settings or input, no frame written (the partial video is removed).
    """
    import contextlib
    import json
    import math

    from ..engine.config import RuntimeConfig
    from ..engine.files import atomic_path, check_target, write_npy
    from ..light.exposure import for_light
    from . import metrics as rt_metrics

    config = RuntimeConfig() if config is None else config
    lights = lights if isinstance(lights, ClipLights) else ClipLights(spec=lights)
    if not output and not frames_out:
        raise RelightError("output: expected -o VIDEO and/or --frames-out DIR")
    if fps is not None and not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise RelightError(f"--fps: must be > 0 and at most {MAX_FPS}, got {fps:g}")
    source = FrameSource(src, masks, fps, skip_bad=skip_bad_frames, matter=matter)
    bg = parse_background(background)
    if bg.kind == "transparent" and output:
        raise RelightError("--background transparent: a video file has no alpha channel; use --frames-out DIR")
    engine = model = rl = None
    if dvp:
        model = DVPModel(dvp, device=config.device, size=dvp_size)
    else:
        from ..relight.relighter import Relighter

        rl = Relighter(config) if relighter is None else relighter
        engine = RelighterEngine(rl, exposure=for_light(exposure, lights.spec))  # night: a stop darker
    schedule = lights.schedule(len(source), rl, name=str(src))
    inputs = [*source.paths, *(Path(p) for p in (*lights.paths, dvp, bg.path) if p and Path(p).is_file())]
    if rl is not None:
        inputs += Path(rl.models_dir).glob("*.onnx")
    for written_last in (lights_out, metrics):  # files written after the work: refuse before it
        if written_last:
            check_target(Path(written_last), inputs)
    stabilizer = Stabilizer(stabilize_strength) if stabilize and model is None else None
    audio = source.path if source.has_audio else None
    sink = FrameSink(output, frames_out, source.rate, protect=inputs, audio_from=audio)
    acc = rt_metrics.TemporalMetrics() if metrics else None
    used_lights: list = []  # (9, 3) per frame: 108 bytes each, bounded for any realistic clip
    bar = progress(len(source)) if progress is not None else contextlib.nullcontext()

    with bar as shown:

        def on_frame(frame, out, extras):
            if lights_out:
                used_lights.append(extras["light"])
            if acc is not None:
                acc.update(out, frame.mask, frame.image, extras.get("albedo"), extras.get("transport"),
                           extras["light"])  # fmt: skip
            if shown is not None:
                shown.update()

        report = relight_video(source, schedule, sink, engine=engine, dvp=model, stabilizer=stabilizer,
                               batch_size=batch_size, background=bg, on_frame=on_frame, with_layers=acc is not None)
    if lights_out:
        path = write_npy(lights_out, np.stack(used_lights), protect=inputs)
        logger.info("wrote the %d frames' lights to %s", len(used_lights), path)
    if acc is not None and report.frames >= 2:
        res = acc.result()
        data = {"frames": report.frames, "seconds_per_frame": report.seconds_per_frame,
                "temporal_error": res.temporal_error, "warping_error": res.warping_error,
                "light_following": res.light_following, "light_gain": res.light_gain,
                "residual_error": res.residual_error,
                "stabilizer": stabilizer is not None, "dvp": None if dvp is None else os.fspath(dvp)}  # fmt: skip
        with atomic_path(metrics, protect=inputs) as tmp:
            tmp.write_text(json.dumps(data, indent=1))
        logger.info("metrics: %s", json.dumps(data))
    return ClipReport(report.frames, report.seconds_per_frame, schedule.description, tuple(source.skipped),
                      source.lost)  # fmt: skip
