"""Human bodies from the ``anny`` parametric model: loading, phenotype and pose sampling, posed meshes.

anny (Apache-2.0 code, MakeHuman-derived CC0 assets) gives a 13.7k-vertex body with UV coordinates,
a 104-bone rig and shape phenotypes. Its own frame has +z up, the person facing −y and their left
hand on +x; :func:`posed_body` turns that into the subject frame of DESIGN.md §3 (the person faces
+x, the camera; their left hand is on +y, the image's right; +z up; feet at z = 0; metres).

The model data is built about a minute the first time and cached on disk under ``ANNY_CACHE_DIR``
(default here ``~/.cache/relight_rt/anny``, ~0.8 GB); later processes load it in under a second
(plus ~2 s for anny's warp skinning kernel the first time a process poses a body), and a posed
mesh then takes ~0.1 s. Everything works offline: anny ships its assets in the wheel.
"""

from __future__ import annotations

import functools
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt.engine.errors import RelightError

log = logging.getLogger(__name__)

DEFAULT_CACHE = Path.home() / ".cache" / "relight_rt" / "anny"
#: anny frame -> subject frame: (x, y, z)_subject = (−y, x, z)_anny, a +90° turn about z.
ANNY_TO_SUBJECT = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])

#: Bone groups by name prefix; a vertex belongs to the group holding most of its skinning weight.
REGIONS = ("torso", "head", "arm_l", "arm_r", "leg_l", "leg_r")
_HAND_BONES = ("wrist", "finger", "metacarpal")
_FOOT_BONES = ("foot", "toe")


def _region_of(bone: str) -> str:
    side = "l" if bone.endswith(".L") else "r"
    if bone.startswith(("neck", "head", "eye")):
        return "head"
    if bone.startswith(("shoulder", "upperarm", "lowerarm") + _HAND_BONES):
        return "arm_" + side
    if bone.startswith(("upperleg", "lowerleg") + _FOOT_BONES):
        return "leg_" + side
    return "torso"


def _import_anny():
    cache = os.environ.setdefault("ANNY_CACHE_DIR", str(DEFAULT_CACHE))
    try:
        import anny
        import anny.paths
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RelightError(
            "bodies need the 'render' extra (anny, torch): pip install 'relight-rt[render,export]'"
        ) from exc
    # anny reads ANNY_CACHE_DIR when it is first imported, which may have happened before us
    anny.paths.set_anny_cache_path(cache)
    return torch, anny


@functools.lru_cache(maxsize=1)
def get_model():
    """The anny full-body model, built once per process (≈ 60 s the first time, then cached on disk).

    Returns:
        anny.Anny in float64 on the CPU; do not modify it.
    """
    torch, anny = _import_anny()
    if torch.get_num_threads() > 2:
        torch.set_num_threads(2)
    log.info("loading the anny body model (cache: %s)", os.environ["ANNY_CACHE_DIR"])
    return anny.Anny()


@dataclass(frozen=True)
class Template:
    """What every anny body shares: topology, UVs and which body region each vertex belongs to.

    Attributes:
        faces: (F, 3) int32 vertex indices.
        uv: (F, 3, 2) float32 texture coordinates per face corner, v up.
        region: (V,) int8 index into REGIONS (largest summed skinning weight).
        hand: (V,) float32 skinning weight on wrist/finger bones.
        foot: (V,) float32 skinning weight on foot/toe bones.
        bone_labels: the rig's bone names.
    """

    faces: np.ndarray
    uv: np.ndarray
    region: np.ndarray
    hand: np.ndarray
    foot: np.ndarray
    bone_labels: tuple[str, ...]


