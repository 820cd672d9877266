"""Things out of focus behind the person, taken out of the default matte (relight_rt.person.matting._things_behind,
issue 48), on synthetic photos: a portrait (a head and a torso cut by the bottom border, a sharp fine texture) before
a smooth backdrop, with a blurred textured thing beside the shoulder that the selfie graph's matte holds and the pose
graph does not see (a guitar leaning behind a girl)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt.image.regions import Region, crop_region
from relight_rt.person.matting import _things_behind as tb
from relight_rt.person.matting._segmentation import Person, as_logits

H, W = 240, 200


def scene(thing: str = "beside", sharp_thing: bool = False) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(rgb (H, W, 3) float32, parts): parts "body" (head and torso, the pose graph sees it) and "thing" (the matte
    holds it, the pose graph does not). ``thing``: "beside" (left of the head, against the torso's top corner only:
    sticking out), "front" (over the middle of the torso: the body all around it), "bottom" (apart from the torso,
    left of it, cut by the photo's bottom border: an elbow the frame cuts). ``sharp_thing``: its texture as sharp as
    the body's (in focus: a held object)."""
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    backdrop = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0), 4.0)
    rgb = np.repeat((0.45 + 0.5 * backdrop)[..., None], 3, axis=2) * np.array([0.8, 1.0, 0.8], np.float32)
    body = ((xx - 110) ** 2 + (yy - 70) ** 2 < 30**2) | ((xx > 60) & (xx < 160) & (yy > 95))
    if thing == "beside":
        part = ((xx - 42) / 22) ** 2 + ((yy - 80) / 28) ** 2 < 1.0
    elif thing == "front":
        part = (xx > 90) & (xx < 130) & (yy > 150) & (yy < 200)
    else:
        part = (xx > 10) & (xx < 50) & (yy > 190)
    part &= ~body if thing != "front" else True
    fine = rng.standard_normal((H, W)).astype(np.float32)
    skin = 0.55 + 0.12 * fine
    rgb[body] = (skin[body, None] * np.array([1.0, 0.8, 0.7], np.float32)).astype(np.float32)
    texture = fine if sharp_thing else cv2.GaussianBlur(fine, (0, 0), 2.5) * 4.0
    rgb[part] = ((0.5 + 0.12 * texture[part, None]) * np.array([0.9, 0.35, 0.3], np.float32)).astype(np.float32)
    return np.clip(rgb, 0.0, 1.0).astype(np.float32), {"body": body & ~part, "thing": part}


