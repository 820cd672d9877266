"""The exposure of a Relighter's decompositions: the light scaled so that a relit person keeps their level, the faces'
cast shadows metered, then the highlight shoulder's loss given back and the highlight guard (relight_rt.light.exposure
holds the rules; this is what of a Decomposition they read, kept once per Decomposition).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..image.color import REC709, channel_max
from ..light import exposure as _exposure
from .decomposition import Decomposition, Memo, readonly
from .detail import unpremultiply


class ExposureMeter:
    """The exposure of a Relighter's decompositions (``expose``), with what it reads of each kept per Decomposition.

    Args:
        memo: where what is computed once per Decomposition is kept (the Relighter's, shared with its ``Factor``).
        detail: the Relighter's ``detail`` (full-resolution detail transfer: the relit picture is the photo times the
            relighting factor).
        own: what every relight of a Decomposition divides by, without stage 2's residual (``Factor.own``'s dict).
        cast: what the faces' cast shadows under a light leave of its shading (``Factor.cast``), None without one.
    """

    def __init__(self, memo: Memo, detail: bool, own: Callable[[Decomposition], dict],
                 cast: Callable[[Decomposition, dict, np.ndarray], np.ndarray | None]) -> None:
        self.memo, self.detail, self.own, self.cast = memo, detail, own, cast

    def expose(self, dec: Decomposition, lights: np.ndarray, exposure) -> np.ndarray:
        """relight_rt.light.exposure.expose with the photo's own mean luminance measured once per Decomposition, the
        faces' cast shadows metered (``meter_shadows``), then relight_rt.light.exposure ``guarded``: the highlight
        shoulder's loss given back (``shoulder_gain``) and the highlight guard (``highlight_factor``) on each light,
        before any EV offset."""
        mode = _exposure.parse_exposure(exposure)
        if mode == "physical":
            return np.array(lights, np.float32)
        state = self.memo(dec)
        if "target" not in state:
            state["target"] = _exposure.mean_luminance(dec.albedo, dec.transport, dec.network_mask, dec.white_light,
                                                       _exposure.METER_POWER)
        lits = _exposure.expose(dec, lights, "auto", target_luminance=state["target"])
        if self.detail:  # the faces' cast shadows are part of the light as seen (``cast``)
            lits = self.meter_shadows(dec, lits)
        # what the highlight shoulder takes is given back (``shoulder_gain``), then the guard, then any EV
        return _exposure.guarded(lits, mode, self.highlight_inputs(dec))

    def meter_shadows(self, dec: Decomposition, lights: np.ndarray) -> np.ndarray:
        """``lights`` (K, 9, 3) or (9, 3), each scaled up by what the faces' cast shadows under it take from the
        person's mean luminance as seen (the power mean of relight_rt.light.exposure ``METER_POWER`` over the
        person's pixels in the network frame): "auto" keeps the light as seen, a shadow included (without, the
        white side lamps' median EV as seen went from -0.18 to -0.20 on 59 photos, benchmarks/photo_faults.py)."""
        lits = np.asarray(lights, np.float32)
        own = self.own(dec)
        if not own["mesh_views"]:
            return lits
        flat = lits.reshape(-1, 9, 3).copy()
        inner, p = own["inner"], _exposure.METER_POWER
        weight = own["alpha"][inner]
        for i, light in enumerate(flat):
            cast = self.cast(dec, own, light)
            if cast is None:
                continue
            lum = np.maximum(own["albedo"][inner] * (own["transport"][inner] @ (light @ REC709)), 0) ** p
            shadowed = float((lum * cast[inner] ** p) @ weight)
            if shadowed > 1e-12:
                flat[i] *= np.float32((float(lum @ weight) / shadowed) ** (1 / p))
        return flat.reshape(lits.shape)

    def highlight_inputs(self, dec: Decomposition) -> _exposure.Highlight:
        """What ``highlight_factor`` and ``shoulder_gain`` read of ``dec`` whatever the light (cached,
        relight_rt.light.exposure ``Highlight``): the person's pixels (alpha > 0.5, network frame) as the relit
        picture is made of them, the share past white allowed, and each pixel's knee.

        With detail the picture is the photo times the relighting factor (relight_rt.relight.factor; diffuse part): per
        pixel the photo's colour times albedo / own scales with the light and the photo's colour times missing /
        own stays, and the highlight shoulder starts at the photo's own peak (``knee``, as ``Composer`` rolls it
        off); without it, the network's albedo times the shading, its knee that picture's peak under the photo's own
        light (``own_light_knee``). The share allowed is the photo's own share at white there, at least
        ``HIGHLIGHT_SHARE``.
        """
        state = self.memo(dec)
        if "highlight" not in state:
            if self.detail:
                own = self.own(dec)
                y0, y1, x0, x1 = own["window"]
                inner = own["inner"]
                photo = dec.network_image[y0:y1, x0:x1][inner]
                base = own["own"][inner]
                lit = photo * (own["albedo"][inner] / base)[:, None]
                steady = photo * (own["missing"][inner] / base)[:, None]
                transport = own["transport"][inner]
                peaks = _exposure.knee(photo)
            else:
                alpha = dec.network_mask
                inner = alpha > 0.5
                photo = dec.network_image[inner]
                lit = unpremultiply(np.ascontiguousarray(dec.albedo), alpha)[inner]
                steady = np.zeros_like(lit)
                transport = unpremultiply(np.ascontiguousarray(dec.transport), alpha)[inner]
                peaks = _exposure.own_light_knee(lit, steady, transport, dec.white_light[:, 0])
            at_white = float(np.mean(channel_max(photo) >= 0.99 * _exposure.HIGHLIGHT_LIMIT)) if photo.size else 0.0
            state["highlight"] = _exposure.Highlight(
                readonly(lit.astype(np.float32)), readonly(steady.astype(np.float32)),
                readonly(np.ascontiguousarray(transport, np.float32)), max(at_white, _exposure.HIGHLIGHT_SHARE),
                readonly(np.asarray(peaks, np.float32)))
        return state["highlight"]