@functools.lru_cache(maxsize=1)
def get_template() -> Template:
    """The shared topology of :func:`get_model` (computed once)."""
    model = get_model()
    faces = model.faces.numpy().astype(np.int32)
    uv = model.texture_coordinates.numpy()[model.face_texture_coordinate_indices.numpy()].astype(np.float32)
    labels = tuple(model.bone_labels)
    weights = model.vertex_bone_weights.numpy()
    indices = model.vertex_bone_indices.numpy()
    n_vertices = weights.shape[0]
    bone_region = np.array([REGIONS.index(_region_of(b)) for b in labels])
    per_region = np.zeros((n_vertices, len(REGIONS)))
    rows = np.repeat(np.arange(n_vertices), weights.shape[1])
    np.add.at(per_region, (rows, bone_region[indices].ravel()), weights.ravel())
    is_hand = np.array([b.startswith(_HAND_BONES) for b in labels])
    is_foot = np.array([b.startswith(_FOOT_BONES) for b in labels])
    hand = (weights * is_hand[indices]).sum(axis=1).astype(np.float32)
    foot = (weights * is_foot[indices]).sum(axis=1).astype(np.float32)
    return Template(faces, uv, per_region.argmax(axis=1).astype(np.int8), hand, foot, labels)


# ---------------------------------------------------------------------------------------------------
# Phenotypes and poses


def sample_phenotype(rng: np.random.Generator) -> dict[str, float]:
    """Adult anny phenotypes: gender, age, muscle, weight, height, proportions, each in [0, 1].

    anny's age anchors are newborn (−1/3), baby (0), child (1/3), young (2/3) and old (1); adults
    are drawn from 0.62 to 1. Height 0.15..0.62 gives people of about 1.5 to 1.95 m.
    """
    return {
        "gender": float(rng.uniform(0.0, 1.0)),
        "age": float(rng.uniform(0.62, 1.0)),
        "muscle": float(np.clip(rng.normal(0.5, 0.18), 0.05, 0.95)),
        "weight": float(np.clip(rng.normal(0.5, 0.2), 0.05, 0.95)),
        "height": float(rng.uniform(0.15, 0.62)),
        "proportions": float(rng.uniform(0.3, 0.9)),
    }


#: Named standing poses; each maps to angles in degrees, read by _pose_angles.
POSES = ("relaxed", "a_pose", "hands_on_hips", "arms_crossed", "one_leg_forward", "walking", "hand_on_hip",
         "hands_in_front")


@dataclass(frozen=True)
class Pose:
    """A standing pose as joint angles in degrees (anny rest-frame axes), see :func:`sample_pose`.

    Per side (index 0 = the person's left, 1 = right): arm lowering from anny's rest A-pose, arm swing
    forward, upper-arm inward twist, elbow bend, hip flexion (leg forward), hip abduction, knee bend.
    Whole body: turn about the vertical, torso twist, torso lean forward, head turn, head tilt.
    """

    name: str
    arm_down: tuple[float, float]
    arm_forward: tuple[float, float]
    arm_twist: tuple[float, float]
    elbow: tuple[float, float]
    hip_forward: tuple[float, float]
    hip_out: tuple[float, float]
    knee: tuple[float, float]
    turn: float
    twist: float
    lean: float
    head_turn: float
    head_tilt: float


