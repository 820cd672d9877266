"""Person alpha for the frames of a video, steady over time, and a measure of what flicker is left.

:class:`VideoMatter` keeps state between frames: the person's region comes from the previous frame's
matte (the detector runs again when the person is lost, every ``redetect_every`` frames, and after a frame whose
matte dropped part of the person, whose box lost that part too), and
the working-grid probability is blended with the previous one warped by DIS optical flow (relight_rt.image.flow),
weighted by how well the flow explains the frame (photometric agreement), which steadies the outline
without dragging it behind a moving person. The person is completed as in a photo only in the frames where the
followed matte drops part of what the flow carries from the last frame (:func:`dropped_share`).
:func:`outline_flicker` measures what is left.
"""

from __future__ import annotations

import logging
import os

import cv2
import numpy as np

from ...engine.errors import RelightError
from ...image.flow import dis_flow, warp
from ...image.guided_filter import fast_guided_filter
from ...image.matte_edges import open_pockets
from ...image.regions import Region, reductions_shared
from ._coarse import GF_EPS, guide_radius
from ._matter import PersonMatter
from ._models import as_rgb
from ._segmentation import Grid, Person, logits_on_grid, person_box, sigmoid, working_grid

log = logging.getLogger(__name__)


def _gray_u8(gray: np.ndarray) -> np.ndarray:
    """(H, W) float gray in [0, 1] -> uint8 for the flow (truncated, as the video matter always did)."""
    return np.clip(gray * 255.0, 0, 255).astype(np.uint8)


_REGION_KEEP_IOU = 0.8
_REGAINED = 0.5  # the region finder's blob of the person followed holds at least this share of their last box
_AGREE_SCALE = 0.05  # gray levels (0-1): the flow explains a pixel by exp(-|I_now - I_prev_warped| / this)
DROPPED_SHARE = 0.05  # VideoMatter completes a frame where the followed matte drops this share of the carried one
# after this many frames completed in a row, what the completions found again leaves the rule's history (a part the
# pose graph has not held for ~0.5 s is left to it; the parkour clip's longest run is 4); with the frame after a drop,
# a run holds at most COMPLETED_RUN + 1 completions (VideoMatter)
COMPLETED_RUN = 12


def _inside(box: tuple[float, float, float, float], region: Region, margin: float = 0.05) -> bool:
    """True when ``box`` lies inside ``region`` with ``margin`` x side to spare on every side."""
    x0, y0, x1, y1 = region.box()
    m = margin * region.side
    return box[0] >= x0 + m and box[1] >= y0 + m and box[2] <= x1 - m and box[3] <= y1 - m


def _held_share(blob: tuple[float, float, float, float], box: tuple[float, float, float, float]) -> float:
    """The share of ``box``'s area that ``blob`` covers (both (x0, y0, x1, y1), image pixels); 0 for an empty box."""
    iw = max(0.0, min(blob[2], box[2]) - max(blob[0], box[0]))
    ih = max(0.0, min(blob[3], box[3]) - max(blob[1], box[1]))
    area = (box[2] - box[0]) * (box[3] - box[1])
    return iw * ih / area if area > 0 else 0.0


def dropped_share(prob: np.ndarray, carried: np.ndarray, agree: np.ndarray) -> float:
    """The share of what is carried over from the last frame that this frame's matte drops.

    Args:
        prob: (h, w) float32 person probability of this frame, in [0, 1] (the followed person alone).
        carried: (h, w) float32 what is compared with, warped onto this frame by the flow, in [0, 1]: for
            :class:`VideoMatter`, the rule's history (or, once after a drop, the last frame's matte as completed).
        agree: (h, w) float32 in [0, 1], how well the flow explains each pixel (1: the warped last frame's
            picture matches this one's), so that what is dropped where the flow is lost (a limb moving fast,
            the backdrop uncovered) counts little.

    Returns:
        sum(agree over carried >= 0.5 and prob < 0.5) / count(carried >= 0.5); 0 when nothing is carried.
    """
    held = carried >= 0.5
    n = int(held.sum())
    if n == 0:
        return 0.0
    return float(agree[held & (prob < 0.5)].sum()) / n


