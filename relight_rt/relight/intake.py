"""What stage 1 reads: a batch of photos and their masks, each cropped to the network's square (``read_batch``)."""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence

import numpy as np

from ..image.crop import CropGeometry
from ..image.io import read_image
from ..person.masks import Matter, resolve_mask
from . import people as people_module
from .people import PartsMatter

log = logging.getLogger(__name__)


def read_batch(images: Sequence, masks: Sequence, auto: Matter | None, group: bool, allow_full: bool,
               resolution: int, preprocess: str) -> tuple[list, list, list, list, list]:
    """Read photos and resolve their masks (relight_rt.person.masks.resolve_mask; ``auto`` the automatic matte, for a
    mask None or "auto") and crop each to the network's square.

    ``group``: keep each person's share of the matte (``PartsMatter``) when the matter finds several, up to
    ``people.MAX_PEOPLE``; ``allow_full``: a mask may cover the whole image or nothing (video frames).

    Returns:
        (RGB images (H, W, 3) float32, masks (H, W), CropGeometry's, per image its people's masks or None, per
        image whether its mask is the automatic matte (no mask or alpha channel given)).
    """
    rgbs, ms, geoms, people, automatic = [], [], [], [], []
    for i, (image, mask) in enumerate(zip(images, masks, strict=True)):
        name = str(image) if isinstance(image, (str, os.PathLike)) else f"image {i}" if len(images) > 1 else "image"
        # an array no one can write to (a Decomposition's photo: a group's people) is not copied
        img = read_image(image, "image", copy=not (isinstance(image, np.ndarray) and not image.flags.writeable))
        matter = auto if mask is None or isinstance(mask, str) else None
        if matter is not None and group and hasattr(matter, "parts"):
            matter = PartsMatter(matter)  # a group photo: everyone's share of the matte kept (``by_person``)
        used = _Used(matter) if matter is not None else None
        m = resolve_mask(img, mask, matter=used, allow_empty=allow_full, name=name)
        automatic.append(used is not None and used.called)
        rgbs.append(np.ascontiguousarray(img[..., :3]) if img.shape[2] == 4 else img)
        ms.append(m)
        found = matter.found if isinstance(matter, PartsMatter) else None
        if found is not None and len(found) > people_module.MAX_PEOPLE:
            log.info("%s: %d people found, relit as one group (person by person up to %d: stage 1 runs once a "
                     "person)", name, len(found), people_module.MAX_PEOPLE)
            found = None
        people.append(found if found is not None and len(found) > 1 else None)
        geoms.append(CropGeometry.from_mask(m, resolution, preprocess))
    return rgbs, ms, geoms, people, automatic


class _Used:
    """A matter that remembers whether it was called (a mask or an alpha channel given wins over it)."""

    def __init__(self, matter: Matter) -> None:
        self.matter, self.called = matter, False

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray:
        self.called = True
        return self.matter(rgb, name=name)
