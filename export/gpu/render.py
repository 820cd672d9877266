"""Stage-1 training samples rendered in plain PyTorch from a bank subject: the GPU twin of export.render.

A sample is what ``python -m export render`` writes for one view (albedo, mask, skin, transport), for an
orthographic camera framed as :func:`export.render.camera.fit_camera` frames it, the subject turned
about +z by a yaw. Visible surfaces come from a z-buffer (:mod:`export.gpu.raster`), one sample per pixel
centre; vertex normals, two-sided normals and texture lookups follow :mod:`export.render.raycast` and
:func:`export.render.transport.sample_texture`.

Transport (DESIGN.md §3) with visibility from shadow maps: D directions ω_d spread evenly over the sphere
(a Fibonacci set, turned by a random rotation per sample); for each, an orthographic depth map of the
subject seen from ω_d, fitted to the covered pixels' footprint, tells whether the light from ω_d reaches
a pixel's point (the point lifted along its face normal by a quarter texel, a slope-scaled depth bias
of half a texel plus half a texel times tan θ, 2×2 bilinear percentage-closer filtering; these three
were chosen against embree on three bank people: less leaks light, more shows shadow acne). The unoccluded cosine
lobe is exact (A_l · Y_k(n)); the directions estimate only what occlusion removes:

    T_k(p) = A_l Y_k(n_p) − (4π / D) Σ_d (1 − V(p, ω_d)) · max(0, n_p·ω_d) · Y_k(ω_d)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from export.render.camera import fit_camera
from export.render.raycast import vertex_normals

from .bank import SubjectData
from .raster import depth_map, rasterize

# A_l of the unoccluded cosine lobe, per coefficient (DESIGN.md §3)
_LOBE = (math.pi,) + (2.0 * math.pi / 3.0,) * 3 + (math.pi / 4.0,) * 5


MAX_RESOLUTION = 2048  #: a sample's side, pixels
MAX_DIRS = 4096  #: visibility directions per sample
MAX_SHADOW_SIZE = 8192  #: a depth map's side, texels
MAX_ARRAY_BYTES = 8 << 30  #: the largest array a sample's settings may ask for (the visibility, a depth-map chunk)


@dataclass(frozen=True)
class RenderSettings:
    """How samples are rendered.

    Attributes:
        resolution: square image side, pixels.
        dirs: visibility directions per sample (64-256 on a GPU).
        shadow_size: side of each direction's depth map, texels.
        margin: free border of the camera's framing, fraction of the side (export.render's default).
        normal_offset: how far a point is lifted along its face normal before the depth test, texels.
        bias: constant depth bias, texels; ``slope_bias`` adds that many texels times tan θ (θ between
            the face normal and the direction, tan capped at 10).
        max_candidates: pixel tests per rasteriser chunk (memory bound).
        dir_chunk: directions whose depth maps are drawn together.
    """

    resolution: int = 256
    dirs: int = 128
    shadow_size: int = 256
    margin: float = 0.05
    normal_offset: float = 0.25
    bias: float = 0.5
    slope_bias: float = 0.5
    max_candidates: int = 1 << 22
    dir_chunk: int = 32

    def __post_init__(self) -> None:
        """Refuse settings whose arrays could not be held, before anything is allocated (issue 50's fuzz)."""
        from relight_rt import RelightError

        if not 8 <= self.resolution <= MAX_RESOLUTION:
            raise RelightError(f"--resolution: expected 8 to {MAX_RESOLUTION} px, got {self.resolution}")
        if not 1 <= self.dirs <= MAX_DIRS:
            raise RelightError(f"--dirs: expected 1 to {MAX_DIRS} directions, got {self.dirs}")
        if not 8 <= self.shadow_size <= MAX_SHADOW_SIZE:
            raise RelightError(f"--shadow-size: expected 8 to {MAX_SHADOW_SIZE} texels, got {self.shadow_size}")
        visibility = self.resolution**2 * self.dirs * 4  # the (pixels, directions) float32 visibility
        depth = min(self.dir_chunk, self.dirs) * self.shadow_size**2 * 4  # one chunk of depth maps
        if max(visibility, depth) > MAX_ARRAY_BYTES:
            raise RelightError(f"--resolution {self.resolution}, --dirs {self.dirs}, --shadow-size {self.shadow_size}: "
                               f"a sample would need {max(visibility, depth) / 2**30:.0f} GiB in one array, more than "
                               f"{MAX_ARRAY_BYTES >> 30} GiB; lower them")


@dataclass(frozen=True)
class DeviceSubject:
    """A bank subject as tensors on one device, every part merged into one mesh.

    Attributes:
        vertices, normals: (V, 3) float32 (normals per part, as the embree tracer computes them).
        faces: (F, 3) int64; face_uv: (F, 3, 2) float32; face_texture: (F,) int64; face_skin: (F,) float32
            (−1: the texture's alpha).
        textures: (4, h, w) float32 RGBA textures.
        lo, hi: (3,) float32 bounding box (unturned).
    """

    name: str
    vertices: torch.Tensor
    normals: torch.Tensor
    faces: torch.Tensor
    face_uv: torch.Tensor
    face_texture: torch.Tensor
    face_skin: torch.Tensor
    textures: tuple[torch.Tensor, ...]
    lo: torch.Tensor
    hi: torch.Tensor

    @classmethod
    def from_data(cls, data: SubjectData, device: torch.device) -> DeviceSubject:
        verts, normals, faces, uv, tex, skin = [], [], [], [], [], []
        offset = 0
        for p in data.parts:
            verts.append(p.vertices)
            normals.append(vertex_normals(p.vertices, p.faces))
            faces.append(p.faces + offset)
            uv.append(p.uv)
            tex.append(np.full(len(p.faces), p.texture))
            skin.append(np.full(len(p.faces), p.skin, np.float32))
            offset += len(p.vertices)
        v = np.concatenate(verts).astype(np.float32)

        def t(a, dtype):
            return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype, device=device)

        return cls(
            name=data.name,
            vertices=t(v, torch.float32),
            normals=t(np.concatenate(normals), torch.float32),
            faces=t(np.concatenate(faces), torch.int64),
            face_uv=t(np.concatenate(uv), torch.float32),
            face_texture=t(np.concatenate(tex), torch.int64),
            face_skin=t(np.concatenate(skin), torch.float32),
            textures=tuple(t(x.transpose(2, 0, 1), torch.float32) for x in data.textures),
            lo=t(v.min(axis=0), torch.float32),
            hi=t(v.max(axis=0), torch.float32),
        )


