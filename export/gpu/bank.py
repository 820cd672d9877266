"""A compact bank of posed, textured people for rendering training samples where anny and embree are absent.

The bank is a folder::

    bank.json            format, subject names, the lights file, the shared template file
    lights.npy           (M, 9, 3) float32 RGB training lights (DESIGN.md §3)
    template.npz         faces (F, 3) int32 and uv (F, 3, 2) float32 of a mesh many parts are cut from (anny's body)
    SUBJECT.npz          one posed person: its parts and textures (no pickles: plain arrays and a JSON string)

A part of a subject is stored one of three ways: as a subset of the template's faces (a packed bit mask;
the body, and garment shells pushed out from it) whose vertices are the template's own (``full``) or only
the ones its faces use (``subset``), or as its own mesh (``mesh``: faces, uv). Vertices are uint16,
quantised over the subject's bounding box (0.03 mm on a 2 m person). Textures are PNG, RGBA: albedo
in RGB (the values of ``NAME_tex.png``, no gamma), the skin texture in A; a part with a constant skin
value keeps it in ``skin`` and ignores A. Albedo textures are shrunk to at most ``texture_size``.

:func:`write_subject` stores an :class:`export.render.scene.Subject`; :func:`read_subject` gives it back
(textures as stored), which is how the fidelity check renders the very same meshes with embree.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from relight_rt import RelightError

FORMAT = "relight_rt.gpu_bank/1"
MEMBER_MAX_BYTES = 256 << 20  # one array of a subject (a posed anny body: ~1 MB); a larger declared size is refused
TEXTURE_MAX_SIDE = 4096  # a bank texture's side (gpu-bank shrinks them to --texture-size, default 512)
LIGHTS_MAX = 1_000_000  # training lights in lights.npy
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")  # a file name inside the bank folder: no path, no hidden file
_DAMAGED = (KeyError, ValueError, TypeError, IndexError, AttributeError, EOFError, OSError, zipfile.BadZipFile)


@dataclass(frozen=True)
class PartData:
    """One part of a bank subject, decoded.

    Attributes:
        name: the part's name ("body", "shirt", ...).
        vertices: (V, 3) float32, subject frame, metres.
        faces: (F, 3) int64 into ``vertices``.
        uv: (F, 3, 2) float32 texture coordinates per corner (v up).
        texture: index into the subject's textures.
        skin: constant skin value, or −1 to read it from the texture's alpha.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    texture: int
    skin: float


@dataclass(frozen=True)
class SubjectData:
    """A bank subject: its parts and its (H, W, 4) float32 RGBA textures in [0, 1]."""

    name: str
    parts: tuple[PartData, ...]
    textures: tuple[np.ndarray, ...]


def _atomic_bytes(path: Path, write) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_template(root: Path, faces: np.ndarray, uv: np.ndarray) -> str:
    """Write the shared template (faces, uv) as ``root/template.npz``; returns its content hash."""
    faces = np.ascontiguousarray(faces, dtype=np.int32)
    uv = np.ascontiguousarray(uv, dtype=np.float32)
    digest = hashlib.sha256(faces.tobytes() + uv.tobytes()).hexdigest()[:16]
    _atomic_bytes(root / "template.npz", lambda tmp: np.savez_compressed(tmp, faces=faces, uv=uv, hash=digest))
    return digest


def read_template(root: Path) -> tuple[np.ndarray, np.ndarray] | None:
    path = Path(root) / "template.npz"
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            faces, uv = _member(z, "faces", path).astype(np.int64), _member(z, "uv", path).astype(np.float32)
    except RelightError:
        raise
    except _DAMAGED as exc:
        raise RelightError(f"bank template {path}: not readable ({type(exc).__name__}: {exc})") from None
    if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces) or faces.min() < 0 or uv.shape != (len(faces), 3, 2):
        raise RelightError(f"bank template {path}: expected (F, 3) faces and (F, 3, 2) uv, got {faces.shape}, "
                           f"{uv.shape}")
    return faces, uv


