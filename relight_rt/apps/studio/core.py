"""The studio's state, free of any web framework: one decomposed photo, its preview layers, renders, uploads.

The photo is decomposed once (stage 1). The page relights a *preview* by itself from the layers this
module packs at display resolution (albedo, transport, mask, background); the server runs the full
pipeline (stage 2 and full-resolution detail) on request. Renders are kept in a bounded store whose
entries expire, so an export fetches exactly the picture that was shown.

Security: nothing here takes a filesystem path from a request. Uploads arrive as bytes and are checked, decoded
and turned into lights by relight_rt.apps.studio.uploads; the page's preview maths (the packed layers unpacked, the
cast shadows' plane, the person drawn) is relight_rt.apps.studio.preview. What the web layer guards (origin, content
types, concurrent uploads, bytes held) is in relight_rt.apps.studio.app.
"""

from __future__ import annotations

import inspect
import io
import json
import logging
import math
import secrets
import shlex
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ...engine.errors import RelightError
from ...image.color import REC709
from ...image.compositing import Background
from ...image.io import encode_image, read_image, sibling_mask
from ...light import exposure as _exposure  # the one exposure rule
from ...light import presets, sh
from ...light.exposure import METER_POWER, Highlight, exposure_scale, guarded, mean_luminance, parse_exposure
from ...light.spec import LightSpec  # the one light parser
from ...relight.compose import GradeSample, sampled_grade, shown_mask  # the one background grade
from ...relight.decomposition import intrinsic_layers
from ...relight.kept_rim import LEAST
from ...relight.look import NEUTRAL_CHROMA_EXP, NEUTRAL_LIFT, SKIN_CHROMA, skin_chroma  # the shaded-skin rule
from ...relight.strength import restore_bands
from .preview import area_reduce, layers_in_box, preview_picture, shadow_plane
from .uploads import MAX_UPLOAD_BYTES, background_upload_light, decode_upload, envmap_upload_light

log = logging.getLogger(__name__)

EXPOSURE_SAMPLES = 1 << 15  # network-frame pixels of the person that the page's exposure rule reads (at most)
SHADOW_CACHE = 8  # the faces' cast shadows (``Studio.shadow``) kept for this many lights, the latest ones


class ResultStore:
    """A bounded, expiring in-memory store: at most ``capacity`` entries, each dropped ``ttl`` seconds
    after it was last read or written (least recently used first when full). Thread-safe.
    Keys are random tokens made here (``put`` returns one), never taken from a request."""

    def __init__(self, capacity: int = 16, ttl: float = 900.0, clock: Callable[[], float] = time.monotonic) -> None:
        if capacity < 1 or ttl <= 0:
            raise RelightError(f"ResultStore: expected capacity >= 1 and ttl > 0, got {capacity}, {ttl}")
        self.capacity, self.ttl, self._clock = capacity, ttl, clock
        self._items: OrderedDict[str, tuple[float, object]] = OrderedDict()
        self._lock = threading.Lock()

    def _expire(self, now: float) -> None:
        for key in [k for k, (t, _) in self._items.items() if now - t > self.ttl]:
            del self._items[key]

    def put(self, value) -> str:
        key = secrets.token_urlsafe(12)
        with self._lock:
            now = self._clock()
            self._expire(now)
            self._items[key] = (now, value)
            while len(self._items) > self.capacity:
                self._items.popitem(last=False)
        return key

    def get(self, key: str):
        """The value, or None when unknown or expired."""
        with self._lock:
            now = self._clock()
            self._expire(now)
            item = self._items.get(key)
            if item is None:
                return None
            self._items[key] = (now, item[1])
            self._items.move_to_end(key)
            return item[1]

    def __len__(self) -> int:
        with self._lock:
            self._expire(self._clock())
            return len(self._items)


@dataclass(frozen=True)
class Render:
    """One full-resolution result: its PNG, the light and exposure that made it, and how long it took."""

    png: bytes
    light: np.ndarray  # (9, 3) float32 RGB, exactly as used
    exposure: object
    seconds: float
    grade_background: bool = False  # the original background followed the light (Background.grade)


def command_line(program: list[str], operands: list, options: list[tuple[str, object]]) -> str:
    """A command line to show and copy, by one rule for every word: each option as one ``--name=VALUE`` word (a
    value that starts with "-", such as an EV of -1e-05, is never read as an option), each operand (a path) with
    ``./`` before it when it is relative and starts with "-" (``-x.png`` is not an option either), all of it
    quoted for a POSIX shell by ``shlex.join`` (issue 50 bugs 10 and 11)."""
    words = [*program]
    for value in operands:
        text = str(value)
        words.append(f"./{text}" if text.startswith("-") else text)
    words += [name if value is None else f"{name}={value}" for name, value in options]
    return shlex.join(words)


