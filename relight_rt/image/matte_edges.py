"""Edge refinement of a coarse person matte at the photo's own resolution, in a band around its outline.

The coarse matte (the segmentation graphs' 256² output, upsampled and guided-filtered) gets the outline's
place right but its soft part wrong: a smear several pixels wide that follows no strand of hair. In a band
around the coarse outline, each pixel's alpha is re-estimated from colour: the person's colour F and the
background's colour B near the pixel are the means of the photo over the sure-foreground and the
sure-background pixels of a window around it (box filters: fast at any size), and alpha is where the
pixel's colour lies on the line from B to F (the colour-line model of Levin et al.'s closed-form matting,
solved per pixel with F and B held fixed):

    alpha_c = clip(((I - B) . (F - B)) / (|F - B|^2 + eps), 0, 1)

Where F and B are alike (a dark coat before a dark doorway) colour says nothing: the estimate is blended
with the coarse alpha by a confidence |F - B|^2 / (|F - B|^2 + tau), which falls further where the pixel's colour
lies off the line from B to F (a third colour: a belt, a bag, a shadow, texture; mixing B and F does not make it, so
where it lies along the line says nothing), except where colour clearly says plain background (alpha 0: the coarse
matte's soft rim past the outline, :func:`_colour_alpha`). A small guided filter
(the photo as guide) then removes pixel noise while keeping strands. On the background's side of the outline the
estimate is held under a ceiling that falls smoothly from 1 at the outline to the coarse alpha at the band's outer
edge: a light patch of background that colour puts between B and F (a white awning beside dark hair on the reference
photo) then fades out instead of ending in the band's straight edge. Outside the band the coarse matte is kept, except
that a faint veil (alpha < 0.2 on the background side, > 0.8 on the person's; < 0.05 / > 0.95 anywhere
away from the outline) is snapped to 0 / 1: composited, it would show the old background. A body that runs out
of the photo's bottom border is made opaque there, away from its outline, under the part the graphs are sure of
(:func:`opaque_where_cut`). For one person's matte, a separate part that the graphs are nowhere sure of, away
from the rest, is dropped after (:func:`without_doubted_parts`).

Inside the person, further from the outline than the band, the graphs sometimes half-see a gap: a sliver of
backdrop between an arm and the body that they leave at alpha 0.4-0.9. Such pixels get colour's answer too
(:func:`_open_gap`), with the background's colour taken from further away (the backdrop beyond the arm): a gap
of background colour opens, and a half-held patch of another colour is the person's (opaque). A gap whose middle the
coarse matte puts under 0.5 is such a pocket too (the interior is taken with its holes filled, :func:`_deep_inside`).
"""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np

from .guided_filter import fast_guided_filter

_SURE = 0.95  # coarse alpha above this (after erosion) is sure foreground, below 1 - this sure background
_SNAP = 0.05  # ... and away from the outline, alpha below this is 0, above 1 - this 1
_VEIL = 0.2  # more than the band's width from the outline, alpha below this is 0 (above 1 - this: 1)
_BAND_FRAC = 0.008  # half-width of the band, as a fraction of the photo's longer side (16 px at 2000 px) ...
_BAND_MIN = 3  # ... at least this many pixels
_EPS = 1e-4
_TAU = 0.3  # |F - B|^2 at which colour and the coarse matte count equally (benchmarks/matting_eval.py)
_OFF_LINE = 0.1  # colour's weight falls as exp(-d^2 / (this x |F - B|^2)), d the pixel's distance from the line B..F
_CLEAR = 0.01  # a pixel within sqrt(this) x |F - B| of the background's colour B is plain background ...
_CLEAR_MIN = 0.02  # ... where |F - B|^2 is at least this (person and background told apart by colour)
_CLEAR_BELOW = 0.9  # ... in the coarse matte's soft part (coarse alpha below this: not its sure interior)
_GF_RADIUS = 1
_GF_EPS = 1e-3
_CUT_REACH = 0.2  # a body cut by the bottom border is made opaque up to this x the photo's height above it
_CUT_SURE = 0.95  # ... in the columns where the matte is at least this at or above the pixel
_FADED = 0.25  # ... where the bottom row's alpha is at least this (the graphs' answer fading toward the border)
_CUT_INSIDE = 0.4  # ... and where alpha is at least this in a colour not the backdrop's (a pale shirt half-seen)
_GAP = 0.9  # beyond the band inside the outline, coarse alpha below this is a gap the graphs half-see ...
_ENCLOSED = 0.7  # ... in a pocket whose rim is at least this share the person's interior (not a soft outline) ...
_GAP_REACH = 4  # ... whose background colour is the sure background's within this x the band's width (2x where none)
_GAP_MATCH = 0.03  # ... opens where a pixel's colour lies within this squared distance of that background colour
_RIM_MATCH = 0.25  # ... unless its rim is that colour too and the pocket nearer its rim than this x (squared) it
_PART_SURE = 0.7  # a separate part of the matte under this everywhere is dropped (largest kept) ...
_PART_APART = 5  # ... where it lies more than this x the band's width from the parts kept
_MAX_POCKETS = 64  # the largest this many pockets of one matte are decided (real photos and the clip: at most 12; a
# matte riddled with 2,600 pockets took 12 s a megapixel, each pocket a window of the photo: fuzz8) ...
_POCKET_SPAN = 1.0  # ... while their bounding boxes add up to at most this x the area searched (64 diagonal lines
# across a megapixel matte, each a pocket as wide as the photo: 6 s)


