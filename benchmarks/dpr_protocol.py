"""DPR (Zhou et al., "Deep Single-Image Portrait Relighting", ICCV 2019) as a yardstick for real photos.

Used by ``benchmarks/real_photos.py``; nothing of DPR is copied into this repository. At run time this module
reads a copy of DPR's public repository (github:zhhoper/DPR) — a checkout, or the bare git directory that a
mirror gives (files are then read with ``git show HEAD:PATH``) — for its demo portrait, its seven demo lights,
its stored demo results, its network definition and its weights.

Light conversion (exact): DPR's shading is ``SH_basis(n) @ sh`` (utils/utils_SH.py), a real SH basis in the
order 1, y, z, x, yx, yz, 3z²−1, xz, x²−y² with the cosine-lobe factors π, 2π/3, π/4 already folded in and no
Condon–Shortley sign; its frame is x = image right, y = away from the camera, z = up (the demo's sphere normals
have y = −sqrt(1 − x² − z²) for the visible half). Ours (DESIGN.md §3) is x = toward the camera, y = image right,
z = up, so n_dpr = (n_y, −n_x, n_z). The 9 x 9 matrix taking DPR coefficients to ours is the least-squares fit of
DPR's shading by ours on sphere normals (both span the same degree-2 polynomials, so the fit is exact: the
residual is printed, ~1e-15). DPR's demo multiplies its lights by 0.7 before use (``DEMO_SCALE``).

Running DPR: the 512-px grey network (model/defineHourglass_512_gray_skip.py + trained_model/trained_model_03.t7,
a plain state dict, loaded with ``torch.load(weights_only=True)``) on the L channel of the photo's 8-bit Lab, as
testNetwork_demo_512.py does; a and b are kept. Results are cached on disk by the hash of input and light.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from relight_rt.image.color import REC709
from relight_rt.light.sh import basis, cosine_lobe

DEMO_SCALE = 0.7  # testNetwork_demo_512.py: sh = sh * 0.7
DEMO_PHOTO = "data/obama.jpg"
N_DEMO_LIGHTS = 7
NET_FILE = "model/defineHourglass_512_gray_skip.py"
WEIGHTS = "trained_model/trained_model_03.t7"
DEFAULT_LOCATIONS = ("/work/.mirror/zhhoper+DPR/repo",)


# ------------------------------------------------------------------------------------------- SH frames


def dpr_basis(normals: np.ndarray) -> np.ndarray:
    """DPR's SH_basis (with its attenuation), (N, 3) normals in DPR's frame → (N, 9); written from its formulas."""
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    att = (math.pi, 2 * math.pi / 3, math.pi / 4)
    c0 = 0.5 / math.sqrt(math.pi)
    c1 = math.sqrt(3) / 2 / math.sqrt(math.pi)
    c2 = math.sqrt(15) / 2 / math.sqrt(math.pi)
    c20 = math.sqrt(5) / 4 / math.sqrt(math.pi)
    c22 = math.sqrt(15) / 4 / math.sqrt(math.pi)
    return np.stack([
        np.full_like(x, c0 * att[0]),
        c1 * y * att[1], c1 * z * att[1], c1 * x * att[1],
        c2 * y * x * att[2], c2 * y * z * att[2], c20 * (3 * z * z - 1) * att[2], c2 * x * z * att[2],
        c22 * (x * x - y * y) * att[2],
    ], axis=1)


def to_dpr_frame(n_ours: np.ndarray) -> np.ndarray:
    """Our frame (x toward the camera, y image right, z up) → DPR's (x image right, y away from the camera, z up)."""
    return np.stack([n_ours[:, 1], -n_ours[:, 0], n_ours[:, 2]], axis=1)


