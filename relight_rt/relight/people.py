"""A group photo relit person by person (``PartsMatter`` keeps each person's share of the matte, ``window`` is where
a person is decomposed, ``by_person`` relights with them)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..image.compositing import Background, clean_edge_colour
from ..image.regions import Crop
from ..light.exposure import knee
from . import compose
from .decomposition import Decomposition
from .kept_rim import with_kept_rim
from .look import dark_colour

MAX_PEOPLE = 16  # matting="all": a photo of more people than this is relit as one group (stage 1 once a person)
_ROWS = 256  # rows of the photo done at a time where a temporary would otherwise be the photo's size
_LIGHTS_BYTES = 1 << 28  # a group photo relit under several lights: at most this many bytes of pictures held at once
_PART_MARGIN = 0.1  # a person of a group is decomposed in their share's box grown by this x its size on each side



class PartsMatter:
    """A Matter that keeps each person's share of the matte it returns: a group photo, relit person by person
    (``by_person``). ``found``: one ((y0, y1, x0, x1), share) per person, the share held only inside its box
    (``PersonMatter.part_crops``): a 16-person photo then holds about one photo of shares, not 16."""

    def __init__(self, matter):
        self.matter, self.found = matter, None

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray:
        if hasattr(self.matter, "part_crops"):
            alpha, self.found = self.matter.part_crops(rgb, name)
        else:  # a matter with whole-photo parts only: each cut to where it is not 0
            alpha, parts = self.matter.parts(rgb, name)
            self.found = [cropped(p) for p in parts]
        self.found = folded(self.found)
        return alpha


def folded(crops: list[Crop]) -> list[Crop]:
    """``crops`` (PartsMatter.found) with each person whose share never reaches half folded into the person whose
    share overlaps theirs most (the largest where none does): stage 1 takes a person where their mask is >= 0.5, and
    such a share was refused as an empty mask, failing the whole photo (people_masks p229, split between two
    people). The shares still sum to the matte; all of them weak: one share, the whole group relit as one."""
    strong = [c for c in crops if c[1].size and c[1].max() >= 0.5]
    weak = [c for c in crops if c[1].size and 0 < c[1].max() < 0.5]
    if not weak:
        return crops
    if not strong:
        merged = weak[0]
        for crop in weak[1:]:
            merged = _merged(merged, crop)
        return [merged]
    for crop in weak:
        overlaps = [_overlap(crop, other) for other in strong]
        best = int(np.argmax(overlaps)) if max(overlaps) > 0 else int(np.argmax([c[1].sum() for c in strong]))
        strong[best] = _merged(strong[best], crop)
    return strong


def _overlap(a: Crop, b: Crop) -> float:
    """How much two people's shares overlap: the sum of the smaller of the two where both boxes meet."""
    (ay0, ay1, ax0, ax1), sa = a
    (by0, by1, bx0, bx1), sb = b
    y0, y1, x0, x1 = max(ay0, by0), min(ay1, by1), max(ax0, bx0), min(ax1, bx1)
    if y1 <= y0 or x1 <= x0:
        return 0.0
    return float(np.minimum(sa[y0 - ay0 : y1 - ay0, x0 - ax0 : x1 - ax0],
                            sb[y0 - by0 : y1 - by0, x0 - bx0 : x1 - bx0]).sum())


def _merged(a: Crop, b: Crop) -> Crop:
    """Two shares as one, in the box holding both."""
    (ay0, ay1, ax0, ax1), sa = a
    (by0, by1, bx0, bx1), sb = b
    y0, y1, x0, x1 = min(ay0, by0), max(ay1, by1), min(ax0, bx0), max(ax1, bx1)
    out = np.zeros((y1 - y0, x1 - x0), np.float32)
    out[ay0 - y0 : ay1 - y0, ax0 - x0 : ax1 - x0] += sa
    out[by0 - y0 : by1 - y0, bx0 - x0 : bx1 - x0] += sb
    return (y0, y1, x0, x1), out


