"""An independent forward pass of the reference network, plain numpy (float64), written from DESIGN.md §1.

It shares no code with export/networks.py or relight_rt/apps/reference_checkpoints.py: it runs the reference's
own (BGR) weights on the reference's own input, as the reference code does at inference (BatchNorm
layers in training mode on one image = per-sample statistics, biased variance, eps 1e-5; dropout off),
so a converted graph (RGB) can be checked against it after reversing the colour channels:

- encoder c0…c5: 4×4 stride-2 convs, padding 1; c0 with bias, no norm; c1…c5 without bias, BN bnc1…bnc5;
  LeakyReLU 0.01 after each;
- residual blocks ra / rb: conv3(bias)–BN–ReLU–conv3(bias)–BN, plus the input;
- decoders a (transport) / b: dc0…dc4 conv3 (no bias)–BN–ReLU–bilinear ×2 (align_corners=True), then
  concatenated with the encoder output of that size (c4, c3, c2, c1, c0); dc5 conv3 with bias, ×2;
  decoder b ends in a sigmoid for stage 1 and in nothing for stage 2 / DVP;
- light head (stage 1) on concat(bottleneck, ra, rb): c0l… 4×4 stride-2 convs, BN + LeakyReLU on all
  but the last (which has a bias), reshaped row-major to (9, 3) (a 1×1 kernel is a plain 1×1 conv).

Also :func:`random_reference_weights`, random BGR weights in a given layout, scaled like a trained
network (conv weights ~ 1/sqrt(fan-in), decoder b's last conv smaller so that a stage-2 residual is
~0.1, not saturated), so that the comparisons are not dominated by clipping or by a saturated sigmoid.
"""

from __future__ import annotations

import numpy as np

EPS = 1e-5
SLOPE = 0.01


def random_reference_weights(layout: dict, seed: int) -> dict[str, np.ndarray]:
    """Random float32 weights (num_batches_tracked int64) for ``layout`` (key -> shape)."""
    rng = np.random.default_rng(seed)
    sd = {}
    for key, shape in layout.items():
        shape = tuple(shape)
        if key.endswith("num_batches_tracked"):
            sd[key] = np.array(1000, np.int64)
        elif key.endswith("running_var"):
            sd[key] = rng.uniform(0.5, 1.5, shape).astype(np.float32)
        elif len(shape) == 4:
            gain = 0.1 if key.startswith("dc5b") else 1.0
            sd[key] = (rng.standard_normal(shape) * gain / np.sqrt(np.prod(shape[1:]))).astype(np.float32)
        elif key.endswith("weight"):  # norm scales
            sd[key] = (1 + 0.2 * rng.standard_normal(shape)).astype(np.float32)
        else:
            scale = 0.01 if key.startswith("dc5b") else 0.1
            sd[key] = (scale * rng.standard_normal(shape)).astype(np.float32)
    return sd


def conv2d(x: np.ndarray, w: np.ndarray, b: np.ndarray | None, stride: int, pad: int) -> np.ndarray:
    """Cross-correlation, NCHW, zero padding, one BLAS matmul per kernel offset."""
    n, c, h, wd = x.shape
    o, _, k, _ = w.shape
    xp = np.pad(x, ((0, 0), (0, 0), (pad, pad), (pad, pad)))
    ho, wo = (h + 2 * pad - k) // stride + 1, (wd + 2 * pad - k) // stride + 1
    out = np.zeros((n, o, ho * wo), np.float64)
    for i in range(k):
        for j in range(k):
            patch = xp[:, :, i : i + stride * (ho - 1) + 1 : stride, j : j + stride * (wo - 1) + 1 : stride]
            out += np.matmul(w[:, :, i, j].astype(np.float64), patch.reshape(n, c, ho * wo))
    out = out.reshape(n, o, ho, wo)
    if b is not None:
        out += b.astype(np.float64)[None, :, None, None]
    return out


def norm(x: np.ndarray, sd: dict, key: str) -> np.ndarray:
    mean = x.mean(axis=(2, 3), keepdims=True)
    var = ((x - mean) ** 2).mean(axis=(2, 3), keepdims=True)
    g = sd[f"{key}.weight"].astype(np.float64)[None, :, None, None]
    b = sd[f"{key}.bias"].astype(np.float64)[None, :, None, None]
    return (x - mean) / np.sqrt(var + EPS) * g + b


def leaky(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, SLOPE * x)


def relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


def _up_axis(x: np.ndarray, axis: int) -> np.ndarray:
    n = x.shape[axis]
    if n == 1:
        return np.repeat(x, 2, axis=axis)
    pos = np.arange(2 * n) * (n - 1) / (2 * n - 1)  # align_corners: the end samples land on the end pixels
    i0 = np.minimum(np.floor(pos).astype(int), n - 2)
    frac = pos - i0
    shape = [1] * x.ndim
    shape[axis] = 2 * n
    frac = frac.reshape(shape)
    return np.take(x, i0, axis=axis) * (1 - frac) + np.take(x, i0 + 1, axis=axis) * frac


