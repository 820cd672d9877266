"""anny bodies: phenotype and pose sampling, the posed mesh and its frame (DESIGN.md §3).

The anny model is built once per process (about a minute the first time, then cached on disk).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("anny")

from export.render import bodies  # noqa: E402
from relight_rt import RelightError  # noqa: E402


@pytest.fixture(scope="session")
def template() -> bodies.Template:
    """anny's shared topology; building the model once serves every test of the session."""
    bodies.get_model()
    return bodies.get_template()


def _straight_pose(rng: np.random.Generator) -> bodies.Pose:
    pose = bodies.sample_pose(rng, "relaxed")
    return dataclasses.replace(pose, turn=0.0, twist=0.0, lean=0.0, head_turn=0.0, head_tilt=0.0)


@pytest.fixture(scope="module")
def body(template) -> bodies.Body:
    rng = np.random.default_rng(11)
    return bodies.posed_body(bodies.sample_phenotype(rng), _straight_pose(rng))


def test_template_shapes(template):
    n_vertices = len(template.region)
    assert template.faces.dtype == np.int32 and template.faces.shape[1] == 3
    assert template.faces.min() == 0 and template.faces.max() == n_vertices - 1
    assert template.uv.shape == (len(template.faces), 3, 2) and template.uv.dtype == np.float32
    assert (template.uv >= 0).all() and (template.uv <= 1).all()
    assert set(np.unique(template.region)) == set(range(len(bodies.REGIONS)))
    assert 0 < (template.hand > 0.5).sum() < n_vertices // 3  # fingers are finely meshed
    assert 0 < (template.foot > 0.5).sum() < n_vertices // 5


def test_posed_body_is_in_the_subject_frame(body, template):
    v = body.vertices
    assert v.dtype == np.float32 and v.shape == (len(template.region), 3) and np.isfinite(v).all()
    height = v[:, 2].max() - v[:, 2].min()
    assert 1.4 < height < 2.05
    assert abs(v[:, 2].min()) < 1e-6  # feet at z = 0
    lm = body.landmarks
    # facing +x: the eyes are in front of the back of the head
    head = v[template.region == bodies.REGIONS.index("head")]
    assert lm["eye.L"][0] > head[:, 0].min() + 0.1
    eyes = body.vertices[np.argmin(np.linalg.norm(body.rest - lm["eye.L"], axis=1))]
    assert eyes[0] > np.median(head[:, 0])
    # the person's left hand side is +y (the image's right), up is +z
    assert lm["wrist.L"][1] > 0.1 > -0.1 > lm["wrist.R"][1]
    assert lm["head"][2] > lm["upperleg01.L"][2] > lm["foot.L"][2]


def test_normals_point_outward(body):
    centre_line = np.array([0.0, 0.0])
    torso = (body.vertices[:, 2] > 1.0) & (body.vertices[:, 2] < 1.2) & (np.abs(body.vertices[:, 1]) < 0.1)
    radial = body.vertices[torso, :2] - centre_line
    assert np.mean(np.sum(radial * body.normals[torso, :2], axis=1) > 0) > 0.9
    np.testing.assert_allclose(np.linalg.norm(body.normals, axis=1), 1.0, atol=1e-4)


def test_phenotypes_are_adult_and_in_range():
    rng = np.random.default_rng(0)
    samples = [bodies.sample_phenotype(rng) for _ in range(200)]
    for key in ("gender", "age", "muscle", "weight", "height", "proportions"):
        vals = np.array([s[key] for s in samples])
        assert (vals >= 0).all() and (vals <= 1).all() and vals.std() > 0.05
    assert min(s["age"] for s in samples) >= 0.6  # anny's "young" anchor is 2/3, "child" 1/3


@pytest.mark.parametrize("name", bodies.POSES)
def test_every_pose_gives_a_standing_body(template, name):
    rng = np.random.default_rng(3)
    pose = bodies.sample_pose(rng, name)
    assert pose.name == name
    b = bodies.posed_body(bodies.sample_phenotype(rng), pose)
    v = b.vertices
    assert np.isfinite(v).all()
    assert 1.3 < v[:, 2].max() < 2.1  # standing, not lying or flying
    # the hands stay near the body (no limbs flung out)
    assert np.abs(v[:, :2]).max() < 0.9


def test_pose_names_and_sampling_are_deterministic():
    a = bodies.sample_pose(np.random.default_rng(7))
    b = bodies.sample_pose(np.random.default_rng(7))
    assert a == b and a.name in bodies.POSES
    names = {bodies.sample_pose(np.random.default_rng(s)).name for s in range(60)}
    assert names == set(bodies.POSES)
    with pytest.raises(RelightError, match="unknown pose 'dab'"):
        bodies.sample_pose(np.random.default_rng(0), "dab")


def test_unknown_phenotype_raises(template):
    with pytest.raises(RelightError, match="unknown phenotype names"):
        bodies.posed_body({"tail": 1.0}, bodies.sample_pose(np.random.default_rng(0)))


def test_vertex_normals_of_a_tetrahedron_point_away_from_its_centre():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)
    n = bodies.vertex_normals(v, f)
    assert ((v - v.mean(axis=0)) * n).sum(axis=1).min() > 0