class VideoMatter:
    """Person alpha for the frames of a video, steady over time (module docstring).

    The region the pose graph sees follows the person from the previous frame's matte (the region finder runs on the
    first frame, in the very frame where the person is lost from the region followed, and every ``redetect_every``
    frames if > 0; the search in the same frame found the parkour clip's frame 66 runner after his jump instead of
    leaving that frame empty: benchmarks/people_masks_eval.py --methods video 0.913 -> 0.922). After a frame whose
    followed matte drops a part of the rule's history (below; with ``complete`` too, where the history is the followed
    matte's alone), the box the next region is built on has lost that part as well, and the pose graph framed on the
    rest can go on missing it (the parkour clip's frame 19 on frame 18's region, built without the legs: 0.74, the photo
    matte 0.94); the next frame starts where the region finder sees the person whole, as a photo's search does
    (:meth:`PersonMatter.find_people` on the whole frame alone, one selfie-graph run: the blob that holds the most of
    the last box, at least _REGAINED of it), and follows on from there (video23: frame 19 0.74 -> 0.90) if the person
    the pose graph finds there still holds _REGAINED of the last box; else the region followed is segmented, as
    without the search (the finder merges people who stand close into one blob, and the pose graph framed between
    them can take the other one). Someone who covers half the last box themselves (in front of the person, or
    overlapping them) can still be taken. A frame is completed as
    in a photo (:meth:`PersonMatter.completed`: half-seen trousers, parts in their own colours, limbs seen only turned;
    two or more selfie-graph runs) where the followed matte gives a reason: where it drops at least ``complete_on_drop``
    (DROPPED_SHARE) of the rule's history that the flow carries over from the last frame, counted where the flow
    explains the picture (:func:`dropped_share`; the agreement less its median change over the person, so that a change
    of exposure does not hide a drop): a leg the pose graph loses for a frame or two, which the completion finds again.
    The rule's history is what the followed matte has held in two frames in a row (a one-frame spike of the pose graph
    is no part to drop) plus what a completion found again of the history, never what only the completion adds (compared
    with that, every later frame would count as dropping it and be completed in turn); the frame right after a drop is
    compared with the last matte as completed too, once (the rest of a part lost over two frames). After
    ``COMPLETED_RUN`` (12) frames completed in a row, what only the completions held leaves the history (a part the pose
    graph holds for two frames and then half-sees reads as a lost leg: kept, but not for good; a leg the pose graph
    never sees again goes too); the cap's frame is a drop like any other, so the frame after it is compared once with
    the last matte as completed and, still finding the part dropped, completed too: a run holds at most
    ``COMPLETED_RUN`` + 1 completions, as intended (the cap ends the history's hold on the part, not the after-a-drop
    rule; the part then leaves the matte in the next frame). A plain frame ends a run: the next one counts from one.
    ``complete`` completes every frame and overrides ``complete_on_drop`` (``completions`` counts the frames completed).
    This default is what ``relight-rt mask`` (a video, ``--sequence``) and ``relight-rt video`` matte with (no option
    there; ``complete_on_drop=None`` here turns it off). Measured on the parkour clip (one video, 100 frames:
    ``benchmarks/people_masks_eval.py --set clip --methods video,video-complete``): neither 0.92207, every frame 0.92752
    (frame 50 0.78 -> 0.95, 96-97 -0.04 each: a dark car taken), on a drop 0.92974 with 16 frames of 100 completed
    (18-19, 44, 49-50, 58, 63, 66-67, 69, 79-82, 84-85; not 96-97: nothing is dropped there; +12-16 % a frame on
    average, benchmarks/video_on_drop.py --clip), DROPPED_SHARE 0.04-0.06 within 0.0004 of it; with the search after a
    drop (video23) 0.93116 (19 completed; DROPPED_SHARE 0.04-0.06: 0.9302-0.9312) and every frame 0.93066
    (0.9294-0.9307). The 720p reference frames complete none and keep their speed (the rule's own history: +~2 %; with
    smoothing 0 the flow runs for the rule: +~10 %); a video whose every frame drops part of the person pays what
    ``complete=True`` does, ~1.6x the default (720p ~19-20 frames/s on 2 loaded cores; docs/BENCHMARKS.md, video16 and
    mendv16). With ``pockets`` (the default), a gap between arm and body that the matte half-holds (alpha under 0.9
    inside the person) is settled by the photo's colour as in a photo (``matte_edges.open_pockets``): open where it
    shows the backdrop, opaque where it shows the person (the reference video's boundary F 0.948 -> 0.991 on the default
    path, 0.928 -> 0.990 with ``complete``, whose ``backed_logits`` leaves such gaps in doubt; +~20 % a 720p frame, +~45
    % at 1080p, paired A/B on 2 loaded cores, benchmarks/video_pockets.py). The person probability on the working grid
    is blended with the previous frame's, warped by DIS optical flow: ``p = (1 - w) p_now + w p_prev_warped``, ``w =
    smoothing * exp(-|I_now - I_prev_warped| / 0.05)`` (the history counts only where the flow explains the picture),
    then refined by the guided filter.

    Args:
        matter: a :class:`PersonMatter` to use (default: a new one with ``models`` and ``device``).
        smoothing: weight of the warped history in [0, 1); 0 turns temporal smoothing off.
        redetect_every: run the region finder every N frames even when the person is tracked (0: never).
        refine: guided-filter edge refinement (as in PersonMatter; always with the gray guide, for speed).
        complete: add to the person what the photo matte adds (:meth:`PersonMatter.completed`) in every frame; slower
            (with ``complete_on_drop`` set, the flow runs in every frame for the search after a drop, smoothing 0 too:
            720p +~7 % at smoothing 0, +~2 % at 0.7, docs/BENCHMARKS.md video23).
        complete_on_drop: ... in a frame where the followed matte drops at least this share (a number in (0, 1];
            a bool or a string is refused) of the rule's history the flow carries over from the last frame
            (:func:`dropped_share`), and the next frame searches again; None: only with ``complete``, which overrides
            it for the completion (the search after a drop keeps this share), and no search after a drop.
        pockets: settle the gaps the matte half-holds inside the person by the photo's colour (refine only).

    Calling it on each frame in order: ``alpha = vm(rgb)``; a frame with nobody in it gives an all-zero
    alpha (no error) and the next frame searches again. Only the largest person is followed.
    """

    def __init__(
        self,
        matter: PersonMatter | None = None,
        *,
        models: str | os.PathLike | None = None,
        device: str = "cpu",
        smoothing: float = 0.7,
        redetect_every: int = 0,
        refine: bool = True,
        complete: bool = False,
        complete_on_drop: float | None = DROPPED_SHARE,
        pockets: bool = True,
    ):
        if not 0.0 <= float(smoothing) < 1.0:
            raise RelightError(f"smoothing: expected a value in [0, 1), got {smoothing}")
        if int(redetect_every) < 0:
            raise RelightError(f"redetect_every: expected >= 0, got {redetect_every}")
        if complete_on_drop is not None and (
            isinstance(complete_on_drop, (bool, str, bytes))
            or not isinstance(complete_on_drop, (int, float, np.integer, np.floating))
            or not 0.0 < float(complete_on_drop) <= 1.0
        ):
            raise RelightError(f"complete_on_drop: expected a share in (0, 1] or None, got {complete_on_drop!r}")
        self.matter = matter if matter is not None else PersonMatter(models, device=device)
        self.smoothing = float(smoothing)
        self.redetect_every = int(redetect_every)
        self.refine = bool(refine)
        self.complete = bool(complete)
        self.complete_on_drop = None if complete_on_drop is None else float(complete_on_drop)
        self.pockets = bool(pockets)
        self.reset()

    def reset(self) -> None:
        """Forget the previous frames (call between videos)."""
        self._region: Region | None = None
        self._prev_prob: np.ndarray | None = None
        self._prev_gray: np.ndarray | None = None
        self._prev_held: np.ndarray | None = None  # the rule's history: the followed matte, not what completion adds
        self._prev_followed: np.ndarray | None = None  # the last frame's followed matte (unsmoothed), for the history
        self._dropped = False  # the last frame dropped part of the rule's history (and was completed)
        self._search = False  # the last frame's followed matte dropped part of the person: its box lost it too
        self._box: tuple[float, float, float, float] | None = None  # the last frame's person's box
        self._run = 0  # frames completed by the rule in a row up to the last one
        self._shape: tuple[int, int] | None = None
        self.index = 0
        self.completions = 0  # frames completed as a photo since the last reset

    def _found(self, rgb: np.ndarray, region: Region | None) -> tuple[Person | None, tuple | None]:
        """The person segmented in ``region`` (None: where the region finder finds them first) and their box, when
        vouched for (:meth:`PersonMatter.vouched`); else (None, None)."""
        if region is None:
            found = self.matter.find_people(rgb)
            if not found:
                return None, None
            region = Region.around(*found[0][1])
        person = self.matter.segment(rgb, region)
        box = person_box(person, rgb.shape[:2])
        if box is None or not self.matter.vouched(rgb, person):
            return None, None
        return person, box

    def _regained(self, rgb: np.ndarray) -> Region | None:
        """Where the person followed may be whole: the region around the region finder's blob (the selfie graph on
        the whole frame alone, one run, where a photo's search starts: :meth:`PersonMatter.find_people` with
        ``max_level=1``; no tiles, so a small person it misses costs no half a second a frame) that holds the most of
        the last frame's box, at least _REGAINED of it; None when no blob does. A blob can hold two people who
        stand close (the finder merges them), so the person segmented there is checked as well (:meth:`__call__`)."""
        if self._box is None:
            return None
        blobs = [b for _, b in self.matter.find_people(rgb, max_level=1)]
        held = [_held_share(b, self._box) for b in blobs]
        if not held or max(held) < _REGAINED:
            return None
        return Region.around(*blobs[int(np.argmax(held))])

    def _carried(self, gray_small: np.ndarray) -> tuple[np.ndarray | None, ...]:
        """What the flow carries from the last frame onto this one, on the working grid: the last probability, how
        well the flow explains each pixel (exp(-|I_now - I_prev_warped| / _AGREE_SCALE)), the rule's history
        (:meth:`_matte`), the rule's agreement (the same, less the change's median over the person held, so that a
        change of exposure does not hide a drop) and the last frame's followed matte. None for each without a last
        frame or where neither the smoothing nor the rule (with ``complete``, its search after a drop) reads it."""
        rule = self.complete_on_drop is not None  # (with ``complete``, for the search after a drop alone)
        if self._prev_prob is None or (self.smoothing == 0 and not rule):
            return None, None, None, None, None
        flow = dis_flow(_gray_u8(gray_small), _gray_u8(self._prev_gray), "ultrafast")  # this frame -> the last
        carried = warp(self._prev_prob, flow, border_value=None)
        change = gray_small - warp(self._prev_gray, flow, border_value=None)
        agree = np.exp(-np.abs(change) / np.float32(_AGREE_SCALE))
        if not rule or self._prev_followed is None:
            return carried, agree, None, None, None
        followed = warp(self._prev_followed, flow, border_value=None)
        if self._prev_held is None:
            return carried, agree, None, None, followed
        held = warp(self._prev_held, flow, border_value=None)
        inside = held[::2, ::2] >= 0.5  # the median of a quarter of the pixels: a quarter of the time (~1 ms at 720p)
        shift = np.float32(np.median(change[::2, ::2][inside])) if inside.any() else np.float32(0)
        return carried, agree, held, np.exp(-np.abs(change - shift) / np.float32(_AGREE_SCALE)), followed

    def _matte(self, rgb: np.ndarray, person: Person, grid: Grid, gray_small: np.ndarray) -> tuple[np.ndarray, ...]:
        """The person's probability on the working grid, completed as in a photo with ``complete`` or where the
        followed matte drops ``complete_on_drop`` of the rule's history carried over (or, in the frame right after such
        a drop, of the last matte as completed); with the rule's record of this frame and what :meth:`_carried` gives.
        Called within the frame's shared reductions (the turned views reuse the upright selfie run).

        The rule's history is what the followed matte (the pose graph's, unsmoothed) has held in this frame and the
        last, min(followed now, followed last warped), plus, in a completed frame, what the completion found again of
        what the history held (a lost leg), min(completed, history): never what only the completion adds (a bag the
        pose graph half-sees), which compared with every later frame's followed matte would count as dropped in each
        and keep completing for good (video16's rule did). Taking the followed matte of one frame alone, a single
        frame where the pose graph is sure of such a bag did the same (mendv16's rule: the next frame dropped it, its
        completion found it again, and so on). The one frame after a drop that compares with the last matte as
        completed finds the rest of a part lost over two frames (the parkour clip's frames 50 and 67: 0.78 -> 0.95,
        0.92 -> 0.95). With ``complete`` the history is what the followed matte held two frames running alone: it
        only says whether the next frame searches again (a drop of it, as by default; the frame after one is not
        searched: compared with the last matte as completed, whatever only the completion adds would count as dropped
        in every frame). Returns the probability, the history's record of this frame, the followed matte (both None
        where the rule is off), what the flow carried and its agreement."""
        carried, agree, held, held_agree, followed = self._carried(gray_small)
        prob = sigmoid(logits_on_grid(person, grid)).astype(np.float32)  # the followed matte
        limit = self.complete_on_drop
        # a part enters the history once the followed matte has held it in two frames in a row: a one-frame
        # spike of the pose graph (a half-seen bag over 0.5 once) is no part the next frame can drop
        steady = None if followed is None else np.minimum(prob, followed)
        mine = None if limit is None else prob  # the followed matte, for the next frame's history
        dropped = held is not None and dropped_share(prob, held, held_agree) >= limit
        # what is dropped lies outside this frame's box as well, which the next frame's region is built on: the next
        # frame starts where the region finder sees the person whole (__call__)
        self._search = dropped
        if not self.complete:
            if held is None:
                self._dropped, self._run = False, 0
                return prob, steady, mine, carried, agree
            # the frame after such a drop is compared with the last matte as completed too (the rest of a part the
            # pose graph loses over two frames); once only, so that what the completion alone adds ends there
            after = not dropped and self._dropped and dropped_share(prob, carried, held_agree) >= limit
            self._dropped = dropped
            if not (dropped or after):
                self._run = 0
                return prob, steady, prob, carried, agree
        # what the photo matte adds to the person: half-seen trousers both graphs see, parts in their own colours,
        # limbs seen only turned
        parts = self.matter.completed(rgb, person)
        self.completions += 1
        full = np.max([sigmoid(logits_on_grid(p, grid)) for p in parts], axis=0).astype(np.float32)
        if self.complete:  # every frame completed: the history is the followed matte's alone (it only feeds the search)
            return full, steady, mine, carried, agree
        self._run += 1
        if self._run >= COMPLETED_RUN:  # a part held by the completions alone for so long is left to the pose graph
            return full, steady, prob, carried, agree
        return full, np.maximum(steady, np.minimum(full, held)), prob, carried, agree

    def __call__(self, image: np.ndarray, name: str = "frame") -> np.ndarray:
        rgb = as_rgb(image, name, copy=False)  # only read from here on
        h, w = rgb.shape[:2]
        if self._shape is not None and self._shape != (h, w):
            raise RelightError(f"{name}: frame is {h}x{w}, the previous frames were {self._shape[0]}x{self._shape[1]}")
        self._shape = (h, w)
        index, self.index = self.index, self.index + 1
        region = self._region
        searched = region is None or bool(self.redetect_every and index % self.redetect_every == 0)
        regain, self._search = self._search and not searched, False
        grid = working_grid((0, 0, w, h))
        gray_full = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        gray_small = gray_full if grid[:2] == (w, h) else cv2.resize(gray_full, grid[:2], interpolation=cv2.INTER_AREA)
        with reductions_shared(rgb):  # the detectors' crops share one set of reduced copies of the frame
            person = box = None
            wider = self._regained(rgb) if regain else None  # the last box lost part of the person: seen whole?
            if wider is not None:
                person, box = self._found(rgb, wider)
                # the blob may hold someone standing close beside them, whom the pose graph framed there can take
                # instead: the person found must still hold the last box, else the region followed is segmented
                if person is not None and _held_share(box, self._box) < _REGAINED:
                    person = box = None
            if person is None:
                person, box = self._found(rgb, None if searched else region)
            if person is None and not searched:  # lost where it was followed: searched for again in this frame
                person, box = self._found(rgb, None)
            if person is not None:
                prob, record, followed, carried, agree = self._matte(rgb, person, grid, gray_small)
        if person is None:
            log.debug("%s: no person found; searching again on the next frame", name)
            self._region, self._prev_prob, self._prev_gray, self._prev_held = None, None, None, None
            self._prev_followed, self._box = None, None
            self._dropped, self._run = False, 0
            return np.zeros((h, w), np.float32)
        self._box = box
        new = Region.around(*box)
        # hysteresis: the pose graph's answer shifts with its crop, so the region stays put while the
        # person stays well inside it (a crop that moves every frame makes the outline shimmer)
        if self._region is None or new.iou(self._region) < _REGION_KEEP_IOU or not _inside(box, self._region):
            self._region = new

        if self.smoothing > 0 and carried is not None:
            wgt = np.float32(self.smoothing) * agree
            prob = prob + wgt * (carried - prob)
        self._prev_prob, self._prev_gray, self._prev_held, self._prev_followed = prob, gray_small, record, followed
        if not self.refine:
            return cv2.resize(prob, (w, h), interpolation=cv2.INTER_LINEAR) if grid[:2] != (w, h) else prob
        alpha = fast_guided_filter(prob, gray_small, gray_full, guide_radius(person, grid), GF_EPS)
        # a gap between arm and body that the graphs half-see (left in doubt by the completion's backed_logits too)
        # is decided by the photo's colour
        return open_pockets(rgb, alpha) if self.pockets else alpha


