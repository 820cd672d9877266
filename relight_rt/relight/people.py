"""A group photo relit person by person (``PartsMatter`` keeps each person's share of the matte, ``by_person``
relights with them)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..compositing import Background, clean_edge_colour
from . import compose
from .decomposition import Decomposition, readonly
from .look import dark_colour, knee

MAX_PEOPLE = 16  # matting="all": a photo of more people than this is relit as one group (memory: a mask each)


class PartsMatter:
    """A Matter that keeps each person's share of the matte it returns (``PersonMatter.parts``): a group photo,
    relit person by person (``by_person``)."""

    def __init__(self, matter):
        self.matter, self.found = matter, None

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray:
        alpha, self.found = self.matter.parts(rgb, name)
        return alpha


def by_person(
    composer: compose.Composer, network_relit: Callable, dec: Decomposition, parts: tuple[Decomposition, ...],
    light: np.ndarray, exposure, bg: Background,
) -> np.ndarray:
    """A group photo relit person by person: each of ``parts`` (the people of ``dec``, each decomposed on their
    own with their share of its matte: their own shape, their face seen at their size, their own exposure)
    gives the person's relit colour; the colours, weighted by the shares (which sum to the matte, so where
    people overlap their changes blend), go over the backdrop with the group's matte. The person's own colour
    and the colour behind the soft edge are the group's (``Composer.foreground`` once, on the whole matte: where
    two people meet neither is background).

    ``composer``: the Relighter's; ``network_relit``: its stage-2 pass (a decomposition, lights (K, 9, 3), a batch
    size and ``want_layers`` -> (diffuse, residual, relit) per light, as ``Relighter`` runs it).
    """
    memo, factor = composer.memo, composer.factor
    backdrop = compose.backdrop_of(dec, bg)
    clean = bg.kind != "original"
    fg, behind = composer.foreground(dec, always=clean and not composer.detail)
    y0, y1, x0, x1 = dec.geometry.box
    alpha = dec.geometry.crop(dec.mask)[..., None]
    weighted = np.zeros(fg.shape, np.float32)  # the people's colours times their shares of the matte, summed
    for part in parts:
        py0, py1, px0, px1 = part.geometry.box
        cy0, cy1, cx0, cx1 = max(py0, y0), min(py1, y1), max(px0, x0), min(px1, x1)
        if cy1 <= cy0 or cx1 <= cx0:
            continue
        looks = None
        if (cy0, cy1, cx0, cx1) == (py0, py1, px0, px1):
            # the person's box lies in the group's (their share lies in its matte): what the group has of the
            # photo whatever the light is theirs, as views (a group photo of many megapixels holds it once; their
            # own colours are the group's already: Relighter._group)
            group = (slice(py0 - y0, py1 - y0), slice(px0 - x0, px1 - x0))
            whole = memo(dec)
            if "dark" not in whole:
                whole["dark"] = tuple(readonly(a) for a in dark_colour(fg))
                whole["knee"] = readonly(knee(fg))
            looks = tuple(a[group] for a in whole["dark"]), whole["knee"][group]
        lit = factor.expose(part, light[None], exposure)[0]
        _, residual, relit = next(network_relit(part, lit[None], 1, want_layers=composer.detail))
        colour = composer.person_colour(part, lit, residual, relit, looks)
        share = part.geometry.crop(part.mask)[..., None]
        if clean and not composer.detail:
            colour = clean_edge_colour(colour, np.ascontiguousarray(part.geometry.crop(part.image)),
                                       composer.foreground(part, always=True)[0], share[..., 0])
        sl = (slice(cy0 - py0, cy1 - py0), slice(cx0 - px0, cx1 - px0))
        weighted[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] += (colour * share)[sl]
    if backdrop is None:  # RGBA, straight colour
        out = np.zeros(dec.geometry.frame + (4,), np.float32)
        np.divide(weighted, alpha, out=out[y0:y1, x0:x1, :3], where=alpha > 0)
        out[..., 3] = dec.mask
    else:
        out = np.array(backdrop, np.float32)
        if bg.graded:  # the group's change, summed over the group's matte (relight_rt.compositing)
            own = composer.foreground(dec)[0]
            colour = np.divide(weighted, alpha, out=np.zeros_like(weighted), where=alpha > 0)
            gain = compose.background_grade(colour, own, alpha)
            out *= gain
            np.clip(out, 0, 1, out=out)
            if behind is not fg:
                behind = np.clip(behind * gain, 0, 1)
        under = behind if not clean and behind is not fg else out[y0:y1, x0:x1]
        out[y0:y1, x0:x1] = under * (1 - alpha) + weighted
    return np.clip(out, 0, 1, out=out)
