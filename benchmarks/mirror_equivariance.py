"""Does a mirrored photo relight to the mirrored result? relight(mirror(photo)) against mirror(relight(photo)).

    python benchmarks/mirror_equivariance.py [--out DIR] [--dpr DPR_REPO]

The bundled example (relight_rt/data/example.png, its alpha as the mask) and DPR's demo portrait (data/obama.jpg of
github:zhhoper/DPR, ``--dpr`` as benchmarks/real_photos.py takes it) under ``LEFT`` and ``campfire`` (the mirror
relit under the light mirrored: y -> -y, relight_rt.light.sh ``MIRROR_SIGNS``). "given": the photo's mask given
(DPR's portrait: the automatic matte of the photo, mirrored for the mirror); "auto": both photos with their own
automatic matte (what the matte adds). Figures: the 99th percentile and the max of the 8-bit |difference| over the
person (mask >= 0.5; for "auto" the union of the two mattes, one mirrored), and the mean. With ``--out`` each case's
two results and their difference (x8) are written side by side. Relights with whatever ``relight_rt`` is importable,
on the CPU; use benchmarks/mesh_flip.py to run it with the mirror averaging off.

The four mirror-symmetric parts (stage 1, face mesh, crop, stage 2) are switched by benchmarks/mesh_flip.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import dpr_protocol as dprp  # noqa: E402
from real_photos import LEFT  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.light.sh import MIRROR_SIGNS  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"


def to8(a: np.ndarray) -> np.ndarray:
    return np.rint(np.clip(a, 0, 1) * 255).astype(np.int16)


def compare(relighter, rgb, mask, light, name: str) -> tuple[dict, np.ndarray]:
    """The figures for one photo and light; mask None: the automatic matte on each."""
    light = np.asarray(relighter.resolve_light(light), np.float64)
    mlight = MIRROR_SIGNS[:, None] * light
    flip = np.ascontiguousarray(rgb[:, ::-1])
    if mask is None:
        d1, d2 = relighter.decompose(rgb), relighter.decompose(flip)
        person = (np.asarray(d1.mask) >= 0.5) | (np.asarray(d2.mask)[:, ::-1] >= 0.5)
    else:
        d1, d2 = relighter.decompose(rgb, mask), relighter.decompose(flip, np.ascontiguousarray(mask[:, ::-1]))
        person = mask >= 0.5
    a = to8(relighter.relight(d1, light.astype(np.float32)))
    b = to8(relighter.relight(d2, mlight.astype(np.float32)))[:, ::-1]
    diff = np.abs(a - b).max(axis=2)[person]
    row = {"case": name, "p99": float(np.percentile(diff, 99)), "max": int(diff.max()), "mean": float(diff.mean()),
           "light_mirror_err": float(np.abs(d2.light - MIRROR_SIGNS[:, None] * d1.light).max())}
    sheet = np.concatenate([a, b, np.clip(np.abs(a - b) * 8, 0, 255)], axis=1).astype(np.uint8)
    return row, sheet


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--dpr", default=None)
    args = p.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    rgba = cv2.imread(str(EXAMPLE), cv2.IMREAD_UNCHANGED)
    photos = [("example", cv2.cvtColor(rgba[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255,
               rgba[..., 3].astype(np.float32) / 255)]
    repo = dprp.DPRRepo.find(args.dpr)
    if repo is None:
        print("no DPR repository (give --dpr): DPR's portrait skipped")
    else:
        rgb = repo.image(dprp.DEMO_PHOTO)
        photos.append(("dpr_obama", rgb, np.asarray(relighter.decompose(rgb).mask, np.float32)))
    rows = []
    for name, rgb, mask in photos:
        for lname, light in (("LEFT", LEFT), ("campfire", "campfire")):
            for how, m in (("given", mask), ("auto", None)):
                row, sheet = compare(relighter, rgb, m, light, f"{name} {lname} {how}")
                rows.append(row)
                print(f"{row['case']:28s} p99 {row['p99']:5.1f}  max {row['max']:3d}  mean {row['mean']:.3f}  "
                      f"light mirror err {row['light_mirror_err']:.4f}", flush=True)
                if args.out is not None:
                    args.out.mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(args.out / f"{name}_{lname}_{how}.png"), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
