"""Temporal metrics for relit videos: flicker, flow-based warping error, light-following.

All three are computed frame pair by frame pair, so a video of any length is measured in
bounded memory with :class:`TemporalMetrics`; the functions :func:`temporal_error`,
:func:`warping_error` and :func:`light_following` are conveniences over whole sequences.

- Temporal error (the paper's flicker measure): mean absolute difference of consecutive output
  frames within the intersection of their masks, averaged over frame pairs. Values in [0, 1]
  units (a uniform one-level flicker of an 8-bit video is 1/255).
- Warping error: frame t+1 of the output is warped onto frame t with optical flow of the INPUT
  video (OpenCV DIS), and the mean absolute difference is taken over mask pixels that are
  visible in both frames (forward-backward flow consistency, Sundaram et al. 2010; relight_rt.image.flow). Motion of the
  person no longer counts as flicker; a moving light still does.
- Light-following score: Pearson correlation, over every masked pixel, channel and frame pair,
  between the motion-compensated change of the output (``warp(out[t+1]) - out[t]``) and the change
  of the diffuse image that the light sequence alone predicts with the intrinsic layers of frame t
  held fixed (``albedo_t * (shading(T_t, L_{t+1}) - shading(T_t, L_t))``). About 1 for a sequence
  that follows its light, about 0 for one whose light stopped moving (no change, or changes that
  do not match the light's). The correlation ignores the size of the response; the least-squares
  gain (output change per unit of predicted change) is reported beside it by
  :class:`TemporalMetrics`.
- Residual error (ours, for dynamic lights): mean ``|warp(out[t+1]) - out[t] - predicted light
  change|`` over the same pixels: the change that neither the motion nor the light explains. With
  a moving light the temporal and warping errors also count the change the light is meant to
  make (a frozen light lowers them); the residual error does not reward that: a frozen light
  leaves the whole predicted change as residual.

Frames are (H, W, 3) RGB, float in [0, 1] or uint8; masks (H, W) float in [0, 1] or uint8
(thresholded at half their range).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ..engine.errors import RelightError
from ..image.flow import check_preset, consistent_flow, dis_flow, to_gray_u8, warp  # the last four re-exported (moved)
from ..image.io import read_image
from ..light import sh

logger = logging.getLogger(__name__)

def as_float_image(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check an (H, W, 3) RGB frame and return it as a new float32 array in [0, 1].

    The conversion is the runtime's one image intake (relight_rt.image.io.read_image): uint8, uint16 or float in
    [0, 1] (floats a rounding outside are clipped); NaN, Inf and other values are refused.
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise RelightError(f"{name}: expected (H, W, 3) image, got {arr.shape} {arr.dtype}")
    return read_image(arr, name)


def as_bool_mask(mask: np.ndarray | None, shape: tuple[int, int], name: str = "mask") -> np.ndarray:
    """Check an (H, W) mask (or (H, W, C), first channel used) and return it as bool; None means all."""
    if mask is None:
        return np.ones(shape, bool)
    arr = np.asarray(mask)
    if arr.ndim == 3:
        arr = arr[..., 0]
    if arr.shape != tuple(shape):
        raise RelightError(f"{name}: expected mask of shape {tuple(shape)}, got {np.asarray(mask).shape}")
    if arr.dtype == np.uint8:
        return arr >= 128
    if arr.dtype == bool:
        return arr.copy()
    return arr.astype(np.float32) >= 0.5


def predicted_light_change(albedo: np.ndarray, transport: np.ndarray, light_a: np.ndarray,
                           light_b: np.ndarray) -> np.ndarray:
    """Change of the diffuse image when the light goes from ``light_a`` to ``light_b``, layers fixed.

    Args:
        albedo: (H, W, 3) float RGB in [0, 1].
        transport: (H, W, 9) float, DESIGN.md §3.
        light_a, light_b: (9, 3) RGB SH lights.

    Returns:
        (H, W, 3) float32 ``albedo * (max(0, T·L_b) - max(0, T·L_a))``.
    """
    t = np.asarray(transport, np.float32)
    a = np.asarray(light_a, np.float32)
    b = np.asarray(light_b, np.float32)
    if t.ndim != 3 or t.shape[2] != 9 or a.shape != (9, 3) or b.shape != (9, 3):
        raise RelightError(f"expected transport (H, W, 9) and lights (9, 3), got {t.shape}, {a.shape}, {b.shape}")
    return np.asarray(albedo, np.float32) * (sh.shading(t, b) - sh.shading(t, a))


@dataclass(frozen=True)
class MetricsResult:
    """Summary of one sequence.

    Attributes:
        temporal_error: mean |out[t+1] - out[t]| over mask intersections, [0, 1] units.
        warping_error: mean |warp(out[t+1]) - out[t]| over non-occluded mask pixels, [0, 1] units;
            NaN when no input frames were given.
        light_following: Pearson correlation of output change and light-predicted change; NaN when
            no intrinsic layers and lights were given, 0 when either change is constant.
        light_gain: least-squares slope of output change on predicted change (1 = full response).
        residual_error: mean |output change − predicted light change| over non-occluded mask pixels
            (motion-compensated when input frames were given), [0, 1] units; NaN without layers.
        pairs: number of frame pairs measured.
    """

    temporal_error: float
    warping_error: float
    light_following: float
    light_gain: float
    residual_error: float
    pairs: int


class TemporalMetrics:
    """Streaming accumulator of the three metrics; holds only the previous frame.

    Call :meth:`update` once per frame in order, then :meth:`result`. ``input_frame`` enables the
    warping error and motion compensation of the light-following score; ``albedo``, ``transport``
    and ``light`` (the layers the light-only prediction uses and that frame's light) enable the
    light-following score.
    """

    def __init__(self, flow_preset: str = "fast"):
        self.flow_preset = check_preset(flow_preset, "flow_preset")
        self._prev: dict | None = None
        self._temporal: list[float] = []
        self._warping: list[float] = []
        self._sums = np.zeros(6, np.float64)  # n, Σx, Σy, Σxx, Σyy, Σxy (x predicted, y output)
        self._residual: list[float] = []

    def update(self, output: np.ndarray, mask: np.ndarray | None = None, input_frame: np.ndarray | None = None,
               albedo: np.ndarray | None = None, transport: np.ndarray | None = None,
               light: np.ndarray | None = None) -> None:
        """Add the next frame.

        Args:
            output: (H, W, 3) relit frame, RGB float [0, 1] or uint8.
            mask: (H, W) person mask; None = every pixel.
            input_frame: (H, W, 3) frame of the input video (flow source).
            albedo: (H, W, 3) albedo of this frame; transport: (H, W, 9); light: (9, 3) this frame's light.
        """
        out = as_float_image(output, "output")
        m = as_bool_mask(mask, out.shape[:2])
        gray = None if input_frame is None else to_gray_u8(as_float_image(input_frame, "input_frame"))
        if gray is not None and gray.shape != out.shape[:2]:
            raise RelightError(f"input_frame: expected {out.shape[:2]} frame, got {gray.shape}")
        has_layers = albedo is not None and transport is not None and light is not None
        prev = self._prev
        if prev is not None:
            if prev["out"].shape != out.shape:
                raise RelightError(f"output: frame size changed from {prev['out'].shape} to {out.shape}")
            both = prev["mask"] & m
            if both.any():
                self._temporal.append(float(np.abs(out - prev["out"])[both].mean()))
            else:
                self._temporal.append(0.0)
            if gray is not None and prev["gray"] is not None:
                forward = dis_flow(prev["gray"], gray, self.flow_preset)
                backward = dis_flow(gray, prev["gray"], self.flow_preset)
                valid = consistent_flow(forward, backward) & prev["mask"] & (warp(m.astype(np.float32), forward) > 0.5)
                warped = warp(out, forward)
                self._warping.append(float(np.abs(warped - prev["out"])[valid].mean()) if valid.any() else 0.0)
            else:
                valid, warped = both, out
            if prev["layers"] is not None and has_layers:
                p_albedo, p_transport, p_light = prev["layers"]
                x = predicted_light_change(p_albedo, p_transport, p_light, light)[valid].astype(np.float64).ravel()
                y = (warped - prev["out"])[valid].astype(np.float64).ravel()
                self._sums += [x.size, x.sum(), y.sum(), x @ x, y @ y, x @ y]
                if x.size:
                    self._residual.append(float(np.abs(y - x).mean()))
        self._prev = {
            "out": out, "mask": m, "gray": gray,
            "layers": (np.asarray(albedo, np.float32), np.asarray(transport, np.float32),
                       np.asarray(light, np.float32)) if has_layers else None,
        }

    def result(self) -> MetricsResult:
        """The metrics of every frame added so far (needs at least two frames)."""
        if not self._temporal:
            raise RelightError("metrics: expected at least two frames, got fewer")
        n, sx, sy, sxx, syy, sxy = self._sums
        if n > 0:
            cov = sxy - sx * sy / n
            var_x = sxx - sx * sx / n
            var_y = syy - sy * sy / n
            tiny = 1e-12 * max(n, 1.0)
            corr = float(cov / np.sqrt(var_x * var_y)) if var_x > tiny and var_y > tiny else 0.0
            gain = float(cov / var_x) if var_x > tiny else 0.0
        else:
            corr = gain = float("nan")
        return MetricsResult(
            temporal_error=float(np.mean(self._temporal)),
            warping_error=float(np.mean(self._warping)) if self._warping else float("nan"),
            light_following=corr,
            light_gain=gain,
            residual_error=float(np.mean(self._residual)) if self._residual else float("nan"),
            pairs=len(self._temporal),
        )


def _measure(outputs: Iterable[np.ndarray], masks: Sequence | None, inputs: Sequence | None,
             albedos: Sequence | None = None, transports: Sequence | None = None,
             lights: Sequence | None = None) -> MetricsResult:
    acc = TemporalMetrics()
    for t, out in enumerate(outputs):
        acc.update(out, None if masks is None else masks[t], None if inputs is None else inputs[t],
                   None if albedos is None else albedos[t], None if transports is None else transports[t],
                   None if lights is None else lights[t])
    return acc.result()


def temporal_error(outputs: Iterable[np.ndarray], masks: Sequence | None = None) -> float:
    """The paper's flicker measure: mean |out[t+1] - out[t]| within mask[t] ∩ mask[t+1].

    Args:
        outputs: N >= 2 frames (H, W, 3) RGB, float [0, 1] or uint8 (a list or a stream).
        masks: N masks (H, W) or None (every pixel).

    Returns:
        Mean over frame pairs, in [0, 1] units; 0 for a static clip.
    """
    return _measure(outputs, masks, None).temporal_error


def warping_error(outputs: Iterable[np.ndarray], inputs: Sequence[np.ndarray], masks: Sequence | None = None) -> float:
    """Mean |warp(out[t+1]) - out[t]| over non-occluded mask pixels, warp from DIS flow of ``inputs``."""
    return _measure(outputs, masks, inputs).warping_error


def light_following(outputs: Iterable[np.ndarray], albedos: Sequence[np.ndarray], transports: Sequence[np.ndarray],
                    lights: Sequence[np.ndarray] | np.ndarray, masks: Sequence | None = None,
                    inputs: Sequence[np.ndarray] | None = None) -> float:
    """Correlation between each frame's output change and the change its light alone predicts.

    Args:
        outputs: N frames (H, W, 3).
        albedos, transports: per-frame intrinsic layers (H, W, 3) and (H, W, 9) (e.g. stage 1's).
        lights: (N, 9, 3) RGB SH light of each frame.
        masks: N masks or None.
        inputs: N input frames for motion compensation; None for a static subject.

    Returns:
        Pearson correlation in [-1, 1]: ≈ 1 follows the light, ≈ 0 frozen or unrelated.
    """
    return _measure(outputs, masks, inputs, albedos, transports, lights).light_following