def sphere_normals(n: int = 2000) -> np.ndarray:
    """(n, 3) unit vectors spread over the whole sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = math.pi * (1 + math.sqrt(5)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def conversion() -> tuple[np.ndarray, float]:
    """(C, residual): our (9,) light = C @ DPR's (9,) coefficients gives the same shading on every normal.

    residual: the largest absolute shading difference of the fit on the sphere, per unit coefficient.
    """
    n = sphere_normals()
    ours = basis(n) * cosine_lobe()[None, :]  # our shading basis: A_l Y_k(n)
    theirs = dpr_basis(to_dpr_frame(n))
    c, *_ = np.linalg.lstsq(ours, theirs, rcond=None)
    return c, float(np.abs(ours @ c - theirs).max())


def dpr_to_ours(sh: np.ndarray) -> np.ndarray:
    """DPR's 9 grey coefficients (already scaled as used) → our (9, 3) white RGB light."""
    c, _ = conversion()
    return np.repeat((c @ np.asarray(sh, np.float64).reshape(9))[:, None], 3, axis=1)


def ours_to_dpr(light: np.ndarray, dc: float | None = None) -> np.ndarray:
    """Our (9, 3) light → DPR's 9 coefficients (its Rec. 709 luminance), optionally rescaled to DC ``dc``."""
    c, _ = conversion()
    lum = np.asarray(light, np.float64) @ REC709.astype(np.float64)
    sh = np.linalg.solve(c, lum)
    return sh * (dc / sh[0]) if dc is not None else sh


# --------------------------------------------------------------------------------------------- the repo


class DPRRepo:
    """Read-only access to a copy of DPR's repository: a checkout or a bare git directory."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.bare = not (self.path / NET_FILE).is_file()
        if self.bare and not (self.path / "HEAD").is_file():
            raise FileNotFoundError(f"{self.path}: neither a DPR checkout nor a git directory")
        self.read(NET_FILE)  # fails early if this is not DPR

    @classmethod
    def find(cls, given: str | None) -> DPRRepo | None:
        """``given``, else $DPR_REPO, else the mirror's usual place; None when none is there."""
        for cand in ([given] if given else [os.environ.get("DPR_REPO"), *DEFAULT_LOCATIONS]):
            if cand and Path(cand).exists():
                return cls(cand)
        return None

    def read(self, rel: str) -> bytes:
        if not self.bare:
            return (self.path / rel).read_bytes()
        return subprocess.run(["git", "--git-dir", str(self.path), "show", f"HEAD:{rel}"], check=True,
                              capture_output=True).stdout

    def image(self, rel: str) -> np.ndarray:
        """An image of the repo as float32 RGB in [0, 1]."""
        bgr = cv2.imdecode(np.frombuffer(self.read(rel), np.uint8), cv2.IMREAD_COLOR)
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255

    def demo_light(self, i: int) -> np.ndarray:
        """Demo light i as the demo uses it: the file's first 9 numbers x 0.7."""
        text = self.read(f"data/example_light/rotate_light_{i:02d}.txt").decode()
        return DEMO_SCALE * np.array([float(v) for v in text.split()][:9])

    def demo_result(self, i: int) -> np.ndarray:
        return self.image(f"result/obama_{i:02d}.jpg")


# ------------------------------------------------------------------------------------------- the network


