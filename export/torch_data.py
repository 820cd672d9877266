"""Torch datasets over the on-disk training data of :mod:`export.dataset`.

``Stage1Dataset`` yields one rendered sample (albedo, mask, skin, transport) with a random
training light and a random horizontal flip that respects the physics (the SH coefficients odd
in y change sign in transport and light). The image itself is rendered by the training step
(on the training device): ``clip(albedo ⊙ max(0, T·L), 0, 1) ⊙ mask``, see :func:`render_input`.

``PhotoDataset`` yields the non-diffuse "photos" of ``python -m export render-photos``.

Randomness is a pure function of (seed, epoch, index), so results do not depend on the number of
loader workers and a resumed run sees exactly the samples it would have seen.

Samples are brought to the training resolution by padding to a square (centred, zeros) and
resizing (area interpolation when shrinking, bilinear when enlarging). Transport is linear in the
resize, so T·L of the resized transport equals the resized shading.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import torch

from relight_rt import RelightError

from .frozen import OnnxStage
from .losses import FLIP_SIGNS
from .shading import render_diffuse

_FLIP = np.asarray(FLIP_SIGNS, dtype=np.float32)


def fit_square(array: np.ndarray, resolution: int) -> np.ndarray:
    """Pad (H, W[, C]) to a centred square with zeros and resize it to resolution².

    Args:
        array: float32 (H, W) or (H, W, C), any C.
        resolution: output side in pixels.

    Returns:
        New float32 array (resolution, resolution[, C]).
    """
    h, w = array.shape[:2]
    side = max(h, w)
    if h != w:
        pad = [((side - h) // 2, side - h - (side - h) // 2), ((side - w) // 2, side - w - (side - w) // 2)]
        pad += [(0, 0)] * (array.ndim - 2)
        array = np.pad(array, pad)
    if side == resolution:
        return np.array(array, dtype=np.float32, copy=True)
    interp = cv2.INTER_AREA if side > resolution else cv2.INTER_LINEAR
    out = cv2.resize(np.ascontiguousarray(array, dtype=np.float32), (resolution, resolution), interpolation=interp)
    if array.ndim == 3 and out.ndim == 2:  # cv2 drops a trailing channel axis of size 1
        out = out[:, :, None]
    return out.astype(np.float32, copy=False)


def _chw(array: np.ndarray) -> torch.Tensor:
    if array.ndim == 2:
        array = array[:, :, None]
    return torch.from_numpy(np.ascontiguousarray(array.transpose(2, 0, 1), dtype=np.float32))


def item_rng(seed: int, epoch: int, index: int) -> np.random.Generator:
    """The random generator of one item in one epoch."""
    return np.random.default_rng([seed, epoch, index])


def epoch_order(n: int, seed: int, epoch: int) -> np.ndarray:
    """The order in which epoch ``epoch`` visits the n items (a permutation)."""
    return np.random.default_rng([seed, epoch, 2**31 - 1]).permutation(n)


class Stage1Dataset(torch.utils.data.Dataset):
    """Stage-1 samples with random lights and flips.

    Args:
        root: folder of samples (DESIGN.md §6 layout).
        lights: (M, 9, 3) float RGB training lights.
        resolution: training resolution (square side).
        names: the samples to use (default: all of ``list_samples(root)``).
        augment: random flips and random lights per epoch; when False (validation) item i always
            gets the same light (drawn from the seed) and no flip.
        seed: base seed.
        cache: keep the resized samples in memory (float16 transport), recommended at ≤ 256².
        flip: allow random horizontal flips when augmenting.

    Items are dicts of float32 tensors: albedo (3,R,R) RGB in [0,1], mask (1,R,R), skin (1,R,R),
    transport (9,R,R), light (9,3) RGB, and ``index`` (int).
    """

    def __init__(
        self,
        root: str | Path,
        lights: np.ndarray,
        resolution: int,
        names: Sequence[str] | None = None,
        augment: bool = True,
        seed: int = 0,
        cache: bool = True,
        flip: bool = True,
    ):
        from . import dataset

        self.root = Path(root)
        self.names = list(dataset.list_samples(self.root) if names is None else names)
        if not self.names:
            raise RelightError(f"{self.root}: no stage-1 samples found (expected NAME_tex.png, NAME_mask.png, ...)")
        lights = np.asarray(lights, dtype=np.float32)
        if lights.ndim != 3 or lights.shape[1:] != (9, 3) or len(lights) == 0:
            raise RelightError(f"lights: expected (M, 9, 3) training lights with M >= 1, got {lights.shape}")
        self.lights = lights
        self.resolution = int(resolution)
        self.augment = augment
        self.flip = flip
        self.seed = int(seed)
        self.epoch = 0
        self._cache: dict[int, dict[str, np.ndarray]] | None = {} if cache else None

    def __len__(self) -> int:
        return len(self.names)

    def set_epoch(self, epoch: int) -> None:
        """Select the randomness of this epoch (call before iterating)."""
        self.epoch = int(epoch)

    def _load(self, index: int) -> dict[str, np.ndarray]:
        if self._cache is not None and index in self._cache:
            return self._cache[index]
        from . import dataset

        s = dataset.read_sample(self.root, self.names[index])
        r = self.resolution
        item = {
            "albedo": fit_square(s["albedo"], r),
            "mask": fit_square(s["mask"], r),
            "skin": fit_square(s["skin"], r),
            "transport": fit_square(s["transport"], r),
        }
        if self._cache is not None:
            item["transport"] = item["transport"].astype(np.float16)
            self._cache[index] = item
        return item

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        s = self._load(index)
        if self.augment:
            rng = item_rng(self.seed, self.epoch, index)
            light = self.lights[rng.integers(len(self.lights))]
            flip = bool(rng.integers(2)) and self.flip
        else:
            light = self.lights[item_rng(self.seed, 2**31 - 2, index).integers(len(self.lights))]
            flip = False
        albedo, mask, skin = s["albedo"], s["mask"], s["skin"]
        transport = s["transport"].astype(np.float32)
        if flip:
            albedo, mask, skin, transport = (x[:, ::-1] for x in (albedo, mask, skin, transport))
            transport = transport * _FLIP
            light = light * _FLIP[:, None]
        return {
            "albedo": _chw(albedo),
            "mask": _chw(mask),
            "skin": _chw(skin),
            "transport": _chw(transport),
            "light": torch.from_numpy(np.array(light, dtype=np.float32)),
            "index": index,
        }


def render_input(batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """The training image of a stage-1 batch: clip(albedo ⊙ max(0, T·L), 0, 1) ⊙ mask.

    Args:
        batch: albedo (N,3,H,W), transport (N,9,H,W), light (N,9,3), mask (N,1,H,W).

    Returns:
        (N, 3, H, W) float image in [0, 1], RGB.
    """
    return render_diffuse(batch["albedo"], batch["transport"], batch["light"], batch["mask"])


def subject_of(photo_name: str) -> str:
    """The subject of a photo name ``SUBJECT__L{j}`` (the whole name when it has no ``__L``)."""
    return photo_name.rsplit("__L", 1)[0]


class PhotoDataset(torch.utils.data.Dataset):
    """Rendered non-diffuse photos (``SUBJECT__L{j}``) at a square training resolution.

    Args:
        root: folder written by ``python -m export render-photos``.
        resolution: square side.
        names: photos to use (default: all of ``list_photos(root)``).
        cache: keep resized photos in memory.

    Items: photo (3,R,R) RGB [0,1], mask (1,R,R), light (9,3) RGB (zeros for a photo of one's own, whose
    light is not known), diffuse (3,R,R) (the renderer's diffuse part, zeros when absent), ``index`` (int).
    """

    def __init__(self, root: str | Path, resolution: int, names: Sequence[str] | None = None, cache: bool = True):
        from . import dataset

        self.root = Path(root)
        self.names = list(dataset.list_photos(self.root) if names is None else names)
        if not self.names:
            raise RelightError(f"{self.root}: no photos found (expected SUBJECT__L{{j}}_photo.png, ...)")
        self.resolution = int(resolution)
        self._cache: dict[int, dict[str, torch.Tensor]] | None = {} if cache else None

    def __len__(self) -> int:
        return len(self.names)

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        if self._cache is not None and index in self._cache:
            return dict(self._cache[index])
        from . import dataset

        p = dataset.read_photo(self.root, self.names[index])
        r = self.resolution
        diffuse = p.get("diffuse")
        item = {
            "photo": _chw(fit_square(p["photo"], r)),
            "mask": _chw(fit_square(p["mask"], r)),
            "light": torch.from_numpy(np.array(p["light"], dtype=np.float32)) if p["light"] is not None
            else torch.zeros(9, 3),  # one's own photo: its light is not known (stage 1 estimates it)
            "diffuse": _chw(fit_square(diffuse, r)) if diffuse is not None else torch.zeros(3, r, r),
            "index": index,
        }
        if self._cache is not None:
            self._cache[index] = item
        return dict(item)


def decompose(model: torch.nn.Module, image: torch.Tensor, mask: torch.Tensor) -> dict[str, torch.Tensor]:
    """Run a stage-1 network on images and mask its outputs (no grad, the model's current mode).

    Args:
        model: a Stage1Net, or a stage-1 ONNX graph loaded by :func:`export.frozen.load_frozen`.
        image: (N, 3, R, R) RGB in [0, 1].
        mask: (N, 1, R, R) in [0, 1].

    Returns:
        transport (N,9,R,R), albedo (N,3,R,R), skin (N,1,R,R) (all masked) and light (N,9,3), float32.
    """
    if isinstance(model, OnnxStage):  # the graph scales and masks its input and masks its outputs itself
        out = model.run({"image": image, "mask": mask})
        return {k: out[k] for k in ("transport", "albedo", "skin", "light")}
    with torch.no_grad():
        transport, albedo, skin, light = model((2.0 * image - 1.0) * mask)
    return {"transport": transport.float() * mask, "albedo": albedo.float() * mask, "skin": skin.float() * mask,
            "light": light.float()}


