"""Training-free temporal stabiliser of the intrinsic layers (albedo, transport) of a video.

In relighting the new light is an explicit input, so flicker in a relit video comes from the
per-frame estimates of albedo and light transport, not from the light. This module filters those
layers over time and leaves the light alone: each frame's own light is applied afterwards, so a
moving light still moves the shading.

For frame t, the previous frame's *stabilised* layers are warped onto frame t with DIS optical
flow of the INPUT frames (which the new light does not touch), then blended with frame t's own
estimate where the warp can be trusted:

    out_t = w * warp(out_{t-1}) + (1 - w) * estimate_t
    w = strength * [forward-backward flow consistent] * exp(-(photometric error / tolerance)²)
              * [pixel inside both masks]

The photometric error is the mean absolute difference, over RGB, between input frame t and the
warped input frame t-1: large where the flow is wrong, at occlusions and at scene cuts. The
recursion is an exponential moving average along motion trajectories: with ``strength`` s, white
per-frame noise in the estimate keeps a standard deviation of sqrt((1 - s) / (1 + s)) of its own
(0.33 at s = 0.8) where the warp is reliable, and the layers lag by about s / (1 - s) frames
(4 at s = 0.8) where the true layer changes (e.g. the transport of a turning body).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator

import numpy as np

from ..engine.errors import RelightError
from ..image.flow import check_preset, consistent_flow, dis_flow, to_gray_u8, warp
from .metrics import as_bool_mask, as_float_image

logger = logging.getLogger(__name__)


class Stabilizer:
    """Stateful stabiliser: feed frames in order with :meth:`update`; :meth:`reset` at a cut.

    Args:
        strength: weight in [0, 1) of the warped history where the warp is fully reliable
            (0 turns the stabiliser off).
        photometric_tolerance: input-frame difference (RGB mean, [0, 1] units) at which the
            blend weight falls to 1/e of ``strength``.
        flow_preset: DIS preset, "ultrafast", "fast" or "medium".
        flow_max_side: optical flow runs on frames shrunk so that their long side is at most this
            (then the flow is scaled back up); None: at full size.
    """

    def __init__(self, strength: float = 0.8, photometric_tolerance: float = 0.05, flow_preset: str = "fast",
                 flow_max_side: int | None = 512):
        if not 0.0 <= strength < 1.0:
            raise RelightError(f"strength: expected a value in [0, 1), got {strength}")
        if not photometric_tolerance > 0.0:
            raise RelightError(f"photometric_tolerance: expected a positive value, got {photometric_tolerance}")
        check_preset(flow_preset, "flow_preset")
        self.strength = float(strength)
        self.photometric_tolerance = float(photometric_tolerance)
        self.flow_preset = flow_preset
        if flow_max_side is not None and flow_max_side < 16:
            raise RelightError(f"flow_max_side: expected None or at least 16 pixels, got {flow_max_side}")
        self.flow_max_side = flow_max_side
        self.last_weight: np.ndarray | None = None  # (H, W) blend weight of the last frame, for inspection
        self._prev: dict | None = None
        self._light: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the history (call at a scene cut or before another video)."""
        self._prev = None
        self._light = None
        self.last_weight = None

    def smooth_light(self, light: np.ndarray) -> np.ndarray:
        """Exponential moving average of a per-frame estimate of the ORIGINAL video's light.

        The input video's own illumination is estimated per frame (stage 1's light head) and
        flickers like the layers; where the runtime divides by the reconstruction under that light
        (detail transfer), the flicker reaches the output. The average uses ``strength``.

        Args:
            light: (9, 3) float RGB estimate for this frame.

        Returns:
            (9, 3) float32 smoothed light (a new array).
        """
        arr = np.asarray(light, np.float32)
        if arr.shape != (9, 3) or not np.isfinite(arr).all():
            raise RelightError(f"light: expected a finite (9, 3) SH light, got {arr.shape}")
        self._light = arr.copy() if self._light is None else self.strength * self._light + (1 - self.strength) * arr
        return self._light.copy()

    def _flow(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        return dis_flow(src, dst, self.flow_preset, self.flow_max_side)

    def update(self, frame: np.ndarray, mask: np.ndarray | None, albedo: np.ndarray,
               transport: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stabilise one frame's layers.

        Args:
            frame: (H, W, 3) input frame, RGB float [0, 1] or uint8 (flow source).
            mask: (H, W) person mask in [0, 1] (or uint8), None for every pixel.
            albedo: (H, W, 3) float albedo estimate of this frame, RGB [0, 1].
            transport: (H, W, 9) float transport estimate of this frame (DESIGN.md §3).

        Returns:
            New arrays (albedo (H, W, 3), transport (H, W, 9)) float32, stabilised.
        """
        img = as_float_image(frame, "frame")
        shape = img.shape[:2]
        m = as_bool_mask(mask, shape)
        alb = np.asarray(albedo, np.float32)
        tra = np.asarray(transport, np.float32)
        if alb.shape != (*shape, 3):
            raise RelightError(f"albedo: expected {(*shape, 3)} float array, got {alb.shape}")
        if tra.shape != (*shape, 9):
            raise RelightError(f"transport: expected {(*shape, 9)} float array, got {tra.shape}")
        gray = to_gray_u8(img)
        prev = self._prev
        if prev is None or prev["gray"].shape != shape or self.strength == 0.0:
            out_a, out_t = alb.copy(), tra.copy()
            self.last_weight = np.zeros(shape, np.float32)
        else:
            backward = self._flow(gray, prev["gray"])  # frame t -> t-1
            forward = self._flow(prev["gray"], gray)
            stack = np.concatenate([prev["albedo"], prev["transport"], prev["frame"],
                                    prev["mask"][..., None].astype(np.float32)], axis=2)
            warped = warp(stack, backward)
            w_albedo, w_transport = warped[..., :3], warped[..., 3:12]
            w_frame, w_mask = warped[..., 12:15], warped[..., 15]
            diff = np.abs(img - w_frame)
            photometric = (diff[..., 0] + diff[..., 1] + diff[..., 2]) * np.float32(1 / 3)
            weight = np.exp(-np.square(photometric * np.float32(1 / self.photometric_tolerance)))
            weight *= np.float32(self.strength)
            weight *= consistent_flow(backward, forward) & m & (w_mask > 0.5)
            weight = weight[..., None]
            out_a = alb + weight * (w_albedo - alb)
            out_t = tra + weight * (w_transport - tra)
            self.last_weight = weight[..., 0]
            if m.any() and logger.isEnabledFor(logging.DEBUG):
                logger.debug("stabiliser: mean weight %.3f inside the mask", float(self.last_weight[m].mean()))
        self._prev = {"gray": gray, "frame": img, "mask": m, "albedo": out_a, "transport": out_t}
        return out_a.copy(), out_t.copy()


def stabilize(frames: Iterable[np.ndarray], masks: Iterable[np.ndarray | None], albedos: Iterable[np.ndarray],
              transports: Iterable[np.ndarray], strength: float = 0.8,
              photometric_tolerance: float = 0.05) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Stabilise a stream of layers; yields (albedo, transport) per frame, holding one frame of history.

    Args:
        frames: (H, W, 3) input frames in order; masks: (H, W) or None per frame;
        albedos: (H, W, 3) per-frame estimates; transports: (H, W, 9) per-frame estimates.
        strength, photometric_tolerance: see :class:`Stabilizer`.
    """
    stab = Stabilizer(strength, photometric_tolerance)
    for frame, mask, albedo, transport in zip(frames, masks, albedos, transports, strict=True):
        yield stab.update(frame, mask, albedo, transport)
