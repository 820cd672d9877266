"""Subjects to render: random clothed anny people, or a user's textured mesh.

Entry points: :func:`random_subject` (seed → Subject, deterministic) and :func:`load_subject`
(a textured .obj). Frame: DESIGN.md §3 (the person faces +x, the camera; +y is the image's right,
their left hand side; +z up; metres; feet at z = 0).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from export.render import bodies, garments
from export.render.preview import preview_subject
from export.render.scene import Part, Subject
from export.render.textures import UVRaster, fbm, rasterize_uv, skin_detail_masks, skin_tone, value_noise

__all__ = ["load_subject", "preview_subject", "random_subject"]

log = logging.getLogger(__name__)

TEXTURE_SIZE = 1024

# anny's UV segmentation labels (data/segmentation/body_parts_segmentation.yaml), RGB
_SEG_COLOURS = {
    "eye_front": [(16, 231, 186), (16, 115, 231)],
    "eye_other": [(255, 101, 0), (24, 170, 109), (253, 249, 16), (249, 108, 136)],
    "mouth": [(112, 172, 255), (206, 153, 167)],
}


@functools.lru_cache(maxsize=1)
def _raster() -> UVRaster:
    return rasterize_uv(bodies.get_template().uv, TEXTURE_SIZE)


@functools.lru_cache(maxsize=1)
def _segmentation_labels() -> dict[str, np.ndarray]:
    """Per listed texel of _raster(): bool masks for eyes and mouth from anny's UV segmentation."""
    import cv2

    raster = _raster()
    try:
        import anny

        path = Path(anny.__file__).parent / "data" / "segmentation" / "body_parts_segmentation.png"
        seg = cv2.imread(str(path), cv2.IMREAD_COLOR)
    except ImportError:
        seg = None
    if seg is None:
        return {k: np.zeros(len(raster.rows), bool) for k in _SEG_COLOURS}
    seg = cv2.resize(seg, (TEXTURE_SIZE, TEXTURE_SIZE), interpolation=cv2.INTER_NEAREST)[..., ::-1]
    rgb = seg[raster.rows, raster.cols].astype(np.int64)
    return {k: np.any([np.all(rgb == c, axis=1) for c in cols], axis=0) for k, cols in _SEG_COLOURS.items()}


def _landmarks(body: bodies.Body) -> dict[str, np.ndarray]:
    lm = dict(body.landmarks)
    rest = body.rest
    top = rest[:, 2].max()
    crown = rest[rest[:, 2] > top - 0.03]
    lm["top"] = np.array([crown[:, 0].mean(), crown[:, 1].mean(), top])
    return lm


def _skin_albedo(points: np.ndarray, rest: np.ndarray, tone: np.ndarray, seed: int, masks: dict[str, np.ndarray],
                 raster: UVRaster, face: _Face | None = None) -> np.ndarray:
    """Skin albedo per texel: the tone with blotchy variation, anny's detail masks and the face's colouring.

    Low-frequency variation is computed on the (V, 3) rest vertices and interpolated (fast); fine
    grain on the (N, 3) texel points.
    """
    faces = bodies.get_template().faces
    low = np.stack([fbm(rest, 25.0, 3, seed), fbm(rest, 12.0, 2, seed + 2)], axis=1)
    low = raster.interpolate(faces, low)
    var = 1.0 + 0.10 * low[:, 0] + 0.03 * (value_noise(points, 180.0, seed + 1) - 0.5)
    red = 0.04 * low[:, 1]
    col = tone[None] * var[:, None]
    col[:, 0] *= 1 + red
    detail = {k: m[raster.rows, raster.cols][:, None] for k, m in masks.items()}
    if face is not None:
        col = _colour_face(col, points, tone, seed, detail, face)
    if "lips" in detail:
        lip_tint = np.array([0.85, 0.52, 0.52]) if face is None else face.lip_tint
        col = col * (1 - 0.6 * detail["lips"]) + 0.6 * detail["lips"] * tone * lip_tint
    for key, tint in (("aureolae", [0.75, 0.6, 0.55]), ("eyelids", [0.9, 0.82, 0.8]), ("crotch", [0.9, 0.85, 0.85])):
        if key in detail:
            col = col * (1 - 0.5 * detail[key]) + 0.5 * detail[key] * tone * np.array(tint)
    for key in ("fingernails", "toenails"):
        if key in detail:
            col = col * (1 - 0.6 * detail[key]) + 0.6 * detail[key] * np.clip(tone * 1.15 + 0.08, 0, 1)
    return np.clip(col, 0.0, 1.0)


