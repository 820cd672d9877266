"""A Decomposition relit under one light or a sweep of K lights: each light exposed (``ExposureMeter.expose``), run
through stage 2 in batches (``Network.relit``) and composited at full resolution (``Composer``); a group photo person
by person (relight_rt.relight.people). What ``Relighter.relight``, ``layers`` and ``iter_relight`` run once the photo
is decomposed and its lights are resolved."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np

from ..image.compositing import Background, parse_background
from ..light import exposure as _exposure
from ..light.spec import LightSpec
from . import people as per_person
from .compose import Composer, backdrop_of
from .decomposition import Decomposition, RelightResult
from .factor import Factor
from .network import Network


class Lighting:
    """The stages that relight a Decomposition, after stage 1: the exposure, stage 2 and the composite.

    Args:
        network: stage 1 and 2 (``Network``; its ``relit`` runs stage 2).
        factor: the relighting factor, whose ``meter`` exposes a light for a Decomposition.
        composer: the full-resolution composite over a backdrop.
        detail: the config's detail transfer (stage 2's layers kept for it).
    """

    def __init__(self, network: Network, factor: Factor, composer: Composer, detail: bool) -> None:
        self._network, self._factor, self._composer, self._detail = network, factor, composer, detail

    def one(self, dec: Decomposition, light, exposure, background, resolve: Callable[[object], np.ndarray],
            layers: bool, keep: bool) -> np.ndarray | RelightResult:
        """``dec`` relit under ``light`` (resolved by ``resolve``, ``Relighter.resolve_light``) with ``exposure``
        over ``background`` (both as ``Relighter.relight`` takes them): the picture, or with ``layers`` the
        RelightResult; ``keep``: a group's per-person state is kept (``dec`` is the caller's, not made for this
        call)."""
        if isinstance(light, (str, os.PathLike)):
            light = LightSpec.of(light)  # read once by the one rule: its exposure and its light
        exposure = _exposure.for_light(exposure, light)  # a preset may ask for its own exposure (night: darker)
        parts, expose = dec.people, self._factor.meter.expose
        if parts:
            bg, light = parse_background(background), resolve(light)
            out = per_person.by_person(self._composer, self._network.relit, dec, parts, light, exposure, bg,
                                       keep=keep)  # a photo decomposed for this call: relit once
            if layers:  # the layers are the group's, decomposed as one
                return replace(self._with_layers(dec, expose(dec, light, exposure), bg), image=out)
            return out
        lit = expose(dec, resolve(light), exposure)
        bg = parse_background(background)
        if layers:
            return self._with_layers(dec, lit, bg)
        outputs = next(self._network.relit(dec, lit[None], 1, want_layers=self._detail))
        return self._composer.compose(dec, lit, outputs, backdrop_of(dec, bg), clean=bg.kind != "original",
                                      grade=bg.graded)

    def _with_layers(self, dec: Decomposition, lit: np.ndarray, bg: Background) -> RelightResult:
        """The picture under the exposed light ``lit`` and the input-frame layers that made it."""
        outputs = next(self._network.relit(dec, lit[None], 1, want_layers=True))
        return self._composer.with_layers(dec, lit, outputs, backdrop_of(dec, bg), bg.kind != "original", bg.graded)

    def each(self, dec: Decomposition, resolved: np.ndarray, exposures: list, background, batch_size: int,
             keep: bool) -> Iterator[np.ndarray]:
        """``dec`` relit under each of the (K, 9, 3) ``resolved`` lights with its exposure, one (H, W, 3|4) picture
        at a time, stage 2 on ``batch_size`` lights at once; ``keep`` as for ``one``."""
        parts = dec.people
        if parts:  # a group: each person's light-independent work done once for several lights
            bg = parse_background(background)
            step = per_person.lights_at_once(dec.geometry.frame, bg.channels, batch_size)
            for s in range(0, len(resolved), step):  # each person's state kept while lights follow (or dec is yours)
                yield from per_person.by_person_lights(self._composer, self._network.relit, dec, parts,
                                                       resolved[s : s + step], exposures[s : s + step], bg,
                                                       keep=keep or s + step < len(resolved))
            return
        expose = self._factor.meter.expose
        if all(e == exposures[0] for e in exposures):
            lits = expose(dec, resolved, exposures[0])
        else:
            lits = np.stack([expose(dec, one[None], e)[0] for one, e in zip(resolved, exposures, strict=True)])
        bg = parse_background(background)
        backdrop = backdrop_of(dec, bg)
        relit = self._network.relit(dec, lits, batch_size, want_layers=self._detail)
        for lit, outputs in zip(lits, relit, strict=True):
            yield self._composer.compose(dec, lit, outputs, backdrop, clean=bg.kind != "original", grade=bg.graded)