def band_width(shape: tuple[int, int]) -> int:
    """Half-width in pixels of the band refined around the outline of an (h, w) photo's matte."""
    return max(_BAND_MIN, int(round(_BAND_FRAC * max(shape))))


def _box(x: np.ndarray, r: int) -> np.ndarray:
    return cv2.boxFilter(x, -1, (2 * r + 1, 2 * r + 1), normalize=False, borderType=cv2.BORDER_CONSTANT)


def refine_edges(rgb: np.ndarray, alpha: np.ndarray, band: int | None = None) -> np.ndarray:
    """Refine a soft matte in a band around its outline (module docstring).

    Args:
        rgb: (H, W, 3) float32 RGB in [0, 1].
        alpha: (H, W) float32 coarse matte in [0, 1].
        band: half-width of the band in pixels (default :func:`band_width`).

    Returns:
        New (H, W) float32 alpha in [0, 1]; outside the band ``alpha`` snapped to 0 / 1 where faint.
    """
    h, w = alpha.shape
    r = band_width((h, w)) if band is None else int(band)
    out = alpha.copy()
    # away from the outline the matte is snapped: a faint veil of the segmentation over the background
    # (or a faint hole in the person) would carry the old background into any composite
    out[out < _SNAP] = 0.0
    out[out > 1 - _SNAP] = 1.0
    edge = (alpha > _SNAP) & (alpha < 1 - _SNAP)
    m = 3 * r + 2  # work on the outlines' bounding boxes only (plus the windows' reach)
    for box in _outline_boxes(edge, m):
        _refine_box(rgb, alpha, out, box, r)
    return opaque_where_cut(out, r, rgb)


def open_pockets(rgb: np.ndarray, alpha: np.ndarray, band: int | None = None) -> np.ndarray:
    """:func:`refine_edges`' pocket decision alone, for a matte not refined here (the video matter's guided filter):
    a pocket the matte half-holds (alpha under _GAP more than ``band`` from the outline once the interior's holes are
    filled, its rim mostly the person) opens where it shows the backdrop's colour and is opaque where it shows any
    other (:func:`_open_gap`). ``VideoMatter`` runs it on every frame (``pockets``; with ``complete``, ``backed_logits``
    leaves such a gap in doubt, ~0.8, for this decision to settle). ``rgb``: (H, W, 3) float32 RGB in [0, 1], as for
    :func:`refine_edges`. Returns a new (H, W) float32 alpha."""
    r = band_width(alpha.shape) if band is None else int(band)
    out = alpha.copy()
    bx, by, bw, bh = cv2.boundingRect((alpha >= 0.5).view(np.uint8))
    if bw == 0:
        return out
    # pockets lie inside the matte: looked for on its bounding box and one pixel of outside round it (a third of a
    # 720p frame's pixels on the reference video)
    y0, y1 = max(by - 1, 0), min(by + bh + 1, alpha.shape[0])
    x0, x1 = max(bx - 1, 0), min(bx + bw + 1, alpha.shape[1])
    a = alpha[y0:y1, x0:x1]
    for (py, px), pocket in _pockets(a < _GAP, _deep_inside((a >= 0.5).astype(np.uint8), r), min_area=r):
        _open_gap(rgb, alpha, out, pocket, (y0 + py, x0 + px), r)
    return out


