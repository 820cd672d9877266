"""The face pass: what the Relighter does for a face beyond stage 1's one look at the whole person.

A second look at a face that stage 1 saw small (``head_box``, ``seen_head_box``, ``head_crops``, ``feather``). Stage 1
sees the whole person in one R x R square, so in a full-body photo the face is 10-20 network pixels tall and its
transport is a blur: a new light barely changes the face and a light from below paints blotches where the blur is wrong.
When the face is small, the Relighter runs stage 1 a second time on a square around the head (the bundled stage 1 is
trained on head-and-shoulders and face framings too) and takes the change of shading on the head from that pass, blended
into the body's over a feathered border. The face is found from stage 1's own skin map: the largest skin blob in the
upper part of the person. No extra model is needed; when no such blob exists (a person seen from behind, a face hidden),
nothing changes.

A face the detector finds gets the normals of its mesh blended into the transport (``FacePass``;
relight_rt.person.face_mesh).
"""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.crop import CropGeometry
from ..person.face_mesh import MIN_FACE_NET, FaceMesh, face_transport
from .decomposition import Decomposition

SMALL_FACE = 0.2  # a face taller or wider than this fraction of the network square is seen well enough
MIN_FACE_PX = 6  # a skin blob smaller than this (network pixels) is not trusted as a face
HEAD_SIDE = 3.0  # side of the head square, in face sizes (hair, ears, neck and a little shoulder)
MIN_HEAD_INPUT = 64  # the head square must hold at least this many input pixels a side
UPPER_PART = 0.45  # the face's centre lies in this upper fraction of the person's height
FACE_ASPECT = 2.5  # a face's skin blob is at most this many times as tall as wide or as wide as tall (an arm is not)
FEATHER = 0.3  # the head pass fades out over this fraction of the head square at each side
SEEN_LARGE = "seen large"  # _small_face: a face seen well enough, no head pass whatever the other map finds
SAME_HEAD = 0.5  # seen_head_box: two maps' boxes overlapping by this much (intersection over union) are one head
SHADOW_LIFTS = (0.5, 0.35)  # FacePass.find: no face found, it looks again with the shadows lifted (these powers)


def head_box(skin: np.ndarray, network_mask: np.ndarray, geometry: CropGeometry) -> tuple[int, int, int, int] | None:
    """The square around a small face, in input pixels (y0, y1, x0, x1, end exclusive), or None.

    Args:
        skin: (R, R) stage 1's skin probability, masked.
        network_mask: (R, R) the person's mask in the network frame.
        geometry: the crop geometry of the decomposition.

    Returns:
        None when no face is found, when it is already large in the network square, or when the photo has
        too few pixels there for a second pass to see more.
    """
    found = _small_face(skin, network_mask, geometry)
    return found[0] if isinstance(found, tuple) else None