def outline_flicker(alphas: list[np.ndarray], frames: list[np.ndarray] | None = None, band: int = 4) -> float:
    """Outline flicker of a matte sequence: mean |alpha_t - alpha_{t-1}| over a band of ``band`` pixels on
    each side of frame t's outline (alpha = 0.5), averaged over frames 1..N-1.

    With ``frames`` (the RGB frames), alpha_{t-1} is first warped onto frame t by DIS optical flow
    (medium preset, full resolution), so the person's own motion is not counted: what remains is the
    edge jumping about. Without frames the raw change is measured (motion included).
    """
    if len(alphas) < 2:
        raise RelightError(f"outline_flicker: expected at least 2 frames, got {len(alphas)}")
    if frames is not None and len(frames) != len(alphas):
        raise RelightError(f"outline_flicker: {len(frames)} frames for {len(alphas)} alphas")
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1, 2 * band + 1))
    total, count = 0.0, 0
    for t in range(1, len(alphas)):
        cur = np.asarray(alphas[t], np.float32)
        prev = np.asarray(alphas[t - 1], np.float32)
        if cur.shape != prev.shape:
            raise RelightError(f"outline_flicker: alpha {t} is {cur.shape}, alpha {t - 1} is {prev.shape}")
        if frames is not None:
            g1 = cv2.cvtColor(np.asarray(frames[t], np.float32), cv2.COLOR_RGB2GRAY)
            g0 = cv2.cvtColor(np.asarray(frames[t - 1], np.float32), cv2.COLOR_RGB2GRAY)
            prev = warp(prev, dis_flow(_gray_u8(g1), _gray_u8(g0), "medium"), border_value=None)
        fg = (cur >= 0.5).astype(np.uint8)
        ring = cv2.dilate(fg, kernel) != cv2.erode(fg, kernel)
        if ring.any():
            total += float(np.abs(cur - prev)[ring].sum())
            count += int(ring.sum())
    return total / max(count, 1)
