"""Faces as a way in to people: the bundled face detector (``matte_face.onnx``, MediaPipe's BlazeFace full range,
Apache-2.0; ``python -m export mask-models``) and what a face says about where its person is.

The graph sees a square region of the image at 192x192 and predicts, for each cell of a 48x48 grid, a face
score (logit) and a box: centre offset and size in input pixels from the cell's centre, plus six key points
(MediaPipe's decoding, with anchors of size 1 at the cell centres). Boxes above :data:`MIN_SCORE` are merged
by weighted non-maximum suppression (MediaPipe's: overlapping boxes are averaged by score).

relight_rt.person.matting uses faces where the body finders fail (close portraits, where the pose graph's presence
flag says nobody) and to tell apart people who stand together (one blob of the selfie segmenter, several
faces).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FACE_SIZE = 192  # the graph's input side
GRID = 48  # its prediction grid (stride 4)
MIN_SCORE = 0.6  # MediaPipe's threshold for the full-range model
NMS_IOU = 0.3  # boxes overlapping more than this are one face
# A face box (BlazeFace's: brows to chin, about the face's width) -> the box its person is likely to fill:
# shoulders about 3.5 face widths across, a standing body about 8 face heights below the brows.
_BODY_HALF_WIDTH = 1.75
_BODY_ABOVE = 0.6
_BODY_BELOW = 8.0


@dataclass(frozen=True)
class Face:
    """A detected face: box (x0, y0, x1, y1) in image pixels and its score (probability)."""

    box: tuple[float, float, float, float]
    score: float

    @property
    def size(self) -> float:
        return max(self.box[2] - self.box[0], self.box[3] - self.box[1])

    def body_box(self, shape: tuple[int, int]) -> tuple[float, float, float, float]:
        """Where the person of this face is likely to be (module constants), clipped to the image (h, w)."""
        x0, y0, x1, y1 = self.box
        cx, s = (x0 + x1) / 2, self.size
        h, w = shape
        return (max(cx - _BODY_HALF_WIDTH * s, 0.0), max(y0 - _BODY_ABOVE * s, 0.0),
                min(cx + _BODY_HALF_WIDTH * s, float(w)), min(y0 + _BODY_BELOW * s, float(h)))  # fmt: skip


_CENTRES = (np.arange(GRID, dtype=np.float64) + 0.5) / GRID  # anchor centres, as fractions of the canvas


def decode(boxes: np.ndarray, scores: np.ndarray, min_score: float = MIN_SCORE) -> list[tuple[np.ndarray, float]]:
    """The graph's outputs for one canvas -> [(box (x0, y0, x1, y1) in canvas fractions [0, 1], score)].

    Args:
        boxes: (16, 48, 48) float32 regressions (``boxes`` output without the batch axis).
        scores: (1, 48, 48) or (48, 48) float32 logits.
    """
    logit = np.asarray(scores, np.float32).reshape(GRID, GRID)
    prob = 1.0 / (1.0 + np.exp(-np.clip(logit, -80.0, 80.0)))
    iy, ix = np.nonzero(prob > min_score)
    out = []
    for i, j in zip(iy.tolist(), ix.tolist(), strict=True):
        r = boxes[:, i, j] / FACE_SIZE
        cx, cy = _CENTRES[j] + r[0], _CENTRES[i] + r[1]
        w, h = r[2], r[3]
        if w > 0 and h > 0:
            out.append((np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], np.float64), float(prob[i, j])))
    return out


def box_iou(a, b) -> float:
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def weighted_nms(found: list[tuple[np.ndarray, float]], iou: float = NMS_IOU) -> list[tuple[np.ndarray, float]]:
    """MediaPipe's weighted non-maximum suppression: the best-scoring box takes every box that overlaps it by
    more than ``iou``; the merged box is their score-weighted mean, its score the best one. Best first."""
    rest = sorted(found, key=lambda t: -t[1])
    out = []
    while rest:
        best = rest[0]
        group = [t for t in rest if box_iou(best[0], t[0]) > iou]
        rest = [t for t in rest if box_iou(best[0], t[0]) <= iou]
        wsum = sum(s for _, s in group)
        box = sum(b * s for b, s in group) / wsum
        out.append((box, best[1]))
    return out