def cropped(a: np.ndarray) -> Crop:
    """((y0, y1, x0, x1), a[y0:y1, x0:x1]): the box holding every pixel of ``a`` (H, W) that is not 0."""
    rows, cols = np.flatnonzero(a.any(axis=1)), np.flatnonzero(a.any(axis=0))
    if rows.size == 0:
        return (0, 0, 0, 0), a[:0, :0]
    y0, y1, x0, x1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    return (y0, y1, x0, x1), np.ascontiguousarray(a[y0:y1, x0:x1])


def window(box: tuple[int, int, int, int], frame: tuple[int, int]) -> tuple[int, int, int, int]:
    """The window (y0, y1, x0, x1) of the photo a person of a group is decomposed in: their share's ``box`` grown
    by _PART_MARGIN of its size and 16 px on each side (the crop's 5 px, the head pass's box and the face
    detector's look around the person stay inside, as on the whole photo), within the ``frame`` (H, W)."""
    y0, y1, x0, x1 = box
    my, mx = int(_PART_MARGIN * (y1 - y0)) + 16, int(_PART_MARGIN * (x1 - x0)) + 16
    return max(y0 - my, 0), min(y1 + my, frame[0]), max(x0 - mx, 0), min(x1 + mx, frame[1])


def windows(image: np.ndarray, crops: list[Crop]) -> list[tuple[np.ndarray, np.ndarray, tuple[int, int]]]:
    """Per person of a group photo ``image`` (H, W, 3, read-only): (their window of it, a view; their share of the
    matte there, from ``crops``, PartsMatter.found; the window's (y, x) in the photo). A person then holds arrays
    of their window's size, not the photo's (16 people on 25 MP held 16 photo-size masks and more: 5.9 GB; issue
    50 bug 1)."""
    out = []
    for (y0, y1, x0, x1), share in crops:
        if not share.any():  # no one's share: nothing of theirs to relight
            continue
        wy0, wy1, wx0, wx1 = window((y0, y1, x0, x1), image.shape[:2])
        mask = np.zeros((wy1 - wy0, wx1 - wx0), np.float32)
        mask[y0 - wy0 : y1 - wy0, x0 - wx0 : x1 - wx0] = share
        out.append((image[wy0:wy1, wx0:wx1], mask, (wy0, wx0)))
    return out