def maps(parts: dict[str, np.ndarray], held_thing: float = 0.99) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(matte, held, pose) on the photo's grid: the matte holds both parts, the people's segmentations hold them at
    0.99 (the thing at ``held_thing``), the pose graph sees the body (0.99) and not the thing (0.01)."""
    matte = parts["body"] | parts["thing"]
    held = np.where(parts["thing"], held_thing, np.where(matte, 0.99, 0.01)).astype(np.float32)
    pose = np.where(parts["body"], 0.99, 0.01).astype(np.float32)
    return matte, held, pose


def gray(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def test_blurred_thing_beside_the_shoulder_leaves():
    rgb, parts = scene()
    things = tb.blurred_things(gray(rgb), *maps(parts))
    assert things[parts["thing"]].mean() > 0.9
    assert not things[parts["body"]].any()


@pytest.mark.parametrize(
    ("case", "kwargs", "held_thing"),
    [
        ("in focus (a held object)", {"sharp_thing": True}, 0.99),
        ("before the body (all around it)", {"thing": "front"}, 0.99),
        ("cut by the bottom border (a body cut by the frame goes on)", {"thing": "bottom"}, 0.99),
        ("an own-colours part (the people's segmentations hardly hold it)", {}, 0.1),
    ],
)
def test_left_alone(case, kwargs, held_thing):
    rgb, parts = scene(**kwargs)
    assert not tb.blurred_things(gray(rgb), *maps(parts, held_thing)).any(), case


def test_no_detail_on_the_body_decides_nothing():
    rgb, parts = scene()
    flat = rgb.copy()
    flat[parts["body"]] = 0.5  # no texture where the pose graph sees the person: no sharpness to compare with
    assert not tb.blurred_things(gray(flat), *maps(parts)).any()


def test_detail_ratio():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((64, 64)).astype(np.float32)
    fine = np.abs(noise - cv2.GaussianBlur(noise, (0, 0), 1.0))
    mid = np.abs(noise - cv2.GaussianBlur(noise, (0, 0), 3.0))
    everywhere = np.ones(noise.shape, bool)
    sharp = tb.detail_ratio(fine, mid, everywhere)
    soft = cv2.GaussianBlur(noise, (0, 0), 2.0)
    blurred = tb.detail_ratio(np.abs(soft - cv2.GaussianBlur(soft, (0, 0), 1.0)),
                              np.abs(soft - cv2.GaussianBlur(soft, (0, 0), 3.0)), everywhere)  # fmt: skip
    assert 0.0 < blurred < 0.5 * sharp < 1.0
    assert np.isnan(tb.detail_ratio(np.zeros((4, 4)), np.zeros((4, 4)), np.ones((4, 4), bool)))


def _people(parts: dict[str, np.ndarray], scale: int, source: str = "roi", held_thing: float = 0.99):
    """A person (``source``) whose region covers the photo at ``scale``, holding ``maps``' segmentation, and the pose
    graph's logits for them."""
    matte, held, pose = maps(parts, held_thing)
    h, w = matte.shape
    big = (h * scale, w * scale)
    region = Region(big[1] / 2, big[0] / 2, float(max(big)))

    def canvas(m: np.ndarray) -> np.ndarray:
        up = cv2.resize(m, (big[1], big[0]), interpolation=cv2.INTER_LINEAR)
        return as_logits(np.clip(crop_region(up, region), 0.01, 0.99))

    return [Person(region, canvas(held), 0.9, source)], (lambda p: canvas(pose))


def _up(a: np.ndarray, scale: int) -> np.ndarray:
    return a if scale == 1 else cv2.resize(a, (a.shape[1] * scale, a.shape[0] * scale), interpolation=cv2.INTER_NEAREST)


@pytest.mark.parametrize("scale", [1, 3])  # 3: the matte's side past _SIDE, read on a reduced grid
def test_without_things_behind_on_the_photo(scale):
    rgb, parts = scene()
    people, pose = _people(parts, scale)
    alpha = _up((parts["body"] | parts["thing"]).astype(np.float32), scale)
    asked = []
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, lambda p: asked.append(p) or pose(p))
    thing, body = _up(parts["thing"].astype(np.uint8), scale) > 0, _up(parts["body"].astype(np.uint8), scale) > 0
    inner = cv2.erode(thing.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert (out[inner] == 0).all()
    inner_body = cv2.erode(body.astype(np.uint8), np.ones((9 * scale, 9 * scale), np.uint8)) > 0
    np.testing.assert_array_equal(out[inner_body], alpha[inner_body])
    assert (out >= 0.5).sum() > 0.95 * body.sum()
    assert len(asked) == 1  # one pose-graph view for the region
    assert out is not alpha and alpha[inner].min() == 1.0  # a new array; the input untouched


def test_without_things_behind_keeps_what_is_in_focus():
    rgb, parts = scene(sharp_thing=True)
    people, pose = _people(parts, 1)
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    assert tb.without_things_behind(rgb, alpha, people, pose) is alpha


def test_own_colours_parts_and_an_empty_matte_are_not_read():
    rgb, parts = scene()
    people, pose = _people(parts, 1, source="own")
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    assert tb.without_things_behind(rgb, alpha, people, pose) is alpha  # no person but an own-colours part
    people, pose = _people(parts, 1)
    empty = np.zeros_like(alpha)
    assert tb.without_things_behind(rgb, empty, people, pose) is empty