def light_json(light: np.ndarray) -> str:
    """The project's light .json (DESIGN.md §6), written from float32 values so that it reloads exactly."""
    rows = [[float(v) for v in row] for row in np.asarray(light, np.float32)]
    return json.dumps({"sh": rows, "order": "rgb"}, indent=1)


def light_npy(light: np.ndarray) -> bytes:
    """The light as .npy bytes: (9, 3) float32 RGB, never pickled."""
    buf = io.BytesIO()
    np.save(buf, np.asarray(light, np.float32), allow_pickle=False)
    return buf.getvalue()


def plate_size(width: int, height: int) -> tuple[int, int]:
    """(width, height) of a panorama view's plate for a preview of width x height: the preview's, enlarged at its
    aspect to at least ``MIN_SIZE`` a side where it is smaller (a view needs that much; the page scales the plate to
    its column)."""
    from ...light.from_background import MIN_SIZE

    scale = max(1.0, MIN_SIZE / min(width, height))
    return math.ceil(width * scale), math.ceil(height * scale)


def request_light(value) -> np.ndarray:
    """The (9, 3) float32 RGB light of a render request's 27 numbers (``LightSpec.from_numbers``)."""
    return LightSpec.from_numbers(value).resolve()


def request_exposure(value) -> object:
    """A render request's exposure: absent is "auto", anything else ``relight_rt.light.exposure.parse_exposure``."""
    return "auto" if value is None else parse_exposure(value)


def _exposure_sample(dec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The person's pixels in the network frame that the page's exposure rule reads: every ``step``-th pixel
    inside the mask, at most EXPOSURE_SAMPLES (all of them for networks up to about 300² pixels of person).

    Returns:
        albedo (n, 3) (the network's, masked, as relight_rt.light.exposure takes it), transport (n, 9), mask (n,),
        float32.
    """
    m = np.asarray(dec.network_mask, np.float32).reshape(-1)
    inside = np.flatnonzero(m > 0)
    idx = inside[:: max(1, math.ceil(inside.size / EXPOSURE_SAMPLES))]
    albedo = np.asarray(dec.albedo, np.float32).reshape(-1, 3)[idx]
    transport = np.asarray(dec.transport, np.float32).reshape(-1, 9)[idx]
    return albedo, transport, m[idx]


def _highlight_sample(relighter, dec) -> Highlight:
    """What the exposure's highlight guard reads (relight_rt.light.exposure ``Highlight``; the relighter's
    ``highlight_inputs``), every ``step``-th pixel, at most EXPOSURE_SAMPLES: lit (n, 3), steady (n, 3),
    transport (n, 9), the share allowed past white and the knees (n,). A runtime without the guard gives no pixels
    (factor 1)."""
    inputs = getattr(relighter, "highlight_inputs", None)
    if inputs is None:
        return Highlight(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros((0, 9), np.float32), 1.0)
    lit, steady, transport, allowed, knee = Highlight(*inputs(dec))
    step = max(1, math.ceil(lit.shape[0] / EXPOSURE_SAMPLES))
    return Highlight(np.ascontiguousarray(lit[::step], np.float32), np.ascontiguousarray(steady[::step], np.float32),
                     np.ascontiguousarray(transport[::step], np.float32), float(allowed),
                     None if knee is None else np.ascontiguousarray(knee[::step], np.float32))


def _grade_sample(relighter, dec) -> GradeSample:
    """What the original backdrop's grade reads (relight_rt.relight.compose ``GradeSample``; the relighter's
    ``grade_inputs``), every ``step``-th pixel, at most EXPOSURE_SAMPLES. A runtime without it gives no pixels (a
    grade of 1)."""
    inputs = getattr(relighter, "grade_inputs", None)
    if inputs is None:
        return GradeSample.empty()
    sample = inputs(dec)
    return sample.every(max(1, math.ceil(sample.weight.shape[0] / EXPOSURE_SAMPLES)))


def _rim_sample(relighter, dec, edge: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The kept background's rim the final result puts on the person's outline (relight_rt.relight.kept_rim; the
    relighter's ``kept_rim``, once per Decomposition), in the preview's frame and size: the pixels it reaches
    (flat indices, int32, increasing) and its straight linear RGB radiance there (n, 3) float32, the rim times the
    shown edge ``edge`` (H, W) reduced by area as the preview's mask is and over that mask, so that the page adds it
    to the straight colour it draws, as ``with_kept_rim`` does to the render's, before the mask premultiplies it. No
    pixels where the relighter applies none (a mask or alpha given, a runtime without the rule) or a pixel holds less
    than half an 8-bit level of it on black (``kept_rim.LEAST``)."""
    none = np.zeros(0, np.int32), np.zeros((0, 3), np.float32)
    find = getattr(relighter, "kept_rim", None)
    kept = find(dec) if find is not None else None
    if kept is None:
        return none
    y0, y1, x0, x1 = (int(v) for v in dec.geometry.box)
    planes = [np.zeros(edge.shape, np.float32) for _ in range(4)]  # zero pages outside the box are never touched
    ys, xs = np.divmod(kept.index, x1 - x0)
    ys, xs = ys + y0, xs + x0
    alpha = edge[ys, xs]
    for c in range(3):
        planes[c][ys, xs] = kept.rim[:, c] * alpha
    planes[3][y0:y1, x0:x1] = edge[y0:y1, x0:x1]
    if size == edge.shape:  # a preview at the photo's size: the box itself (area_reduce's weights the identity)
        (oy0, ox0), reduced = (y0, x0), [p[y0:y1, x0:x1] for p in planes]
    else:
        (oy0, _, ox0, _), reduced = area_reduce(planes, size, [y0, y1, x0, x1])
    m = reduced[3]
    rim = np.stack(reduced[:3], axis=-1) / np.maximum(m, 1e-6)[..., None]
    at = (m > 0.5 / 255) & (rim @ REC709 >= LEAST)  # the mask the page reads is 8-bit: none below half a level
    yy, xx = np.nonzero(at)
    index = ((yy + oy0) * size[1] + xx + ox0).astype(np.int32)
    return index, np.ascontiguousarray(rim[at], np.float32)