def without_doubted_parts(alpha: np.ndarray, r: int) -> np.ndarray:
    """``alpha`` without the separate parts of the matte (8-connected, alpha >= 0.5) that the graphs are nowhere
    sure of (alpha under _PART_SURE throughout), the largest part kept whatever it holds; their soft rim within ``r``
    goes with them. The selfie graph on a small portrait's own square half-sees the blurred garden behind her
    (blobs at 0.5-0.7 apart from her); a part of the person seen apart (the runner's hand beyond the railing) is
    sure somewhere, and a doubted part within _PART_APART x ``r`` of the parts kept is theirs (a strand of hair:
    dropped, the reference photo's soft band lost 0.230 -> 0.237). Measured (benchmarks/people_masks_eval.py;
    _PART_SURE chosen on photos half A among 0.6-0.9 before the distance test: +0.0004, +0.0011, +0.0012, +0.0011,
    0.7 where the clip stays; _PART_APART 2, 3, 5: half A +0.0011 each, 5 the one with no image worse on any set):
    half A 0.9168 -> 0.9178, half B 0.8900 -> 0.8902, the clip unchanged, no image worse (the small portrait's
    garden 0.80 -> 0.90); the reference photo's IoU, boundary F and soft-band error unchanged (0.9727, 0.9937,
    0.230). ~5 ms on a 2.5-MP matte of one part, ~14 ms on the reference photo's (17 parts, strands near the hair). In
    place; returns ``alpha``."""
    n, labels = cv2.connectedComponents((alpha >= 0.5).astype(np.uint8), connectivity=8)  # (4x ...WithStats' speed)
    if n <= 2:
        return alpha
    big = 1 + int(np.bincount(labels.ravel(), minlength=n)[1:].argmax())
    ys, xs = np.nonzero((labels > 0) & (labels != big))  # the other parts' pixels: few, read on their own
    of = labels[ys, xs]
    keep = np.bincount(of[alpha[ys, xs] >= _PART_SURE], minlength=n) > 0
    keep[[0, big]] = True
    doubted = ~keep[of]
    if not doubted.any():
        return alpha
    # each doubted part on its own box, reaching _PART_APART x r past it (the parts kept beyond are farther)
    ys, xs, of = ys[doubted], xs[doubted], of[doubted]
    reach = int(np.ceil(_PART_APART * r))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    for label in np.unique(of):
        py, px = ys[of == label], xs[of == label]
        y0, x0 = max(int(py.min()) - reach, 0), max(int(px.min()) - reach, 0)
        y1, x1 = int(py.max()) + reach + 1, int(px.max()) + reach + 1
        box = labels[y0:y1, x0:x1]
        part = box == label
        kept = keep[box] & (box > 0)
        # near the parts kept, a doubted part is a strand of their hair or a fold of their clothes seen apart
        if kept.any() and cv2.distanceTransform((~kept).astype(np.uint8), cv2.DIST_L2, 3)[part].min() <= reach:
            continue
        a = alpha[y0:y1, x0:x1]
        a[part | (cv2.dilate(part.astype(np.uint8), disc).astype(bool) & (a < 0.5))] = 0.0
    return alpha


def _outline_boxes(edge: np.ndarray, margin: int) -> list[tuple[int, int, int, int]]:
    """(y0, y1, x0, x1) boxes that hold every pixel of ``edge`` with ``margin`` around it: one per group of outlines
    whose boxes meet (a group photo's people apart: their own boxes, not one box round all of them, which cost 16
    people on 25 MP 2.4 GB of temporaries; issue 50 bug 1)."""
    rows, cols = np.flatnonzero(edge.any(axis=1)), np.flatnonzero(edge.any(axis=0))
    if rows.size == 0:
        return []
    # labelled inside the edge's bounding box first (a portrait's outline leaves most of the photo out): the same
    # components, so the same groups; where there are several groups, their order (which box is refined last where
    # two overlap) is OpenCV's labels' over the whole photo, as it always was
    ey, ex = int(rows[0]), int(cols[0])
    inner = edge[ey : int(rows[-1]) + 1, ex : int(cols[-1]) + 1].astype(np.uint8)
    boxes = _grouped(cv2.connectedComponentsWithStats(inner, connectivity=8)[2], (ey, ex), edge.shape, margin)
    if len(boxes) > 1:
        boxes = _grouped(cv2.connectedComponentsWithStats(edge.astype(np.uint8), connectivity=8)[2], (0, 0),
                         edge.shape, margin)
    return boxes


