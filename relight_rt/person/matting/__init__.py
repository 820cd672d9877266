"""Automatic person matting, bundled and offline: any photo of a person, no mask needed.

Three graphs converted from Google MediaPipe (Apache-2.0; ``python -m export mask-models``, model card):

- ``matte_roi.onnx`` (MediaPipe selfie segmentation, 250 kB) runs on the whole image letterboxed to
  256x256 and says where people are (connected regions of its probability map). When it finds nobody
  at that scale, overlapping tiles (2x2 up to 6x6, each >= 256 px) are searched, so a small person in
  a big photo is still found.
- ``matte_pose.onnx`` (MediaPipe pose landmark "full", segmentation head, 5.7 MB) runs on a square
  region 1.25x the person's box (zero-padded past the image border, as MediaPipe does) and gives
  person logits at 256x256 plus a pose-presence probability. The region is re-centred on that
  segmentation until it is stable (at most ``max_passes`` runs), so a crude first box is corrected;
  where the segmentation runs into the region's edge, the next region reaches further that way.
- ``matte_face.onnx`` (MediaPipe BlazeFace full range, 1.1 MB; optional: relight_rt.person.face_detector) finds faces.
  A face is the second way in where the pose graph's presence flag says nobody (close portraits: the
  selfie graph then segments the face's region), and with ``person="all"`` it tells apart people whom
  the selfie graph sees as one blob (a group is matted face by face).

Where the pose graph's presence flag says nobody, the selfie graph vouches for a person when its segmentation of
the same region has the pose graph's shape (a runner in mid-air, a man lying down); a close portrait is checked as
one when a face at least 0.3x the person's width lies in a pose-graph person ending near the bottom; what the pose
graph half-sees is the person's where the selfie graph agrees (dark trousers); and with nobody else found, the
default matte takes the selfie graph's blob when it is sure of it, else the pose graph's segmentation of it when the
selfie graph on the whole photo sees that shape. A selfie-graph person is averaged with the selfie graph's answer on
the whole photo where the two agree (less of what stands behind a portrait). The default matte also takes someone
the selfie graph sees joined to the person who shows a face of their own (an embracing couple), carries a selfie-graph
segmentation on past its region's side where it was cut there (whole or not at all), and takes what the selfie graph
sees joined to the person in the person's own colours (dark trousers the pose graph misses, not their shadow), and
leaves out, whole, someone out of focus behind the person (a smaller, blurred face of their own in the matte)
(measured on a broad real set: benchmarks/people_masks_eval.py).

``person="all"`` gathers the selfie graph's probability over every tile scale (not only the first that
finds anybody), so passers-by beside a big subject are candidates too; a candidate already inside the
people matted is skipped, a wide blob where the pose graph sees nobody is tried strip by strip, and
people shorter than MIN_PERSON_FRACTION of the photo's height are left out. What it finds (measured on
benchmarks/people_photos.py, docs/RESULTS.md "Automatic mattes"): everyone at least 6 % of the photo's
height tall who stands apart from the others and is in view, down to the street photo's passers-by at
10 % (130 px, faces of 15 px); people who overlap one another in the picture (walking side by side, one
half behind another) can come as one person or, the one behind, not at all, and so can a person of whom
only a sliver shows at the frame's edge.

The 256² logits are mapped back onto a working grid (the region at <= 512 px), turned into a
probability, and refined to full resolution by a fast guided filter steered by the photo (He & Sun
2015: the local linear model alpha ≈ a·I + b is fitted on the working grid with the gray photo as
guide; a and b are upsampled and applied to the full-resolution gray photo), so hair and arm outlines
follow the photo's own edges. Only the person's region is processed at full resolution. Then
(``edges=True``, photos only) the alpha is re-estimated from colour in a band around the outline at
full resolution (relight_rt.image.matte_edges: hair strands, no smear of the old background).

:class:`VideoMatter` keeps state between frames: the person's region comes from the previous frame's
matte (the detector runs again, in the same frame, only when the person is lost, or every ``redetect_every``
frames), the person is completed as in a photo (half-seen trousers, parts in their own colours), and
the working-grid probability is blended with the previous one warped by DIS optical flow, weighted by
how well the flow explains the frame (photometric agreement), which steadies the outline without
dragging it behind a moving person. :func:`outline_flicker` measures what is left.

Modules (one concept each; this package re-exports the public names):

- ``_models``: the graph files, :func:`find_matting_models`, and :func:`as_rgb` (the images matting
  accepts, through the runtime's one image intake relight_rt.image.io).
- ``_segmentation``: a graph's segmentation of one square region (:class:`Person`, :func:`person_box`) and the
  working grid that carries it back over the photo (the square regions themselves, :class:`Region` and
  :func:`crop_region`, are relight_rt.image.regions', re-exported here).
- ``_detect``: where people are (selfie-graph blobs over tiles, faces, a wide blob's strips, faint places).
- ``_matter``: :class:`PersonMatter`, the conductor (it holds the graphs and orders the stages below: who is
  found, what is added to them, the full-resolution alpha) and :func:`shared_matter`.
- ``_candidate``: one candidate's person (the pose graph re-centred until it settles, the portrait check, whether a
  person is there: presence, a face, or the selfie graph agreeing).
- ``_largest``: the largest person's search (person="largest"; a person reached from nobody set aside).
- ``_everyone``: everyone's search (person="all"; also asked by the two below).
- ``_company``: the people with the largest person (peers as tall and seen whole, someone joined with a face).
- ``_completion``: what is added to a person found (half-seen pixels both graphs see, their own colours, limbs seen
  only turned).
- ``_colours``: the person's own colours (what the selfie graph sees joined to the matte, kept by colour).
- ``_shadow``: the person's own cast shadow on the ground at their feet, taken out of the matte.
- ``_things_behind``: things out of focus behind the person (parts the pose graph does not see, blurred where the
  body is sharp, sticking out of the matte: a guitar leaning behind a girl), taken out of the default matte.
- ``_parts``: a group's people as parts of one matte (a segmentation split by faces, rejoined for the matte,
  each person's share of it, people split by faces meeting along the photo's own edges).
- ``_coarse``: the coarse matte at full resolution (working grid + fast guided filter, relight_rt.image.guided_filter).
- ``_video``: :class:`VideoMatter` and :func:`outline_flicker` (flow from relight_rt.image.flow).

Public API (the matting protocol of relight_rt.person.masks: rgb (H, W, 3) float32 in [0, 1] -> soft alpha
(H, W) float32 in [0, 1] at full resolution): ``PersonMatter``, ``VideoMatter``, ``outline_flicker``,
``find_matting_models``, ``shared_matter``, and ``estimate_foreground`` (relight_rt.image.foreground: the
decontaminated foreground colour of a matte's soft edge, for compositing over a new backdrop).
"""

from __future__ import annotations

from ...engine.session import bundled_models_dir as bundled_models_dir
from ...image.foreground import estimate_foreground as estimate_foreground  # re-exported (issue 33)
from ...image.matte_edges import refine_edges as refine_edges  # re-exported: the edge refinement photos get
from ...image.regions import Region, crop_region
from ._coarse import region_alpha
from ._everyone import MIN_PERSON_FRACTION
from ._matter import GUIDES, PERSON_MODES, PersonMatter, shared_matter
from ._models import FACE_FILE, MIN_SIDE, POSE_FILE, ROI_FILE, SIZE, as_rgb, find_matting_models
from ._segmentation import Person, person_box
from ._video import VideoMatter, outline_flicker

__all__ = [
    "FACE_FILE",
    "GUIDES",
    "MIN_PERSON_FRACTION",
    "MIN_SIDE",
    "PERSON_MODES",
    "POSE_FILE",
    "ROI_FILE",
    "SIZE",
    "Person",
    "PersonMatter",
    "Region",
    "VideoMatter",
    "as_rgb",
    "crop_region",
    "estimate_foreground",
    "find_matting_models",
    "outline_flicker",
    "person_box",
    "region_alpha",
    "shared_matter",
]
