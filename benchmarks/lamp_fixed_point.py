"""Is face_refit a fixed point on a light the face already shows, with light29's lamp target on?

    python benchmarks/lamp_fixed_point.py [--share 0.3] [--seed 2]

tests/runtime/relight/test_strength.py's ``test_face_refit_keeps_a_light_the_face_already_shows...`` face, rebuilt
here (6000 skin normals facing the camera, drawn as the test's ``_normals`` draws them; the light a lamp from the
front right and a little above, projected to nine terms, plus 0.1 ambient; the photo 0.6 x transport . light, so
the face shows exactly that light). Prints ``strength.lamp_fit``'s share and explained figure there, and the
relative residual on the face (after the best scale) of the light itself, of the lamp fit, and of face_refit's
answer with ``LAMP_SHARE`` = ``--share``, with the answer's band-1 direction off the light's. face31's record
(docs/results_pending.md): the rule, not the test, is wrong there.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from relight_rt.person.face_mesh import lobe_transport
from relight_rt.relight import strength


def test_face(seed: int, n: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """(transport (n, 9), light (9,)): the unit test's face and the nine-term light it shows."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 0] = np.abs(v[:, 0]) + 0.3
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    transport = np.stack([lobe_transport(x) for x in v]).astype(np.float64)
    lamp = np.array([1.0, 0.4, 0.3]) / np.linalg.norm([1.0, 0.4, 0.3])
    light = 0.4 * lobe_transport(lamp).astype(np.float64) / np.pi
    light[0] += 0.1
    return transport, light


def residual(transport: np.ndarray, light: np.ndarray, photo: np.ndarray) -> float:
    s = transport @ light
    k = float(s @ photo) / float(s @ s)
    return float(np.sqrt(np.mean((photo - k * s) ** 2) / np.mean(photo**2)))


def band1(light: np.ndarray) -> np.ndarray:
    v = np.asarray(light, np.float64)[[3, 1, 2]]
    return v / np.linalg.norm(v)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--share", type=float, default=0.3)
    p.add_argument("--seed", type=int, default=2)
    args = p.parse_args(argv)
    transport, light = test_face(args.seed)
    photo = 0.6 * (transport @ light)
    lamp = strength.lamp_fit(transport, photo)
    strength.LAMP_SHARE = args.share
    rgb = np.repeat(light[:, None], 3, axis=1).astype(np.float32)
    out = strength.face_refit(rgb, transport, photo, np.full(len(photo), 0.5), transport)
    off = float(np.degrees(np.arccos(np.clip(band1(out[:, 1]) @ band1(light), -1, 1))))
    print(f"lamp fit: share {lamp.share:.3f}, explained {lamp.explained:.4f}; qualifies at share {args.share}: "
          f"{lamp.share >= args.share and lamp.explained >= strength.LAMP_EXPLAINED}")
    own, fit, answer = (residual(transport, x, photo) for x in (light, lamp.light, out[:, 1]))
    print(f"relative residual on the face: the light itself {own:.4f}, the lamp fit {fit:.4f}, face_refit's answer "
          f"{answer:.4f}")
    print(f"face_refit's answer: band-1 direction {off:.2f} deg off the light's, largest coefficient change "
          f"{np.abs(out - rgb).max():.4f} (largest coefficient {np.abs(light).max():.4f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