def seen_head_box(dec: Decomposition) -> tuple[int, int, int, int] | None:
    """``head_box`` of ``dec``, looked for on each of stage 1's skin maps (``dec.skin_views``: the picture's and its
    mirror's, mapped back) and the answers combined alike whichever is which; on ``dec.skin`` without them.

    The search takes a threshold (skin > 0.5 blobs, ``SMALL_FACE``, ``MIN_HEAD_INPUT``), and on the mean of two maps
    that disagree its answer is on neither (mesh42): on p272 the mean joined a small dark face's blob to its neck
    (35 x 58 network px against 36 x 42 and 35 x 50 on each map), over ``SMALL_FACE``, and the head pass was
    dropped; on p238 the mirror's map missed a back-lit face (13 x 8 against 26 x 26) and the mean's blob made a
    square under ``MIN_HEAD_INPUT``. So: a map that sees the face large, none (a second look on the other's smaller
    blob, a face half hidden by a hand or a turned one, drew grey patches on p080's and p273's noses under rim);
    else the mean map's box where it finds a small face on one of theirs (overlapping by ``SAME_HEAD``: the two
    maps' mean still says where); else one map finds a small face, its box; both, their mean box (the start rounded
    down, the end up: a photo's mirror gets the box mirrored) where they overlap by ``SAME_HEAD`` or more, else the
    larger blob's (equal blobs apart: none); neither, none.
    """
    if dec.skin_views is None:
        return head_box(dec.skin, dec.network_mask, dec.geometry)
    answers = [_small_face(v, dec.network_mask, dec.geometry) for v in dec.skin_views]
    if SEEN_LARGE in answers:
        return None
    found = [f for f in answers if isinstance(f, tuple)]
    mean = head_box(dec.skin, dec.network_mask, dec.geometry)
    if mean is not None and any(_overlap(mean, f[0]) >= SAME_HEAD for f in found):
        return mean  # the maps agree with their mean: its box (the held-out renders' full framing: RMSE as before)
    if len(found) < 2:
        return found[0][0] if found else None
    (a, area_a), (b, area_b) = found
    if _overlap(a, b) >= SAME_HEAD:
        start, end = (lambda i: (a[i] + b[i]) // 2), (lambda i: -((-a[i] - b[i]) // 2))  # noqa: E731
        return start(0), end(1), start(2), end(3)
    if area_a == area_b:
        return None
    return a if area_a > area_b else b


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> float:
    """Intersection over union of two boxes (y0, y1, x0, x1, end exclusive)."""
    h = max(0, min(a[1], b[1]) - max(a[0], b[0]))
    w = max(0, min(a[3], b[3]) - max(a[2], b[2]))
    union = (a[1] - a[0]) * (a[3] - a[2]) + (b[1] - b[0]) * (b[3] - b[2]) - h * w
    return h * w / union if union > 0 else 0.0


def _small_face(skin: np.ndarray, network_mask: np.ndarray, geometry: CropGeometry
                ) -> tuple[tuple[int, int, int, int], int] | str | None:
    """``head_box``'s box and its face blob's area (network pixels); ``SEEN_LARGE`` where a face is seen well enough
    (no second look needed); None where no small face is found or the photo has too few pixels there."""
    inner = network_mask > 0.5
    rows = np.flatnonzero(inner.any(axis=1))
    if rows.size == 0:
        return None
    top, height = int(rows[0]), int(rows[-1] - rows[0] + 1)
    blobs = ((skin > 0.5) & inner).astype(np.uint8)
    n, _, stats, centres = cv2.connectedComponentsWithStats(blobs, connectivity=8)
    r = geometry.resolution
    best, best_area = None, 0
    for i in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[i])
        if y <= top + UPPER_PART * height and min(bw, bh) > SMALL_FACE * r:
            # a large skin blob from the upper part down: a face seen well whose centre lies lower (a portrait
            # framed from the chest up); a small blob beside it is a temple or an ear, not a small face (DPR's
            # portrait got a second pass on a 96-px square of its temple, and a red patch there under neon)
            return SEEN_LARGE
        compact = max(bw, bh) <= FACE_ASPECT * min(bw, bh)  # the reference clip's raised forearm (13 x 86) outweighed
        if compact and centres[i][1] <= top + UPPER_PART * height and area > best_area:  # its face (25 x 35) by 2 %
            best, best_area = i, area
    if best is None:
        return None
    face = max(int(stats[best, cv2.CC_STAT_WIDTH]), int(stats[best, cv2.CC_STAT_HEIGHT]))
    if face > SMALL_FACE * r:
        return SEEN_LARGE
    if face < MIN_FACE_PX:
        return None
    # network pixel u is at square pixel (u + 0.5) S/R - 0.5; the square's origin is the crop box minus offset
    k = geometry.scale
    cx, cy = centres[best]
    y0b, _, x0b, _ = geometry.box
    oy, ox = geometry.offset
    cx_in = (cx + 0.5) * k - 0.5 - ox + x0b
    cy_in = (cy + 0.5) * k - 0.5 - oy + y0b
    side = HEAD_SIDE * face * k
    if side < MIN_HEAD_INPUT:
        return None
    h, w = geometry.frame
    y0, x0 = max(int(round(cy_in - side / 2)), 0), max(int(round(cx_in - side / 2)), 0)
    y1, x1 = min(int(round(cy_in + side / 2)), h), min(int(round(cx_in + side / 2)), w)
    if y1 - y0 < MIN_HEAD_INPUT or x1 - x0 < MIN_HEAD_INPUT:
        return None
    return (y0, y1, x0, x1), best_area


def feather(h: int, w: int, cut: tuple[bool, bool, bool, bool] = (False, False, False, False)) -> np.ndarray:
    """(h, w) float32 weight: 1 in the middle of a box, falling smoothly to 0 at its sides.

    ``cut`` (top, bottom, left, right): sides where the box ends at the photo's border keep weight 1 there
    (nothing lies beyond to blend with).
    """
    ty = (np.arange(h, dtype=np.float32) + 0.5) / h
    tx = (np.arange(w, dtype=np.float32) + 0.5) / w
    return feather_at(ty[:, None], tx[None, :], cut)


def feather_at(ty: np.ndarray, tx: np.ndarray, cut: tuple[bool, bool, bool, bool] = (False, False, False, False)
               ) -> np.ndarray:
    """``feather``'s weight at positions inside the box given as fractions of its height ``ty`` and width ``tx``
    (0 and 1 its sides; arrays that broadcast, pixel i's centre at (i + 0.5) / n): where a point that is not a
    pixel's centre (a network pixel's, seen from the photo) lies under the head pass's blend (the caller keeps
    to the box: past a side that is not cut the weight is 0, past a cut one 1)."""

    def ramp(t: np.ndarray, cut_start: bool, cut_end: bool) -> np.ndarray:
        up = np.ones_like(t) if cut_start else np.clip(t / FEATHER, 0, 1)
        down = np.ones_like(t) if cut_end else np.clip((1 - t) / FEATHER, 0, 1)
        r = np.minimum(up, down)
        return r * r * (3 - 2 * r)  # smoothstep

    return ramp(np.asarray(ty, np.float32), cut[0], cut[1]) * ramp(np.asarray(tx, np.float32), cut[2], cut[3])