def _display_size(h: int, w: int, max_pixels: int) -> tuple[int, int]:
    s = min(1.0, math.sqrt(max_pixels / (h * w)))
    return max(2, round(h * s)), max(2, round(w * s))


def _box_of(where: np.ndarray) -> list[int]:
    """[y0, y1, x0, x1] the box of ``where``'s True pixels (ends exclusive); [] without one."""
    ys, xs = np.nonzero(where)
    return [int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1] if ys.size else []


def _changed_box(a: np.ndarray, b: np.ndarray, within: tuple[int, int, int, int]) -> list[int]:
    """[y0, y1, x0, x1] the box of the pixels where ``a`` and ``b`` differ, looked for ``within`` that box alone
    (they agree outside it); [] where they agree."""
    y0, y1, x0, x1 = (int(v) for v in within)
    differ = a[y0:y1, x0:x1] != b[y0:y1, x0:x1]
    rows, cols = np.flatnonzero(differ.any(axis=1)), np.flatnonzero(differ.any(axis=0))
    if not rows.size:
        return []
    return [y0 + int(rows[0]), y0 + int(rows[-1]) + 1, x0 + int(cols[0]), x0 + int(cols[-1]) + 1]


def _slices(box: list[int]) -> tuple[slice, slice]:
    return slice(box[0], box[1]), slice(box[2], box[3])


