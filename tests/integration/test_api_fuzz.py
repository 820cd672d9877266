"""Hostile input through the Python API (issue 35 items 4, 5, 18 and the must-show): every case runs in a
subprocess under a 4 GB address-space limit (tests/_hostile.py) and must end with one RelightError, below
1 GB resident, without crashing the interpreter.

- item 4: reference checkpoints that were memory bombs: a stride-0 (30000, 30000) tensor over a one-float
  storage (3.6 GB after as_strided + copy), a 2 MB deflated 2 GiB storage, a 3 MB data.pkl holding a 3 GiB
  BINBYTES8;
- item 5: a data.pkl whose dict key is a tuple nested 200,000 deep (the interpreter segfaulted hashing it);
- item 18: arrays are held to max_pixels like files (a 60000 x 60000 view raised MemoryError);
- issue 50 bug 2: many tensor records over one storage (each record is a copy).
"""

from __future__ import annotations

import struct
import zipfile

import numpy as np
import pytest
from _graphs import models_dir
from _hostile import PEAK_LIMIT, run_limited
from _torch_zip import deflated_zeros, op_global, op_str, tensor_record, write_archive, write_raw_zip, write_state_dict

__all__ = ["models_dir"]  # fixture


def _state_head() -> bytes:
    return b"\x80\x02" + op_global("collections", "OrderedDict") + b")R(" + op_str("w")


