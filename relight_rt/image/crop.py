"""The crop / pad / resize that takes an input photo to the network's square, and its inverse.

Forward (the reference's preprocessing, DESIGN.md §4):

1. Box: rows and columns where ``mask > 0`` (any non-zero value, as the reference), widened by a
   5 px margin and clipped to the image. As in the reference, the end of the box is the last mask
   pixel + 5 taken as an exclusive slice end, so the margin is 5 px before and 4 px after the mask.
   With ``SYMMETRIC_CROP`` (``mode="quality"`` only) the margin is 5 px on both sides, and a square padded on
   odd left-right padding is made one row larger, so that a photo's mirror image is cropped to the mirrored box.
2. Square: the crop (h, w) is zero-padded on its short side to a square of side S = max(h, w),
   ``(S - min(h, w)) // 2`` pixels before it and the rest after it. In ``mode="quality"`` a person cut
   by the photo's border (the mask touches it: a portrait, a half body) keeps that cut on the square's
   border: the padding goes to the other side only, so the network sees a body that continues beyond
   the frame — as in the framings it was trained on — and not one that ends above a black band.
   When the mask touches both borders of the padded axis, or neither, the crop stays centred.
3. Resize the square to the network resolution R x R. ``mode="reference"`` uses cv2.INTER_LINEAR
   always (bit-for-bit the reference path); ``mode="quality"`` (the default) uses cv2.INTER_AREA when
   shrinking (S > R: no aliasing) and cv2.INTER_LINEAR when enlarging.

Inverse: network pixels go back to the crop box by bilinear interpolation when enlarging (S > R) and
cv2.INTER_AREA when shrinking; outside the box the mask is zero, so nothing there is touched.
Pixel centres follow OpenCV's convention: network pixel u covers square pixels ((u + 0.5) S/R - 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..engine.errors import RelightError

MARGIN = 5
MODES = ("quality", "reference")
# mode="quality" places the box and the square alike on a photo and its mirror image: the margin on both sides of
# the mask (the reference's exclusive end leaves 4 px after it) and, where padding the crop left-right is odd, a square
# one row larger (below) so the left and right padding are equal; otherwise a mirror's crop sits a pixel apart (0.55
# network pixels on the 290 x 508 example), which alone kept a mirrored photo from relighting to the mirrored result
# once stage 1 and the face mesh are averaged (mirror31). mode="reference" keeps the reference's crop bit for bit.
# On since mirror34 with the other three parts of the mirror-symmetric chain (relight_rt.relight.network
# ``STAGE1_MIRROR``, ``STAGE2_MIRROR``, relight_rt.person.face_mesh ``MESH_FLIP``; docs/RESULTS.md: "Shipped: the
# mirror-symmetric chain").
SYMMETRIC_CROP = True


def _by_four(fn, a: np.ndarray) -> np.ndarray:
    """Apply an OpenCV resampling ``fn`` to (H, W[, C]); more than 4 channels go through in groups of 4."""
    if a.ndim == 2 or a.shape[2] <= 4:
        out = fn(a)
        return out[..., None] if out.ndim < a.ndim else out
    return np.concatenate([_by_four(fn, np.ascontiguousarray(a[..., i : i + 4])) for i in range(0, a.shape[2], 4)], 2)


def _toward_cut(centred: int, total: int, cut_before: bool, cut_after: bool) -> int:
    """Padding before the crop on its padded axis: none when only its start is cut by the photo's border,
    all of it when only its end is, otherwise the centred amount."""
    if cut_before and not cut_after:
        return 0
    if cut_after and not cut_before:
        return total
    return centred


@dataclass(frozen=True)
class CropGeometry:
    """Where the network's R x R square lies in the input image.

    Attributes:
        frame: (H, W) of the input image.
        box: (y0, y1, x0, x1), the crop in input pixels (end exclusive).
        offset: (oy, ox), where the crop starts inside the padded square.
        side: S, the side of the padded square in input pixels.
        resolution: R, the network's square size.
        mode: "quality" or "reference" (how the forward resize interpolates).
    """

    frame: tuple[int, int]
    box: tuple[int, int, int, int]
    offset: tuple[int, int]
    side: int
    resolution: int
    mode: str = "quality"

    @classmethod
    def from_mask(cls, mask: np.ndarray, resolution: int, mode: str = "quality", margin: int = MARGIN) -> CropGeometry:
        """The geometry for a (H, W) float mask (the box covers every pixel with mask > 0)."""
        if mode not in MODES:
            raise RelightError(f"preprocessing mode is {mode!r}, expected one of {list(MODES)}")
        rows = np.flatnonzero(mask.any(axis=1))
        cols = np.flatnonzero(mask.any(axis=0))
        if rows.size == 0:
            raise RelightError("mask is empty; expected the person in white")
        h_img, w_img = mask.shape[:2]
        symmetric = SYMMETRIC_CROP and mode == "quality"
        end = int(symmetric)  # the box's exclusive end one past the margin (symmetric) or on it (the reference)
        y0, y1 = max(int(rows[0]) - margin, 0), min(int(rows[-1]) + end + margin, h_img)
        x0, x1 = max(int(cols[0]) - margin, 0), min(int(cols[-1]) + end + margin, w_img)
        # with margin 0 the exclusive end would drop the last mask row/column; keep it inside the box
        y1, x1 = max(y1, int(rows[-1]) + 1), max(x1, int(cols[-1]) + 1)
        h, w = y1 - y0, x1 - x0
        side = max(h, w)
        if symmetric and h > w:
            side += (side - w) % 2  # equal padding left and right: the odd pixel goes to the rows (below)
        pad = (side - min(h, w)) // 2
        if mode == "quality":
            # a cut by the photo's border stays on the square's border (module docstring, step 2)
            if h > w:
                pad = _toward_cut(pad, side - w, cols[0] == 0, cols[-1] == w_img - 1)
            else:
                pad = _toward_cut(pad, side - h, rows[0] == 0, rows[-1] == h_img - 1)
        offset = (0, pad) if h > w else (pad, 0)
        return cls((h_img, w_img), (y0, y1, x0, x1), offset, side, int(resolution), mode)

    @property
    def crop_shape(self) -> tuple[int, int]:
        """(h, w) of the crop box."""
        y0, y1, x0, x1 = self.box
        return y1 - y0, x1 - x0

    @property
    def scale(self) -> float:
        """Input pixels per network pixel, S / R (> 1: the network sees the person smaller than the photo)."""
        return self.side / self.resolution

    def crop(self, image: np.ndarray) -> np.ndarray:
        """The crop box of an input-frame array (a view, not a copy)."""
        y0, y1, x0, x1 = self.box
        return image[y0:y1, x0:x1]

    def to_network(self, image: np.ndarray) -> np.ndarray:
        """Input frame (H, W[, C]) float32 → network frame (R, R[, C]): crop, zero-pad to a square, resize."""
        return self.crop_to_network(self.crop(image))

    def crop_to_network(self, crop: np.ndarray) -> np.ndarray:
        """``to_network`` of what lies in the crop box, given as the box's (h, w[, C]) float32 (no input-frame array
        made around it)."""
        h, w = self.crop_shape
        if crop.shape[:2] != (h, w):
            raise RelightError(f"crop_to_network: expected the crop box's ({h}, {w}), got {crop.shape[:2]}")
        oy, ox = self.offset
        crop = np.ascontiguousarray(crop)
        r = self.resolution
        interp = cv2.INTER_AREA if (self.side > r and self.mode == "quality") else cv2.INTER_LINEAR

        def square_and_resize(a: np.ndarray) -> np.ndarray:
            sq = cv2.copyMakeBorder(a, oy, self.side - h - oy, ox, self.side - w - ox, cv2.BORDER_CONSTANT, value=0)
            return sq if self.side == r else cv2.resize(sq, (r, r), interpolation=interp)

        return _by_four(square_and_resize, crop)

    def net_affine(self, origin: tuple[int, int] = (0, 0), start: tuple[int, int] = (0, 0)) -> np.ndarray:
        """(2, 3) float64: the affine map from a crop-box pixel (x, y), counted from ``start`` (y, x) in the box, to
        the network frame's (x, y), counted from ``origin`` (y, x) (a window of it): where ``to_network`` puts that
        pixel (the padded square resized as ``cv2.resize`` maps pixel centres). ``cv2.warpAffine`` with
        ``WARP_INVERSE_MAP`` reads a network map onto the box with it (``to_crop``)."""
        (oy, ox), k = self.offset, self.resolution / self.side
        return np.array([[k, 0.0, (ox + start[1] + 0.5) * k - 0.5 - origin[1]],
                         [0.0, k, (oy + start[0] + 0.5) * k - 0.5 - origin[0]]])

    def to_crop(self, net: np.ndarray, origin: tuple[int, int] = (0, 0)) -> np.ndarray:
        """Network frame (R, R[, C]) → the crop box (h, w[, C]) in input pixels (new float32 array).

        ``origin`` (y, x): ``net`` is only the window of the network frame that starts there (enlarging
        only; what lies beyond the window repeats its border).
        """
        h, w = self.crop_shape
        oy, ox = self.offset
        r, s = self.resolution, self.side
        net = np.ascontiguousarray(net, dtype=np.float32)
        if origin != (0, 0) and s <= r:
            raise RelightError("to_crop: a window origin needs an enlarging geometry (side > resolution)")
        if s == r:
            return net[oy : oy + h, ox : ox + w].copy()
        if s > r:
            # enlarging: sample only the crop box (no S x S intermediate); the same mapping as cv2.resize
            m = self.net_affine(origin)
            flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            return _by_four(lambda a: cv2.warpAffine(a, m, (w, h), flags=flags, borderMode=cv2.BORDER_REPLICATE), net)
        return _by_four(lambda a: cv2.resize(a, (s, s), interpolation=cv2.INTER_AREA)[oy : oy + h, ox : ox + w], net)

    def to_input(self, net: np.ndarray) -> np.ndarray:
        """Network frame (R, R[, C]) → input frame (H, W[, C]) float32, zero outside the crop box."""
        crop = self.to_crop(net)
        full = np.zeros(self.frame + crop.shape[2:], dtype=np.float32)
        y0, y1, x0, x1 = self.box
        full[y0:y1, x0:x1] = crop
        return full
