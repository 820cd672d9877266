"""Clothed subjects: random_subject determinism, part validity, exact skin labels, shells.

Shares the one anny model of the test process (bodies.get_model is cached).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("anny")
pytest.importorskip("trimesh")

from export.render import bodies, garments, subjects  # noqa: E402
from export.render.preview import sample_texture  # noqa: E402
from export.render.scene import Part, Subject  # noqa: E402

SEED_TROUSERS = 1  # jeans + loose top + boots + hair (checked by test_outfits_of_the_fixture_seeds)
SEED_SKIRT = 2  # top + skirt + shoes + hair


@pytest.fixture(scope="module")
def subject() -> Subject:
    return subjects.random_subject(SEED_TROUSERS)


@pytest.fixture(scope="module")
def skirted() -> Subject:
    return subjects.random_subject(SEED_SKIRT)


def _centroid_values(part: Part, tex) -> np.ndarray:
    return sample_texture(tex, part.uv.mean(axis=1))


def test_outfits_of_the_fixture_seeds(subject, skirted):
    names = {p.name for p in subject.parts}
    assert {"body", "body_covered", "jeans", "top", "hair"} <= names
    assert "skirt" in {p.name for p in skirted.parts}


def _check_part(part: Part) -> None:
    assert part.vertices.dtype == np.float32 and part.vertices.ndim == 2 and part.vertices.shape[1] == 3
    assert np.isfinite(part.vertices).all()
    assert part.faces.dtype == np.int32 and part.faces.shape[1] == 3 and len(part.faces) > 0
    assert part.faces.min() >= 0 and part.faces.max() < len(part.vertices)
    assert part.uv.shape == (len(part.faces), 3, 2) and part.uv.dtype == np.float32
    assert (part.uv >= 0).all() and (part.uv <= 1).all()
    albedo = np.asarray(part.albedo)
    assert albedo.dtype == np.float32 and albedo.shape[-1] == 3 and albedo.ndim in (1, 3)
    assert (albedo >= 0).all() and (albedo <= 1).all()
    for tex in (part.skin, part.roughness, part.specular):
        arr = np.asarray(tex, dtype=np.float32)
        assert arr.ndim in (0, 2) and (arr >= 0).all() and (arr <= 1).all()
    assert 0.0 <= part.subsurface <= 1.0
    # no degenerate slivers in bulk
    tri = part.vertices[part.faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert np.mean(area > 1e-10) > 0.99


def test_parts_are_valid(subject, skirted):
    for subj in (subject, skirted):
        for part in subj.parts:
            _check_part(part)


def test_same_seed_gives_identical_subject(subject):
    again = subjects.random_subject(SEED_TROUSERS)
    assert again.name == subject.name == f"anny_{SEED_TROUSERS:06d}"
    assert [p.name for p in again.parts] == [p.name for p in subject.parts]
    for a, b in zip(subject.parts, again.parts, strict=True):
        for f in dataclasses.fields(Part):
            np.testing.assert_array_equal(np.asarray(getattr(a, f.name)), np.asarray(getattr(b, f.name)))


def test_different_seeds_differ(subject, skirted):
    assert not np.array_equal(subject.parts[0].vertices, skirted.parts[0].vertices)


def test_subject_frame_and_size(subject):
    lo, hi = subject.bounds()
    assert 1.4 < hi[2] - lo[2] < 2.1 and abs(lo[2]) < 0.05
    assert np.abs(hi[:2]).max() < 1.0 and np.abs(lo[:2]).max() < 1.0


def test_skin_on_hands_not_under_garments(subject):
    template = bodies.get_template()
    body = next(p for p in subject.parts if p.name == "body")
    covered = next(p for p in subject.parts if p.name == "body_covered")
    # hands: skin (no gloves in any outfit)
    hand_faces = np.isin(body.faces, np.nonzero(template.hand > 0.95)[0]).all(axis=1)
    hand_skin = _centroid_values(Part("h", body.vertices, body.faces[hand_faces], body.uv[hand_faces], body.albedo),
                                 body.skin)
    assert hand_faces.sum() > 100 and np.mean(hand_skin == 1.0) > 0.95
    # under garments: no skin anywhere on fully covered faces, and shells are never skin
    assert np.mean(_centroid_values(covered, covered.skin) == 0.0) > 0.98
    for part in subject.parts:
        if part.name not in ("body", "body_covered"):
            assert np.asarray(part.skin).max() == 0.0
    assert body.subsurface == 1.0 and covered.subsurface == 0.0


def test_face_front_is_skin_scalp_is_not(subject):
    template = bodies.get_template()
    body = next(p for p in subject.parts if p.name == "body")
    uv_of_vertex = np.zeros((len(template.region), 2), np.float32)
    uv_of_vertex[template.faces.ravel()] = template.uv.reshape(-1, 2)
    head = np.nonzero(template.region == bodies.REGIONS.index("head"))[0]
    v = body.vertices[head]
    # the front-most 3 cm of the head (nose, lips, cheeks, brows) along its facing direction
    chin_to_top = v[:, 2].max() - v[:, 2].min()
    middle = (v[:, 2] > v[:, 2].min() + 0.25 * chin_to_top) & (v[:, 2] < v[:, 2].max() - 0.3 * chin_to_top)
    facing = v[middle, :2].mean(axis=0) - v[:, :2].mean(axis=0)
    facing = np.append(facing / np.linalg.norm(facing), 0.0)
    depth = v @ facing
    front = head[middle & (depth > depth.max() - 0.03)]
    skin = sample_texture(body.skin, uv_of_vertex[front])
    assert len(front) > 50 and np.mean(skin == 1.0) > 0.8
    top = head[v[:, 2] > v[:, 2].max() - 0.02]  # crown: under the hair
    assert np.mean(sample_texture(body.skin, uv_of_vertex[top]) == 0.0) > 0.9


def test_clothing_false_leaves_more_skin(subject):
    bare = subjects.random_subject(SEED_TROUSERS, clothing=False)
    assert {p.name for p in bare.parts} <= {"body", "body_covered"}
    assert float(np.mean(bare.parts[0].skin)) > float(np.mean(subject.parts[0].skin))


def test_loose_shell_sits_outside_the_body(subject):
    template = bodies.get_template()
    body = next(p for p in subject.parts if p.name == "body")
    top = next(p for p in subject.parts if p.name == "top")
    # every shell vertex is a body vertex pushed out along its normal: match by nearest body vertex
    normals = bodies.vertex_normals(body.vertices, template.faces)
    d = top.vertices[:, None, :] - body.vertices[None, ::7, :]
    nearest = np.argmin((d**2).sum(-1), axis=1) * 7
    offset = ((top.vertices - body.vertices[nearest]) * normals[nearest]).sum(axis=1)
    assert np.median(offset) > 0.002
    assert np.abs(offset).max() < 0.1


def _offsets_along_normals(shell: Part, body: Part) -> np.ndarray:
    normals = bodies.vertex_normals(body.vertices, bodies.get_template().faces)
    d = shell.vertices[:, None, :] - body.vertices[None, :, :]
    nearest = np.argmin((d**2).sum(-1), axis=1)
    return ((shell.vertices - body.vertices[nearest]) * normals[nearest]).sum(axis=1)


def _outline_vertices(part: Part) -> np.ndarray:
    """Vertices on the part's open border (edges used by one face)."""
    edges = np.sort(np.concatenate([part.faces[:, [0, 1]], part.faces[:, [1, 2]], part.faces[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def test_hair_shell_comes_down_onto_the_scalp_at_the_hairline(subject):
    # the shell is cut along whole triangles; standing off the forehead there it showed a sawtooth step
    body = next(p for p in subject.parts if p.name == "body")
    hair = next(p for p in subject.parts if p.name == "hair")
    offset = _offsets_along_normals(hair, body)
    edge = _outline_vertices(hair)
    inner = np.setdiff1d(np.arange(len(hair.vertices)), edge)
    assert np.median(offset[inner]) > 0.004  # the hair has volume...
    assert np.percentile(np.abs(offset[edge]), 90) < 0.0025  # ...and none at its outline
    top = next(p for p in subject.parts if p.name == "top")  # a garment hem keeps its thickness
    assert np.median(_offsets_along_normals(top, body)[_outline_vertices(top)]) > 0.002


def test_skirt_bridges_the_legs_and_faces_outward(skirted):
    skirt = next(p for p in skirted.parts if p.name == "skirt")
    tri = skirt.vertices[skirt.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = skirt.vertices[:, :2].mean(axis=0)
    radial = tri.mean(axis=1)[:, :2] - centre
    assert np.mean((normal[:, :2] * radial).sum(axis=1) > 0) > 0.95
    template = bodies.get_template()
    legs = np.isin(template.region, [bodies.REGIONS.index("leg_l"), bodies.REGIONS.index("leg_r")])
    body = skirted.parts[0].vertices[legs]
    band = (body[:, 2] > skirt.vertices[:, 2].min() + 0.05) & (body[:, 2] < skirt.vertices[:, 2].max() - 0.05)
    r_body = np.linalg.norm(body[band, :2] - centre, axis=1)
    r_skirt = np.linalg.norm(skirt.vertices[:, :2] - centre, axis=1)
    # the hem ring is wider than the widest leg section it hides (the shell bridges the legs)
    hem = skirt.vertices[:, 2] < skirt.vertices[:, 2].min() + 1e-4
    assert np.median(r_skirt[hem]) > np.percentile(r_body, 90)


def test_sample_outfit_is_deterministic_and_complete():
    a = garments.sample_outfit(np.random.default_rng(4))
    b = garments.sample_outfit(np.random.default_rng(4))
    assert [g.name for g in a] == [g.name for g in b]
    kinds = {g.kind for s in range(40) for g in garments.sample_outfit(np.random.default_rng(s))}
    assert kinds == set(garments.GARMENT_KINDS)
    for s in range(40):
        for g in garments.sample_outfit(np.random.default_rng(s)):
            assert g.material in garments.MATERIALS
            (r0, r1), (s0, s1) = garments.MATERIALS[g.material]
            assert r0 <= g.roughness <= r1 and s0 <= g.specular <= s1


def test_long_hair_curtain_leaves_the_face_open():
    subject = subjects.random_subject(205)  # an outfit with long hair
    curtain = next(p for p in subject.parts if p.name == "hair_long")
    _check_part(curtain)
    body = next(p for p in subject.parts if p.name == "body")
    template = bodies.get_template()
    head = body.vertices[template.region == bodies.REGIONS.index("head")]
    axis = head[head[:, 2] > head[:, 2].max() - 0.06, :2].mean(axis=0)
    nose = head[np.argmax(head @ np.array([1.0, 0.0, 0.0]))]  # the turn is below ±35°: the front-most point
    facing = np.arctan2(*(nose[:2] - axis)[::-1])
    ang = np.arctan2(curtain.vertices[:, 1] - axis[1], curtain.vertices[:, 0] - axis[0])
    off = np.abs(np.angle(np.exp(1j * (ang - facing))))
    assert off.min() > np.radians(45)  # nothing hangs in front of the face
    assert curtain.vertices[:, 2].min() < head[:, 2].min()  # it reaches below the chin


@pytest.fixture(scope="module")
def bare_body() -> tuple[bodies.Body, garments.Surface, dict]:
    rng = np.random.default_rng(21)
    body = bodies.posed_body(bodies.sample_phenotype(rng), bodies.sample_pose(rng, "relaxed"))
    template = bodies.get_template()
    return body, garments.Surface(body.rest, template.region, template.foot), subjects._landmarks(body)


def _one(kind: str, **params) -> garments.Garment:
    pat = garments.Pattern("solid", np.full((3, 3), 0.5, np.float32))
    return garments.Garment(kind, kind, pat, "cotton", 0.8, 0.02, params=params)


def test_coverage_rules(bare_body):
    body, surf, lm = bare_body
    template = bodies.get_template()
    head = template.region == bodies.REGIONS.index("head")
    hands = template.hand > 0.9
    feet = template.foot > 0.9
    knee_z = lm["lowerleg01.L"][2]
    near_knees = (np.abs(body.rest[:, 2] - knee_z) < 0.03) & ~hands
    trousers = garments.coverage(_one("bottom", waist=0.1, leg_end=0.0), surf, lm)
    shorts = garments.coverage(_one("bottom", waist=0.1, leg_end=0.7), surf, lm)
    assert trousers[near_knees].all() and not shorts[near_knees].any()
    assert not trousers[feet | head | hands].any()
    tee = garments.coverage(_one("top", sleeve=0.45, hem=0.05, neck=0.05), surf, lm)
    long_sleeve = garments.coverage(_one("top", sleeve=1.95, hem=0.05, neck=0.05), surf, lm)
    z = body.rest[:, 2]
    forearm = (np.isin(template.region, [2, 3]) & (template.hand < 0.01) & (z < lm["lowerarm01.L"][2] - 0.04)
               & (z > lm["wrist.L"][2] + 0.04))
    assert long_sleeve[forearm].mean() > 0.95 and tee[forearm].mean() < 0.05
    assert not (tee | long_sleeve)[head | hands].any()
    jacket = garments.coverage(_one("jacket", hem=0.0, opening=0.06), surf, lm)
    torso = template.region == bodies.REGIONS.index("torso")
    chest = torso & (np.abs(z - lm["spine01"][2]) < 0.04) & (np.abs(body.rest[:, 1] - lm["neck01"][1]) < 0.03)
    front, back = chest & (body.rest[:, 0] > lm["spine01"][0]), chest & (body.rest[:, 0] < lm["spine01"][0])
    assert front.sum() > 5 and back.sum() > 5
    assert not jacket[front].any() and jacket[back].all() and long_sleeve[front].all()
    shoes = garments.coverage(_one("shoes", height=0.03), surf, lm)
    assert shoes[feet].all() and not shoes[near_knees | hands | head].any()
    hair = garments.coverage(_one("hair", length=1.0, front=0.06), surf, lm)
    face = head & (body.rest[:, 0] > lm["eye.L"][0] - 0.01) & (body.rest[:, 2] < lm["eye.L"][2] + 0.01)
    assert face.sum() > 100 and not hair[face].any()
    assert hair[head & (body.rest[:, 2] > body.rest[:, 2].max() - 0.02)].all()  # the crown
    with pytest.raises(ValueError, match="unknown garment kind"):
        garments.coverage(_one("cape"), surf, lm)