class DPRNet:
    """DPR's 512-px grey relighting network on the CPU, with a disk cache of its outputs."""

    def __init__(self, repo: DPRRepo, cache: Path, threads: int = 2) -> None:
        self.repo, self.cache, self.threads = repo, Path(cache), threads
        self._net = None
        self.tag = hashlib.sha1(repo.read(WEIGHTS)).hexdigest()[:12]

    def _load(self):
        import torch  # only when DPR actually runs (cache misses)

        torch.set_num_threads(self.threads)
        with tempfile.TemporaryDirectory() as tmp:
            src = Path(tmp) / "dpr_hourglass_512.py"
            src.write_bytes(self.repo.read(NET_FILE))
            wpath = Path(tmp) / "weights.t7"
            wpath.write_bytes(self.repo.read(WEIGHTS))
            spec = importlib.util.spec_from_file_location("dpr_hourglass_512", src)
            mod = importlib.util.module_from_spec(spec)
            sys.modules[spec.name] = mod
            spec.loader.exec_module(mod)
            state = torch.load(wpath, map_location="cpu", weights_only=True)
        net = mod.HourglassNet()
        net.load_state_dict(state)
        net.train(False)
        self._net = net
        return net

    def relight_l(self, l512: np.ndarray, sh: np.ndarray) -> np.ndarray:
        """(512, 512) uint8 Lab L → DPR's relit L, float32 in [0, 1] (cached)."""
        key = hashlib.sha1(self.tag.encode() + l512.tobytes() + np.asarray(sh, np.float32).tobytes()).hexdigest()
        path = self.cache / f"dpr_{key[:24]}.npy"
        if path.is_file():
            return np.load(path, allow_pickle=False)
        import torch

        net = self._net or self._load()
        x = torch.from_numpy((l512.astype(np.float32) / 255)[None, None])
        light = torch.from_numpy(np.asarray(sh, np.float32).reshape(1, 9, 1, 1))
        with torch.no_grad():
            out, _ = net(x, light, 0)
        res = out[0, 0].numpy().astype(np.float32)
        self.cache.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npy")
        np.save(tmp, res, allow_pickle=False)
        os.replace(tmp, path)
        return res

    def relight(self, rgb: np.ndarray, sh: np.ndarray, box: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Relight a photo (float RGB in [0, 1]) with DPR under DPR coefficients ``sh`` (as used, scale included).

        box None: the demo's protocol (the whole photo squashed to 512 x 512, Lab a/b of the 512 image kept,
        the result resized back). box (x0, y0, x1, y1): only that square region is relit (resized to 512, its
        L replaced at full resolution, a/b of the photo kept); the rest of the photo is returned unchanged.
        """
        u8 = np.clip(rgb * 255 + 0.5, 0, 255).astype(np.uint8)
        bgr = cv2.cvtColor(u8, cv2.COLOR_RGB2BGR)
        if box is None:
            h, w = bgr.shape[:2]
            lab = cv2.cvtColor(cv2.resize(bgr, (512, 512)), cv2.COLOR_BGR2LAB)
            lab[..., 0] = (self.relight_l(lab[..., 0], sh) * 255).astype(np.uint8)  # the demo truncates
            out = cv2.resize(cv2.cvtColor(lab, cv2.COLOR_LAB2BGR), (w, h))
            return cv2.cvtColor(out, cv2.COLOR_BGR2RGB).astype(np.float32) / 255
        x0, y0, x1, y1 = box
        crop = bgr[y0:y1, x0:x1]
        lab_small = cv2.cvtColor(cv2.resize(crop, (512, 512), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2LAB)
        l_out = self.relight_l(lab_small[..., 0], sh)
        lab = cv2.cvtColor(crop, cv2.COLOR_BGR2LAB)
        l_full = cv2.resize(l_out, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
        lab[..., 0] = np.clip(l_full * 255 + 0.5, 0, 255).astype(np.uint8)
        out = bgr.copy()
        out[y0:y1, x0:x1] = cv2.cvtColor(lab, cv2.COLOR_LAB2BGR)
        return cv2.cvtColor(out, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def square_around(box: tuple[int, int, int, int], shape: tuple[int, int],
                  scale: float = 2.0) -> tuple[int, int, int, int]:
    """A square of side ``scale`` x the face box's larger side, centred on it, moved/shrunk to fit the image."""
    x0, y0, x1, y1 = box
    h, w = shape
    side = int(min(round(scale * max(x1 - x0, y1 - y0)), h, w))
    cx, cy = (x0 + x1) // 2, (y0 + y1) // 2
    sx = int(np.clip(cx - side // 2, 0, w - side))
    sy = int(np.clip(cy - side // 2, 0, h - side))
    return sx, sy, sx + side, sy + side
