"""Triangle rasterisation in plain PyTorch: a z-buffer over many views of one mesh at once (CPU or CUDA).

Pixel (i, j) of an H×W view has its centre at continuous coordinates (x, y) = (j + ½, i + ½): x runs
along a row, y down the rows. A triangle covers the pixel centres inside it (edges included: a centre on
a shared edge goes to both triangles and the depth test picks one). No anti-aliasing: one sample per
pixel centre, as the embree renderer casts one ray per pixel centre.

Triangles are binned by the size of their pixel bounding box (1, 2, 4, 8, ... pixels on the longer
side); each bin enumerates the k×k pixel centres of its triangles' boxes, tests them with edge
functions and keeps the nearest with ``scatter_reduce``. Every triangle costs at most 4× its box, and
memory is bounded by ``max_candidates`` per chunk.
"""

from __future__ import annotations

import torch

_EMPTY_KEY = torch.iinfo(torch.int64).max
_DEPTH_STEPS = float(1 << 30)


def _triangles(xy: torch.Tensor, faces: torch.Tensor, height: int, width: int):
    """Per (view, face): corner coordinates, the first and last covered pixel column/row, and a keep flag."""
    tri = xy[:, faces]  # (B, F, 3, 2)
    c0, c1, c2 = tri.unbind(2)
    lo = torch.ceil(torch.minimum(torch.minimum(c0, c1), c2) - 0.5)
    hi = torch.floor(torch.maximum(torch.maximum(c0, c1), c2) - 0.5)
    limit = torch.tensor([width - 1, height - 1], device=xy.device, dtype=xy.dtype)
    lo = lo.clamp_min(0.0)
    hi = torch.minimum(hi, limit)
    ext = hi - lo + 1.0
    e1, e2 = c1 - c0, c2 - c0
    area = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    finite = torch.isfinite(xy).all(dim=-1)[:, faces].all(dim=-1)
    keep = (ext[..., 0] > 0) & (ext[..., 1] > 0) & (area.abs() > 1e-12) & finite
    return tri, lo.long(), ext.long(), keep


