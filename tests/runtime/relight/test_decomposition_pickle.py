"""A Decomposition carries everything its relighting needs (issue 47): pickled and reloaded, or sent to another
process, it relights to the same picture as in the process that made it, for a photo with a face (its face
meshes, the head pass, the refit light, the foreground colours of its soft edge), a group (its people) and a video
frame. Before, what the Relighter prepared stayed in a cache beside the Decomposition: the bundled example under
golden-hour came back 0.198 different."""

from __future__ import annotations

import pickle
import subprocess
import sys
from dataclasses import replace
from importlib.resources import files

import cv2
import numpy as np
import pytest

import relight_rt
from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.io import read_image

EXAMPLE_SCENE = files("relight_rt") / "data" / "example_scene.jpg"  # a person with a face, automatic matte
EXAMPLE = files("relight_rt") / "data" / "example.png"  # a person with alpha
SAME = 1e-6
LIGHT = lights.preset("golden-hour")
SIDE = (lights.directional((0.3, -1.0, 0.2)) + lights.ambient((0.1, 0.1, 0.1))).astype(np.float32)


def reloaded(dec):
    return pickle.loads(pickle.dumps(dec))


def test_a_photo_with_a_face_relights_the_same_after_pickling():
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = relighter.decompose(str(EXAMPLE_SCENE))
    # what its relighting needs travels with it: the face pass's meshes, the head pass, the soft edge's colours
    assert dec.photo and len(dec.face_meshes) == 1 and dec.head is not None and dec.foreground is not None
    assert dec.head.face_meshes is not None and not dec.foreground[0].flags.writeable
    back = reloaded(dec)
    assert len(back.face_meshes) == 1 and back.head_box == dec.head_box and not back.face_meshes[0].flags.writeable
    fresh = Relighter(RuntimeConfig(device="cpu"))  # never saw it, has no matte: relighting needs neither
    for background in ("original", "transparent", "black"):
        want = relighter.relight(dec, LIGHT, background=background)
        assert np.abs(fresh.relight(back, LIGHT, background=background) - want).max() <= SAME
        assert np.abs(relighter.relight(reloaded(dec), LIGHT, background=background) - want).max() <= SAME
    np.testing.assert_array_equal(fresh.layers(back, LIGHT).image, relighter.relight(dec, LIGHT))


def test_a_decomposition_sent_to_another_process_relights_the_same(tmp_path):
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = relighter.decompose(str(EXAMPLE_SCENE))
    (tmp_path / "dec.pkl").write_bytes(pickle.dumps(dec))
    np.save(tmp_path / "light.npy", LIGHT)
    script = (
        "import pickle, sys, numpy as np\n"
        "from relight_rt import Relighter, RuntimeConfig\n"
        "folder = sys.argv[1]\n"
        "dec = pickle.loads(open(folder + '/dec.pkl', 'rb').read())\n"
        "out = Relighter(RuntimeConfig(device='cpu')).relight(dec, np.load(folder + '/light.npy'))\n"
        "np.save(folder + '/out.npy', out)\n"
    )
    subprocess.run([sys.executable, "-c", script, str(tmp_path)], check=True, timeout=300)
    assert np.abs(np.load(tmp_path / "out.npy") - relighter.relight(dec, LIGHT)).max() <= SAME


def test_a_group_relights_the_same_after_pickling():
    rgba = read_image(str(EXAMPLE))
    a = rgba[..., 3:4]
    one = rgba[..., :3] * a + 0.55 * (1 - a)
    two = np.ascontiguousarray(np.hstack([one, one[:, ::-1]]))  # the example person and its mirror image
    relighter = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    dec = relighter.decompose(two)
    assert len(dec.people) == 2 and all(p.foreground is not None for p in dec.people)
    back = reloaded(dec)
    fresh = Relighter(RuntimeConfig(device="cpu", matting="all"))
    for background in ("original", "transparent", "black"):
        want = relighter.relight(dec, SIDE, background=background)
        assert np.abs(fresh.relight(back, SIDE, background=background) - want).max() <= SAME
    # a person of the group relit on their own: what the group's relights kept cannot change it
    alone = Relighter(RuntimeConfig(device="cpu")).relight(back.people[0], SIDE)
    np.testing.assert_array_equal(relighter.relight(dec.people[0], SIDE), alone)
    as_one = relighter.relight(replace(dec, people=()), SIDE)  # the people are what differs
    assert np.abs(as_one - relighter.relight(dec, SIDE)).max() > 0.01


@pytest.mark.parametrize("detail", [True, False])
def test_a_video_frame_relights_the_same_after_pickling(detail):
    relighter = relight_rt.open(RuntimeConfig(device="cpu", detail=detail))
    image = read_image(str(EXAMPLE_SCENE))
    mask = cv2.GaussianBlur(relighter.decompose(image).mask, (0, 0), 3)  # a soft edge wider than feathering
    (frame,) = relighter.decompose_batch([image], [mask], allow_full=True)
    assert not frame.photo and frame.face_meshes is None and frame.head is None and frame.foreground is None
    fresh = Relighter(RuntimeConfig(device="cpu", detail=detail))
    for background in ("original", "transparent", "black"):
        want = relighter.relight(frame, LIGHT, background=background)
        assert np.abs(fresh.relight(reloaded(frame), LIGHT, background=background) - want).max() <= SAME