class _TemplateIndex:
    """Finds the template faces a part was cut from, by its per-corner UVs (exact float32 match)."""

    def __init__(self, faces: np.ndarray, uv: np.ndarray):
        self.faces = np.asarray(faces, np.int64)
        rows = np.ascontiguousarray(np.asarray(uv, np.float32).reshape(len(uv), 6))
        self.lookup: dict[bytes, int] = {}
        for i, r in enumerate(rows):
            self.lookup.setdefault(r.tobytes(), i)

    def match(self, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> tuple[str, np.ndarray] | None:
        """("full" | "subset", face ids) when the part is the template's faces ``ids`` (in order), else None."""
        rows = np.ascontiguousarray(np.asarray(uv, np.float32).reshape(len(uv), 6))
        ids = np.fromiter((self.lookup.get(r.tobytes(), -1) for r in rows), np.int64, len(rows))
        if len(ids) == 0 or ids.min() < 0 or np.any(np.diff(ids) <= 0):
            return None
        tf = self.faces[ids]
        faces = np.asarray(faces, np.int64)
        n_template_v = int(self.faces.max()) + 1
        if len(vertices) == n_template_v and np.array_equal(faces, tf):
            return "full", ids
        used = np.unique(tf)
        remap = np.full(n_template_v, -1, np.int64)
        remap[used] = np.arange(len(used))
        if len(vertices) == len(used) and np.array_equal(faces, remap[tf]):
            return "subset", ids
        return None


def _texture_rgba(albedo, skin, size: int) -> np.ndarray:
    """(h, w, 4) uint8: albedo RGB and skin in A, shrunk so the longer side is at most ``size``."""
    a = np.asarray(albedo, np.float32)
    if a.ndim == 1:
        a = a[:3].reshape(1, 1, 3)
    a = np.clip(a[..., :3], 0.0, 1.0)
    s = np.asarray(skin, np.float32)
    s = np.broadcast_to(s, a.shape[:2]) if s.ndim == 0 else s
    if s.shape != a.shape[:2]:
        s = cv2.resize(s, (a.shape[1], a.shape[0]), interpolation=cv2.INTER_LINEAR)
    rgba = np.concatenate([a, np.clip(s, 0.0, 1.0)[..., None]], axis=-1)
    longer = max(rgba.shape[:2])
    if longer > size:
        scale = size / longer
        shape = (max(1, round(rgba.shape[1] * scale)), max(1, round(rgba.shape[0] * scale)))
        rgba = cv2.resize(rgba, shape, interpolation=cv2.INTER_AREA)
    return np.round(rgba * 255.0).astype(np.uint8)


def _encode_png(rgba: np.ndarray) -> np.ndarray:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise RelightError("could not encode a bank texture as PNG")
    return buf.reshape(-1)


def write_subject(root: Path, subject, *, texture_size: int = 512, template: _TemplateIndex | None = None) -> Path:
    """Store a Subject (export.render.scene) as ``root/NAME.npz``, atomically. Returns the path."""
    root = Path(root)
    parts = list(subject.parts)
    if not parts:
        raise RelightError(f"subject {subject.name!r}: no parts to store")
    lo, hi = (np.asarray(b, np.float64) for b in subject.bounds())
    span = np.maximum(hi - lo, 1e-6)
    arrays: dict[str, np.ndarray] = {"lo": lo.astype(np.float64), "span": span}
    textures: dict[int, int] = {}
    tex_data: list[tuple] = []  # (albedo, skin array or None)
    vertex_ids: dict[int, int] = {}
    meta_parts = []
    for i, p in enumerate(parts):
        key = id(p.albedo)
        skin_is_texture = np.ndim(p.skin) >= 2
        if key not in textures:
            textures[key] = len(tex_data)
            tex_data.append([p.albedo, None])
        t = textures[key]
        if skin_is_texture and tex_data[t][1] is None:
            tex_data[t][1] = p.skin
        entry = {"name": p.name, "texture": t, "skin": -1.0 if skin_is_texture else float(p.skin)}
        verts = np.asarray(p.vertices, np.float64)
        match = template.match(verts, p.faces, p.uv) if template is not None else None
        if match is not None:
            mode, ids = match
            entry["mode"] = mode
            mask = np.zeros(len(template.faces), bool)
            mask[ids] = True
            arrays[f"p{i}_mask"] = np.packbits(mask)
        else:
            entry["mode"] = "mesh"
            arrays[f"p{i}_faces"] = np.asarray(p.faces, np.int32)
            arrays[f"p{i}_uv"] = np.asarray(p.uv, np.float32)
        if id(p.vertices) in vertex_ids and entry["mode"] == "full":
            entry["vertices_of"] = vertex_ids[id(p.vertices)]
        else:
            q = np.round((verts - lo) / span * 65535.0)
            arrays[f"p{i}_vertices"] = np.clip(q, 0, 65535).astype(np.uint16)
            vertex_ids[id(p.vertices)] = i
        meta_parts.append(entry)
    for j, (albedo, skin) in enumerate(tex_data):
        arrays[f"tex{j}"] = _encode_png(_texture_rgba(albedo, 0.0 if skin is None else skin, texture_size))
    meta = {"format": FORMAT, "name": subject.name, "parts": meta_parts, "textures": len(tex_data)}
    arrays["meta"] = np.array(json.dumps(meta))
    path = root / f"{subject.name}.npz"
    _atomic_bytes(path, lambda tmp: np.savez_compressed(tmp, **arrays))
    return path


def _member(z, key: str, path: Path) -> np.ndarray:
    """The array ``key`` of the npz ``z``, its declared size checked against MEMBER_MAX_BYTES before it is read."""
    name = f"{key}.npy"
    if name not in z.zip.namelist():
        raise RelightError(f"bank subject {path}: no array {key!r}")
    with z.zip.open(name) as f:
        version = np.lib.format.read_magic(f)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(f)
    if dtype.hasobject:
        raise RelightError(f"bank subject {path}: array {key!r} holds objects")
    size = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if size > MEMBER_MAX_BYTES:
        raise RelightError(f"bank subject {path}: array {key!r} declares {shape} {dtype} ({size / 2**20:.0f} MiB), "
                           f"more than {MEMBER_MAX_BYTES >> 20} MiB")
    return z[key]


def _texture(png: np.ndarray, path: Path, j: int) -> np.ndarray:
    """Decode texture ``j`` (RGBA PNG bytes), its declared size checked before decoding."""
    from relight_rt.engine.limits import _png

    data = np.asarray(png, np.uint8).tobytes() if png.dtype == np.uint8 and png.ndim == 1 else b""
    wh = _png(io.BytesIO(data))
    if wh is None or not (1 <= wh[0] <= TEXTURE_MAX_SIDE and 1 <= wh[1] <= TEXTURE_MAX_SIDE):
        raise RelightError(f"bank subject {path}: texture {j} is not an RGBA PNG of at most {TEXTURE_MAX_SIDE} px "
                           f"a side (header: {wh})")
    bgra = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if bgra is None or bgra.ndim != 3 or bgra.shape[2] != 4:
        raise RelightError(f"bank subject {path}: texture {j} is not an RGBA PNG")
    return cv2.cvtColor(bgra, cv2.COLOR_BGRA2RGBA).astype(np.float32) / 255.0


def read_subject(path: Path, template: tuple[np.ndarray, np.ndarray] | None) -> SubjectData:
    """Decode ``SUBJECT.npz``; ``template`` is :func:`read_template`'s (faces, uv), needed by template parts.

    Raises:
        RelightError: an unreadable or damaged file (a missing or malformed array, an array or texture declaring
            more than MEMBER_MAX_BYTES / TEXTURE_MAX_SIDE, faces or textures indexed out of range).
    """
    path = Path(path)
    try:
        z = np.load(path, allow_pickle=False)
    except (*_DAMAGED, RelightError) as exc:
        raise RelightError(f"bank subject {path}: not readable ({exc})") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise RelightError(f"bank subject {path}: not an .npz archive")
    try:
        with z:
            return _decode(z, path, template)
    except RelightError:
        raise
    except _DAMAGED as exc:
        raise RelightError(f"bank subject {path}: damaged ({type(exc).__name__}: {exc})") from None


def _decode(z, path: Path, template) -> SubjectData:
    meta = json.loads(str(_member(z, "meta", path)))
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise RelightError(f"bank subject {path}: format {getattr(meta, 'get', dict().get)('format')!r}, "
                           f"expected {FORMAT!r}")
    lo, span = _member(z, "lo", path), _member(z, "span", path)
    n_tex = int(meta["textures"])
    if not 0 <= n_tex <= sum(n.startswith("tex") for n in z.files):
        raise RelightError(f"bank subject {path}: {n_tex} textures declared, fewer stored")
    textures = [_texture(_member(z, f"tex{j}", path), path, j) for j in range(n_tex)]
    decoded: list[np.ndarray] = []
    parts = []
    for i, e in enumerate(meta["parts"]):
        if "vertices_of" in e:
            k = int(e["vertices_of"])
            if not 0 <= k < len(decoded):
                raise RelightError(f"bank subject {path}: part {i} takes the vertices of part {k}")
            verts = decoded[k]
        else:
            q = _member(z, f"p{i}_vertices", path)
            if q.ndim != 2 or q.shape[1] != 3:
                raise RelightError(f"bank subject {path}: part {i}'s vertices are {q.shape}, expected (V, 3)")
            verts = (q.astype(np.float64) / 65535.0 * span + lo).astype(np.float32)
        decoded.append(verts)
        if e["mode"] == "mesh":
            faces = _member(z, f"p{i}_faces", path).astype(np.int64)
            uv = _member(z, f"p{i}_uv", path).astype(np.float32)
        else:
            if template is None:
                raise RelightError(f"bank subject {path}: part {e['name']!r} needs the bank's template.npz")
            t_faces, t_uv = template
            ids = np.flatnonzero(np.unpackbits(_member(z, f"p{i}_mask", path), count=len(t_faces)))
            faces, uv = t_faces[ids], t_uv[ids]
            if e["mode"] == "subset":
                used = np.unique(faces)
                remap = np.full(int(t_faces.max()) + 1, -1, np.int64)
                remap[used] = np.arange(len(used))
                faces = remap[faces]
        tex = int(e["texture"])
        ok = faces.ndim == 2 and faces.shape[1] == 3 and uv.shape == (len(faces), 3, 2) and len(faces) > 0
        if not ok or faces.min() < 0 or faces.max() >= len(verts) or not 0 <= tex < len(textures):
            raise RelightError(f"bank subject {path}: part {i} indexes outside its vertices or textures "
                               f"(faces {faces.shape}, uv {uv.shape}, {len(verts)} vertices, texture {tex} of "
                               f"{len(textures)})")
        if not (np.isfinite(verts).all() and np.isfinite(uv).all()):
            raise RelightError(f"bank subject {path}: part {i} holds NaN or Inf")
        parts.append(PartData(str(e["name"]), verts, faces, uv, tex, float(e["skin"])))
    return SubjectData(str(meta["name"]), tuple(parts), tuple(textures))


def to_subject(data: SubjectData):
    """The bank subject as an export.render.scene.Subject (for the embree renderer)."""
    from export.render.scene import Part, Subject

    parts = []
    for p in data.parts:
        tex = data.textures[p.texture]
        skin = tex[..., 3].copy() if p.skin < 0 else p.skin
        parts.append(Part(p.name, p.vertices, p.faces.astype(np.int32), p.uv, tex[..., :3].copy(), skin))
    return Subject(parts, data.name)


def write_index(root: Path, lights_file: str = "lights.npy") -> dict:
    """(Re)write ``root/bank.json`` from the subject files present; returns it."""
    root = Path(root)
    names = sorted(p.stem for p in root.glob("*.npz") if p.stem != "template")
    sizes = {n: (root / f"{n}.npz").stat().st_size for n in names}
    total = sum(f.stat().st_size for f in root.iterdir() if f.is_file())
    index = {"format": FORMAT, "lights": lights_file, "subjects": names, "bytes": total,
             "mean_subject_bytes": int(np.mean(list(sizes.values()))) if sizes else 0}
    text = json.dumps(index, indent=1)
    _atomic_bytes(root / "bank.json", lambda tmp: Path(tmp).write_text(text))
    return index


def read_index(root: Path) -> dict:
    """``root/bank.json``, checked: its subjects and lights file are plain names of files inside ``root``."""
    path = Path(root) / "bank.json"
    try:
        index = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise RelightError(
            f"--bank {root}: no readable bank.json ({exc}); build one with python -m export gpu-bank"
        ) from None
    if not isinstance(index, dict):
        raise RelightError(f"--bank {root}: bank.json is not a JSON object; build one with python -m export gpu-bank")
    subjects = index.get("subjects")
    if index.get("format") != FORMAT or not isinstance(subjects, list) or not subjects:
        raise RelightError(f"--bank {root}: bank.json of format {index.get('format')!r} with "
                           f"{len(subjects) if isinstance(subjects, list) else 'no list of'} subjects; expected "
                           f"{FORMAT!r} and at least one")
    names = [*subjects, index.get("lights")]
    bad = [n for n in names if not (isinstance(n, str) and _NAME.fullmatch(n))]
    if bad:
        raise RelightError(f"--bank {root}: bank.json names {bad[0]!r}: expected the names of files inside the bank "
                           "folder (no paths)")
    return index


def read_lights(root: Path, index: dict) -> np.ndarray:
    path = Path(root) / index["lights"]
    try:
        mapped = np.load(path, allow_pickle=False, mmap_mode="r")  # the shape, before anything is read
        if not isinstance(mapped, np.ndarray) or mapped.ndim != 3 or mapped.shape[1:] != (9, 3):
            raise ValueError(f"expected (M, 9, 3) lights, got {getattr(mapped, 'shape', type(mapped).__name__)}")
        if len(mapped) > LIGHTS_MAX:
            raise ValueError(f"{len(mapped)} lights, more than {LIGHTS_MAX}")
        lights = np.array(mapped, dtype=np.float32)
    except _DAMAGED as exc:
        raise RelightError(f"bank lights {path}: not readable ({exc})") from None
    if lights.ndim != 3 or lights.shape[1:] != (9, 3) or not len(lights) or not np.isfinite(lights).all():
        raise RelightError(f"bank lights {path}: expected (M, 9, 3) finite RGB lights, got {lights.shape}")
    return lights