def colours_in_group(part: Decomposition, group_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A group's person's own colour and the colour behind their soft edge (``Decomposition.foreground``) from the
    group's matte ``group_mask`` (H, W) in their box, not their share of it: where two people meet neither is
    background."""
    y0, y1, x0, x1 = part.geometry.box
    oy, ox = part.origin
    return compose.colours_of(part.geometry.crop(part.image), group_mask[y0 + oy : y1 + oy, x0 + ox : x1 + ox],
                              part.photo)


def with_shown_edge(factor, dec: Decomposition, parts: list[Decomposition]) -> Decomposition:
    """The group ``dec`` (its matte always the automatic one: ``PartsMatter``) with its people ``parts``, each with
    their own colour from the group's matte (``colours_in_group``), and the group's soft edge as the photo shows it
    (``compose.shown_edge`` on the group's matte, once, a band of rows at a time: ``compose.shown_edge_bands``, so
    that no temporary of that rule is the photo's size; where two people meet the matte is solid and nothing moves):
    ``dec.edge``, each person's colour behind their soft edge then the one behind that edge (the one
    ``colours_in_group`` found is let go as soon as it is found). The group's own colour there is the people's,
    weighted by their shares (as ``by_person_lights`` adds them up), so that the photo's own light gives the photo
    back where two people's soft edges overlap too. ``factor``: the Relighter's (``derive``). A hard matte gives
    ``dec`` with ``parts`` and their colours (the photo) as they are."""
    geom = dec.geometry
    y0, y1, x0, x1 = geom.box
    alpha = geom.crop(dec.mask)
    own, hard = [], []
    for part in parts:
        fg, behind = colours_in_group(part, dec.mask)
        own.append(fg)
        hard.append(behind is fg)  # no soft pixel in their box: the photo both
        del behind
    if all(hard):  # no soft edge anywhere
        return factor.derive(dec, people=tuple(factor.derive(part, foreground=(fg, fg))
                                               for part, fg in zip(parts, own, strict=True)))
    image = geom.crop(dec.image)  # a view: the rule runs a band of rows at a time (compose.shown_edge_bands)
    boxes = [_boxes(part, geom.box) for part in parts]

    def own_colour(a: int, b: int) -> np.ndarray:
        """The people's own colours weighted by their shares in rows a to b of the group's box; the photo where no
        one's share reaches."""
        fg = np.zeros((b - a, x1 - x0, 3), np.float32)
        weight = np.zeros((b - a, x1 - x0, 1), np.float32)
        for part, colour, ((py0, _, px0, _), (cy0, cy1, cx0, cx1)) in zip(parts, own, boxes, strict=True):
            r0, r1 = max(cy0, y0 + a), min(cy1, y0 + b)
            if r1 > r0 and cx1 > cx0:
                inner = (slice(r0 - py0, r1 - py0), slice(cx0 - px0, cx1 - px0))
                share = part.geometry.crop(part.mask)[inner][..., None]
                fg[r0 - y0 - a : r1 - y0 - a, cx0 - x0 : cx1 - x0] += share * colour[inner]
                weight[r0 - y0 - a : r1 - y0 - a, cx0 - x0 : cx1 - x0] += share
        return np.where(weight > 0, fg / np.maximum(weight, 1e-12), image[a:b])

    # each person's colour behind: the group's in their box, the photo beyond it
    theirs = [np.array(part.geometry.crop(part.image), dtype=np.float32) for part in parts]
    shown = np.empty(alpha.shape, np.float32)
    for a, b, edge, behind in compose.shown_edge_bands(image, alpha, own_colour):
        shown[a:b] = edge
        for mine, ((py0, _, px0, _), (cy0, cy1, cx0, cx1)) in zip(theirs, boxes, strict=True):
            r0, r1 = max(cy0, y0 + a), min(cy1, y0 + b)
            if r1 > r0 and cx1 > cx0:
                mine[r0 - py0 : r1 - py0, cx0 - px0 : cx1 - px0] = behind[r0 - y0 - a : r1 - y0 - a,
                                                                         cx0 - x0 : cx1 - x0]
    out = [factor.derive(part, foreground=(fg, behind)) for part, fg, behind in zip(parts, own, theirs, strict=True)]
    return factor.derive(dec, people=tuple(out), edge=shown)


def _boxes(part: Decomposition, box: tuple[int, int, int, int]) -> tuple[tuple, tuple]:
    """A group's person's crop box in the photo (y0, y1, x0, x1), and its part within the group's crop ``box``."""
    oy, ox = part.origin
    by0, by1, bx0, bx1 = part.geometry.box  # in the part's window
    py0, py1, px0, px1 = by0 + oy, by1 + oy, bx0 + ox, bx1 + ox
    y0, y1, x0, x1 = box
    return (py0, py1, px0, px1), (max(py0, y0), min(py1, y1), max(px0, x0), min(px1, x1))


def by_person(
    composer: compose.Composer, network_relit: Callable, dec: Decomposition, parts: tuple[Decomposition, ...],
    light: np.ndarray, exposure, bg: Background, keep: bool = True,
) -> np.ndarray:
    """A group photo relit person by person: each of ``parts`` (the people of ``dec``, each decomposed on their
    own with their share of its matte, in a window of the photo at their ``origin``: their own shape, their face
    seen at their size, their own light and exposure; ``light`` reaches each with their light's deviation from the
    group's, ``reaching``, so the group's own light gives the photo back) gives the person's relit colour; the
    colours, weighted by the shares (which sum to the matte, so where people overlap their changes blend), go over
    the backdrop with the group's matte (over its own photo: the matte's soft edge as the photo shows it,
    ``dec.edge``, the shares scaled to sum to it, ``with_shown_edge``). The person's own colour and the colour behind
    the soft edge are their ``foreground``, taken from the group's matte in their box (``colours_in_group``: where
    two people meet neither is background).

    Memory (issue 50 bug 1): every array a person holds is their box's or their window's, the group holds only its
    crop box's shown edge, and the people's weighted colours are added into the output as they come.

    ``composer``: the Relighter's; ``network_relit``: its stage-2 pass (a decomposition, lights (K, 9, 3), a batch
    size and ``want_layers`` -> (diffuse, residual, relit) per light, as ``Relighter`` runs it); ``keep``: as for
    ``by_person_lights``.
    """
    return by_person_lights(composer, network_relit, dec, parts, np.asarray(light)[None], [exposure], bg, keep)[0]


def reaching(lights: np.ndarray, part: Decomposition, dec: Decomposition) -> np.ndarray:
    """The lights (K, 9, 3) or (9, 3) that reach ``part``, a person of the group ``dec``, when ``lights`` are asked
    for: each plus the person's own light's deviation from the group's (both taken as white, the lights the photo
    is divided by), scaled per colour by the light's degree-0 coefficient over the group's. Each person keeps the
    light fitted to them (their shading, exposure and colours derived from it) and the group's own light reaches
    each of them as their own, so it gives the group's photo back; under a new light a person lit more from one
    side than the group keeps that much more from that side, in the new light's strength and colour. A group light
    of no strength (degree 0 <= 0) or a light with none in a colour adds no deviation there.

    One light for the whole group instead (each person's replaced by the group's, or by one refit over all their
    pixels) gives the photo back too, but explains each person's pixels less well than their own refit, and under
    new lights people who stood in one light drifted further apart in brightness (benchmarks/group_own_light.py,
    31 group photos, 12 lights: 0.30 EV between two people on average against 0.20 here, 0.21 before)."""
    group = dec.white_light
    if not group[0, 0] > 1e-6:
        return np.asarray(lights, np.float32)
    lights = np.asarray(lights, np.float32)
    scale = np.maximum(lights[..., :1, :], 0) / group[0, 0]  # (..., 1, 3): per colour, the light over the group's
    return (lights + scale * (part.white_light - group)).astype(np.float32)


def lights_at_once(frame: tuple[int, int], channels: int, most: int) -> int:
    """How many lights ``by_person_lights`` takes together for a group photo of ``frame`` (H, W): up to ``most``,
    as many pictures as ``_LIGHTS_BYTES`` holds (a 25-MP group: one at a time)."""
    return max(1, min(most, _LIGHTS_BYTES // max(frame[0] * frame[1] * channels * 4, 1)))


def by_person_lights(
    composer: compose.Composer, network_relit: Callable, dec: Decomposition, parts: tuple[Decomposition, ...],
    lights: np.ndarray, exposures: list, bg: Background, keep: bool = True,
) -> list[np.ndarray]:
    """``by_person`` under each of the (K, 9, 3) ``lights`` with its exposure: person by person, what a person's
    relit colour needs whatever the light (their own colour's ``dark_colour``, ``knee`` and ``neutral_darks``, the
    full-resolution guide) made once for the K lights and let go before the next person; the K pictures are held
    together (``lights_at_once`` says how many a photo's size allows). ``keep``: the rest of what each person's
    relight keeps for the next call (their fine texture, shadow fill, own light's reconstruction: the Relighter's
    memo) is kept; False (a group decomposed for this call alone, relit once): let go after the person too (16
    people on 25 MP kept ~0.2 GB of it to the end)."""
    memo, factor = composer.memo, composer.factor
    backdrop = compose.backdrop_of(dec, bg)
    clean = bg.kind != "original"
    y0, y1, x0, x1 = dec.geometry.box
    alpha = dec.geometry.crop(dec.mask)[..., None]
    cover, scaled = alpha, False  # what the backdrop shows through; whether the people's shares are scaled to it
    if backdrop is not None and not clean and dec.edge is not None:  # the group's edge as the photo shows it
        cover, scaled = dec.edge[..., None], True  # (``with_shown_edge``): the shares scaled to sum to it
    if backdrop is None:  # RGBA, straight colour: the weighted colours summed here, divided by alpha below
        out = np.zeros(dec.geometry.frame + (4,), np.float32)
        region = out[y0:y1, x0:x1, :3]
    else:
        out = np.array(backdrop, np.float32)
        region = out[y0:y1, x0:x1]
        for r in range(0, y1 - y0, _ROWS):  # what shows through the soft edge; the people's colours are added to
            region[r : r + _ROWS] *= 1 - cover[r : r + _ROWS]  # it (in bands: 1 - alpha is the photo's size)
    graded = backdrop is not None and bg.graded
    # the group's matte as the photo shows it (``with_shown_edge``): the kept rim's background is what it leaves
    shown = compose.shown_mask(dec) if backdrop is not None and not clean else None
    people = []
    for part in parts:
        (py0, _, px0, _), (cy0, cy1, cx0, cx1) = _boxes(part, dec.geometry.box)
        if cy1 <= cy0 or cx1 <= cx0:
            continue
        fg, behind = composer.foreground(part)
        if backdrop is not None and not clean and behind is not fg:  # the colour behind the soft edge shows
            inner = (slice(cy0 - py0, cy1 - py0), slice(cx0 - px0, cx1 - px0))
            a = cover[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0]
            region[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] = behind[inner] * (1 - a)
        people.append((part, (cy0, cy1, cx0, cx1), (py0, px0)))
    outs = [out] + [out.copy() for _ in range(len(lights) - 1)]  # one picture per light, the backdrop in each
    regions = [o[y0:y1, x0:x1, :3] if backdrop is None else o[y0:y1, x0:x1] for o in outs]
    if graded:  # what shows of the backdrop in the box, graded once the people's change is known
        under = region.copy()
        sums = [[np.zeros(3), np.zeros(3), 0.0] for _ in outs]
    for part, (cy0, cy1, cx0, cx1), (py0, px0) in people:
        looks = None
        if composer.detail:  # made once per person for the K lights, not kept for every person
            fg = composer.foreground(part)[0]
            looks = dark_colour(fg), knee(fg), compose.person_neutral(part, factor.beard(part))  # as one alone
        share = part.geometry.crop(part.mask)[..., None]
        to_cover = None  # the shares' scale to the shown edge in the person's box (the group's box: the photo's size)
        if scaled:
            box = (slice(cy0 - y0, cy1 - y0), slice(cx0 - x0, cx1 - x0))
            to_cover = np.divide(cover[box], alpha[box], out=np.ones_like(cover[box]), where=alpha[box] > 0)
        for k, (light, exposure) in enumerate(zip(lights, exposures, strict=True)):
            lit = factor.meter.expose(part, reaching(light, part, dec)[None], exposure)[0]
            _, residual, relit = next(network_relit(part, lit[None], 1, want_layers=composer.detail))
            colour = composer.person_colour(part, lit, residual, relit, looks)
            if scaled and part.photo:  # the kept background's light on their edge (the automatic matte's),
                # its background what no one covers (relight_rt.relight.kept_rim)
                colour = with_kept_rim(colour, composer.kept_rim(part, shown[py0 : py0 + colour.shape[0],
                                                                            px0 : px0 + colour.shape[1]]), copy=False)
            if clean and not composer.detail:
                colour = clean_edge_colour(colour, np.ascontiguousarray(part.geometry.crop(part.image)),
                                           composer.foreground(part, always=True)[0], share[..., 0])
            if graded:  # the person's change in light, over their share (people add up to the group's)
                old, weight = composer.own_light(part)  # found once per person, whatever the light
                sums[k] = [sums[k][0] + compose.light_sum(colour, share), sums[k][1] + old, sums[k][2] + weight]
            colour *= share
            if to_cover is not None:
                colour[cy0 - py0 : cy1 - py0, cx0 - px0 : cx1 - px0] *= to_cover
            regions[k][cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] += colour[cy0 - py0 : cy1 - py0,
                                                                           cx0 - px0 : cx1 - px0]
            del colour, residual, relit
        del looks, to_cover
        for one in (part, part.head):  # the guide is remade per call, never kept for every person (issue 50 bug 1)
            if one is not None and keep:
                memo(one).pop("gray", None)
            elif one is not None:
                memo(one).clear()
    for k, out in enumerate(outs):
        region = regions[k]
        if backdrop is None:
            np.divide(region, alpha, out=region, where=alpha > 0)
            out[..., 3] = dec.mask
        elif graded:  # the group's change, summed over the people (relight_rt.image.compositing's grade)
            gain = compose.grade_of_sums(*sums[k])
            region += under * (gain - 1)  # the backdrop's share of the box, and everything outside it
            for band in (out[:y0], out[y1:], out[y0:y1, :x0], out[y0:y1, x1:]):
                band *= gain
        np.clip(out, 0, 1, out=out)
    return outs