def sample_pose(rng: np.random.Generator, name: str | None = None) -> Pose:
    """A natural standing pose: one of POSES (random when ``name`` is None) with random variation."""
    if name is None:
        name = POSES[int(rng.integers(len(POSES)))]
    if name not in POSES:
        raise RelightError(f"unknown pose {name!r}; expected one of {', '.join(POSES)}")

    def pair(lo: float, hi: float, sym: float = 1.0) -> tuple[float, float]:
        a = float(rng.uniform(lo, hi))
        b = float(rng.uniform(lo, hi)) if sym < 1.0 else a + float(rng.normal(0.0, 0.1 * (hi - lo)))
        return a, b

    arm_down = pair(28, 38, 0.0)
    arm_forward = pair(-5, 10, 0.0)
    arm_twist = pair(-10, 15, 0.0)
    elbow = pair(-30, -5, 0.0)
    hip_forward = pair(-3, 3, 0.0)
    hip_out = pair(-2, 4, 0.0)
    knee = pair(0, 5, 0.0)
    if name == "a_pose":
        arm_down = pair(5, 22, 0.0)
        elbow = pair(-35, -15, 0.0)
    elif name == "hands_on_hips":
        arm_down = pair(5, 15, 0.0)
        arm_twist = pair(70, 90, 0.0)
        arm_forward = pair(-15, -5, 0.0)
        elbow = pair(50, 65, 0.0)
    elif name == "hand_on_hip":
        side = int(rng.integers(2))
        arm_down = tuple(float(rng.uniform(5, 15)) if i == side else arm_down[i] for i in range(2))
        arm_twist = tuple(float(rng.uniform(70, 90)) if i == side else arm_twist[i] for i in range(2))
        elbow = tuple(float(rng.uniform(50, 65)) if i == side else elbow[i] for i in range(2))
        arm_forward = tuple(float(rng.uniform(-15, -5)) if i == side else arm_forward[i] for i in range(2))
    elif name == "arms_crossed":
        arm_down = pair(30, 36, 0.0)
        arm_forward = pair(15, 25, 0.0)
        arm_twist = pair(60, 75, 0.0)
        elbow = pair(55, 70, 0.0)
    elif name == "hands_in_front":
        arm_forward = pair(5, 15, 0.0)
        arm_twist = pair(35, 50, 0.0)
        elbow = pair(10, 25, 0.0)
    elif name == "one_leg_forward":
        side = int(rng.integers(2))
        hip_forward = tuple(float(rng.uniform(15, 28)) if i == side else float(rng.uniform(-8, 0)) for i in range(2))
        knee = tuple(float(rng.uniform(5, 20)) if i == side else float(rng.uniform(0, 5)) for i in range(2))
    elif name == "walking":
        swing = float(rng.uniform(15, 28)) * (1 if rng.random() < 0.5 else -1)
        hip_forward = (swing, -swing)
        knee = (float(rng.uniform(5, 25)) if swing < 0 else 5.0, float(rng.uniform(5, 25)) if swing > 0 else 5.0)
        arm_forward = (-0.8 * swing, 0.8 * swing)
        elbow = pair(-25, -5, 0.0)
    return Pose(
        name=name,
        arm_down=arm_down,
        arm_forward=arm_forward,
        arm_twist=arm_twist,
        elbow=elbow,
        hip_forward=hip_forward,
        hip_out=hip_out,
        knee=knee,
        turn=float(rng.uniform(-35, 35)),
        twist=float(rng.uniform(-10, 10)),
        lean=float(rng.uniform(-3, 5)),
        head_turn=float(rng.uniform(-25, 25)),
        head_tilt=float(rng.uniform(-8, 8)),
    )


def _rotation(axis: np.ndarray, degrees: float) -> np.ndarray:
    """(3, 3) rotation by ``degrees`` about ``axis`` (right-hand rule), Rodrigues' formula."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / max(np.linalg.norm(axis), 1e-12)
    a = math.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _pose_rotations(pose: Pose, heads: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-bone (3, 3) deltas in anny's rest-frame axes ('local-ref': carried along by the parent).

    anny axes: x = the person's left, y = backward, z = up.
    """
    x, y, z = np.eye(3)
    forward = -y
    rot: dict[str, np.ndarray] = {}
    for i, s in enumerate(("L", "R")):
        sign = 1.0 if s == "L" else -1.0
        upper = _unit(heads[f"lowerarm01.{s}"] - heads[f"upperarm01.{s}"])
        fore = _unit(heads[f"wrist.{s}"] - heads[f"lowerarm01.{s}"])
        hinge = _unit(np.cross(upper, forward)) * sign
        # lower the arm about the forward axis, swing it forward about the lateral axis, twist it inward
        r_arm = _rotation(x, -pose.arm_forward[i]) @ _rotation(y, sign * pose.arm_down[i])
        twist = _rotation(upper, sign * pose.arm_twist[i])
        rot[f"upperarm01.{s}"] = r_arm @ twist
        # elbow: fold the forearm further from the upper arm's direction (anny's rest pose is already bent)
        bend_axis = _unit(np.cross(fore, upper)) if np.linalg.norm(np.cross(fore, upper)) > 1e-3 else hinge
        rot[f"lowerarm01.{s}"] = _rotation(bend_axis, -pose.elbow[i])
        rot[f"upperleg01.{s}"] = _rotation(x, -pose.hip_forward[i]) @ _rotation(y, -sign * pose.hip_out[i])
        rot[f"lowerleg01.{s}"] = _rotation(x, pose.knee[i])
    rot["spine03"] = _rotation(z, pose.twist) @ _rotation(x, pose.lean)
    rot["neck02"] = _rotation(z, 0.5 * pose.head_turn)
    rot["head"] = _rotation(z, 0.5 * pose.head_turn) @ _rotation(y, pose.head_tilt)
    rot["root"] = _rotation(z, pose.turn)
    return rot