def make_checkpoints(folder) -> dict[str, str]:
    """The bombs of item 4 and 5: file name -> a word the RelightError must contain."""
    # a (30000, 30000) float tensor with strides (0, 0) over a storage of one float: 508 bytes
    body = _state_head() + tensor_record("0", "FloatStorage", 1, 0, (30000, 30000), (0, 0)) + b"u."
    write_archive(folder / "stride0.pth", body, {"0": bytes(4)})
    # a storage that declares (and really inflates to) 2 GiB of zeros: ~2 MB on disk
    n = 1 << 31
    body = _state_head() + tensor_record("0", "FloatStorage", n // 4, 0, (n // 4,), (1,)) + b"u."
    write_raw_zip(folder / "storage.pth", [("archive/data.pkl", body, 0, len(body)),
                                           ("archive/byteorder", b"little", 0, 6),
                                           ("archive/data/0", deflated_zeros(n), 8, n)])  # fmt: skip
    # data.pkl: PROTO 4, BINBYTES8 of 3 GiB (deflated: ~3 MB), STOP
    n = 3 << 30
    head = b"\x80\x04\x8e" + struct.pack("<Q", n)
    write_raw_zip(folder / "binbytes.pth", [("archive/data.pkl", deflated_zeros(n, head, b"."), 8,
                                             len(head) + n + 1)])  # fmt: skip
    # {((...(0,)...),): 1}: a dict key nested 200,000 deep (TUPLE1 200,000 times): ~400 KB
    body = b"\x80\x02}K\x00" + b"\x85" * 200_000 + b"K\x01s."
    write_archive(folder / "deep.pth", body, {})
    # the same depth through a list appended to itself level by level, and a modest but forged depth
    body = b"\x80\x02" + b"]" * 5000 + b"a" * 4999 + b"."
    write_archive(folder / "deeplist.pth", body, {})
    # issue 50 bug 2: 200 records that each view the whole of one 32 MiB storage of zeros (deflated: ~32 KB); each
    # record is copied out of its storage, so they asked for 6.4 GB
    numel, keys = 8 << 20, 200
    record = tensor_record("0", "FloatStorage", numel, 0, (numel,), (1,))
    body = b"\x80\x02" + op_global("collections", "OrderedDict") + b")R(" + b"".join(
        op_str(f"k{i}") + record for i in range(keys)) + b"u."
    with zipfile.ZipFile(folder / "views.pth", "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("archive/data.pkl", body)
        z.writestr("archive/byteorder", "little")
        z.writestr("archive/data/0", bytes(numel * 4))
    return {"stride0.pth": "only contiguous", "storage.pth": "elements", "binbytes.pth": "uncompressed",
            "deep.pth": "nests", "deeplist.pth": "nests", "views.pth": "200 tensors hold"}  # fmt: skip


_CHECKPOINT_CASES = """
import sys
from relight_rt import RelightError
from relight_rt.apps.reference_checkpoints import import_reference, read_torch_checkpoint
for name in sys.argv[1:]:
    for route, call in (("read", lambda: read_torch_checkpoint(name)),
                        ("import", lambda: import_reference("out", stage2=name, width=2, resolution=128))):
        try:
            call()
            print("NO-ERROR", name, route)
        except RelightError as exc:
            print("ERROR", name, route, str(exc).replace("\\n", " "))
"""


def test_reference_checkpoint_bombs_are_refused_before_reading(tmp_path):
    pytest.importorskip("onnx")
    expected = make_checkpoints(tmp_path)
    code = _CHECKPOINT_CASES.replace("sys.argv[1:]", repr(sorted(expected)))
    rc, out, err, peak = run_limited(code, cwd=tmp_path, cases=len(expected))
    assert rc == 0, (rc, out, err)  # -11: the interpreter crashed (item 5)
    lines = out.splitlines()
    assert len(lines) == 2 * len(expected), out
    for line in lines:
        _, name, route, message = line.split(" ", 3)
        # the importer checks the layout first, before any storage is read: a mismatch may be what it says
        layout = route == "import" and "does not match the reference" in message
        assert line.startswith("ERROR ") and name in message and (expected[name] in message or layout), line
        if layout and name == "views.pth":  # the file's 200 names: the first few, then a count
            assert "unexpected keys: k0, k1," in message and "k11 and 188 more" in message
    assert 0 < peak < PEAK_LIMIT, peak
    assert not (tmp_path / "out").exists()


def test_a_real_state_dict_still_reads(tmp_path):
    """The checks above keep what torch.save writes: nested containers a few levels deep, shared memo entries."""
    from relight_rt.apps.reference_checkpoints import read_torch_checkpoint

    state = {"a": np.arange(6, dtype=np.float32).reshape(2, 3), "b": np.zeros((), np.int64)}
    got = read_torch_checkpoint(write_state_dict(tmp_path / "ok.pth", state))
    assert list(got) == ["a", "b"] and np.array_equal(got["a"], state["a"])


_ARRAY_CASES = """
import numpy as np
from relight_rt import RelightError, Relighter, RuntimeConfig, lights
from relight_rt.light.envmap import envmap_from_light, project_envmap
from relight_rt.light.sh import render_sphere
from relight_rt.image.io import read_image, read_mask
from relight_rt.person.matting import as_rgb

huge = np.broadcast_to(np.zeros(3, np.uint8), (60000, 60000, 3))  # no memory until something converts it
flat = np.broadcast_to(np.zeros((), np.float32), (60000, 60000))
small, small_mask = np.zeros((64, 48, 3), np.float32), np.zeros((64, 48), np.float32)
small_mask[10:50, 10:30] = 1
rl = Relighter(RuntimeConfig(device="cpu"))
light = lights.preset("studio")
cases = {
    "read_image": lambda: read_image(huge),
    "read_mask": lambda: read_mask(flat, (60000, 60000)),
    "as_rgb": lambda: as_rgb(huge),
    "project_envmap": lambda: project_envmap(np.broadcast_to(np.float32(1), (30000, 60000, 3))),
    "relight": lambda: rl.relight(huge, light),
    "relight mask": lambda: rl.relight(small, light, mask=flat),
    "relight background": lambda: rl.relight(small, light, mask=small_mask, background=huge),
    "decompose": lambda: rl.decompose(huge, flat),
    "render_sphere": lambda: render_sphere(light, size=60000),
    "envmap_from_light": lambda: envmap_from_light(light, 60000),
}
for name, call in cases.items():
    try:
        call()
        print("NO ERROR", name.replace(" ", "_"))
    except RelightError as exc:
        print("ERROR", name.replace(" ", "_"), str(exc))
    except Exception as exc:
        print("WRONG", name.replace(" ", "_"), type(exc).__name__, exc)
"""


def test_arrays_are_held_to_max_pixels(tmp_path, models_dir):
    """issue 18 of round 3: a 60000 x 60000 view (no memory of its own) raised MemoryError, or took all memory,
    when converted; every entry point refuses it from its shape, as a file is refused from its header."""
    rc, out, err, peak = run_limited(_ARRAY_CASES, cwd=tmp_path, env={"RELIGHT_RT_MODELS": str(models_dir)},
                                     cases=3)  # fmt: skip
    assert rc == 0, (rc, out, err)
    lines = out.splitlines()
    assert len(lines) == 10, out
    for line in lines:
        assert line.startswith("ERROR ") and "megapixels" in line and "more than the limit" in line, line
    assert 0 < peak < PEAK_LIMIT, peak