@dataclass(frozen=True)
class _Face:
    """Where the face is (rest pose) and how this person's face is coloured; see _colour_face."""

    eye_l: np.ndarray
    eye_r: np.ndarray
    flush: float  # cheek and nose redness, 0..1
    under_eye: float  # darkening below the eyes, 0..1
    stubble: float  # beard shadow, 0 (none) .. 1
    stubble_colour: np.ndarray
    freckles: float  # density of small dark spots, 0..1
    lip_tint: np.ndarray


def _sample_face(rng: np.random.Generator, lm: dict[str, np.ndarray], masculine: float, hair: np.ndarray | None
                 ) -> _Face:
    beard = hair if hair is not None else np.array([0.1, 0.08, 0.07])
    stubble = float(rng.uniform(0.3, 1.0)) if rng.uniform() < 0.8 * max(masculine - 0.3, 0.0) / 0.7 else 0.0
    return _Face(
        eye_l=np.asarray(lm["eye.L"], float), eye_r=np.asarray(lm["eye.R"], float),
        flush=float(rng.uniform(0.2, 1.0)), under_eye=float(rng.uniform(0.0, 1.0)),
        stubble=stubble, stubble_colour=np.asarray(beard, float),
        freckles=float(rng.uniform(0.3, 1.0)) if rng.uniform() < 0.25 else 0.0,
        lip_tint=np.array([0.85, 0.52, 0.55]) * rng.uniform(0.9, 1.1, 3),
    )


def _blob(d: np.ndarray, sigma) -> np.ndarray:
    """exp(-|d/sigma|²/2) over the last axis of d (N, k): a soft elliptical spot."""
    return np.exp(-0.5 * np.sum((d / np.asarray(sigma)) ** 2, axis=-1))


def _colour_face(col: np.ndarray, points: np.ndarray, tone: np.ndarray, seed: int, detail: dict[str, np.ndarray],
                 face: _Face) -> np.ndarray:
    """Colour a face as photos show one at close range, on the (N, 3) texel albedos ``col``.

    Placed from the eyes in the rest pose (x forward, y to the person's left, z up), sized by their
    distance: redness over the cheeks, nose and ears (blood under thin skin), darker skin below the eyes,
    beard shadow with stubble dots on the jaw, chin and upper lip, fine pore grain, and freckles.
    Everything is a multiplicative tint of the person's own tone, so it scales with skin depth.
    """
    mid = 0.5 * (face.eye_l + face.eye_r)
    s = max(float(np.abs(face.eye_l[1] - face.eye_r[1])) / 0.062, 0.5)  # 1 for an average face
    rel = (points - mid) / s  # face-scaled offsets, metres of an average face
    on_head = (rel[:, 2] > -0.16) & (rel[:, 2] < 0.12) & (np.abs(rel[:, 1]) < 0.11)
    if not on_head.any():
        return col.copy()
    p = rel[on_head]
    fr = np.clip((p[:, 0] + 0.06) / 0.04, 0.0, 1.0)  # the face's front, not the back of the head
    yz = p[:, 1:]
    cheeks = np.maximum(_blob(yz - [0.040, -0.040], [0.020, 0.016]), _blob(yz - [-0.040, -0.040], [0.020, 0.016]))
    nose = _blob(yz - [0.0, -0.035], [0.010, 0.016]) * np.clip(p[:, 0] / 0.02, 0, 1)
    ears = detail["ears"][on_head, 0] if "ears" in detail else 0.0
    redness = face.flush * (0.7 * cheeks * fr + 0.6 * nose + 0.5 * ears)
    tint = 1.0 - redness[:, None] * np.array([0.0, 0.16, 0.11])
    dark = face.under_eye * 0.12 * np.maximum(_blob(yz - [0.032, -0.016], [0.013, 0.006]),
                                               _blob(yz - [-0.032, -0.016], [0.013, 0.006])) * fr
    tint = tint * (1.0 - dark[:, None] * np.array([1.0, 1.15, 0.9]))
    # pores: fine grain on the face (about 1.5 mm), stronger on nose and cheeks
    pores = value_noise(points[on_head], 650.0, seed + 11) - 0.5
    tint = tint * (1.0 + (0.035 + 0.03 * (cheeks + nose))[:, None] * pores[:, None] * fr[:, None])
    if face.freckles > 0:
        spots = value_noise(points[on_head], 320.0, seed + 13)
        dots = np.clip((spots - (1.0 - 0.12 * face.freckles)) / 0.03, 0, 1) * (0.4 + cheeks + nose) * fr
        tint = tint * (1.0 - 0.25 * np.clip(dots, 0, 1)[:, None] * np.array([0.8, 1.0, 1.2]))
    head = col[on_head] * tint
    if face.stubble > 0:
        # the bearded area: below the cheekbones to under the chin, and the upper lip
        jaw = np.clip((-0.06 - p[:, 2]) / 0.025, 0, 1) * np.clip((p[:, 2] + 0.14) / 0.02, 0, 1)
        lip = _blob(yz - [0.0, -0.062], [0.022, 0.007])
        side = np.clip((0.075 - np.abs(p[:, 1])) / 0.02, 0, 1)
        area = np.clip(np.maximum(jaw * side, lip), 0, 1) * np.clip((p[:, 0] + 0.08) / 0.04, 0, 1)
        if "lips" in detail:
            area = area * (1.0 - np.clip(2.0 * detail["lips"][on_head, 0], 0, 1))
        hairs = np.clip((value_noise(points[on_head], 1400.0, seed + 17) - 0.55) / 0.1, 0, 1)
        cover = (face.stubble * area * (0.15 + 0.25 * hairs))[:, None]
        head = head * (1 - cover) + cover * np.minimum(face.stubble_colour, tone * 0.5)
    out = col.copy()
    out[on_head] = head
    return out