@dataclass(frozen=True)
class Body:
    """A posed anny body in the subject frame (see the module docstring).

    Attributes:
        vertices: (V, 3) float32 posed positions, metres, feet at z = 0.
        rest: (V, 3) float32 positions in anny's rest pose (same phenotype), subject-frame axes, feet at 0;
            garments and patterns are laid out on these so they follow the pose.
        normals: (V, 3) float32 unit area-weighted vertex normals of ``vertices`` (outward).
        landmarks: rest-pose joint positions (subject frame) by bone name, (3,) float64 each.
        phenotype: the anny phenotype used.
        pose: the Pose used.
    """

    vertices: np.ndarray
    rest: np.ndarray
    normals: np.ndarray
    landmarks: dict[str, np.ndarray]
    phenotype: dict[str, float]
    pose: Pose


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) float32 unit area-weighted vertex normals of a mesh with counter-clockwise faces."""
    v = vertices.astype(np.float64)
    tri = v[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(v)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return (vn / np.maximum(norm, 1e-12)).astype(np.float32)


def posed_body(phenotype: dict[str, float], pose: Pose) -> Body:
    """Shape anny with ``phenotype``, pose it with ``pose``, and express it in the subject frame.

    Args:
        phenotype: anny phenotype values in [0, 1] by name (see sample_phenotype); missing ones are 0.5.
        pose: a Pose (see sample_pose).

    Returns:
        Body with float32 arrays, feet at z = 0, the pelvis on the z axis.
    """
    torch, _ = _import_anny()
    model = get_model()
    template = get_template()
    unknown = set(phenotype) - set(model.phenotype_labels)
    if unknown:
        raise RelightError(f"unknown phenotype names {sorted(unknown)}; expected {model.phenotype_labels}")
    with torch.no_grad():
        kwargs = {k: torch.tensor([float(v)], dtype=torch.float64) for k, v in phenotype.items()}
        rest_out = model(phenotype_kwargs=kwargs)
        heads_arr = rest_out["rest_bone_heads"][0].numpy()
        heads = {b: heads_arr[i] for i, b in enumerate(template.bone_labels)}
        deltas = np.tile(np.eye(4), (1, len(template.bone_labels), 1, 1))
        for bone, r in _pose_rotations(pose, heads).items():
            deltas[0, template.bone_labels.index(bone), :3, :3] = r
        out = model(pose_parameters=torch.from_numpy(deltas), phenotype_kwargs=kwargs)
        posed = out["vertices"][0].numpy()
        rest = out["rest_vertices"][0].numpy()
    if not np.isfinite(posed).all():
        raise RelightError(f"anny returned non-finite vertices for phenotype {phenotype} and pose {pose.name}")
    posed = posed @ ANNY_TO_SUBJECT.T
    rest = rest @ ANNY_TO_SUBJECT.T
    centre_rest = np.array([*(heads["root"] @ ANNY_TO_SUBJECT.T)[:2], rest[:, 2].min()])
    centre_posed = np.array([*(out["bone_poses"][0, 0, :3, 3].numpy() @ ANNY_TO_SUBJECT.T)[:2], posed[:, 2].min()])
    landmarks = {b: (h @ ANNY_TO_SUBJECT.T) - centre_rest for b, h in heads.items()}
    posed = (posed - centre_posed).astype(np.float32)
    return Body(
        vertices=posed,
        rest=(rest - centre_rest).astype(np.float32),
        normals=vertex_normals(posed, template.faces),
        landmarks=landmarks,
        phenotype=dict(phenotype),
        pose=pose,
    )