def _candidates(tri, lo, ext, keep, max_candidates: int):
    """Yield (view, face, px, py, bary) chunks: pixel centres inside a triangle, with its barycentrics."""
    size = ext.amax(dim=-1)
    k = 1
    largest = int(size[keep].max()) if bool(keep.any()) else 0
    while k // 2 < largest:
        in_bin = keep & (size <= k) & (size > k // 2)
        idx = in_bin.nonzero()
        if len(idx):
            offsets = torch.arange(k * k, device=tri.device)
            dx, dy = offsets % k, offsets // k
            per = max(1, max_candidates // (k * k))
            for s in range(0, len(idx), per):
                b, f = idx[s : s + per].unbind(1)
                x0, y0 = lo[b, f].unbind(-1)
                w, h = ext[b, f].unbind(-1)
                px = x0[:, None] + dx[None]
                py = y0[:, None] + dy[None]
                inbox = (dx[None] < w[:, None]) & (dy[None] < h[:, None])
                t = tri[b, f]  # (n, 3, 2)
                cx = px.to(t.dtype) + 0.5
                cy = py.to(t.dtype) + 0.5
                bary = _barycentric(t, cx, cy)
                inside = inbox & (bary >= -1e-6).all(dim=-1)
                n_i, c_i = inside.nonzero().unbind(1)
                yield b[n_i], f[n_i], px[n_i, c_i], py[n_i, c_i], bary[n_i, c_i]
        k *= 2


def _barycentric(t: torch.Tensor, cx: torch.Tensor, cy: torch.Tensor) -> torch.Tensor:
    """Barycentric weights (n, c, 3) of points (cx, cy) (n, c) in triangles t (n, 3, 2)."""
    x0, y0 = t[:, 0, 0, None], t[:, 0, 1, None]
    x1, y1 = t[:, 1, 0, None], t[:, 1, 1, None]
    x2, y2 = t[:, 2, 0, None], t[:, 2, 1, None]
    area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    w0 = ((x1 - cx) * (y2 - cy) - (y1 - cy) * (x2 - cx)) / area
    w1 = ((x2 - cx) * (y0 - cy) - (y2 - cy) * (x0 - cx)) / area
    return torch.stack([w0, w1, 1.0 - w0 - w1], dim=-1)


def rasterize(
    xy: torch.Tensor,
    depth: torch.Tensor,
    faces: torch.Tensor,
    height: int,
    width: int,
    *,
    max_candidates: int = 1 << 22,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The nearest triangle at every pixel centre of B views of one mesh.

    Args:
        xy: (B, V, 2) float vertex positions in each view, pixel units (x along rows, y down).
        depth: (B, V) float distance from the viewer (smaller is nearer).
        faces: (F, 3) int64 vertex indices.
        height, width: view size in pixels.
        max_candidates: pixel tests per chunk (bounds memory: about 100 bytes each).

    Returns:
        face: (B, H, W) int64 index of the visible triangle, −1 where none covers the pixel centre.
        bary: (B, H, W, 3) float barycentric weights of its corners at the pixel centre (zeros where empty).
    """
    n_views = xy.shape[0]
    tri, lo, ext, keep = _triangles(xy, faces, height, width)
    dmin = depth.amin(dim=1, keepdim=True)
    span = (depth.amax(dim=1, keepdim=True) - dmin).clamp_min(1e-12)
    dnorm = (depth - dmin) / span  # 0..1 per view, for an integer depth key
    tri_d = dnorm[:, faces]  # (B, F, 3)
    keys = torch.full((n_views * height * width,), _EMPTY_KEY, dtype=torch.int64, device=xy.device)
    for b, f, px, py, bary in _candidates(tri, lo, ext, keep, max_candidates):
        z = (bary * tri_d[b, f]).sum(dim=-1).clamp(0.0, 1.0)
        key = (z * _DEPTH_STEPS).long() * (1 << 32) + f
        keys.scatter_reduce_(0, (b * height + py) * width + px, key, reduce="amin")
    keys = keys.view(n_views, height, width)
    hit = keys != _EMPTY_KEY
    face = torch.where(hit, keys % (1 << 32), torch.full_like(keys, -1))
    bary = torch.zeros((n_views, height, width, 3), dtype=xy.dtype, device=xy.device)
    vb, vi, vj = hit.nonzero().unbind(1)
    if len(vb):
        t = tri[vb, face[vb, vi, vj]]
        bary[vb, vi, vj] = _barycentric(t, vj[:, None].to(xy.dtype) + 0.5, vi[:, None].to(xy.dtype) + 0.5)[:, 0]
    return face, bary


def depth_map(
    xy: torch.Tensor,
    depth: torch.Tensor,
    faces: torch.Tensor,
    size: int,
    *,
    max_candidates: int = 1 << 22,
) -> torch.Tensor:
    """The nearest depth at every pixel centre of B square views (a shadow map per view).

    Args:
        xy: (B, V, 2) vertex positions, pixel units; depth: (B, V) (smaller is nearer); faces: (F, 3) int64.
        size: side of the square views.

    Returns:
        (B, size, size) float depth of the nearest surface, +inf where nothing covers the pixel centre.
    """
    n_views = xy.shape[0]
    tri, lo, ext, keep = _triangles(xy, faces, size, size)
    tri_d = depth[:, faces]
    buf = torch.full((n_views * size * size,), float("inf"), dtype=depth.dtype, device=xy.device)
    for b, f, px, py, bary in _candidates(tri, lo, ext, keep, max_candidates):
        z = (bary * tri_d[b, f]).sum(dim=-1)
        buf.scatter_reduce_(0, (b * size + py) * size + px, z, reduce="amin")
    return buf.view(n_views, size, size)