def up2(x: np.ndarray) -> np.ndarray:
    """Bilinear ×2 with align_corners=True."""
    return _up_axis(_up_axis(x, 2), 3)


def _conv(sd: dict, key: str, x: np.ndarray, stride: int, pad: int) -> np.ndarray:
    return conv2d(x, sd[f"{key}.weight"], sd.get(f"{key}.bias"), stride, pad)


def _residual(sd: dict, key: str, x: np.ndarray) -> np.ndarray:
    h = relu(norm(_conv(sd, f"{key}.c1", x, 1, 1), sd, f"{key}.b1"))
    return x + norm(_conv(sd, f"{key}.c2", h, 1, 1), sd, f"{key}.b2")


def _decoder(sd: dict, branch: str, h: np.ndarray, feats: list[np.ndarray]) -> np.ndarray:
    for i in range(5):
        h = up2(relu(norm(_conv(sd, f"dc{i}{branch}", h, 1, 1), sd, f"bndc{i}{branch}")))
        h = np.concatenate([h, feats[4 - i]], axis=1)
    return up2(_conv(sd, f"dc5{branch}", h, 1, 1))


def network(sd: dict, x: np.ndarray, kind: str) -> dict[str, np.ndarray]:
    """The raw network on a reference input x (already 2·image − 1, masked; plus the light for the DVP).

    Returns:
        stage1: transport, albedo, skin (sigmoid), light (N, 9, 3); stage2 / dvp: out (decoder b, as is).
    """
    feats = [leaky(_conv(sd, "c0", x.astype(np.float64), 2, 1))]
    for i in range(1, 6):
        feats.append(leaky(norm(_conv(sd, f"c{i}", feats[-1], 2, 1), sd, f"bnc{i}")))
    hrb = _residual(sd, "rb", feats[5])
    out_b = _decoder(sd, "b", hrb, feats)
    if kind != "stage1":
        return {"out": out_b}
    hra = _residual(sd, "ra", feats[5])
    transport = _decoder(sd, "a", hra, feats)
    hb = 1.0 / (1.0 + np.exp(-out_b))
    h = np.concatenate([feats[5], hra, hrb], axis=1)
    n_light = sum(1 for k in sd if k.endswith("l.weight") and k.startswith("c"))
    for i in range(n_light):
        w = sd[f"c{i}l.weight"]
        stride, pad = (1, 0) if w.shape[-1] == 1 else (2, 1)
        h = conv2d(h, w, sd.get(f"c{i}l.bias"), stride, pad)
        if i < n_light - 1:
            h = leaky(norm(h, sd, f"bnc{i}l"))
    light = h.reshape(h.shape[0], 9, 3)
    return {"transport": transport, "albedo": hb[:, :3], "skin": hb[:, 3:4], "light": light}


def contract_outputs(sd: dict, kind: str, feeds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """What a converted graph must output for RGB ``feeds``, computed the reference's way in BGR.

    The RGB inputs are turned into the reference's BGR input, the reference network runs, and its
    outputs are turned back to RGB and masked / clipped as the format-1 contract says.
    """
    mask = feeds["mask"].astype(np.float64)
    if kind == "stage1":
        bgr = feeds["image"][:, ::-1].astype(np.float64)
        r = network(sd, (2 * bgr - 1) * mask, kind)
        return {
            "albedo": r["albedo"][:, ::-1] * mask,
            "skin": r["skin"] * mask,
            "transport": r["transport"] * mask,
            "light": r["light"][:, :, ::-1],
        }
    if kind == "stage2":
        bgr = feeds["diffuse"][:, ::-1].astype(np.float64)
        r = network(sd, (2 * bgr - 1) * mask, kind)["out"]  # the reference adds r unmasked, then masks the sum
        return {"residual": (r * mask)[:, ::-1], "relit": (np.clip(bgr + r, 0, 1) * mask)[:, ::-1]}
    bgr = feeds["frame"][:, ::-1].astype(np.float64)
    light_bgr = feeds["light"][:, :, ::-1].astype(np.float64)  # (N, 9, 3), columns B, G, R
    n, _, h, w = bgr.shape
    tiled = np.broadcast_to(light_bgr.reshape(n, 27, 1, 1), (n, 27, h, w))  # channel 3k + c = light[k, c]
    out = network(sd, np.concatenate([(2 * bgr - 1) * mask, tiled], axis=1), kind)["out"]
    return {"relit": (np.clip((out + 1) / 2, 0, 1) * mask)[:, ::-1]}


def relative_error(got: np.ndarray, want: np.ndarray) -> float:
    """‖got − want‖ / ‖want‖ (float64)."""
    want = np.asarray(want, np.float64)
    return float(np.linalg.norm(np.asarray(got, np.float64) - want) / np.linalg.norm(want))