class _Box:
    """What fit_camera needs of a subject: its bounds."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        self._lo, self._hi = lo, hi

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lo, self._hi


@functools.lru_cache(maxsize=1)
def _moments_to_sh() -> np.ndarray:
    from export.render.transport import _sh_from_moments

    return _sh_from_moments()


def sh_basis(d: torch.Tensor) -> torch.Tensor:
    """(…, 9) real SH of unit directions (…, 3), DESIGN.md §3 order, through relight_rt.sh's definition."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    m = torch.stack([torch.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, y * z, x * z], dim=-1)
    return m @ torch.as_tensor(_moments_to_sh(), dtype=d.dtype, device=d.device)


def sphere_directions(n: int, generator: torch.Generator, device: torch.device) -> torch.Tensor:
    """(n, 3) unit directions spread evenly over the sphere (Fibonacci), turned by a random rotation."""
    k = torch.arange(n, dtype=torch.float64) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = torch.sqrt((1.0 - z * z).clamp_min(0.0))
    d = torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], dim=1)
    q, rr = torch.linalg.qr(torch.randn(3, 3, generator=generator, dtype=torch.float64))
    q = q * torch.sign(torch.diagonal(rr))[None]
    if torch.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return (d @ q.T).to(device=device, dtype=torch.float32)


