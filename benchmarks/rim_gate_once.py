"""How far the fill rim's colour gate moves without its second blur (relight_rt.relight.shadow_rim ``rim_colour_gate``).

    PYTHONPATH=$PWD python benchmarks/rim_gate_once.py PHOTO [PHOTO ...]

``rim_colour_gate`` spreads the rim's colour (one blur over the window's RIM_SPREAD), then hands it to
``look.skin_chroma``, which blurs it again over its own 1.5 px before reading its YCrCb skin ramp. This relights each
photo (the bundled models, the automatic matte, ``studio``), takes the gate's inputs on its first call, and prints
the gate as it is against the same ramp read straight off the spread colour (no second blur): the largest and mean
difference. Photos with no rim to gate (a grey photo, no deep shadow) say so.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photos", nargs="+")
    args = p.parse_args()

    import cv2
    import numpy as np

    import relight_rt
    from relight_rt import lights
    from relight_rt.image.color import REC709
    from relight_rt.image.io import read_image
    from relight_rt.relight import shadow_rim
    from relight_rt.relight.look import skin_chroma

    seen = []
    gate = shadow_rim.rim_colour_gate

    def spy(rgb, rim, lit, sigma):
        out = gate(rgb, rim, lit, sigma)
        seen.append((rgb, rim, lit, sigma, out))
        return out

    def spread(rgb, rim, lit, sigma):
        """The rim's colour at the lit person's luminance, as rim_colour_gate spreads it (before skin_chroma)."""
        weighted = np.dstack([rgb * rim[..., None], rim]).astype(np.float32)
        prior = weighted[..., :3].reshape(-1, 3).sum(axis=0) / float(rim.sum())
        step = 4 if sigma >= 8 else 1
        small = weighted if step == 1 else cv2.resize(weighted, None, fx=1 / step, fy=1 / step,
                                                      interpolation=cv2.INTER_AREA)  # fmt: skip
        small = cv2.GaussianBlur(small, (0, 0), sigma / step)
        both = small if step == 1 else cv2.resize(small, rim.shape[::-1], interpolation=cv2.INTER_LINEAR)
        colour = ((both[..., :3] + shadow_rim.SPREAD_PRIOR * prior) / (both[..., 3:] + shadow_rim.SPREAD_PRIOR))
        colour = colour.astype(np.float32)
        level = float(np.median(rgb[lit] @ REC709))
        colour *= (level / np.maximum(colour @ REC709, 1e-4))[..., None]
        return np.clip(colour, 0, 1)

    def ramp(colour):
        """look.skin_chroma's YCrCb skin ramp read straight off ``colour`` (no blur)."""
        ycc = cv2.cvtColor(colour.astype(np.float32), cv2.COLOR_RGB2YCrCb) * 255
        soft = lambda v, lo, hi: np.clip(np.minimum(v - lo, hi - v) / 8 + 0.5, 0, 1)  # noqa: E731
        return (soft(ycc[..., 1], 135, 180) * soft(ycc[..., 2], 85, 135)).astype(np.float32)

    shadow_rim.rim_colour_gate = spy
    r = relight_rt.open()
    for photo in args.photos:
        seen.clear()
        r.relight(read_image(photo), lights.preset("studio"))
        name = Path(photo).name
        if not seen or seen[0][4] is None:
            print(f"{name}: no rim colour gate (grey photo, or no lift to gate)")
            continue
        rgb, rim, lit, sigma, g = seen[0]
        colour = spread(rgb, rim.astype(np.float32), lit, sigma)
        assert np.array_equal(skin_chroma(colour, np.ones(rim.shape, np.float32))[1], g)  # the gate, reproduced
        d = np.abs(ramp(colour) - g)
        print(f"{name}: window {g.shape[1]}x{g.shape[0]}, spread {sigma:.1f} px: the gate without the second blur "
              f"moves by up to {d.max():.4f} (mean {d.mean():.5f}; gate mean {g.mean():.3f})")


if __name__ == "__main__":
    main()
