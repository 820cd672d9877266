"""Non-diffuse "photos" of a rendered subject under an environment map, for stage 2.

photo = albedo ⊙ S' + specular, where
- S is the diffuse shading: by default S = max(0, T·L), the stage-1 model (T the occlusion-aware
  transport, L the SH projection of the environment map); with ``full_shading`` the shading a camera
  would record, S = ∫ V(ω) max(0, n·ω) E(ω) dω under the full environment map E, whose hard shadows
  and sharp terminators the 9 SH coefficients cannot hold (same normalisation: T·L is S with E
  band-limited to SH order 2). The diffuse image is always albedo ⊙ max(0, T·L), what stage 1 can
  represent, so photo − diffuse is everything stage 2 has to add;
- S' is S with a soft subsurface look on skin: S blurred within the subject's mask, more in red than
  in blue (light scatters further in red), mixed in by ``subsurface × skin`` per pixel;
- specular is a GGX microfacet lobe (Walter et al. 2007; Smith masking; Schlick's Fresnel) whose
  reflectance at normal incidence is the material's ``specular`` value (about 0.04 for a dielectric
  such as skin or cotton, more for oily skin, satin or leather; Schlick's rise toward grazing angles is
  scaled along, so that 0 means no specular at all), lit by the full environment map with
  visibility: each pixel casts ``n_samples`` rays sampled from the lobe and ``n_samples`` from the
  map's brightness, combined with the balance heuristic (multiple importance sampling, Veach 1997).

With zero specular strength and zero subsurface (and SH shading) the photo equals the diffuse image exactly.
Every image is linear (no gamma), like the albedo.
"""

from __future__ import annotations

import cv2
import numpy as np

from relight_rt.engine.errors import RelightError
from relight_rt.image.color import REC709
from relight_rt.light.envmap import directions_envmap, project_envmap, solid_angles_envmap
from relight_rt.light.sh import shading

from .raycast import Tracer
from .transport import RAYS_PER_BATCH, GBuffer, tangent_frame

F0 = 0.04  # the dielectric whose Schlick curve shapes the Fresnel rise; Part.specular rescales it
SSS_RADIUS_M = np.array([0.008, 0.004, 0.0025])  # blur radius (Gaussian sigma) per RGB channel, metres


