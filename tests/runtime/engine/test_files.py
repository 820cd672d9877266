"""relight_rt.engine.files: every file written atomically (a temporary file beside it, then a rename), with the
usual permissions, never over an input; several files as one (write_all: all of them or none)."""

import os

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.engine.files import atomic_path, npy_writer, npz_writer, write_all, write_npy, write_npz
from relight_rt.image.io import image_writer, write_image


def test_write_npy_npz(tmp_path):
    a = np.arange(27, dtype=np.float32).reshape(9, 3)
    np.testing.assert_array_equal(np.load(write_npy(tmp_path / "l.npy", a), allow_pickle=False), a)
    with np.load(write_npz(tmp_path / "t.npz", {"T": a}), allow_pickle=False) as z:
        np.testing.assert_array_equal(z["T"], a)


def test_write_all_takes_the_writers_of_the_single_files(tmp_path):
    """decompose writes its five files through write_all with the writers write_image / write_npy / write_npz use,
    so the files written as one are the very bytes of the files written one by one."""
    a = np.arange(27, dtype=np.float32).reshape(9, 3)
    img = np.linspace(0, 1, 4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3)
    one = [write_image(tmp_path / "1.png", img), write_npy(tmp_path / "1.npy", a),
           write_npz(tmp_path / "1.npz", {"T": a})]
    both = write_all([(tmp_path / "2.png", image_writer(img, tmp_path / "2.png")), (tmp_path / "2.npy", npy_writer(a)),
                      (tmp_path / "2.npz", npz_writer({"T": a}))])
    for p1, p2 in zip(one, both, strict=True):
        if p1.suffix == ".npz":  # a zip stamps its members with the time: compare the arrays
            with np.load(p1) as z1, np.load(p2) as z2:
                assert z1.files == z2.files and z1["T"].tobytes() == z2["T"].tobytes()
        else:
            assert p1.read_bytes() == p2.read_bytes()
    with pytest.raises(RelightError, match="cannot hold transparency"):
        image_writer(np.zeros((2, 2, 4)), tmp_path / "x.jpg")  # encoded when the writer is made, before any file


def test_atomic_path_gives_usual_permissions_and_cleans_up(tmp_path):
    import stat


    target = tmp_path / "out.bin"
    with atomic_path(target) as tmp:
        assert tmp.suffix == ".bin" and tmp.parent == tmp_path
        tmp.write_bytes(b"abc")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "broken.bin") as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("writer failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