def _tangents(n: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Two unit tangents of unit vectors n (D, 3) (Duff et al. 2017, as export.render.transport)."""
    x, y, z = n.unbind(-1)
    s = torch.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = torch.stack([1.0 + s * x * x * a, s * b, -s * x], dim=-1)
    bt = torch.stack([b, s + y * y * a, -y], dim=-1)
    return t, bt


def visibility(
    subject_vertices: torch.Tensor,
    faces: torch.Tensor,
    points: torch.Tensor,
    geo_normals: torch.Tensor,
    dirs: torch.Tensor,
    settings: RenderSettings,
) -> torch.Tensor:
    """(M, D) fraction of light from each direction that reaches each point (shadow maps, module doc).

    Args:
        subject_vertices: (V, 3) the mesh; faces: (F, 3) int64.
        points: (M, 3) surface points; geo_normals: (M, 3) their unit face normals (on the viewer's side).
        dirs: (D, 3) unit directions toward the light.
    """
    size = settings.shadow_size
    out = []
    for s in range(0, len(dirs), settings.dir_chunk):
        w = dirs[s : s + settings.dir_chunk]  # (Dc, 3)
        u, v = _tangents(w)
        pa, pb = points @ u.T, points @ v.T  # (M, Dc)
        a0, a1 = pa.amin(0), pa.amax(0)
        b0, b1 = pb.amin(0), pb.amax(0)
        extent = torch.maximum(a1 - a0, b1 - b0).clamp_min(1e-4)
        texel = extent / (size - 4)  # two free texels on every side
        oa = 0.5 * (a0 + a1) - 0.5 * size * texel
        ob = 0.5 * (b0 + b1) - 0.5 * size * texel
        va, vb, vh = subject_vertices @ u.T, subject_vertices @ v.T, subject_vertices @ w.T  # (V, Dc)
        xy = torch.stack([(va - oa) / texel, (vb - ob) / texel], dim=-1).transpose(0, 1)  # (Dc, V, 2)
        zbuf = depth_map(xy, -vh.T, faces, size, max_candidates=settings.max_candidates)  # -height: nearest light
        cos_g = (geo_normals @ w.T).clamp(-1.0, 1.0)  # (M, Dc)
        lifted = points[:, None] + geo_normals[:, None] * (settings.normal_offset * texel)[None, :, None]
        x = ((lifted * u[None]).sum(-1) - oa) / texel - 0.5
        y = ((lifted * v[None]).sum(-1) - ob) / texel - 0.5
        h = (lifted * w[None]).sum(-1)
        tan = (torch.sqrt((1.0 - cos_g * cos_g).clamp_min(0.0)) / cos_g.abs().clamp_min(0.1)).clamp_max(10.0)
        limit = h + texel[None] * (settings.bias + settings.slope_bias * tan)
        x0, y0 = torch.floor(x), torch.floor(y)
        fx, fy = x - x0, y - y0
        d_index = torch.arange(len(w), device=dirs.device)[None].expand_as(x)
        lit = torch.zeros_like(x)
        for dy, wy in ((0, 1.0 - fy), (1, fy)):
            for dx, wx in ((0, 1.0 - fx), (1, fx)):
                xi = (x0 + dx).long().clamp(0, size - 1)
                yi = (y0 + dy).long().clamp(0, size - 1)
                top = -zbuf[d_index, yi, xi]  # height of the surface nearest the light there
                lit = lit + wx * wy * (top <= limit).to(x.dtype)
        out.append(lit)
    return torch.cat(out, dim=1)


def _turned(subject: DeviceSubject, yaw_deg: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Vertices and normals turned about +z through the centre of the bounds (export.render.cli.turn_subject)."""
    if yaw_deg == 0.0:
        return subject.vertices, subject.normals
    from relight_rt.light.sh import rotation_matrix

    rot = torch.as_tensor(rotation_matrix(yaw=yaw_deg, degrees=True), dtype=torch.float32,
                          device=subject.vertices.device)
    centre = 0.5 * (subject.lo + subject.hi)
    centre = torch.stack([centre[0], centre[1], torch.zeros_like(centre[2])])
    return (subject.vertices - centre) @ rot.T + centre, subject.normals @ rot.T


def _sample_textures(subject: DeviceSubject, face: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """(M, 4) RGBA at UVs (M, 2) of the covered pixels' faces (bilinear, clamped: sample_texture's lookup)."""
    rgba = torch.zeros((len(face), 4), dtype=uv.dtype, device=uv.device)
    tex_id = subject.face_texture[face]
    for t, texture in enumerate(subject.textures):
        sel = (tex_id == t).nonzero().squeeze(1)
        if len(sel) == 0:
            continue
        grid = torch.stack([2.0 * uv[sel, 0] - 1.0, 1.0 - 2.0 * uv[sel, 1]], dim=-1).view(1, 1, -1, 2)
        got = F.grid_sample(texture[None], grid, mode="bilinear", padding_mode="border", align_corners=False)
        rgba[sel] = got[0, :, 0].T
    return rgba


SAMPLE_CHANNELS = 14  # a packed sample: albedo 3, mask 1, skin 1, transport 9 (``pack``, ``unpack``)


def pack(sample: dict[str, torch.Tensor]) -> torch.Tensor:
    """(14, R, R): a ``render_sample`` dict's maps stacked in ``SAMPLE_CHANNELS``' order (the training pool's and the
    held-out set's layout)."""
    return torch.cat([sample["albedo"], sample["mask"], sample["skin"], sample["transport"]])


def unpack(x: torch.Tensor) -> dict[str, torch.Tensor]:
    """A batch (N, 14, R, R) of packed samples as ``render_sample``'s maps (views of ``x``)."""
    return {"albedo": x[:, :3], "mask": x[:, 3:4], "skin": x[:, 4:5], "transport": x[:, 5:]}


def render_sample(
    subject: DeviceSubject,
    settings: RenderSettings,
    *,
    framing: str = "full",
    yaw_deg: float = 0.0,
    generator: torch.Generator,
) -> dict[str, torch.Tensor]:
    """Render one stage-1 sample on the subject's device.

    Returns:
        albedo (3, R, R) RGB in [0, 1], mask (1, R, R) in {0, 1}, skin (1, R, R) in [0, 1], transport (9, R, R)
        (zero off the mask), float32.
    """
    res = settings.resolution
    verts, normals = _turned(subject, yaw_deg)
    lo, hi = verts.amin(0), verts.amax(0)
    cam = fit_camera(_Box(lo.cpu().double().numpy(), hi.cpu().double().numpy()), res, margin=settings.margin,
                     framing=framing)
    cy, cz = cam.center
    half = cam.half_extent
    xy = torch.stack([((verts[:, 1] - cy) / half + 1.0) * (0.5 * res),
                      ((cz - verts[:, 2]) / half + 1.0) * (0.5 * res)], dim=-1)
    face, bary = rasterize(xy[None], (cam.eye_x - verts[:, 0])[None], subject.faces, res, res,
                           max_candidates=settings.max_candidates)
    face, bary = face[0].view(-1), bary[0].view(-1, 3)
    index = (face >= 0).nonzero().squeeze(1)
    f, b = face[index], bary[index]
    corners = subject.faces[f]  # (M, 3)
    tri = verts[corners]  # (M, 3, 3)
    position = (b[..., None] * tri).sum(1)
    shading = F.normalize((b[..., None] * normals[corners]).sum(1), dim=-1, eps=1e-20)
    geo = F.normalize(torch.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1), dim=-1, eps=1e-20)
    geo = torch.where((geo[:, :1] < 0), -geo, geo)  # two-sided: toward the camera (rays travel along −x)
    shading = torch.where(((shading * geo).sum(-1, keepdim=True) < 0), -shading, shading)
    uv = (b[..., None] * subject.face_uv[f]).sum(1)
    rgba = _sample_textures(subject, f, uv)
    skin_const = subject.face_skin[f]
    skin = torch.where(skin_const < 0, rgba[:, 3], skin_const).clamp(0.0, 1.0)
    albedo = rgba[:, :3].clamp(0.0, 1.0)

    dirs = sphere_directions(settings.dirs, generator, verts.device)
    vis = visibility(verts, subject.faces, position, geo, dirs, settings)
    y_dirs = sh_basis(dirs)  # (D, 9)
    lobe = torch.as_tensor(_LOBE, dtype=torch.float32, device=verts.device)
    cos = (shading @ dirs.T).clamp_min(0.0)  # (M, D)
    transport = lobe * sh_basis(shading) - (4.0 * math.pi / settings.dirs) * (((1.0 - vis) * cos) @ y_dirs)

    def image(values: torch.Tensor) -> torch.Tensor:
        out = torch.zeros((res * res, values.shape[1]), dtype=torch.float32, device=verts.device)
        out[index] = values.float()
        return out.T.reshape(values.shape[1], res, res)

    ones = torch.ones((len(index), 1), device=verts.device)
    return {"albedo": image(albedo), "mask": image(ones), "skin": image(skin[:, None]),
            "transport": image(transport)}