class EnvSampler:
    """Look-ups into an equirectangular map and importance sampling of its pixels by luminance × solid angle."""

    def __init__(self, env: np.ndarray) -> None:
        env = np.asarray(env, np.float32)
        if env.ndim != 3 or env.shape[2] != 3 or env.shape[1] != 2 * env.shape[0]:
            raise RelightError(f"env: expected an (H, 2H, 3) environment map, got {env.shape}")
        if not np.all(np.isfinite(env)) or env.min() < 0:
            raise RelightError("env: expected finite non-negative radiance")
        self.env = env
        self.h, self.w = env.shape[:2]
        omega = solid_angles_envmap(self.h).astype(np.float64)
        weight = (env.astype(np.float64) @ REC709 + 1e-4 * env.mean()) * omega
        self.prob = (weight / weight.sum()).ravel()  # probability of each pixel
        self.cdf = np.cumsum(self.prob)
        self.pdf_solid = (self.prob / omega.ravel())  # density per steradian inside each pixel

    def _pixel(self, dirs: np.ndarray) -> np.ndarray:
        theta = np.arccos(np.clip(dirs[..., 2], -1.0, 1.0))
        phi = np.arctan2(-dirs[..., 1], dirs[..., 0]) % (2 * np.pi)
        i = np.minimum((theta / np.pi * self.h).astype(np.int64), self.h - 1)
        j = np.minimum((phi / (2 * np.pi) * self.w).astype(np.int64), self.w - 1)
        return i * self.w + j

    def lookup(self, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radiance (..., 3) and sampling density (...,) per steradian in directions (..., 3)."""
        idx = self._pixel(dirs)
        return self.env.reshape(-1, 3)[idx], self.pdf_solid[idx]

    def sample(self, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
        """Directions (*shape, 3) float32 drawn ∝ luminance × solid angle, uniform within a pixel."""
        idx = np.minimum(np.searchsorted(self.cdf, rng.random(shape) * self.cdf[-1]), self.cdf.size - 1)
        i, j = np.divmod(idx, self.w)
        u = rng.random((*shape, 2))
        z = np.cos(np.pi * i / self.h) + (np.cos(np.pi * (i + 1) / self.h) - np.cos(np.pi * i / self.h)) * u[..., 0]
        phi = 2 * np.pi * (j + u[..., 1]) / self.w
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        return np.stack([r * np.cos(phi), -r * np.sin(phi), z], axis=-1).astype(np.float32)


def _ggx_d(cos_h: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    a2 = alpha * alpha
    t = cos_h * cos_h * (a2 - 1.0) + 1.0
    return a2 / (np.pi * t * t)


def _smith_g1(cos_x: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    a2 = alpha * alpha
    return 2.0 * cos_x / (cos_x + np.sqrt(a2 + (1.0 - a2) * cos_x * cos_x))


def specular(
    tracer: Tracer,
    gbuffer: GBuffer,
    sampler: EnvSampler,
    *,
    n_samples: int = 16,
    rng: np.random.Generator,
    offset: float | None = None,
) -> np.ndarray:
    """Specular radiance (M, 3) float32 of the covered pixels (zero where the strength is zero)."""
    m = len(gbuffer.index)
    out = np.zeros((m, 3), np.float32)
    sel = np.flatnonzero(gbuffer.specular > 0)
    if len(sel) == 0 or n_samples < 1:
        return out
    eps = 1e-4 * tracer.scale if offset is None else float(offset)
    n = gbuffer.normal[sel].astype(np.float64)
    v = gbuffer.view[sel].astype(np.float64)
    alpha = np.clip(gbuffer.roughness[sel].astype(np.float64), 0.02, 1.0)[:, None]
    p = len(sel)
    # lobe samples: half vectors from D(h) cos θ_h, reflected about h
    u = rng.random((p, n_samples, 2))
    tan2 = alpha * alpha * u[..., 0] / np.maximum(1.0 - u[..., 0], 1e-12)
    cos_t = 1.0 / np.sqrt(1.0 + tan2)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2 * np.pi * u[..., 1]
    t, b = tangent_frame(n.astype(np.float32))
    h = (sin_t * np.cos(phi))[..., None] * t[:, None] + (sin_t * np.sin(phi))[..., None] * b[:, None]
    h = h + cos_t[..., None] * n[:, None]
    l_brdf = 2.0 * np.einsum("pnd,pd->pn", h, v)[..., None] * h - v[:, None]
    l_env = sampler.sample((p, n_samples), rng).astype(np.float64)
    dirs = np.concatenate([l_brdf, l_env], axis=1)  # (p, 2n, 3)
    dirs /= np.maximum(np.linalg.norm(dirs, axis=-1, keepdims=True), 1e-12)
    nv = np.clip(np.einsum("pd,pd->p", n, v), 1e-4, 1.0)[:, None]
    nl = np.einsum("pnd,pd->pn", dirs, n)
    hv = dirs + v[:, None]
    hv /= np.maximum(np.linalg.norm(hv, axis=-1, keepdims=True), 1e-12)
    nh = np.clip(np.einsum("pnd,pd->pn", hv, n), 0.0, 1.0)
    vh = np.clip(np.einsum("pnd,pd->pn", hv, v), 1e-6, 1.0)
    d = _ggx_d(nh, alpha)
    # Schlick's curve for F0 = 0.04, rescaled to reach the material's reflectance at normal incidence
    strength = gbuffer.specular[sel].astype(np.float64)[:, None]
    fresnel = np.minimum(1.0, strength * (1.0 + (1.0 / F0 - 1.0) * (1.0 - vh) ** 5))
    g = _smith_g1(np.clip(nl, 0, 1), alpha) * _smith_g1(nv, alpha)
    ok = (nl > 0) & (np.einsum("pnd,pd->pn", dirs, gbuffer.geo_normal[sel]) > 0)
    # f·cos = D F G / (4 n·v); the BRDF-sampling density of l is D n·h / (4 v·h)
    f_cos = d * fresnel * g / (4.0 * nv)
    pdf_brdf = d * nh / (4.0 * vh)
    radiance, pdf_env = sampler.lookup(dirs)
    origins = gbuffer.position[sel] + eps * gbuffer.geo_normal[sel]
    rays_o = np.broadcast_to(origins[:, None], dirs.shape)[ok]
    visible = np.zeros(ok.shape, bool)
    visible[ok] = ~tracer.occluded(rays_o, dirs[ok])
    weight = np.where(visible, f_cos / np.maximum(n_samples * (pdf_brdf + pdf_env), 1e-12), 0.0)
    spec = np.einsum("pn,pnc->pc", weight, radiance.astype(np.float64))
    out[sel] = spec.astype(np.float32)
    return out


def median_cut(env: np.ndarray, n_lights: int) -> tuple[np.ndarray, np.ndarray]:
    """Split an environment map into ``n_lights`` regions of about equal power, one point light each.

    Median cut (Debevec 2005): the region with the most power is halved along its longer side
    (measured in angle, columns shortened by sin θ), at the row or column where its luminance × solid
    angle reaches half, until there are ``n_lights`` regions. Each light sits at its region's
    power-weighted mean direction and carries the region's integral ∫ E dω (RGB), so Σ power = ∫ E dω.

    Returns:
        directions (K, 3) float64 unit vectors, power (K, 3) float64; K ≤ ``n_lights`` (regions of a
        single pixel are not split further).
    """
    env = np.asarray(env, np.float64)
    h, w = env.shape[:2]
    omega = solid_angles_envmap(h).astype(np.float64)
    energy = env * omega[..., None]  # (H, W, 3) radiance × solid angle
    lum = energy @ REC709 + 1e-9 * omega
    dirs = directions_envmap(h)
    sin_t = np.sqrt(1.0 - dirs[:, 0, 2] ** 2)  # per row

    def power(r0: int, r1: int, c0: int, c1: int) -> float:
        return float(lum[r0:r1, c0:c1].sum()) if (r1 - r0) * (c1 - c0) > 1 else -1.0  # one pixel: final

    regions, powers = [(0, h, 0, w)], [power(0, h, 0, w)]
    while len(regions) < n_lights and max(powers) >= 0:
        i = int(np.argmax(powers))
        r0, r1, c0, c1 = regions.pop(i)
        powers.pop(i)
        rows, cols = r1 - r0, c1 - c0
        tall = cols == 1 or (rows > 1 and rows >= cols * sin_t[r0:r1].mean())
        profile = lum[r0:r1, c0:c1].sum(axis=1 if tall else 0)
        half = int(np.searchsorted(np.cumsum(profile), 0.5 * profile.sum())) + 1
        cut = (r0 if tall else c0) + min(half, len(profile) - 1)  # both halves non-empty
        parts = [(r0, cut, c0, c1), (cut, r1, c0, c1)] if tall else [(r0, r1, c0, cut), (r0, r1, cut, c1)]
        regions += parts
        powers += [power(*p) for p in parts]
    out_dirs, out_power = [], []
    for r0, r1, c0, c1 in regions:
        wgt = lum[r0:r1, c0:c1, None]
        d = (dirs[r0:r1, c0:c1] * wgt).sum(axis=(0, 1))
        out_dirs.append(d / max(np.linalg.norm(d), 1e-12))
        out_power.append(energy[r0:r1, c0:c1].sum(axis=(0, 1)))
    return np.asarray(out_dirs), np.asarray(out_power)


def full_shading(
    tracer: Tracer,
    gbuffer: GBuffer,
    env: np.ndarray,
    *,
    n_lights: int = 256,
    offset: float | None = None,
) -> np.ndarray:
    """Diffuse shading (M, 3) float32 of the covered pixels under the full environment map, with visibility.

    S(p) = ∫ V(p,ω) max(0, n·ω) E(ω) dω, with E replaced by the ``n_lights`` point lights of
    :func:`median_cut`: deterministic (no Monte Carlo grain, which stage 2 could not predict), a sun
    keeps its hard shadow, and a broad sky becomes many dim lights whose shadows overlap softly.
    Shadow rays start as in :func:`export.render.transport.transport`.
    """
    m = len(gbuffer.index)
    dirs, power = median_cut(env, n_lights)
    eps = 1e-4 * tracer.scale if offset is None else float(offset)
    out = np.zeros((m, 3), np.float64)
    chunk = max(1, RAYS_PER_BATCH // len(dirs))
    for s in range(0, m, chunk):
        e = min(m, s + chunk)
        nl = gbuffer.normal[s:e].astype(np.float64) @ dirs.T  # (P, K)
        ok = nl > 0
        origins = gbuffer.position[s:e] + eps * gbuffer.geo_normal[s:e]
        origins = np.broadcast_to(origins[:, None], (e - s, len(dirs), 3))
        rays = np.broadcast_to(dirs[None], origins.shape)
        visible = np.zeros(ok.shape, bool)
        visible[ok] = ~tracer.occluded(origins[ok], rays[ok])
        out[s:e] = np.where(visible, nl, 0.0) @ power
    return out.astype(np.float32)


def _subsurface(shade_img: np.ndarray, mask: np.ndarray, pixel_size: float) -> np.ndarray:
    """Shading blurred within the mask, a Gaussian of SSS_RADIUS_M per channel; (R, R, 3) float32."""
    out = np.empty_like(shade_img)
    m = mask.astype(np.float32)
    for c in range(3):
        sigma = float(SSS_RADIUS_M[c] / pixel_size)
        if sigma < 0.3:
            out[..., c] = shade_img[..., c]
            continue
        num = cv2.GaussianBlur(shade_img[..., c] * m, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
        den = cv2.GaussianBlur(m, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
        out[..., c] = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.0)
    return out


def render_photo(
    tracer: Tracer,
    gbuffer: GBuffer,
    transport: np.ndarray,
    env: np.ndarray,
    *,
    pixel_size: float,
    albedo: np.ndarray | None = None,
    n_samples: int = 16,
    full: bool = False,
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Render a photo of a subject under an environment map.

    Args:
        tracer: the subject's tracer (visibility of the specular lobe).
        gbuffer: covered pixels with their materials.
        transport: (M, 9) transport of the covered pixels (from the stage-1 sample).
        env: (H, 2H, 3) float linear RGB environment map (DESIGN.md §3 layout).
        pixel_size: side of one pixel at the subject, metres (sets the subsurface blur in pixels).
        albedo: (M, 3) RGB albedo to use instead of the G-buffer's (e.g. the 8-bit one written to disk).
        n_samples: specular lobe samples and environment samples per pixel (each).
        full: shade with the full environment map (:func:`full_shading`) instead of its SH projection.
        rng: random generator.

    Returns:
        dict with ``photo`` and ``diffuse`` (R, R, 3) float32 linear RGB (not clipped), ``mask`` (R, R)
        float32, ``light`` (9, 3) float64 RGB = SH projection of ``env``.
    """
    transport = np.asarray(transport, np.float32)
    if transport.shape != (len(gbuffer.index), 9):
        raise RelightError(f"transport: expected ({len(gbuffer.index)}, 9) per covered pixel, got {transport.shape}")
    alb = gbuffer.albedo if albedo is None else np.asarray(albedo, np.float32)
    sampler = EnvSampler(env)
    light = project_envmap(sampler.env)
    shade = shading(transport, light).astype(np.float32)  # (M, 3)
    diffuse = alb * shade
    if full:
        shade = full_shading(tracer, gbuffer, sampler.env)
    photo = alb * shade
    w = gbuffer.subsurface * gbuffer.skin
    if np.any(w > 0):
        blurred = _subsurface(gbuffer.image(shade), gbuffer.mask, pixel_size).reshape(-1, 3)[gbuffer.index]
        photo = alb * (shade + w[:, None] * (blurred - shade))
    if np.any(gbuffer.specular > 0):
        photo = photo + specular(tracer, gbuffer, sampler, n_samples=n_samples, rng=rng)
    return {"photo": gbuffer.image(photo), "diffuse": gbuffer.image(diffuse), "mask": gbuffer.mask, "light": light}


def glossier(gbuffer: GBuffer, amount: float) -> GBuffer:
    """The same surfaces made shinier, for photos whose non-diffuse part is large (``render-photos --gloss``).

    ``amount`` in [0, 1]: 0 keeps the materials as drawn; 1 multiplies every surface's specular reflectance
    by 5 (capped at 1) and its GGX roughness by 0.5 (at least 0.08): oily skin with highlights on forehead,
    nose and cheeks, satin and leather that read as vinyl, cotton with a visible sheen, hair with a bright
    band. The diffuse albedo and the subsurface part are unchanged, so the SH diffuse image is too.
    """
    import dataclasses

    if not 0.0 <= amount <= 1.0:
        raise RelightError(f"gloss: expected an amount in [0, 1], got {amount}")
    if amount == 0.0:
        return gbuffer
    spec = np.minimum(1.0, gbuffer.specular * (1.0 + 4.0 * amount)).astype(np.float32)
    rough = np.maximum(0.08, gbuffer.roughness * (1.0 - 0.5 * amount)).astype(np.float32)
    return dataclasses.replace(gbuffer, specular=spec, roughness=rough)


def pixel_size(half_extent: float, resolution: int) -> float:
    """Side of one pixel, metres, of a camera seeing 2 × ``half_extent`` over ``resolution`` pixels."""
    return 2.0 * half_extent / max(int(resolution), 1)


__all__ = ["EnvSampler", "F0", "SSS_RADIUS_M", "full_shading", "glossier", "median_cut", "pixel_size", "render_photo",
           "specular"]