def _body_textures(body: bodies.Body, tone: np.ndarray, outfit: list[garments.Garment], rng: np.random.Generator,
                   lm: dict[str, np.ndarray], face: _Face | None = None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Body albedo/skin/roughness/specular textures (TEXTURE_SIZE²) and the (V,) union vertex coverage."""
    template = bodies.get_template()
    raster = _raster()
    faces = template.faces
    points = raster.interpolate(faces, body.rest)
    nearest = faces[raster.face, raster.bary.argmax(axis=1)]
    surf = garments.Surface(points, template.region[nearest], raster.interpolate(faces, template.foot))
    vsurf = garments.Surface(body.rest, template.region, template.foot)
    seed = int(rng.integers(1 << 30))

    albedo = _skin_albedo(points, body.rest, tone, seed, skin_detail_masks(TEXTURE_SIZE), raster, face)
    skin = np.ones(len(points), dtype=np.float32)
    (r0, r1), (s0, s1) = garments.MATERIALS["skin"]
    rough = np.full(len(points), rng.uniform(r0, r1), dtype=np.float32)
    rough -= 0.05 * np.clip(fbm(points, 20.0, 2, seed + 3), -1, 1).astype(np.float32)
    spec = np.full(len(points), rng.uniform(s0, s1), dtype=np.float32)

    # eyes, eyebrows, mouth
    seg = _segmentation_labels()
    eye = seg["eye_front"]
    if eye.any():
        albedo[eye] = np.array([0.82, 0.8, 0.76]) * rng.uniform(0.85, 1.0)
        iris_col = np.array(rng.choice([[0.25, 0.14, 0.07], [0.12, 0.07, 0.04], [0.3, 0.4, 0.5], [0.3, 0.35, 0.2]]))
        for side in ("L", "R"):
            sel = eye & (np.sign(points[:, 1]) == (1 if side == "L" else -1))
            if sel.any():
                front = points[sel, 0].max()
                iris = sel & (points[:, 0] > front - 0.0025)
                albedo[iris] = iris_col
        spec[eye] = 0.3
        rough[eye] = 0.1
    albedo[seg["eye_other"]] = [0.3, 0.12, 0.1]
    albedo[seg["mouth"]] = [0.35, 0.12, 0.12]
    skin[eye | seg["eye_other"] | seg["mouth"]] = 0.0
    hair_col = garments.hair_color_of(outfit)
    brow_col = hair_col if hair_col is not None else tone * 0.3
    for side in ("L", "R"):
        e = lm[f"eye.{side}"]
        dy = (points[:, 1] - e[1]) * np.sign(e[1])  # outward from the face's middle
        arch = e[2] + 0.021 + 0.004 * (1 - ((dy - 0.002) / 0.024) ** 2)
        thick = 0.0035 * (1 - 0.5 * np.clip((dy + 0.02) / 0.045, 0, 1))
        brow = (points[:, 0] > e[0] - 0.005) & (np.abs(dy - 0.002) < 0.024) & (np.abs(points[:, 2] - arch) < thick)
        albedo[brow] = 0.45 * albedo[brow] + 0.55 * brow_col

    covered_v = np.zeros(len(body.rest), dtype=bool)
    for g in outfit:
        cov = garments.coverage(g, surf, lm)
        covered_v |= garments.coverage(g, vsurf, lm)
        if g.kind == "skirt" or not cov.any():
            continue
        # hair: strands along the head's vertical, fine across it
        where = points[cov] * np.array([3.0, 3.0, 0.3]) if g.kind == "hair" else points[cov]
        albedo[cov] = garments.evaluate_pattern(g.pattern, where)
        skin[cov] = 0.0
        rough[cov] = g.roughness
        spec[cov] = g.specular
    fill = np.array([0.5, 0.5, 0.5], dtype=np.float32)
    tex = {
        "albedo": raster.image(albedo.astype(np.float32), fill),
        "skin": raster.image(skin, 0.0),
        "roughness": raster.image(rough, 0.6),
        "specular": raster.image(spec, 0.0),
    }
    return tex, covered_v


def random_subject(seed: int, *, clothing: bool = True) -> Subject:
    """A random adult anny person in a natural standing pose, with skin, clothes, hair and shoes.

    Args:
        seed: any int; the same seed gives an identical Subject (arrays equal).
        clothing: False gives the bare body (underwear only) — useful for tests.

    Returns:
        Subject named "anny_<seed>", parts: "body" (faces with any exposed skin, subsurface 1),
        "body_covered" (faces under garments, subsurface 0; same textures), then garment shells.
        Body textures are TEXTURE_SIZE² (albedo RGB float32, skin/roughness/specular float32).
    """
    seed = int(seed)
    rng = np.random.default_rng(seed)
    phenotype = bodies.sample_phenotype(rng)
    pose = bodies.sample_pose(rng)
    depth = float(rng.uniform(0, 1))
    outfit = garments.sample_outfit(rng, feminine=phenotype["gender"])
    if not clothing:
        outfit = [g for g in outfit if g.kind == "underwear"]
    body = bodies.posed_body(phenotype, pose)
    template = bodies.get_template()
    # the face's colouring draws from its own stream, so shape, pose and clothes stay what they were per seed
    looks = np.random.default_rng([seed, 0xFACE])
    tone = skin_tone(depth, tuple(looks.uniform(-1.0, 1.0, 2)))
    lm = _landmarks(body)
    face = _sample_face(looks, lm, 1.0 - phenotype["gender"], garments.hair_color_of(outfit))
    tex, covered_v = _body_textures(body, tone, outfit, rng, lm, face)
    faces, uv = template.faces, template.uv
    exposed = ~covered_v[faces].all(axis=1)
    parts = []
    for name, sel, sss in (("body", exposed, 1.0), ("body_covered", ~exposed, 0.0)):
        if sel.any():
            parts.append(Part(name, body.vertices, faces[sel], uv[sel], tex["albedo"], tex["skin"],
                              tex["roughness"], tex["specular"], sss))
    vsurf = garments.Surface(body.rest, template.region, template.foot)
    for g in outfit:
        if g.kind == "skirt":
            parts.append(garments.skirt_shell(g, body, template.region, rng))
        elif g.loose > 0:
            shell = garments.offset_shell(g, body, faces, uv, garments.coverage(g, vsurf, lm), tex)
            if shell is not None:
                parts.append(shell)
        if g.kind == "hair":
            curtain = garments.hair_curtain(g, body, template.region, rng)
            if curtain is not None:
                parts.append(curtain)
    log.info("subject %d: %s, %s, %s", seed, pose.name, ", ".join(g.name for g in outfit),
             {k: round(v, 2) for k, v in phenotype.items()})
    return Subject(parts, f"anny_{seed:06d}")


def load_subject(path: str | Path, skin_path: str | Path | None = None) -> Subject:
    """A user's textured mesh (.obj + .mtl + texture) as a Subject; see export.render.objmesh.load_obj."""
    from export.render.objmesh import load_obj

    return load_obj(path, skin_path)
