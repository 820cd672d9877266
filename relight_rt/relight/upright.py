"""A person lying or tilted, decomposed in their upright frame.

Stage 1 learnt from renders of people standing upright; it reads a body lying on its side as an upright one's
shading turned (the light placed on the wrong side of the body, a white shirt dark in a band). Turning the picture by
an angle about the view axis turns the scene's light by the same angle about the camera's axis (+x, DESIGN.md §3),
and spherical harmonics turn exactly, so stage 1 may look at the crop turned upright and its answer be turned back:
albedo and skin by the inverse turn of the pixel grid, the transport's nine coefficients by the SH rotation as well
(shading = T . L is unchanged: with L_up = M @ L, T = T_up @ M), and the light by the inverse rotation. Quarter
turns keep the pixel grid exact, so an upright body sees the very pixels it would see as a standing one.

``np.rot90(image, q)`` turns the picture q quarters counter-clockwise: the image's right (+y) goes to its top (+z),
a rotation about +x by q x 90 deg (``quarter_rotation``).

Which way is up (``upright_quarters``, ``UprightTurn``): from the matte's second moments and the person's one face, no
pose landmarks (the bundled pose graph keeps its segmentation only). Measured (benchmarks/heldout_change.py measure
--turn 90 / 270, held-out renders turned with their lights): relight RMSE 0.14-0.18 -> 0.08-0.13 per framing (upright:
0.08-0.12), change contrast 0.29-0.48x -> 0.51-0.78x (upright 0.59-0.81x); no photo turned the wrong way, upright ones
bit for bit as before (docs/RESULTS.md "Stage 1 and 2 on held-out renders"). Left as they were: a face found only in
a turned view gets no face mesh (relight_rt.person.face_mesh takes the skull above the face in the picture), a turned
person no head pass (relight_rt.relight.face_pass ``head_crops``), stage 2 and video frames (a turn decided per frame
could flip between frames).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.crop import CropGeometry
from ..light import sh

STAGE1_IMAGES = ("albedo", "skin", "transport")  # stage 1's (N, C, R, R) outputs, turned as pictures


def quarter_rotation(quarters: int) -> np.ndarray:
    """(3, 3) float64: the scene's rotation when the picture turns ``quarters`` x 90 deg counter-clockwise
    (``np.rot90``): about +x (the view axis), carrying +y (the picture's right) toward +z (its top); exact."""
    return np.rint(sh.rotation_matrix(roll=90.0 * (quarters % 4), degrees=True))


def quarter_coefficients(quarters: int) -> np.ndarray:
    """(9, 9) float64 M: a light seen in the picture turned ``quarters`` quarters is ``M @ light``."""
    return sh.rotation_coefficients(quarter_rotation(quarters))


def turn_picture(a: np.ndarray, quarters: int, axes: tuple[int, int] = (0, 1)) -> np.ndarray:
    """``a`` turned ``quarters`` x 90 deg counter-clockwise on ``axes`` (rows, columns), a new contiguous array."""
    return np.ascontiguousarray(np.rot90(a, quarters % 4, axes))


def turned_back(out: dict[str, np.ndarray], quarters: int) -> dict[str, np.ndarray]:
    """Stage 1's outputs for one picture seen turned ``quarters`` quarters, in the picture's own frame.

    Args:
        out: "albedo" (3, R, R), "skin" (1, R, R), "transport" (9, R, R) channel-first, "light" (9, 3), as stage 1
            gives them for the turned picture.
        quarters: the turn the picture was seen in.

    Returns:
        The same keys, float32: the images turned back, the transport's coefficients T @ M (M =
        ``quarter_coefficients(quarters)``) and the light M.T @ light.
    """
    m = quarter_coefficients(quarters)
    back = {k: turn_picture(out[k], -quarters, (1, 2)) for k in STAGE1_IMAGES}
    t = back["transport"]
    back["transport"] = (m.T.astype(np.float32) @ t.reshape(9, -1)).reshape(t.shape)
    back["light"] = (m.T @ np.asarray(out["light"], np.float64)).astype(np.float32)
    return back


def mirror_picture(a: np.ndarray, axis: int = 1) -> np.ndarray:
    """``a`` mirrored left-right (its columns, ``axis``, reversed), a new contiguous array."""
    return np.ascontiguousarray(np.flip(a, axis))


def mirror_averaged(out: dict[str, np.ndarray], mirrored: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Stage 1's answers for a picture averaged with its answers for the picture mirrored left-right, mapped back.

    Args:
        out, mirrored: "albedo" (3, R, R), "skin" (1, R, R), "transport" (9, R, R) channel-first and "light" (9, 3):
            stage 1's outputs for the picture and for its mirror image.

    Returns:
        The same keys, float32: the mean of ``out`` and ``mirrored`` mapped back (images mirrored, the transport's
        and the light's coefficients times relight_rt.light.sh ``MIRROR_SIGNS``). A picture and its mirror image get
        each other's answer mirrored: the result does not depend on which way the picture faces.
    """
    signs = sh.MIRROR_SIGNS.astype(np.float32)
    back = {k: mirror_picture(mirrored[k], 2) for k in STAGE1_IMAGES}
    back["transport"] = back["transport"] * signs[:, None, None]
    back["light"] = np.asarray(mirrored["light"], np.float32) * signs[:, None]
    return {k: ((np.asarray(out[k], np.float32) + back[k]) * np.float32(0.5)).astype(np.float32) for k in back}


# ------------------------------------------------------------------------------------------ which way is up

LONG_BODY = 1.5  # the matte's long axis over its short one (from its second moments) from which it is a body's length
HEAD_OFF = 0.75  # ... whose head is at one end: the face this many face sizes off the matte's centre along the axis
HEAD_END = 0.5  # ... and at least this fraction of the way from the matte's centre to its end on that side
# ... and no thicker across that axis than a body lying (the spread of its pixels across it, in face sizes): a body on
# its side or back is at most ~3.5 face sizes across (shoulders, bent knees; a uniform band t wide spreads t / sqrt(12))
# while a row of people standing is a body's height (~8 face sizes) across. Held-out renders turned: 0.7-1.0.
THIN_BODY = 1.5
FOREHEAD, CHIN = 10, 152  # the face mesh's points at the top of the forehead and the chin (MediaPipe's face landmarker)
SAME_FACE = 0.5  # faces whose centres lie closer than this many face sizes are one face (seen in two turned views)
_UP = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])  # (x, y) picture direction turned to the top by q


def matte_axis(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The matte's centre, long axis and elongation, from its second moments (alpha-weighted).

    Args:
        mask: (H, W) float alpha in [0, 1], not empty.

    Returns:
        (centre (x, y), unit long-axis direction (x, y) (its sign arbitrary), long over short axis length >= 1),
        in pixels, x to the right and y down.
    """
    mom = cv2.moments(np.asarray(mask, np.float32))
    total = mom["m00"]
    cov = np.array([[mom["mu20"], mom["mu11"]], [mom["mu11"], mom["mu02"]]]) / total
    vals, vecs = np.linalg.eigh(cov)  # ascending
    return np.array([mom["m10"], mom["m01"]]) / total, vecs[:, 1], float(np.sqrt(vals[1] / max(vals[0], 1e-12)))


def standing(mask: np.ndarray) -> bool:
    """True for a matte of a body's length (``LONG_BODY``) whose long axis is nearer the picture's vertical: a person
    standing (or sitting) upright, decided without a face."""
    _, axis, long_ = matte_axis(mask)
    return long_ >= LONG_BODY and abs(axis[1]) >= abs(axis[0])


def upright_quarters(mask: np.ndarray, faces: list[tuple[float, float, float, float, float]],
                     cut_below: float = 0.0) -> int:
    """How many quarters (``np.rot90``) to turn a person's picture so that they stand upright: 0, 1, 2 or 3.

    The head's direction is the one from the matte's centre to its one face, when the face lies ``HEAD_OFF`` face
    sizes off it, and the person is turned by the quarter that brings that direction nearest the picture's top (none
    when it is within 45 deg of it). A matte of a body's length (``LONG_BODY`` times its width) whose long axis is
    nearer the picture's vertical stands, face or not; one lying across the picture is turned only when its face
    also lies at least ``HEAD_END`` of the way from its centre to its end along that axis (a vaulting runner whose
    legs stretch out sideways keeps his upright torso: his face lies straight above the matte's centre) and it is no
    thicker across that axis than a body (``THIN_BODY``: a mask given over a row of people standing, of whom one face
    is found, is a body's height across). A matte no
    longer than it is wide (a head and shoulders, a face filling the photo: a sideways selfie, a photo stored
    without its EXIF turn) whose face lies near its centre is turned by the face's own up (chin to forehead; not
    known: 0). Otherwise 0: no face (nothing says where the head is), several faces (a group), a matte the photo's
    bottom edge cuts over at least a face's width (a body that goes on below the frame stands: two people side by
    side framed from the waist up, a person beside something the matte holds).

    Args:
        mask: (H, W) float alpha in [0, 1] (the network frame's), not empty.
        faces: the faces found in the same pixels, each (x, y, size, up_x, up_y): its centre, its size and its up
            (chin to forehead, a unit vector; (0, 0): not known), x to the right and y down.
        cut_below: how wide the photo's bottom edge cuts the matte, in the same pixels (0: not cut).
    """
    centre, axis, long_ = matte_axis(mask)
    if long_ >= LONG_BODY and abs(axis[1]) >= abs(axis[0]):
        return 0  # standing (or upside down: not told apart here)
    if len(faces) != 1 or cut_below >= faces[0][2]:
        return 0
    x, y, size, up_x, up_y = faces[0]
    off = np.array([x, y]) - centre
    far = np.hypot(*off) >= HEAD_OFF * size
    if long_ >= LONG_BODY:
        # the person's pixels as the intake counts them (alpha >= 0.5); a matte all fainter (a half-alpha mask, a
        # thin one shrunk to the network's square) has none: then every pixel it covers
        ys, xs = np.nonzero(mask >= 0.5) if (mask >= 0.5).any() else np.nonzero(mask > 0)
        along = float(off @ axis)
        pixels = np.stack([xs, ys], axis=1) - centre
        reach = pixels @ axis  # the matte's pixels along its axis
        if not far or abs(along) < HEAD_END * (reach.max() if along > 0 else -reach.min()):
            return 0
        if np.std(pixels @ np.array([-axis[1], axis[0]])) > THIN_BODY * size:  # across it: a row of people
            return 0
    head = off if far else np.array([up_x, up_y])
    return int(np.argmax(_UP @ head)) if head.any() else 0


def unturn_point(x: float, y: float, quarters: int, shape: tuple[int, int]) -> tuple[float, float]:
    """(x, y) of a pixel (centres at integers) of ``np.rot90(a, quarters)`` in ``a`` of (H, W) ``shape``."""
    h, w = shape
    q = quarters % 4
    if q == 1:
        return w - 1 - y, x
    if q == 2:
        return w - 1 - x, h - 1 - y
    if q == 3:
        return y, h - 1 - x
    return x, y


class UprightTurn:
    """Decides a person's upright turn (``upright_quarters``) from their matte and their faces: the faces found upright
    (the face meshes a photo's decomposition finds anyway, relight_rt.relight.face_pass ``FacePass.find``), else those
    found in the person's crop turned a quarter, a half and three quarters. A standing matte needs no face: it costs
    one pass of second moments over the network-frame matte."""

    def __init__(self, faces) -> None:
        self.faces = faces  # a relight_rt.relight.face_pass.FacePass

    def quarters(self, rgb: np.ndarray, mask: np.ndarray, geom: CropGeometry, net_mask: np.ndarray,
                 meshes: tuple[np.ndarray, ...] | None) -> int:
        """The quarter turns (``np.rot90``) that bring the person of ``net_mask`` (R, R) upright, 0-3.

        Args:
            rgb: (H, W, 3) float32 RGB photo.
            mask: (H, W) its person matte.
            geom: its crop to the network frame.
            net_mask: (R, R) the person's matte in the network frame.
            meshes: the face meshes found upright in ``geom.box`` ((468, 3) x, y, z in input pixels); None: not
                looked for yet (looked for here when the matte is not a standing one's).

        The faces a turned view finds tell the turn only: their meshes are not the photo's (the face's transport
        from its mesh, relight_rt.person.face_mesh, takes the skull to lie above the face in the picture).
        """
        if standing(net_mask):
            return 0
        upright = self.faces.find(rgb, geom.box) if meshes is None else meshes
        found = [self._in_network(geom, m[:, :2]) for m in upright]
        if not found:  # a face only a turned view shows (the same face may show in two)
            crop = geom.crop(rgb)
            y0, _, x0, _ = geom.box
            for q in (1, 2, 3):
                view = np.ascontiguousarray(np.rot90(crop, q))
                for m in self.faces.find(view, (0, view.shape[0], 0, view.shape[1])):
                    x, y = unturn_point(m[:, 0], m[:, 1], q, crop.shape[:2])
                    face = self._in_network(geom, np.stack([x + x0, y + y0], axis=1))
                    same = [i for i, (fx, fy, size, *_) in enumerate(found)
                            if np.hypot(face[0] - fx, face[1] - fy) < SAME_FACE * size]
                    if not same:
                        found.append(face)
                    elif np.dot(face[3:], found[same[0]][3:]) <= 0:  # two views' meshes disagree on its up
                        found[same[0]] = found[same[0]][:3] + (0.0, 0.0)
        return upright_quarters(net_mask, found, self._cut_below(geom, mask))

    @staticmethod
    def _cut_below(geom: CropGeometry, mask: np.ndarray) -> float:
        """How wide the photo's bottom edge cuts the matte (alpha > 0.5), in network pixels."""
        return float(np.count_nonzero(mask[-1] > 0.5)) / geom.scale

    @staticmethod
    def _in_network(geom: CropGeometry, points: np.ndarray) -> tuple[float, float, float, float, float]:
        """A face's (x, y, size, up_x, up_y) in network pixels from its mesh's points (x, y) in input pixels."""
        k = geom.scale
        (by0, _, bx0, _), (oy, ox) = geom.box, geom.offset
        x, y = points[:, 0].mean(), points[:, 1].mean()
        up = points[FOREHEAD] - points[CHIN]
        up = up / max(float(np.hypot(*up)), 1e-9)
        return ((x - bx0 + ox) / k - 0.5, (y - by0 + oy) / k - 0.5, float(np.ptp(points, axis=0).max()) / k,
                float(up[0]), float(up[1]))