def _resize(a: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    h, w = size
    if a.shape[:2] == (h, w):
        return np.ascontiguousarray(a, np.float32)
    interp = cv2.INTER_AREA if h < a.shape[0] else cv2.INTER_LINEAR
    chans = [
        cv2.resize(np.ascontiguousarray(a[..., i : i + 4]), (w, h), interpolation=interp)
        for i in range(0, a.shape[2], 4)
    ]
    chans = [c[..., None] if c.ndim == 2 else c for c in chans]
    return np.concatenate(chans, axis=2).astype(np.float32)


class Studio:
    """One photo, decomposed once, and what the page asks of it.

    Args:
        photo: image file (RGB or RGBA; see ``Relighter.decompose``).
        mask: mask file; None: NAME_mask.png beside the photo, else its alpha channel.
        background: "original", "transparent" or an image file of the photo's size.
        relighter: a ``relight_rt.Relighter`` (the caller chooses models and device).
        preview_pixels: the most pixels of the in-browser preview (the photo is shrunk to fit, never enlarged).
        models: the models folder the relighter came from, for the exported command line (None: default).
        panoramas: equirectangular panorama files (.hdr, .exr, ...) the page may view as the scene
            (``panorama_view``); the page chooses among them by index, never by path.
    """

    def __init__(self, photo, mask, background, relighter, preview_pixels: int = 1_000_000, models=None,
                 panoramas=()) -> None:  # fmt: skip
        self.photo = Path(photo)
        self.mask = Path(mask) if mask is not None else sibling_mask(self.photo)
        self.background = str(background)
        self.models = models
        if self.background not in ("original", "transparent") and not Path(self.background).is_file():
            raise RelightError(f"--background {self.background}: expected original, transparent or an image file")
        from ..panorama import check_panorama_file

        self.panoramas = [check_panorama_file(p, "--panorama") for p in panoramas]  # before the server starts
        if not isinstance(preview_pixels, int) or preview_pixels < 64 * 64:
            raise RelightError(f"preview_pixels: expected a whole number >= 4096, got {preview_pixels!r}")
        self.relighter = relighter
        self.dec = relighter.decompose(self.photo, self.mask)
        self._bg = None if self.background in ("original", "transparent") else self.background
        self._lock = threading.Lock()  # one pipeline run at a time (the Decomposition caches results)
        self.renders = ResultStore(capacity=16, ttl=900.0)
        self.plates = ResultStore(capacity=8, ttl=900.0)  # panorama views' plates (PNG), by id
        self._panorama_cache: dict[int, np.ndarray] = {}  # index: the loaded map (the latest one only)
        self._panorama_lock = threading.Lock()
        self.exposure_supported = "exposure" in inspect.signature(relighter.relight).parameters
        self._shadows: OrderedDict[bytes, dict] = OrderedDict()  # light -> ``shadow``'s answer, the latest ones
        self._layers = self._pack_layers(preview_pixels)
        self._photo_png: bytes | None = None

    # ------------------------------------------------------------------------------------ preview layers

    def _background_image(self) -> np.ndarray | None:
        """(H, W, 3) background in the input frame; None for transparent."""
        if self.background == "transparent":
            return None
        if self.background == "original":
            return np.asarray(self.dec.image)
        bg = read_image(self.background, "background")
        if bg.shape[:2] != self.dec.image.shape[:2]:
            raise RelightError(
                f"--background {self.background}: is {bg.shape[0]}x{bg.shape[1]}, expected the photo's "
                f"{self.dec.image.shape[0]}x{self.dec.image.shape[1]}"
            )
        return bg[..., :3]

    def _pack_layers(self, max_pixels: int) -> dict:
        """Display-resolution layers, quantised: transport as uint16 (per-channel offset and scale),
        albedo (premultiplied by the mask), mask (over the photo's own background the automatic matte's shown
        edge, as the render composites), background, the skin's chroma ((c + 1) / 2) and weight as uint8;
        channel-planar, little-endian."""
        dec = self.dec
        h, w = dec.image.shape[:2]
        size = _display_size(h, w, max_pixels)
        # the transport the final result relights with: stage 1's with its directional bands restored
        # (relight_rt.relight.strength), so that the preview changes as strongly as the result does
        restored = restore_bands(np.ascontiguousarray(dec.transport))
        transport = _resize(dec.to_input(restored), size)
        # the photo's own albedo (photo / its shading under its own light, white): the preview then relights the
        # photo as the final result does, not stage 1's network albedo (whose colours are a guess); divided by the
        # shading the final result divides by (bands restored) rather than stage 1's own (a refit own light,
        # relight_rt.relight.strength.refit_light, can leave that one dark where the restored one is not)
        albedo = intrinsic_layers(dec, sh.shading(restored, dec.white_light))["albedo"]
        mask = np.asarray(dec.mask)
        rim_index, rim = np.zeros(0, np.int32), np.zeros((0, 3), np.float32)
        if self.background == "original" and dec.edge is not None:
            # the render puts the relit person over their own photo with the soft edge the photo shows (the
            # automatic matte's: relight_rt.relight.compose.shown_edge); the albedo is premultiplied by that edge
            shown = shown_mask(dec)
            albedo = albedo * np.divide(shown, mask, out=np.zeros_like(shown), where=mask > 0)[..., None]
            mask = shown
            # the kept background's rim on that edge, which the render adds where the new light darkens it
            rim_index, rim = _rim_sample(self.relighter, dec, shown, size)
        albedo = _resize(albedo, size)
        mask = _resize(mask[..., None], size)
        bg = self._background_image()
        bg = np.zeros(size + (3,), np.float32) if bg is None else _resize(bg, size)
        # what the final result's shaded-skin rule reads (relight_rt.relight.look.shaded_skin): the skin's local
        # chroma (P - Y) / P, stored as (c + 1) / 2, and the skin weight; the page applies the rule with them
        chroma, weight = skin_chroma(dec.network_image, dec.skin)
        skin = dec.to_input(np.concatenate([chroma, weight[..., None]], axis=2))
        skin = _resize(np.concatenate([(skin[..., :3] + 1) / 2, skin[..., 3:]], axis=2), size)
        lo = transport.reshape(-1, 9).min(axis=0)
        hi = transport.reshape(-1, 9).max(axis=0)
        scale = np.where(hi > lo, (hi - lo) / 65535.0, 1.0)
        q16 = np.rint((transport - lo) / scale).clip(0, 65535).astype("<u2").transpose(2, 0, 1)
        eight = np.concatenate([albedo, mask, bg, skin], axis=2)
        q8 = np.rint(np.clip(eight, 0, 1) * 255).astype(np.uint8).transpose(2, 0, 1)
        # the exposure rule of the final result (relight_rt.light.exposure: the mean luminance of the network's diffuse
        # image inside the mask, the photo's own light as the target) on the person's network-frame pixels
        albedo_s, transport_s, mask_s = self._exposure = _exposure_sample(dec)
        target = mean_luminance(albedo_s[None], transport_s[None], mask_s[None], dec.white_light, METER_POWER)
        # the exposure's highlight guard (relight_rt.light.exposure.highlight_factor) on the pixels the final result
        # reads
        lit_h, steady_h, transport_h, allowed, _ = self._highlight = _highlight_sample(self.relighter, dec)
        # the original backdrop's grade (relight_rt.relight.compose.background_grade) on the pixels it reads
        grade = self._grade = _grade_sample(self.relighter, dec)
        head = q16.tobytes() + q8.tobytes()
        offset = -(-len(head) // 4) * 4  # float32 planes start 4-byte aligned
        planes = np.concatenate([transport_s.T, albedo_s.T, mask_s[None]]).astype("<f4")
        guard = np.concatenate([lit_h.T, steady_h.T, transport_h.T]).astype("<f4")
        graded = np.concatenate([grade.lit.T, grade.steady.T, grade.transport.T, grade.weight[None],
                                 grade.knee[None], grade.own.T, grade.neutral[None]]).astype("<f4")
        blend = grade.head  # the head pass's blend on some of those pixels: their indices, then float32 planes
        headed = grade.head.index.astype("<i4").tobytes() + np.concatenate(
            [np.stack(blend[1:7]), blend.transport.T]).astype("<f4").tobytes()
        return {
            "height": size[0],
            "width": size[1],
            "transport_offset": lo.astype(float).tolist(),
            "transport_scale": scale.astype(float).tolist(),
            "exposure_target": target,
            "exposure_power": METER_POWER,
            "display_gamma": _exposure.DISPLAY_GAMMA,  # an EV's gain on encoded values: 2 ** (EV / this)
            "exposure_samples": int(mask_s.size),
            "exposure_offset": offset,
            "highlight_samples": int(lit_h.shape[0]),
            "grade_samples": int(grade.weight.shape[0]),
            "grade_offset": offset + planes.nbytes + guard.nbytes,
            "grade_head_samples": int(blend.index.shape[0]),
            "grade_head_offset": offset + planes.nbytes + guard.nbytes + graded.nbytes,
            "highlight_offset": offset + planes.nbytes,
            "highlight_allowed": allowed,
            "highlight_limit": _exposure.HIGHLIGHT_LIMIT,
            "highlight_max_down": _exposure.HIGHLIGHT_MAX_DOWN,
            "shoulder_knee": list(_exposure.KNEE_RANGE),  # the shoulder's loss given back (exposure.shoulder_gain)
            "shoulder_max_up": _exposure.SHOULDER_MAX_UP,
            "shoulder_tol": _exposure.SHOULDER_TOL,
            "shoulder_samples": _exposure.SHOULDER_SAMPLES,
            "skin_chroma": SKIN_CHROMA,
            "neutral_lift": list(NEUTRAL_LIFT),  # the near-neutral darks' rule in the grade (look.neutral_values)
            "neutral_chroma_exp": float(NEUTRAL_CHROMA_EXP),
            "own_white": np.asarray(dec.white_light, np.float64)[:, 0].tolist(),
            "rim_samples": int(rim_index.size),
            "rim_offset": offset + planes.nbytes + guard.nbytes + graded.nbytes + len(headed),
            "data": head + bytes(offset - len(head)) + planes.tobytes() + guard.tobytes() + graded.tobytes() + headed
            + rim_index.astype("<i4").tobytes() + rim.T.astype("<f4").tobytes(),
        }

    def preview_light(self, light, exposure="auto", meter: float = 1.0) -> np.ndarray:
        """The light the page's preview draws for ``light`` (27 numbers or (9, 3)) and ``exposure``: the final
        result's exposure rule (relight_rt.light.exposure: the mean-keeping scale, the faces' cast shadows metered
        (``meter``: ``shadow``'s for this light, 1 without), the shoulder's loss given back, the highlight guard, the
        EV) on the page's samples, so that the preview and the final result have one brightness. What studio.js
        ``previewLight`` computes."""
        lit = request_light(light)
        exp = request_exposure(exposure)
        if not self.exposure_supported:
            return lit
        if exp == "physical":
            return lit
        albedo_s, transport_s, mask_s = self._exposure
        target = self._layers["exposure_target"]
        scale = exposure_scale(albedo_s[None], transport_s[None], mask_s[None], lit, target, "auto", METER_POWER)
        exposed = (lit * np.float32(scale)).astype(np.float32) * np.float32(meter)
        return guarded(exposed, exp, self._highlight)

    def shadow(self, light) -> dict:
        """What the final result does under ``light`` (27 numbers) that the preview's layers leave out, at the
        preview's size, for the page to draw: the body pass's cast shadows (relight_rt.relight.relighter
        ``Relighter.cast_shadows``) and the head pass's change (``Relighter.head_change``). {"box": [y0, y1, x0, x1]
        (preview pixels; empty: no shadow), "meter": the exposure's lift for them (``preview_light``), "depth": bytes,
        uint8, 255 x (1 - the factor on the shading) over the box, row-major, "head_box": the same for the head
        pass's change (empty: none), "head": bytes, float32 little-endian, the factor it puts on the shading there
        (``_head_factor``: the relit person's luminance with the head pass against without, each reduced to the
        preview's pixels, carried into the preview's own luminance)}. Kept
        for the last ``SHADOW_CACHE`` lights (the page asks again for a light it comes back to); a runtime without
        them answers none."""
        lit = request_light(light)
        key = lit.tobytes()
        with self._lock:
            hit = self._shadows.get(key)
            if hit is not None:
                self._shadows.move_to_end(key)
                return hit
            find = getattr(self.relighter, "cast_shadows", None)
            depth, meter = find(self.dec, lit) if find is not None else (None, 1.0)
            hit = {"box": [], "meter": float(meter), "depth": b"", "head_box": [], "head": b""}
            size = (self._layers["height"], self._layers["width"])
            if depth is not None:
                q = np.rint(np.clip(_resize(depth[..., None], size)[..., 0], 0, 1) * 255).astype(np.uint8)
                box = _box_of(q != 0)
                if box:
                    hit["box"], hit["depth"] = box, np.ascontiguousarray(q[_slices(box)]).tobytes()
            change = getattr(self.relighter, "head_change", None)
            levels = change(self.dec, lit) if change is not None else None
            changed = _changed_box(*levels, self.dec.geometry.box) if levels is not None else []
            if changed:  # the two luminances each reduced to a preview pixel, where the head pass changes them
                box, (before, after) = area_reduce(levels, size, changed)
                if box:
                    cast = shadow_plane(hit, *size)[_slices(box)] if hit["box"] else None
                    ratio = self._head_factor(lit, float(meter), box, before, after, cast)
                    inner = _box_of(np.abs(ratio - 1) > 1e-4)
                    if inner:
                        box = [box[0] + inner[0], box[0] + inner[1], box[2] + inner[2], box[2] + inner[3]]
                        hit["head_box"] = box
                        hit["head"] = np.ascontiguousarray(ratio[_slices(inner)], "<f4").tobytes()
            self._shadows[key] = hit
            while len(self._shadows) > SHADOW_CACHE:
                self._shadows.popitem(last=False)
        return hit

    def _head_factor(self, light: np.ndarray, meter: float, box: list[int], before: np.ndarray, after: np.ndarray,
                     cast: np.ndarray | None) -> np.ndarray:
        """The factor on the preview's shading over ``box`` (preview pixels) that stands for the head pass's change
        of the person's luminance from ``before`` to ``after`` (``shadow``; ``cast``: the body's cast-shadow factor
        there, None: none): the ratio after / before, where it brightens never more than the gain that adds the
        head pass's difference after - before to the preview's own luminance there (under ``preview_light``,
        "auto"). Where the preview is already brighter than the result's "before" (it leaves out stage 2's residual
        and the head pass's own colour), the ratio alone would amplify that disagreement (bright specks on dark
        cloth); a darkening ratio shrinks it and stays (the difference would take a preview darker than "before"
        to black). ``ratio`` 1 where no luminance is left; no gain where the preview draws nothing."""
        sl = _slices(box)
        layers = layers_in_box(self._layers["data"], self._layers, sl)
        shown = preview_picture(layers, self._layers, self.preview_light(light, "auto", meter), cast) @ REC709
        ratio = np.divide(np.maximum(after, 0), before, out=np.ones_like(before), where=before > 1e-4)
        added = shown + layers["mask"] * (after - before)  # premultiplied, as the preview is
        gain = np.divide(added, shown, out=np.ones_like(shown), where=shown > 1e-4)
        return np.minimum(ratio, np.maximum(gain, 1)).astype(np.float32)

    def preview_grade(self, shown) -> np.ndarray:
        """(3,) the background's grade the page's preview draws for the light it shows (``preview_light``'s) when
        the background follows the light: the final result's rule (relight_rt.relight.compose
        ``background_grade``) on the pixels it reads, in the network frame (``sampled_grade`` on the relighter's
        ``grade_inputs``: the person's own colour under the matte, relit without stage 2's residual and rolled off
        past its knee, against itself). What sh.js ``backgroundGrade`` computes."""
        return sampled_grade(self._grade, np.asarray(shown, np.float32).reshape(9, 3))

    def photo_png(self) -> bytes:
        """The photo as the pipeline reads it (upright, RGB, full resolution) as PNG: the page's "before"."""
        if self._photo_png is None:
            self._photo_png = encode_image(np.asarray(self.dec.image)[..., :3], ".png", "photo")
        return self._photo_png

    def layers_bytes(self) -> bytes:
        """The binary the page reads: 9 planes of uint16 transport, then 11 planes of uint8 (albedo R, G, B
        premultiplied by the mask, mask, background R, G, B, the skin's chroma R, G, B as (c + 1) / 2, the skin
        weight), each plane height x width, row-major; then, from
        byte ``exposure_offset``, the exposure sample (``_exposure_sample``) as float32 planes of
        ``exposure_samples`` values: transport 0…8, albedo R, G, B, mask; then, from byte ``highlight_offset``,
        the highlight guard's sample (``_highlight_sample``) as float32 planes of ``highlight_samples`` values:
        lit R, G, B, steady R, G, B, transport 0…8; then, from byte ``grade_offset``, the background grade's sample
        (``_grade_sample``) as float32 planes of ``grade_samples`` values: lit R, G, B, steady R, G, B, transport
        0…8, weight, knee, own R, G, B, the near-neutral darks' weight; then, from byte ``grade_head_offset``, the
        head pass's blend on ``grade_head_samples`` of those pixels (relight_rt.relight.compose ``HeadBlend``): their
        indices as int32, then float32 planes: weight, skin, body scale, body stays, scale, stays, transport 0…8;
        then, from byte ``rim_offset``, the kept background's rim (``_rim_sample``) on ``rim_samples`` preview
        pixels: their flat indices as int32, then float32 planes: its linear R, G, B."""
        return self._layers["data"]

    def info(self) -> dict:
        """What the page needs to start: sizes, layer format, the photo's own light, presets, features."""
        h, w = self.dec.image.shape[:2]
        own = np.asarray(self.dec.white_light, np.float32)
        return {
            "photo": self.photo.name,
            "width": w,
            "height": h,
            "preview": {k: v for k, v in self._layers.items() if k != "data"},
            "background": "transparent" if self.background == "transparent" else "image",
            "original_background": self.background == "original",  # the toggle "background follows the light"
            "own_light": own.tolist(),
            "presets": {name: presets.preset(name).astype(np.float32).tolist() for name in presets.list_presets()},
            "preset_exposure": {name: presets.preset_exposure(name) for name in presets.list_presets()},
            "diffuse_only": bool(self.relighter.diffuse_only),
            "people": self._people(),
            "exposure": self.exposure_supported,
            "max_upload_mb": MAX_UPLOAD_BYTES >> 20,
            "panoramas": [p.name for p in self.panoramas],
        }

    def _people(self) -> int:
        """How many people the full result relights one by one (a group photo with matting="all"; the live
        preview draws the group's layers, one body); 1 otherwise."""
        return len(getattr(self.dec, "people", ())) or 1

    # ------------------------------------------------------------------------------------ full results

    def render(self, light, exposure="auto", grade_background=False) -> tuple[str, Render]:
        """Run the full pipeline under ``light`` (27 numbers, RGB) and keep the PNG; returns (id, render).
        ``grade_background``: the original background follows the light (Background.grade; the studio's toggle,
        ignored for other backgrounds)."""
        lit = request_light(light)
        exp = request_exposure(exposure)
        if not isinstance(grade_background, bool):
            raise RelightError(f"grade_background: expected true or false, got {grade_background!r}")
        grade = grade_background and self.background == "original"
        kwargs = {"background": Background.original(grade=True) if grade else self._bg or self.background}
        if self.exposure_supported:
            kwargs["exposure"] = exp
        with self._lock:
            t0 = time.perf_counter()
            image = self.relighter.relight(self.dec, lit, **kwargs)
            png = encode_image(image, ".png", "result")
            seconds = time.perf_counter() - t0
        rec = Render(png, lit, exp if self.exposure_supported else "auto", seconds, grade)
        return self.renders.put(rec), rec

    def command(self, render: Render, light_file: str) -> str:
        """The ``relight-rt relight`` command line that reproduces ``render`` from the exported light file, its
        words made by one rule (:func:`command_line`)."""
        # paths as the user gave them to ``relight-rt studio`` (relative ones: to where the server was started)
        options: list[tuple[str, object]] = []
        if self.mask is not None:
            options.append(("--mask", self.mask))
        elif getattr(getattr(self.relighter, "config", None), "matting", "auto") == "all":
            options.append(("--person", "all"))  # the studio's matte took everyone: so must the command's
        options.append(("--light", light_file))
        if self.background != "original":
            options.append(("--background", self.background))
        if render.grade_background:
            options.append(("--grade-background", None))
        if self.exposure_supported and render.exposure != "auto":
            options.append(("--exposure", render.exposure))
        if self.models is not None:
            options.append(("--models", self.models))
        options.append(("--output", f"{self.photo.stem}_relit.png"))
        return command_line(["relight-rt", "relight"], [self.photo], options)

    # ------------------------------------------------------------------------------------ uploaded lights

    def envmap_light(self, data: bytes) -> np.ndarray:
        """(9, 3) float32 light of an uploaded equirectangular map (:func:`envmap_upload_light`)."""
        return envmap_upload_light(data)

    def photo_light(self, data: bytes) -> np.ndarray:
        """(9, 3) float32 light estimated (stage 1) from an uploaded photo of a person; mask: its alpha, else
        the automatic person matte."""
        image = decode_upload(data, "photo")
        with self._lock:
            dec = self.relighter.decompose_batch([image], [None])[0] if image.shape[2] == 4 else \
                self.relighter.decompose(image[..., :3], None)
        return np.array(dec.white_light, dtype=np.float32)

    def panorama_view(self, index, view) -> tuple[str, dict]:
        """The panorama number ``index`` (of those the server was started with) seen in direction ``view``
        ((azimuth, elevation, fov) degrees or "AZ,EL[,FOV]": ``relight_rt.apps.panorama.parse_view``): its plate at
        the preview's size (PNG, kept under the returned id) and its SH light rotated into that view, in the
        plate's units (``relight_rt.apps.panorama.panorama_view``: what ``composite --view`` lights the person with).

        Returns:
            (plate id, {"light": 27 numbers, "view": [az, el, fov], "horizon": row fraction, "name": file name}).
        """
        from ..panorama import load_panorama, panorama_view, parse_view

        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(self.panoramas):
            raise RelightError(f"panorama: expected a number from 0 to {len(self.panoramas) - 1} (the panoramas the "
                               f"studio was started with), got {index!r}")  # fmt: skip
        az, el, fov = parse_view(view)
        with self._panorama_lock:
            env = self._panorama_cache.get(index)
            if env is None:
                env = load_panorama(self.panoramas[index], f"--panorama {self.panoramas[index].name}")
                self._panorama_cache = {index: env}  # one map held at a time
        pv = panorama_view(env, plate_size(self._layers["width"], self._layers["height"]), (az, el, fov))
        pid = self.plates.put(encode_image(pv.plate, ".png", "plate"))
        return pid, {"light": pv.light.astype(np.float32).tolist(), "view": [az, el, fov],
                     "horizon": float(pv.horizon), "name": self.panoramas[index].name}  # fmt: skip

    def background_light(self, data: bytes, key_light=None) -> np.ndarray:
        """(9, 3) float32 light of an uploaded background photo (:func:`background_upload_light`)."""
        return background_upload_light(data, key_light)
