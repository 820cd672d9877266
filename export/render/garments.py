"""Clothes, hair and shoes on an anny body: where each garment covers the skin, and loose shells.

Every garment has a coverage rule on the body's rest pose (which texels and vertices it hides).
Tight garments are only that: the body texture takes the garment's pattern and material there and the
skin label goes to 0. Loose garments (and hair and shoes) also get a shell: the covered part of the
posed body surface pushed out along its normals, with low-frequency fold noise, so that cloth has
wrinkles and casts occlusion. Skirts and dresses get a frustum-like shell around the hips and legs.
Frame: the subject frame of DESIGN.md §3 (person faces +x, +z up, metres).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from export.render.bodies import REGIONS, Body
from export.render.scene import Part
from export.render.textures import Pattern, evaluate_pattern, fbm, random_color, random_pattern, value_noise

log = logging.getLogger(__name__)

#: Photo-render materials: (roughness range, specular range); subsurface is 1 for skin only.
MATERIALS = {
    "skin": ((0.35, 0.5), (0.04, 0.08)),
    "cotton": ((0.75, 0.9), (0.01, 0.03)),
    "knit": ((0.85, 0.95), (0.01, 0.02)),
    "denim": ((0.8, 0.9), (0.01, 0.03)),
    "satin": ((0.2, 0.3), (0.15, 0.3)),
    "synthetic": ((0.45, 0.6), (0.04, 0.08)),
    "leather": ((0.3, 0.4), (0.08, 0.15)),
    "hair": ((0.35, 0.45), (0.08, 0.15)),
}

GARMENT_KINDS = ("top", "bottom", "skirt", "shoes", "hair", "underwear", "jacket")


@dataclass(frozen=True)
class Garment:
    """One garment (or hair, shoes): its coverage rule, look and shell.

    Attributes:
        kind: one of GARMENT_KINDS.
        name: a readable name ("tshirt", "jeans", ...), used for the Part.
        pattern: its procedural texture.
        material: a MATERIALS key.
        roughness, specular: drawn from the material's ranges.
        loose: shell offset from the body in metres (0: tight, texture only).
        folds: fold displacement amplitude in metres.
        params: coverage parameters (see coverage()).
    """

    kind: str
    name: str
    pattern: Pattern
    material: str
    roughness: float
    specular: float
    loose: float = 0.0
    folds: float = 0.0
    params: dict[str, float] = field(default_factory=dict)


def _material(rng: np.random.Generator, name: str) -> tuple[float, float]:
    (r0, r1), (s0, s1) = MATERIALS[name]
    return float(rng.uniform(r0, r1)), float(rng.uniform(s0, s1))


def _garment(rng, kind, name, pattern, material, loose=0.0, folds=0.0, **params) -> Garment:
    rough, spec = _material(rng, material)
    return Garment(kind, name, pattern, material, rough, spec, float(loose), float(folds),
                   {k: float(v) for k, v in params.items()})


def sample_outfit(rng: np.random.Generator, feminine: float = 0.5) -> list[Garment]:
    """A random outfit, in painting order (later garments cover earlier ones on the body texture).

    Always underwear-like cover of the pelvis, then one of: top + trousers/shorts/skirt, or a dress;
    shoes most of the time; hair most of the time.

    Args:
        rng: the random generator.
        feminine: 0..1 (anny's gender phenotype: 0 male, 1 female); shifts the odds of dresses, skirts
            and long hair, never excludes them.
    """
    f = float(np.clip(feminine, 0.0, 1.0))
    out: list[Garment] = []
    under = Pattern("solid", np.stack([random_color(rng, dark=True)] * 3), 0.05, int(rng.integers(1 << 30)))
    out.append(_garment(rng, "underwear", "underwear", under, "cotton"))
    dress = rng.random() < 0.03 + 0.22 * f
    odds = np.array([0.32, 0.32, 0.22, 0.03 + 0.3 * f])
    bottom = "skirt" if dress else str(rng.choice(["trousers", "jeans", "shorts", "skirt"], p=odds / odds.sum()))
    if bottom in ("trousers", "jeans", "shorts"):
        pat = random_pattern(rng, ("denim",) if bottom == "jeans" else ("solid", "checks", "noise", "stripes"))
        mat = "denim" if bottom == "jeans" else str(rng.choice(["cotton", "synthetic", "knit"]))
        leg_end = rng.uniform(0.0, 0.08) if bottom != "shorts" else rng.uniform(0.45, 0.8)
        out.append(_garment(rng, "bottom", bottom, pat, mat, loose=rng.choice([0.0, 0.012, 0.02]),
                            folds=rng.uniform(0.004, 0.012), waist=rng.uniform(0.05, 0.14), leg_end=leg_end))
    # top (or the bodice of a dress)
    sleeve = float(rng.choice([0.0, 0.45, 0.6, 1.0, 1.95], p=[0.15, 0.3, 0.15, 0.1, 0.3]))
    top_pat = random_pattern(rng)
    top_mat = str(rng.choice(["cotton", "knit", "satin", "synthetic"], p=[0.5, 0.2, 0.15, 0.15]))
    # the hem, relative to the hips, overlaps the trousers' waistband most of the time (crop tops otherwise);
    # under a skirt it ends just below the skirt's lowest waistline
    if dress:
        hem = 0.08
    elif bottom == "skirt":
        hem = 0.05
    else:
        u = float(rng.uniform(0.0, 1.0))
        waist = out[-1].params["waist"]
        hem = waist - 0.1 * u / 0.85 if u < 0.85 else waist + 0.02 + 0.5 * (u - 0.85)
    loose = 0.0 if rng.random() < 0.3 else float(rng.uniform(0.008, 0.025))
    out.append(_garment(rng, "top", "dress_top" if dress else "top", top_pat, top_mat, loose=loose,
                        folds=rng.uniform(0.004, 0.014), sleeve=sleeve, hem=hem, neck=rng.uniform(0.01, 0.12)))
    if bottom == "skirt":
        pat = top_pat if dress else random_pattern(rng)
        mat = top_mat if dress else str(rng.choice(["cotton", "satin", "denim", "synthetic"]))
        out.append(_garment(rng, "skirt", "dress" if dress else "skirt", pat, mat, loose=0.012,
                            folds=rng.uniform(0.1, 0.35), waist=0.1 if dress else rng.uniform(0.06, 0.14),
                            length=rng.uniform(0.25, 0.75), flare=rng.uniform(0.03, 0.2)))
    if rng.random() < 0.85:
        boot = rng.random() < 0.15
        pat = Pattern("solid", np.stack([random_color(rng, dark=rng.random() < 0.6)] * 3), 0.05, 0)
        mat = "leather" if rng.random() < 0.6 else "synthetic"
        out.append(_garment(rng, "shoes", "boots" if boot else "shoes", pat, mat, loose=0.007, folds=0.001,
                            height=rng.uniform(0.12, 0.3) if boot else 0.03))
    if rng.random() < 0.97 - 0.17 * (1 - f):
        shade = rng.random()
        base = (np.array([0.04, 0.03, 0.025]) if shade < 0.45 else np.array([0.22, 0.13, 0.07]) if shade < 0.75
                else np.array([0.6, 0.45, 0.25]) if shade < 0.88 else np.array([0.5, 0.2, 0.08]) if shade < 0.94
                else np.array([0.55, 0.55, 0.55]))
        base = np.clip(base * rng.uniform(0.8, 1.25), 0, 1)
        pat = Pattern("noise", np.stack([base, np.clip(base * 1.5 + 0.03, 0, 1), base]).astype(np.float32),
                      0.004, int(rng.integers(1 << 30)))
        p_long = 0.1 + 0.35 * f
        length = float(rng.choice([0.0, 0.5, 1.0], p=[1 - 2 * p_long, p_long, p_long]))
        out.append(_garment(rng, "hair", "hair", pat, "hair", loose=rng.uniform(0.008, 0.02), folds=0.004,
                            length=length, front=rng.uniform(0.04, 0.08)))
    if not dress and rng.random() < 0.2:  # drawn last so that the rest of the outfit does not depend on it
        mat = str(rng.choice(["denim", "leather", "cotton", "synthetic"]))
        pat = random_pattern(rng, ("denim",) if mat == "denim" else ("solid", "checks", "noise"))
        top = next(i for i, g in enumerate(out) if g.kind == "top")
        jacket = _garment(rng, "jacket", "jacket", pat, mat, loose=rng.uniform(0.02, 0.035),
                          folds=rng.uniform(0.008, 0.016), hem=out[top].params["hem"] - rng.uniform(0.0, 0.12),
                          opening=rng.uniform(0.03, 0.1))
        out.insert(top + 1, jacket)
    return out


# ---------------------------------------------------------------------------------------------------
# coverage rules


@dataclass(frozen=True)
class Surface:
    """Points on the body's rest pose where coverage is evaluated (texels or vertices).

    points (N, 3) rest-pose positions (subject frame), region (N,) int index into REGIONS,
    foot (N,) skinning weight on foot bones.
    """

    points: np.ndarray
    region: np.ndarray
    foot: np.ndarray


def _arm_t(points: np.ndarray, lm: dict[str, np.ndarray], side: str) -> np.ndarray:
    """Position along the arm: 0 at the shoulder joint, 1 at the elbow, 2 at the wrist (projection)."""
    a, b, c = lm[f"upperarm01.{side}"], lm[f"lowerarm01.{side}"], lm[f"wrist.{side}"]

    def project(p0, p1):
        d = p1 - p0
        s = ((points - p0) @ d) / max(float(d @ d), 1e-9)
        s_c = np.clip(s, 0.0, 1.0)
        dist = np.linalg.norm(points - (p0 + s_c[:, None] * d), axis=1)
        return s, dist

    s1, d1 = project(a, b)
    s2, d2 = project(b, c)
    return np.where(d1 <= d2, np.minimum(s1, 1.0), 1.0 + np.maximum(s2, 0.0))


def coverage(garment: Garment, surf: Surface, lm: dict[str, np.ndarray]) -> np.ndarray:
    """(N,) bool: which surface points the garment hides (rules on the rest pose).

    Landmarks are rest-pose joint positions in the subject frame (Body.landmarks), plus "top" (head top).
    """
    p, reg = surf.points, surf.region
    x, z = p[:, 0], p[:, 2]
    torso = reg == REGIONS.index("torso")
    head = reg == REGIONS.index("head")
    arm_l, arm_r = reg == REGIONS.index("arm_l"), reg == REGIONS.index("arm_r")
    leg = (reg == REGIONS.index("leg_l")) | (reg == REGIONS.index("leg_r"))
    hip_z = 0.5 * (lm["upperleg01.L"][2] + lm["upperleg01.R"][2])
    ankle_z = 0.5 * (lm["foot.L"][2] + lm["foot.R"][2])
    neck_z = lm["neck01"][2]
    prm = garment.params
    k = garment.kind
    if k == "underwear":
        return (torso & (z < hip_z + 0.08)) | (leg & (z > hip_z - 0.08))
    if k == "bottom":
        waist = hip_z + prm["waist"]
        leg_end = ankle_z + prm["leg_end"] * (hip_z - ankle_z)
        return (torso & (z < waist)) | (leg & (z > leg_end))
    if k == "skirt":
        waist = hip_z + prm["waist"]
        return torso & (z < waist) & (z > hip_z - 0.02)
    if k == "jacket":  # a long-sleeved top open down the front
        shut = dataclasses.replace(garment, kind="top", params={"hem": prm["hem"], "neck": 0.02, "sleeve": 1.9})
        opening = torso & (x > lm["spine03"][0]) & (np.abs(p[:, 1] - lm["neck01"][1]) < prm["opening"])
        return coverage(shut, surf, lm) & ~opening
    if k == "top":
        hem = hip_z + prm["hem"]
        front = np.clip((x - lm["neck01"][0]) / 0.08, 0.0, 1.0)
        neck_cut = neck_z - 0.015 - prm["neck"] * front
        body = (torso | leg) & (z > hem) & (z < neck_cut)
        sleeve = prm["sleeve"]
        arms = np.zeros_like(body)
        if sleeve > 0:
            arms = (arm_l & (_arm_t(p, lm, "L") < sleeve)) | (arm_r & (_arm_t(p, lm, "R") < sleeve))
        else:  # sleeveless: cover the shoulder cap only
            arms = (arm_l & (_arm_t(p, lm, "L") < 0.05)) | (arm_r & (_arm_t(p, lm, "R") < 0.05))
        return body | arms
    if k == "shoes":
        top = ankle_z + prm["height"]
        return leg & ((z < top) | (surf.foot > 0.5))
    if k == "hair":
        top = lm["top"]
        depth = top[2] - z
        front = (x - top[0]) / 0.09
        limit = np.interp(front, [-0.6, 0.1, 0.45], [0.16 + 0.06 * prm["length"], 0.13, prm["front"]])
        on_head = head & (depth < limit) & (z > neck_z + 0.02)
        if prm["length"] > 0:
            drop = 0.12 + 0.25 * prm["length"]
            back = x < lm["neck01"][0] - 0.03
            on_head |= (head | torso) & back & (z > neck_z - drop)
        return on_head
    raise ValueError(f"unknown garment kind {k!r}")


# ---------------------------------------------------------------------------------------------------
# shells


def _smooth_on_mesh(values: np.ndarray, faces: np.ndarray, iterations: int) -> np.ndarray:
    """Average per-vertex values with their edge neighbours ``iterations`` times (umbrella operator)."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.concatenate([edges, edges[:, ::-1]])
    deg = np.bincount(edges[:, 0], minlength=len(values)).astype(np.float64)
    v = values.astype(np.float64)
    for _ in range(iterations):
        acc = np.bincount(edges[:, 0], weights=v[edges[:, 1]], minlength=len(v))
        v = 0.5 * v + 0.5 * acc / np.maximum(deg, 1)
    return v


def _rings_from_outline(faces: np.ndarray, n_vertices: int, rings: int) -> np.ndarray:
    """(n_vertices,) float: how many edge steps each vertex of ``faces`` lies inside their open outline
    (0 on it), capped at ``rings``; vertices not in ``faces`` get ``rings``."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    level = np.full(n_vertices, float(rings))
    reached = np.zeros(n_vertices, dtype=bool)
    reached[uniq[count == 1].ravel()] = True
    level[reached] = 0.0
    for r in range(1, rings):
        nxt = np.zeros(n_vertices, dtype=bool)
        nxt[uniq[reached[uniq[:, 0]], 1]] = True
        nxt[uniq[reached[uniq[:, 1]], 0]] = True
        nxt &= ~reached
        level[nxt] = float(r)
        reached |= nxt
    return level


def offset_shell(garment: Garment, body: Body, faces: np.ndarray, uv: np.ndarray, covered: np.ndarray,
                 textures: dict[str, np.ndarray]) -> Part | None:
    """The covered part of the posed body pushed out along its normals, with fold noise.

    Args:
        garment: a Garment with loose > 0.
        body: the posed Body.
        faces: (F, 3) body faces; uv: (F, 3, 2) body UVs (the shell reuses them, and the body's textures).
        covered: (V,) bool vertex coverage of this garment.
        textures: "albedo", "roughness", "specular" body textures the shell samples.

    Returns:
        Part (skin 0), or None when the garment covers no whole face.
    """
    sel = covered[faces].all(axis=1)
    if not sel.any():
        return None
    near = _smooth_on_mesh(covered.astype(np.float64), faces, 6)
    fold = fbm(body.rest * np.array([1.0, 1.0, 2.5]), 9.0, 3, garment.pattern.seed + 3)
    ripple = value_noise(body.rest, 28.0, garment.pattern.seed + 7) - 0.5
    offset = garment.loose * (0.4 + 0.6 * near) + garment.folds * (1.5 * fold + 0.4 * ripple) * near
    offset = np.maximum(offset, 0.6 * garment.loose * near + 0.002)
    if garment.kind == "hair":
        # hair thins out toward the hairline: the shell comes down onto the scalp over its last rings of
        # vertices, so its whole-triangle outline does not stand off the forehead as a sawtooth step (the
        # texel-exact hairline painted on the body shows instead)
        t = _rings_from_outline(faces[sel], len(offset), 3) / 3.0
        offset = 0.001 + (offset - 0.001) * t * t * (3.0 - 2.0 * t)
    moved = body.vertices + body.normals * offset[:, None].astype(np.float32)
    used = np.unique(faces[sel])
    remap = np.full(len(moved), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return Part(
        name=garment.name,
        vertices=moved[used].astype(np.float32),
        faces=remap[faces[sel]].astype(np.int32),
        uv=uv[sel].astype(np.float32),
        albedo=textures["albedo"],
        skin=0.0,
        roughness=textures["roughness"],
        specular=textures["specular"],
        subsurface=0.0,
    )


def skirt_shell(garment: Garment, body: Body, region: np.ndarray, rng: np.random.Generator, rings: int = 24,
                sectors: int = 72, texture_size: int = 256) -> Part:
    """A frustum-like shell from the waist down that bridges the legs, with hanging folds.

    Built on the posed body: each ring's radius (about the hips' vertical axis) hugs the widest torso
    or leg point in its angular sector (arms and hands are ignored), never narrows going down, flares,
    and ripples with folds that grow toward the hem. Its own texture is the garment pattern evaluated
    on the shell (texture_size × 2·texture_size, u around, v down from the waist).

    Args:
        garment: a Garment of kind "skirt".
        body: the posed Body.
        region: (V,) per-vertex index into REGIONS (Template.region).
        rng: random generator for the folds.
    """
    lm = body.landmarks
    hangs_on = np.isin(region, [REGIONS.index(r) for r in ("torso", "leg_l", "leg_r")])
    v = body.vertices[hangs_on]
    hip_z = 0.5 * (lm["upperleg01.L"][2] + lm["upperleg01.R"][2])
    knee_z = 0.5 * (lm["lowerleg01.L"][2] + lm["lowerleg01.R"][2])
    ankle_z = 0.5 * (lm["foot.L"][2] + lm["foot.R"][2])
    prm = garment.params
    z_top = hip_z + prm["waist"]
    z_hem = knee_z + (1.0 - 2.0 * prm["length"]) * (hip_z - knee_z) if prm["length"] < 0.5 else \
        knee_z - (2.0 * prm["length"] - 1.0) * (knee_z - ankle_z - 0.08)
    z_hem = float(min(z_hem, z_top - 0.15))
    band = (v[:, 2] < z_top + 0.03) & (v[:, 2] > z_hem - 0.03)
    near_hips = band & (np.abs(v[:, 2] - z_top) < 0.06)
    cxy = v[near_hips, :2].mean(axis=0) if near_hips.any() else v[:, :2].mean(axis=0)
    zs = np.linspace(z_top, z_hem, rings)
    theta = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    rel = v[band, :2] - cxy
    ang = np.mod(np.arctan2(rel[:, 1], rel[:, 0]), 2 * np.pi)
    rad = np.linalg.norm(rel, axis=1)
    sector = np.minimum((ang / (2 * np.pi) * sectors).astype(np.int64), sectors - 1)
    ring = np.clip(np.round((z_top - v[band, 2]) / max(z_top - z_hem, 1e-6) * (rings - 1)).astype(np.int64),
                   0, rings - 1)
    radius = np.zeros((rings, sectors))
    np.maximum.at(radius, (ring, sector), rad)
    for _ in range(4):  # fill empty sectors and smooth around the ring
        radius = np.maximum(radius, 0.5 * (np.roll(radius, 1, axis=1) + np.roll(radius, -1, axis=1)))
    radius = np.maximum.accumulate(radius, axis=0)  # never narrower below
    depth = (z_top - zs) / max(z_top - z_hem, 1e-6)
    n_folds = int(rng.integers(7, 14))
    phase = rng.uniform(0, 2 * np.pi)
    wobble = np.array([fbm(np.stack([np.cos(theta), np.sin(theta), np.full(sectors, d)], 1), 2.0, 2,
                           garment.pattern.seed) for d in depth])
    folds = garment.folds * depth[:, None] ** 1.5 * (0.5 * np.sin(n_folds * theta + phase)[None] + wobble)
    r = radius + garment.loose + prm["flare"] * depth[:, None] * (z_top - z_hem) + 0.06 * folds
    pts = np.stack([cxy[0] + r * np.cos(theta)[None], cxy[1] + r * np.sin(theta)[None],
                    np.broadcast_to(zs[:, None], r.shape)], axis=-1).reshape(-1, 3)
    # faces: quads between ring i and i+1, counter-clockwise seen from outside (normal points out)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(sectors), indexing="ij")
    a = i * sectors + j
    b = i * sectors + (j + 1) % sectors
    c = (i + 1) * sectors + (j + 1) % sectors
    d = (i + 1) * sectors + j
    faces = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    # uv: u around (wrapping seam uses its own column), v down the skirt
    uu = np.concatenate([np.stack([j, j, j + 1], -1).reshape(-1, 3), np.stack([j, j + 1, j + 1], -1).reshape(-1, 3)])
    vv_a = np.stack([i, i + 1, i + 1], -1).reshape(-1, 3)
    vv_b = np.stack([i, i + 1, i], -1).reshape(-1, 3)
    vv = np.concatenate([vv_a, vv_b])
    uv = np.stack([uu / sectors, 1.0 - vv / (rings - 1)], axis=-1).astype(np.float32)
    # texture: the pattern on the shell (unwrapped cylinder at the mean radius, so it is undistorted)
    tr, tc = np.meshgrid(np.arange(texture_size), np.arange(2 * texture_size), indexing="ij")
    t_theta = (tc + 0.5) / (2 * texture_size) * 2 * np.pi
    t_z = z_top - (tr + 0.5) / texture_size * (z_top - z_hem)
    r_mean = float(radius.mean() + garment.loose)
    tex_pts = np.stack([r_mean * np.cos(t_theta), r_mean * np.sin(t_theta), t_z], -1).reshape(-1, 3)
    albedo = evaluate_pattern(garment.pattern, tex_pts).reshape(texture_size, 2 * texture_size, 3)
    return Part(
        name=garment.name,
        vertices=pts.astype(np.float32),
        faces=faces.astype(np.int32),
        uv=uv,
        albedo=albedo,
        skin=0.0,
        roughness=garment.roughness,
        specular=garment.specular,
        subsurface=0.0,
    )


def hair_color_of(garments: list[Garment]) -> np.ndarray | None:
    """(3,) colour of the outfit's hair, or None without hair (eyebrows use it)."""
    for g in garments:
        if g.kind == "hair":
            return np.asarray(g.pattern.colors[0], dtype=np.float32)
    return None


def hair_curtain(garment: Garment, body: Body, region: np.ndarray, rng: np.random.Generator, rings: int = 20,
                 sectors: int = 40, texture_size: int = 128) -> Part | None:
    """Long hair hanging from the head's sides and back down toward (or past) the shoulders.

    An open, vertical curtain around the head's vertical axis that spans the sides and the back
    (the face's ±70° stay open). Each ring hangs from the widest head section above it; at the back
    it is pushed outside the neck and upper back; at the sides it ends in the shoulders, as hair
    resting on them does. Its own texture has vertical strands (texture_size × 2·texture_size).

    Returns:
        Part (skin 0), or None for short hair (params["length"] == 0).
    """
    length = garment.params.get("length", 0.0)
    if length <= 0:
        return None
    lm = body.landmarks
    head_v = body.vertices[region == REGIONS.index("head")]
    torso_v = body.vertices[region == REGIONS.index("torso")]
    eyes = [body.vertices[int(np.argmin(np.linalg.norm(body.rest - lm[f"eye.{s}"], axis=1)))] for s in "LR"]
    eye_mid = 0.5 * (eyes[0] + eyes[1])
    top = head_v[:, 2].max()
    crown = head_v[head_v[:, 2] > top - 0.06]
    cxy = crown[:, :2].mean(axis=0)
    facing = eye_mid[:2] - cxy
    phi0 = math.atan2(facing[1], facing[0])
    z_top = top - 0.045  # starts under the scalp shell, so the two overlap
    shoulder_z = 0.5 * (lm["shoulder01.L"][2] + lm["shoulder01.R"][2])
    z_bot = float(min(shoulder_z - 0.02 - 0.3 * (length - 0.5), z_top - 0.12))
    zs = np.linspace(z_top, z_bot, rings)
    open_half = math.radians(70.0)
    theta = phi0 + np.linspace(open_half, 2 * np.pi - open_half, sectors)
    pts = np.concatenate([head_v, torso_v])
    is_head = np.arange(len(pts)) < len(head_v)
    rel = pts[:, :2] - cxy
    ang = np.mod(np.arctan2(rel[:, 1], rel[:, 0]) - theta[0], 2 * np.pi)
    sector = np.round(ang / (theta[-1] - theta[0]) * (sectors - 1)).astype(np.int64)
    ok = (sector >= 0) & (sector < sectors)
    rad = np.linalg.norm(rel, axis=1)
    ring = np.round((z_top - pts[:, 2]) / (z_top - z_bot) * (rings - 1)).astype(np.int64)
    ok &= (ring >= 0) & (ring < rings)
    head_r = np.zeros((rings, sectors))
    np.maximum.at(head_r, (ring[ok & is_head], sector[ok & is_head]), rad[ok & is_head])
    head_r = np.maximum.accumulate(head_r, axis=0)  # hangs from the widest section above
    back_r = np.zeros((rings, sectors))
    np.maximum.at(back_r, (ring[ok & ~is_head], sector[ok & ~is_head]), rad[ok & ~is_head])
    behind = np.abs(np.mod(theta - phi0, 2 * np.pi) - np.pi) < math.radians(35.0)
    back_r = np.minimum(back_r, head_r.max() + 0.04)  # over the nape and upper back, not the shoulder blades
    radius = np.where(behind[None], np.maximum(head_r, back_r), head_r)
    for _ in range(3):
        radius[:, 1:-1] = np.maximum(radius[:, 1:-1], 0.5 * (radius[:, :-2] + radius[:, 2:]))
    radius = np.maximum.accumulate(radius, axis=0)
    waves = garment.folds * np.sin(rng.integers(8, 16) * (theta - phi0) + rng.uniform(0, 2 * np.pi))
    depth = np.linspace(0, 1, rings)[:, None]
    tuck = np.clip(np.linspace(-1.0, 3.0, rings), 0.0, 1.0)[:, None]  # the top rings tuck under the scalp shell
    r = radius + (garment.loose + 0.01) * tuck + waves[None] * (0.3 + depth)
    verts = np.stack([cxy[0] + r * np.cos(theta)[None], cxy[1] + r * np.sin(theta)[None],
                      np.broadcast_to(zs[:, None], r.shape)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(sectors - 1), indexing="ij")
    a, b = i * sectors + j, i * sectors + j + 1
    c, d = (i + 1) * sectors + j + 1, (i + 1) * sectors + j
    faces = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    uu = np.concatenate([np.stack([j, j, j + 1], -1).reshape(-1, 3), np.stack([j, j + 1, j + 1], -1).reshape(-1, 3)])
    vv = np.concatenate([np.stack([i, i + 1, i + 1], -1).reshape(-1, 3), np.stack([i, i + 1, i], -1).reshape(-1, 3)])
    uv = np.stack([uu / (sectors - 1), 1.0 - vv / (rings - 1)], axis=-1).astype(np.float32)
    # strands: noise stretched along the hair (v), fine across it (u)
    tr, tc = np.meshgrid(np.arange(texture_size), np.arange(2 * texture_size), indexing="ij")
    grid = np.stack([tc * 0.6, tr * 0.04, np.zeros_like(tr, dtype=np.float64)], -1).reshape(-1, 3)
    streak = value_noise(grid, 1.0, garment.pattern.seed) * 0.6 + 0.4 * value_noise(grid, 0.37, garment.pattern.seed)
    base = np.asarray(garment.pattern.colors[0], dtype=np.float64)
    albedo = np.clip(base[None] * (0.7 + 0.6 * streak[:, None]), 0, 1).reshape(texture_size, 2 * texture_size, 3)
    return Part(
        name=garment.name + "_long",
        vertices=verts.astype(np.float32),
        faces=faces.astype(np.int32),
        uv=uv,
        albedo=albedo.astype(np.float32),
        skin=0.0,
        roughness=garment.roughness,
        specular=garment.specular,
        subsurface=0.0,
    )