def _grouped(stats: np.ndarray, at: tuple[int, int], shape: tuple[int, int], margin: int
             ) -> list[tuple[int, int, int, int]]:
    """``_outline_boxes`` from OpenCV's component stats of the part of the photo whose top left is ``at``."""
    h, w = shape
    ey, ex = at
    grown = [(max(ey + y - margin, 0), min(ey + y + bh + margin, h), max(ex + x - margin, 0),
              min(ex + x + bw + margin, w)) for x, y, bw, bh, _ in stats[1:]]  # fmt: skip
    cell = 16  # the grown boxes are drawn on a grid of this many pixels: those that touch there are one group
    coarse = np.zeros((-(-h // cell), -(-w // cell)), np.uint8)
    for y0, y1, x0, x1 in grown:
        coarse[y0 // cell : -(-y1 // cell), x0 // cell : -(-x1 // cell)] = 1
    _, labels = cv2.connectedComponents(coarse, connectivity=8)
    groups: dict[int, tuple[int, int, int, int]] = {}
    for y0, y1, x0, x1 in grown:  # each group's box: its outlines' bounding box and the margin, exactly
        key = int(labels[y0 // cell, x0 // cell])
        g = groups.get(key)
        groups[key] = (y0, y1, x0, x1) if g is None else (min(g[0], y0), max(g[1], y1), min(g[2], x0), max(g[3], x1))
    return list(groups.values())


def _refine_box(rgb: np.ndarray, alpha: np.ndarray, out: np.ndarray, box: tuple[int, int, int, int], r: int) -> None:
    """:func:`refine_edges` inside ``box`` (y0, y1, x0, x1), in place on ``out``."""
    y0, y1, x0, x1 = box
    a = np.ascontiguousarray(alpha[y0:y1, x0:x1])
    img = np.ascontiguousarray(rgb[y0:y1, x0:x1])
    inside = (a >= 0.5).astype(np.uint8)
    fg = cv2.distanceTransform(inside, cv2.DIST_L2, 3) > r  # sure: more than r px from the outline
    outside = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    bg = outside > r
    unknown = ~(fg | bg)
    fg_w = (fg & (a >= _SURE)).astype(np.float32)
    bg_w = (bg & (a <= 1 - _SURE)).astype(np.float32)
    # mean colour of the sure pixels in a window of radius 2r (4r where the nearer window holds none)
    b_col, blend, clear = _colour_alpha(img, a, fg_w, bg_w, 2 * r, 2 * r)
    est = _guided(img, blend)
    est[clear] = 0.0  # the guided filter's smear of the person's alpha over plain background
    sub = out[y0:y1, x0:x1]
    # on the background's side, colour's answer fades out toward the band's outer edge (where the coarse matte is
    # sure of background): a light patch of background there would otherwise end in the band's straight edge
    t = np.clip(outside[unknown] / r, 0.0, 1.0)
    ceiling = np.maximum(a[unknown], 1 - t * t * (3 - 2 * t))
    sub[unknown] = np.clip(np.minimum(est[unknown], ceiling), 0.0, 1.0)
    sub[bg & (a < _VEIL)] = 0.0
    sub[fg & (a > 1 - _VEIL)] = 1.0
    for (py, px), pocket in _pockets(a < _GAP, _deep_inside(inside, r), min_area=r):
        _open_gap(rgb, alpha, out, pocket, (y0 + py, x0 + px), r)


def _pockets(low: np.ndarray, interior: np.ndarray, min_area: int) -> Iterator[tuple[tuple[int, int], np.ndarray]]:
    """The connected parts of ``low & interior`` whose rim (the pixels just around them) lies mostly in
    ``interior``: a pocket the person closes around (the slivers between arm and dress: 0.71-1.0 of the rim), not a
    soft stretch along the outline (the soft top of Grace Hopper's dark cap before a dark blue flag: 0.49).
    Pockets under ``min_area`` pixels are left out, and all but the largest _MAX_POCKETS, as long as their boxes
    span _POCKET_SPAN of ``low``'s area. Yields each as ((top, left), mask of its bounding box)."""
    part = (low & interior).astype(np.uint8)
    # labelled on the box that holds them (a tenth of a 720p video frame's matte box), a pixel of nothing round it: the
    # same parts as over the whole
    cx, cy, cw, ch = cv2.boundingRect(part)
    if cw == 0:
        return
    n, labels, stats, _ = cv2.connectedComponentsWithStats(part[cy : cy + ch, cx : cx + cw], connectivity=8)
    labels = np.pad(labels, 1)
    h, w = low.shape
    found, span = 0, 0
    st = stats[1:]  # largest first, ties by place (labels number differently on a box than over the whole)
    for i in 1 + np.lexsort((st[:, cv2.CC_STAT_LEFT] + cx, st[:, cv2.CC_STAT_TOP] + cy, -st[:, cv2.CC_STAT_AREA])):
        x, y, bw, bh, area = (int(v) for v in stats[i])
        if area < min_area or found == _MAX_POCKETS:  # a speck: nothing a composite would show, and each pocket
            break  # costs a window of the photo
        x, y = x + cx, y + cy
        y0, y1, x0, x1 = max(y - 1, 0), min(y + bh + 1, h), max(x - 1, 0), min(x + bw + 1, w)
        comp = labels[y0 - cy + 1 : y1 - cy + 1, x0 - cx + 1 : x1 - cx + 1] == i
        rim = (cv2.dilate(comp.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0) & ~comp
        if rim.any() and interior[y0:y1, x0:x1][rim].mean() >= _ENCLOSED:
            found, span = found + 1, span + bw * bh
            if span > _POCKET_SPAN * h * w:
                break
            yield (y0, x0), comp


def _outside_parts(inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 4-connected parts of the outside of ``inside`` (uint8, 1 inside; label 0 the inside itself) and, per
    label, whether it reaches the box's border (a hole does not): (labels (H, W), outside (n,) bool)."""
    n, labels = cv2.connectedComponents(1 - inside, connectivity=4)
    outside = np.zeros(n, bool)
    outside[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    outside[0] = False
    return labels, outside


def _deep_inside(inside: np.ndarray, r: int) -> np.ndarray:
    """The pixels more than ``r`` from the outline of ``inside`` (uint8, 1 inside) once its holes are filled (the parts
    of its outside that do not reach the box's border). The coarse matte puts the middle of a gap two canvas pixels
    wide under 0.5 (the reference clip's arms and dress: 0.4-0.6 there): a hole, whose own outline left the gap's
    sides out of the interior, so no pocket was found and the gap stayed half-held (alpha 0.5-0.8). Filled, the gap
    is one pocket, its rim the person around it. A real hole (the backdrop in the crook of an arm) is filled too: its
    rim is a pocket whose band-refined edge :func:`_open_gap` leaves as it is."""
    labels, outside = _outside_parts(inside)
    filled = (~outside).astype(np.uint8)  # per label: 1 where a hole (or the inside, label 0)
    return cv2.distanceTransform(filled[labels], cv2.DIST_L2, 3) > r


def _open_gap(rgb: np.ndarray, alpha: np.ndarray, out: np.ndarray, pocket: np.ndarray, at: tuple[int, int], r: int):
    """Colour's alpha for a pocket (a mask whose top left is at ``at`` in the photo): the person's colour from the
    sure foreground around it (radius 2r), the background's from the sure background up to _GAP_REACH x r away,
    where the backdrop shows beyond the limb that closes the pocket. The pocket's pixels near that background colour
    get colour's answer; the rest that the graphs half-hold (>= 0.5), beyond the band of an outline, are the
    person's, opaque (a fold of the person's own colour: kept at the graphs' 0.5-0.9, relit it showed the old photo
    through). The reference video's frames leave the slivers between arm and dress at 0.4-0.9 in the coarse matte
    (_layout.backed_logits leaves them in doubt). In place on ``out``."""
    h, w = alpha.shape
    m = 2 * _GAP_REACH * r + 1
    y0, x0 = max(at[0] - m, 0), max(at[1] - m, 0)
    y1, x1 = min(at[0] + pocket.shape[0] + m, h), min(at[1] + pocket.shape[1] + m, w)
    # views: read where the windows reach, never copied whole (a float64 photo's window as float32, OpenCV's products)
    a, img = alpha[y0:y1, x0:x1], np.asarray(rgb[y0:y1, x0:x1], np.float32)
    inside = (a >= 0.5).astype(np.uint8)
    fg_w = ((cv2.distanceTransform(inside, cv2.DIST_L2, 3) > r) & (a >= _SURE)).astype(np.float32)
    bg_w = ((cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3) > r) & (a <= 1 - _SURE)).astype(np.float32)
    py, px = at[0] - y0, at[1] - x0
    # colour's answer is read on the pocket only: worked out on its box and the rim test's reach round it (r >= the
    # guided filter's 2 px), from the window's sums (the values of the whole window's answer, but for a float32 ulp
    # where the guided filter's running sums round: 6 pixels of 60 random mattes; none on the reference frames;
    # open_pockets on 720p frames ~0.42x the time with the helpers below, benchmarks/video_pockets.py --base)
    cy0, cx0 = max(py - r, 0), max(px - r, 0)
    cy1, cx1 = min(py + pocket.shape[0] + r, a.shape[0]), min(px + pocket.shape[1] + r, a.shape[1])
    b_col, blend, _ = _colour_alpha(img, a, fg_w, bg_w, 2 * r, _GAP_REACH * r, at=(cy0, cy1, cx0, cx1))
    a_c, img_c = a[cy0:cy1, cx0:cx1], img[cy0:cy1, cx0:cx1]
    near_b = _backdrop_coloured(img_c, b_col)
    est = _guided(img_c, np.where(near_b, blend, a_c))
    sel = np.zeros(a_c.shape, bool)
    sel[py - cy0 : py - cy0 + pocket.shape[0], px - cx0 : px - cx0 + pocket.shape[1]] = pocket
    # colour cannot tell it from the person (p236's beige folds); asked only where some of the pocket would open
    if (near_b & sel).any() and _rim_like_backdrop(img_c, a_c, sel, b_col, r):
        near_b = np.zeros_like(near_b)
    into = out[y0 + cy0 : y0 + cy1, x0 + cx0 : x0 + cx1]
    # the person's own colour, which the graphs half-hold; not in the band of a real outline (a hole holding sure
    # background: its soft rim, refined there, made opaque had its error 0.019 -> 0.108 on a blurred 100 x 80 hole)
    held = sel & ~near_b & (a_c >= 0.5)
    if held.any():
        into[held & _beyond_real_outline(inside, a, r, (cy0, cy1, cx0, cx1))] = 1.0
    sel &= near_b
    into[sel] = np.clip(est[sel], 0.0, 1.0)


def _beyond_real_outline(inside: np.ndarray, a: np.ndarray, r: int, at: tuple[int, int, int, int]) -> np.ndarray:
    """The pixels of the box ``at`` (y0, y1, x0, x1) more than ``r`` from the outline of ``inside`` (uint8) where only
    the outside that reaches the border of ``inside`` or holds sure background (``a`` <= 1 - _SURE) counts: a gap's
    under-0.5 middle is filled (its sides are the pocket's, :func:`_deep_inside`), a real hole keeps its band."""
    labels, outside = _outside_parts(inside)
    outside[labels[a <= 1 - _SURE]] = True
    outside[0] = False  # label 0: the inside itself
    # the distance on the box and as far round it as an outside pixel may lie within r: OpenCV's 3x3 chamfer distance
    # is at least 0.955x the chessboard distance, so the answer is the one over the whole of ``inside``
    m = r + r // 8 + 3
    y0, y1, x0, x1 = at
    sy, sx = max(y0 - m, 0), max(x0 - m, 0)
    near = labels[sy : y1 + m, sx : x1 + m]
    far = cv2.distanceTransform((~outside[near]).astype(np.uint8), cv2.DIST_L2, 3) > r
    return far[y0 - sy : y1 - sy, x0 - sx : x1 - sx]


def _rim_like_backdrop(img: np.ndarray, a: np.ndarray, sel: np.ndarray, b_col: np.ndarray, r: int) -> bool:
    """Whether the person around the pocket ``sel`` (the sure pixels, alpha >= _SURE, within ``r`` of it: its rim) wears
    the backdrop's colour itself: their mean colour within _GAP_MATCH (squared) of the backdrop's (``b_col``'s mean over
    the pocket), and the pocket's mean colour is nearer its rim's than _RIM_MATCH x (squared) the backdrop's. There
    the backdrop test passes for the person's own colour too and says nothing: a lighter streak on
    beige trousers before beige pavement (p236) half-opened pixel by pixel (1.0 -> 0.53-0.69). Such a pocket is left
    whole to the graphs, which see a person there; the backdrop seen between arm and dress is a colour apart from its
    rim (the reference video's gaps: 0.45-0.92 squared against 0.002-0.05 for p236's pockets)."""
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    rim = cv2.dilate(sel.astype(np.uint8), disc).astype(bool) & ~sel & (a >= _SURE)
    if not rim.any():
        return False
    p_col, r_col, b_mean = img[sel].mean(axis=0), img[rim].mean(axis=0), b_col[sel].mean(axis=0)
    rb, pr, pb = r_col - b_mean, p_col - r_col, p_col - b_mean
    return float(rb @ rb) < _GAP_MATCH and float(pr @ pr) < _RIM_MATCH * float(pb @ pb)


def opaque_where_cut(alpha: np.ndarray, r: int, rgb: np.ndarray | None = None) -> np.ndarray:
    """``alpha`` with the body that runs out of the photo's bottom border made opaque there: the pixels of the
    matte (alpha >= 0.5) more than ``r`` from its outline (the image border is no outline: the body goes on past
    it), within _CUT_REACH x the height above the bottom border and joined to it through such pixels, set to 1.
    The segmentation graphs are least sure where the frame cuts the body (a patterned shirt, a dark coat):
    DPR's portrait kept its checked shirt at alpha 0.53-0.73 over the bottom right, and a composite showed the
    new background through it. With ``rgb`` (the photo, float RGB), a pixel the graphs leave a little under
    0.5 (down to _CUT_INSIDE) counts as body too where its colour is not the backdrop's (beyond _GAP_MATCH of
    the sure background's mean within _GAP_REACH x r; anywhere no sure background is that near): the same
    portrait's pale blue collar sat at 0.47-0.52 in a patch the outline went round, and relit it stayed a pale
    blob, while a ring of red backdrop at 0.4-0.5 around a gap between arm and body must stay soft. Only pixels
    with a sure one (alpha >= _CUT_SURE) at or above them in their column count: a blurred backdrop the graphs
    half-see (0.5-0.7) where the border cuts it, joined to the body's side, was made opaque up to the reach (a
    small portrait: a block of garden beside her shoulders; people_masks photos half A 0.9161 -> 0.9167, B
    0.8881 -> 0.8881, the clip unchanged; 13 photos better (the portrait 0.746 -> 0.799, a blurred backdrop at the
    bottom +0.009), 7 worse (a dark jacket with nothing sure above it -0.008)). The outline's band keeps its soft
    alpha. In place; returns ``alpha``."""
    h, w = alpha.shape
    n = min(max(int(round(_CUT_REACH * h)), r + 2), h)
    low = alpha[h - n :]
    inside = low >= 0.5
    unsure = (low >= _CUT_INSIDE) & ~inside
    if rgb is not None and unsure.any():
        img = rgb[h - n :]
        reach = _GAP_REACH * r
        # the backdrop's mean over windows this wide is smooth: measured at 1/s of the size (s x s blocks,
        # area-averaged; counts in blocks' shares), read back by linear interpolation
        s = max(1, reach // 8)
        size = (max(w // s, 1), max(n // s, 1))
        small = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
        sure = cv2.resize((low <= 1 - _SURE).astype(np.float32), size, interpolation=cv2.INTER_AREA)
        b_col, b_n = _side_mean(small, sure, max(reach // s, 1))
        b_col = cv2.resize(b_col, (w, n), interpolation=cv2.INTER_LINEAR)
        b_n = cv2.resize(b_n, (w, n), interpolation=cv2.INTER_LINEAR)
        uy, ux = np.nonzero(unsure)
        far = ~_backdrop_coloured(img[uy, ux], b_col[uy, ux]) | (b_n[uy, ux] < 0.5 / (s * s))
        inside[uy[far], ux[far]] = True
    # only under the body the graphs are sure of: a doubted blob the border cuts, with nothing sure above it in its
    # columns, is the backdrop the graphs half-see (a small portrait's blurred garden), not a body leaving the frame
    inside &= (alpha[: h - n] >= _CUT_SURE).any(axis=0) | np.logical_or.accumulate(low >= _CUT_SURE, axis=0)
    inside = inside.astype(np.uint8)
    # the graphs' answer fades toward the border (zidane's coat: 0.85 -> 0.45 over the last 14 rows), which
    # would put an outline along it: over the last rows the body is taken to be where it is just above them,
    # in the columns where the border row still holds some of it (not below feet that end above the border)
    fade = min(2 * r + 2, n - 1)
    inside[n - fade :] = inside[n - fade - 1] & (alpha[h - 1] >= _FADED)
    if not inside[-1].any():
        return alpha
    core = cv2.distanceTransform(np.pad(inside, ((1, 0), (0, 0)), constant_values=1), cv2.DIST_L2, 3)[1:] > r
    _, labels = cv2.connectedComponents(core.astype(np.uint8), connectivity=8)
    cut = np.unique(labels[-1][core[-1]])
    if cut.size:
        alpha[h - n :][np.isin(labels, cut)] = 1.0
    return alpha


def _colour_alpha(
    img: np.ndarray, a: np.ndarray, fg_w: np.ndarray, bg_w: np.ndarray, f_reach: int, b_reach: int,
    at: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Colour's alpha (module docstring), blended with the coarse ``a`` by its confidence, from the mean colours of the
    sure foreground (weights ``fg_w``, windows of radius ``f_reach``) and the sure background (``bg_w``, ``b_reach``);
    the confidence is multiplied by exp(-d^2 / (_OFF_LINE |F - B|^2)), d the distance of the pixel's colour from the
    segment B..F: a colour that no mix of B and F makes says nothing of alpha (people_masks, IoU: photos 0.9013 ->
    0.9021, half A 0.9155 -> 0.9161, B 0.8872 -> 0.8881; clip 0.9232 -> 0.9248; the reference masks' soft band
    unchanged, 0.230 photo / 0.194 video). A pixel is plain background, alpha 0, where colour says so clearly: its
    colour lies within sqrt(_CLEAR) x |F - B| of B and colour's alpha is under _SNAP, person and background differ by
    colour (|F - B|^2 >= _CLEAR_MIN), and the coarse matte is not sure of the person there (below _CLEAR_BELOW). The
    coarse matte's soft rim reaches 3-8 px past the outline (0.18 at 3-4 px outside the reference clip's dress, where
    the pixels lie 0.02 from the white backdrop's colour), and the blend by confidence kept a third of it: relit, that
    rim changed the background beside the person (issue 48). Within 0.1 |F - B| of B (_CLEAR 0.01): at 0.2 the faint
    strands of the reference photo's hair went too (error in its hand mask's soft band 0.224 -> 0.234; 0.230 at 0.1) for
    the same band. Returns (the background colour B per pixel (h, w, 3), the blended alpha (h, w) float32, where colour
    says plain background (h, w) bool); with ``at`` (y0, y1, x0, x1), on that box only (:func:`_side_mean_at`)."""
    if at is None:
        f_col, f_n = _side_mean(img, fg_w, f_reach)
        b_col, b_n = _side_mean(img, bg_w, b_reach)
    else:
        f_col, f_n = _side_mean_at(img, fg_w, f_reach, at)
        b_col, b_n = _side_mean_at(img, bg_w, b_reach, at)
        img, a = img[at[0] : at[1], at[2] : at[3]], a[at[0] : at[1], at[2] : at[3]]
    d = f_col - b_col
    dd = _channel_sum(d * d)
    ib = img - b_col
    ib2 = _channel_sum(ib * ib)
    along = _channel_sum(ib * d)
    a_c = np.clip(along / (dd + _EPS), 0.0, 1.0)
    # the squared distance of the pixel's colour from the segment B..F: |I - B - a_c (F - B)|^2
    off = np.maximum(ib2 - a_c * (2 * along - a_c * dd), 0.0)
    conf = dd / (dd + _TAU) * (f_n > 0) * (b_n > 0) * np.exp(-off / (_OFF_LINE * dd + _EPS))
    near_b = ib2 < _CLEAR * dd
    clear = near_b & (a_c < _SNAP) & (dd >= _CLEAR_MIN) & (f_n > 0) & (b_n > 0)
    clear &= a < _CLEAR_BELOW  # where the graphs are sure of the person, a part may wear the backdrop's colour
    return b_col, np.where(clear, 0.0, conf * a_c + (1 - conf) * a).astype(np.float32), clear


def _channel_sum(x: np.ndarray) -> np.ndarray:
    """(h, w) the sum of an (h, w, 3) array's channels, added in numpy's own order for three, (c0 + c1) + c2 (the
    same values as ``x.sum(-1)``, without its strided reduction: several times faster at full size)."""
    out = x[..., 0] + x[..., 1]
    out += x[..., 2]
    return out


def _backdrop_coloured(img: np.ndarray, b_col: np.ndarray) -> np.ndarray:
    """Where a pixel's colour lies within _GAP_MATCH (squared distance) of the backdrop's colour ``b_col``: the
    one rule by which a half-seen pocket opens (``_open_gap``) and a half-seen patch at the border stays soft
    (``opaque_where_cut``)."""
    d = img - b_col
    return _channel_sum(d * d) < _GAP_MATCH


def _side_mean(img: np.ndarray, weight: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean colour in windows of radius r, falling back to radius 2r where a window holds none."""
    weighted = img * weight[..., None]
    num, den = _box(weighted, r), _box(weight, r)
    far = den <= 0.5  # no sure pixel within r: the wider window's
    if far.any():
        np.copyto(num, _box(weighted, 2 * r), where=far[..., None])
        np.copyto(den, _box(weight, 2 * r), where=far)
    num /= np.maximum(den, 1e-6)[..., None]
    return num, den


def _side_mean_at(img: np.ndarray, weight: np.ndarray, r: int, box: tuple[int, int, int, int]
                  ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`_side_mean` on the box (y0, y1, x0, x1) only: each window's sums taken over the part of the image its
    windows reach (radius r; 2r where it falls back), the division on the box alone. The sums are exact in float64
    (OpenCV's box filter of float32), so the values are :func:`_side_mean`'s."""
    y0, y1, x0, x1 = box
    h, w = weight.shape

    def sums(k: int) -> tuple[np.ndarray, np.ndarray]:
        sy, sx = max(y0 - k, 0), max(x0 - k, 0)
        wgt = weight[sy : min(y1 + k, h), sx : min(x1 + k, w)]
        inner = (slice(y0 - sy, y1 - sy), slice(x0 - sx, x1 - sx))
        # OpenCV's product, the same float32 values as numpy's (whose broadcast over three channels costs ~20x)
        part = img[sy : sy + wgt.shape[0], sx : sx + wgt.shape[1]]
        return _box(cv2.multiply(part, cv2.cvtColor(wgt, cv2.COLOR_GRAY2RGB)), k)[inner], _box(wgt, k)[inner]

    num, den = sums(r)
    far = den <= 0.5  # no sure pixel within r: the wider window's
    if far.any():
        num_far, den_far = sums(2 * r)
        mask = far.view(np.uint8)
        num, den = cv2.copyTo(num_far, mask, num), cv2.copyTo(den_far, mask, den)
    # OpenCV's division by the count repeated over the channels (IEEE, numpy's values, at a third of its time)
    return cv2.divide(num, cv2.cvtColor(np.maximum(den, np.float32(1e-6)), cv2.COLOR_GRAY2RGB)), den


def _guided(img: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A gray-guided filter of radius _GF_RADIUS (He et al.), to remove pixel noise along the strands."""
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    return fast_guided_filter(p, g, g, _GF_RADIUS, _GF_EPS)