def head_crops(decs: list[Decomposition]) -> list[tuple]:
    """Per decomposition whose face stage 1 saw small (``seen_head_box``): (its index, it, the head's
    box (y0, y1, x0, x1) in the input frame, the photo inside that box (a read-only view: stage 1 reads it without
    a copy) and the mask there). A person stage 1 saw turned upright (``Decomposition.upright``) gets none: the face
    is looked for in the upper part of an upright person, and the second pass would see the head sideways."""
    todo = []
    for i, dec in enumerate(decs):
        if dec.upright:
            continue
        box = seen_head_box(dec)
        if box is not None:
            y0, y1, x0, x1 = box
            todo.append((i, dec, box, dec.image[y0:y1, x0:x1],
                         np.ascontiguousarray(dec.mask[y0:y1, x0:x1])))
    return todo


class FacePass:
    """The face detector and landmarker of a models folder (relight_rt.person.face_mesh), loaded on first use."""

    def __init__(self, models_dir: Path) -> None:
        self.models_dir = models_dir
        self._mesh: FaceMesh | None = None
        self._lock = threading.Lock()

    def mesh(self) -> FaceMesh:
        """The face detector and landmarker of the models folder (relight_rt.person.face_mesh), loaded once."""
        if self._mesh is None:
            with self._lock:
                if self._mesh is None:
                    self._mesh = FaceMesh(self.models_dir, device="cpu")
        return self._mesh

    def find(self, image: np.ndarray, box: tuple[int, int, int, int]) -> tuple[np.ndarray, ...]:
        """The meshes of the faces in ``image`` (H, W, 3) inside ``box`` (y0, y1, x0, x1), none without the face
        models: ((468, 3) float64 x, y, z in input pixels, ...).

        Where none is found as the photo is, the detector and landmarker look again at it with its shadows lifted
        (``SHADOW_LIFTS``, the powers their crops are raised to, one after the other until a face is found): a face
        lit hard from one side, half of it near black, is missed as it is (on Extended Yale B, 17 of 48 photos lit
        from 50-70 degrees) and its relighting then falls back to stage 1's blurred transport."""
        mesh = self.mesh()
        if not mesh.available:
            return ()
        for gamma in (1.0, *SHADOW_LIFTS):
            found = mesh.faces(image, box, lift=gamma)
            if found:
                return tuple(found)
        return ()

    def add_faces(self, dec: Decomposition, transport: np.ndarray,
                  window: tuple[int, int, int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Blend the transport of each of ``dec.face_meshes`` into ``transport`` (the window's, unpremultiplied), in
        place; returns (skin, openings), (h, w) bool each: where the faces' skin lies well inside their meshes, and
        their openings as deep inside, off every face's skin (the eyes' sockets; ``face_transport``; none without a
        mesh)."""
        mesh = self.mesh()
        skin = np.zeros(transport.shape[:2], bool)
        openings = np.zeros(transport.shape[:2], bool)
        if not dec.face_meshes:
            return skin, openings
        if not mesh.available:
            raise RelightError(f"{self.models_dir}: a decomposition with face meshes needs the face models to relight")
        for net in self.window_points(dec, window):
            t_face, weight, face_skin, face_openings = face_transport(net, mesh.triangles, transport[..., 0])
            transport += weight[..., None] * (t_face - transport)
            skin |= face_skin
            openings |= face_openings
        return skin, openings & ~skin

    @staticmethod
    def window_points(dec: Decomposition, window: tuple[int, int, int, int]) -> tuple[np.ndarray, ...]:
        """``dec.face_meshes`` in the pixels of a window (y0, y1, x0, x1) of the network frame (pixel centres at
        integers, z in the same units), those too small there (``MIN_FACE_NET``) left out."""
        geom = dec.geometry
        k = geom.scale
        (by0, _, bx0, _), (oy, ox) = geom.box, geom.offset
        y0, _, x0, _ = window
        out = []
        for pts in dec.face_meshes or ():
            net = np.empty_like(pts)  # input pixels -> the window's pixel indices (centres at integers)
            net[:, 0] = (pts[:, 0] - bx0 + ox) / k - 0.5 - x0
            net[:, 1] = (pts[:, 1] - by0 + oy) / k - 0.5 - y0
            net[:, 2] = pts[:, 2] / k
            if np.ptp(net[:, :2], axis=0).max() >= MIN_FACE_NET:
                out.append(net)
        return tuple(out)
