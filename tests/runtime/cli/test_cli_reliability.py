"""Issue 18 against the CLI's image commands: inputs never overwritten (also through folders, symlinks and hard
links), one line and a non-zero exit for every OSError and malformed file, interrupted runs, clear messages."""

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import (
    OWN_LIGHT,
    make_models_dir,
    meta_for,
    models_dir,
    person,
    save,
    stage1_model,
    stage2_model,
    write_person,
)

from relight_rt import cli

__all__ = ["models_dir"]  # fixture

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    np.save(tmp_path / "light.npy", OWN_LIGHT.astype(np.float64))
    (tmp_path / "img").mkdir()
    (tmp_path / "masks").mkdir()
    for i, name in enumerate("ab"):
        write_person(tmp_path / "img", name, i, mask_folder=tmp_path / "masks")
    return tmp_path


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (hidden ones included) with its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def one_error(code: int, err: str, match: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("relight-rt: error: "), err
    assert match in lines[0], lines[0]
    return lines[0]


# ------------------------------------------------------------------------------------------- 1: inputs


def test_masks_in_a_mask_folder_are_inputs(work, capsys):
    before = snapshot(work)
    code, _, err = run(["relight", "img/a.png", "--mask", "masks/", "--preset", "studio", "-o", "masks/a_mask.png"],
                       capsys)
    one_error(code, err, "refusing to overwrite the input")
    (work / "link.png").symlink_to(work / "masks" / "a_mask.png")
    os.link(work / "masks" / "b_mask.png", work / "hard.png")
    (work / "imgs").symlink_to(work / "img", target_is_directory=True)
    for target in ("link.png", "hard.png", "imgs/a.png", "masks/../masks/a_mask.png"):
        code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "-o", target], capsys)
        one_error(code, err, "refusing to overwrite the input")
    # the mask of a --light-from photo is read too
    write_person(work, "donor", 5)
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--light-from", "donor.png", "-o", "donor_mask.png"],
                       capsys)
    one_error(code, err, "refusing to overwrite the input")
    after = snapshot(work)
    assert {k: v for k, v in after.items() if k in before} == before


def test_lights_show_protects_its_light_file(work, capsys):
    (work / "alias.png").symlink_to(work / "light.npy")
    code, _, err = run(["lights", "show", "light.npy", "-o", "alias.png"], capsys)
    one_error(code, err, "refusing to overwrite the input")
    np.testing.assert_array_equal(np.load(work / "light.npy"), OWN_LIGHT)
    cv2.imwrite("env.hdr", np.ones((8, 16, 3), np.float32))
    (work / "env.json").symlink_to(work / "env.hdr")
    code, _, err = run(["lights", "from-envmap", "env.hdr", "-o", "env.json"], capsys)
    one_error(code, err, "refusing to overwrite the input")


# ------------------------------------------------------------------------------------------- 4: OSError, files


def test_output_under_a_file(work, capsys):
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "-o", "img/a.png/x.png"],
                       capsys)
    one_error(code, err, "is not a folder")
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "-o", "img/a.png/sub"], capsys)
    one_error(code, err, "Not a directory")
    code, _, err = run(["decompose", "img/a.png", "--mask", "masks/a_mask.png", "-o", "light.npy/dec"], capsys)
    one_error(code, err, "light.npy")
    code, _, err = run(["lights", "show", "studio", "-o", "light.npy/s.png"], capsys)
    one_error(code, err, "is not a folder")


def _deny_writes(monkeypatch, folder: Path):
    """Make ``folder`` read-only for this process (chmod does not stop root, so the calls are refused here)."""
    import tempfile

    real_mkstemp, real_mkdir = tempfile.mkstemp, Path.mkdir

    def mkstemp(*a, dir=None, **k):
        if dir is not None and Path(dir).resolve().is_relative_to(folder.resolve()):
            raise PermissionError(13, "Permission denied", str(dir))
        return real_mkstemp(*a, dir=dir, **k)

    def mkdir(self, *a, **k):
        if self.resolve().is_relative_to(folder.resolve()) and not self.exists():
            raise PermissionError(13, "Permission denied", str(self))
        return real_mkdir(self, *a, **k)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    monkeypatch.setattr(Path, "mkdir", mkdir)


@pytest.mark.parametrize(
    "argv",
    [["decompose", "img/a.png", "--mask", "masks/a_mask.png", "-o", "ro"],
     ["lights", "show", "studio", "-o", "ro/s.png"],
     ["lights", "from-photo", "img/a.png", "--mask", "masks/a_mask.png", "-o", "ro/l.npy"],
     ["lights", "from-envmap", "env.hdr", "-o", "ro/l.json"],
     ["relight", "img", "--mask", "masks", "--preset", "studio", "-o", "ro/new"],
     ["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "-o", "ro/a.png"],
     ["video", "img", "--masks", "masks", "--preset", "studio", "--frames-out", "ro/frames"],
     ["video", "img", "--masks", "masks", "--preset", "studio", "-o", "ro/o.mp4"],
     ["video", "img", "--masks", "masks", "--preset", "studio", "-o", "ro/new/o.avi"]],
)  # fmt: skip
def test_read_only_output_folder(work, capsys, monkeypatch, argv):
    cv2.imwrite("env.hdr", np.ones((8, 16, 3), np.float32))
    (work / "ro").mkdir()
    _deny_writes(monkeypatch, work / "ro")
    code, _, err = run(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert lines and all(x.startswith("relight-rt: ") for x in lines) and "Traceback" not in err
    assert "Permission denied" in err
    assert list((work / "ro").iterdir()) == []


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root ignores folder permissions")
def test_read_only_output_folder_for_real(work, capsys):
    (work / "ro").mkdir()
    os.chmod(work / "ro", 0o555)
    try:
        code, _, err = run(["decompose", "img/a.png", "--mask", "masks/a_mask.png", "-o", "ro"], capsys)
        one_error(code, err, "Permission denied")
    finally:
        os.chmod(work / "ro", 0o755)


def test_malformed_light_files(work, capsys):
    (work / "deep.json").write_text('{"sh": ' + "[" * 100_000 + "]" * 100_000 + "}")
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (1 << 21, 1 << 20, 1 << 20)  # 19 TiB claimed
    with open(work / "huge.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
    np.savez(work / "z.npz", sh=OWN_LIGHT)
    (work / "z.npz").rename(work / "npz.npy")
    (work / "zero.npy").write_bytes(b"")
    np.save(work / "big.npy", np.full((9, 3), 1e300))
    np.save(work / "b4.npy", np.full((9, 3), 4e38))
    cases = {"deep.json": "nested too deeply", "huge.npy": "announces", "npz.npy": ".npz", "zero.npy": "empty",
             "big.npy": "too large", "b4.npy": "too large"}
    for name, match in cases.items():
        code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--light", name, "-o", "o.png"], capsys)
        one_error(code, err, match)
        assert "NaN" not in err
    assert not (work / "o.png").exists()


def test_max_pixels(work, capsys):
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "--max-pixels", "10000",
                        "-o", "o.png"], capsys)  # fmt: skip
    one_error(code, err, "100x150 (0.0 megapixels), more than the limit of 0.01 megapixels")
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "--max-pixels", "15000",
                        "-o", "o.png"], capsys)  # fmt: skip
    assert code == 0, err
    bomb = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + (200_000).to_bytes(4, "big") * 2 + b"\x08\x02\x00\x00\x00"
    (work / "bomb.png").write_bytes(bomb + bytes(100))
    code, _, err = run(["relight", "bomb.png", "--preset", "studio", "-o", "o2.png"], capsys)
    one_error(code, err, "more than the limit of 100 megapixels")


def test_memory_error_is_one_line(work, capsys, monkeypatch):
    from relight_rt.relight.relighter import Relighter

    def boom(*args, **kwargs):
        raise MemoryError()

    monkeypatch.setattr(Relighter, "decompose", boom)
    code, _, err = run(["decompose", "img/a.png", "--mask", "masks/a_mask.png", "-o", "d"], capsys)
    one_error(code, err, "out of memory")


# ------------------------------------------------------------------------------------------- 5: non-finite


def test_nan_network_output_is_an_error_naming_the_model(work, capsys, tmp_path_factory):
    folder = tmp_path_factory.mktemp("nan_models")
    save(stage1_model(64), folder / "stage1.onnx")
    save(stage2_model(gain=float("nan")), folder / "stage2.onnx")
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "--models", folder,
                        "-o", "o.png"], capsys)  # fmt: skip
    line = one_error(code, err, "stage2.onnx")
    assert "NaN or Inf" in line
    assert not (work / "o.png").exists()


# ------------------------------------------------------------------------------------------- 6: interruption


def test_folder_listing_ignores_own_temp_and_output_files(work, capsys):
    (work / "img" / ".a_relit.png.k3j2.tmp.png").write_bytes(b"left by SIGKILL")
    code, _, err = run(["relight", "img", "--mask", "masks", "--preset", "studio", "-o", "img"], capsys)
    assert code == 0, err
    assert sorted(p.name for p in (work / "img").iterdir() if not p.name.startswith(".")) == [
        "a.png", "a_relit.png", "b.png", "b_relit.png"]
    code, _, err = run(["relight", "img", "--mask", "masks", "--preset", "studio", "-o", "img"], capsys)
    assert code == 0, err  # the outputs are not taken as new inputs (no a_relit_relit.png)
    assert not list((work / "img").glob("*_relit_relit*"))


def test_skip_existing_resumes_a_batch(work, capsys):
    (work / "out").mkdir()
    (work / "out" / "a_relit.png").write_bytes(b"kept")
    code, _, err = run(["relight", "img", "--mask", "masks", "--preset", "studio", "-o", "out", "--skip-existing"],
                       capsys)
    assert code == 0, err
    assert (work / "out" / "a_relit.png").read_bytes() == b"kept"
    assert cv2.imread(str(work / "out" / "b_relit.png")).shape == (150, 100, 3)


_DRIVER = """
import os, signal, sys
import relight_rt.image.io as io
from relight_rt import cli
# a run started in the background without job control inherits SIGINT ignored (and Python then installs no
# KeyboardInterrupt handler); this driver stands for a user at a terminal, so it restores Python's default
signal.signal(signal.SIGINT, signal.default_int_handler)
real = io.os.chmod
def chmod(path, mode):  # inside atomic_path, with the temporary file on disk: the signal arrives now
    os.kill(os.getpid(), getattr(signal, sys.argv[1]))
    return real(path, mode)
io.os.chmod = chmod
sys.exit(cli.main(sys.argv[2:]))
"""


@pytest.mark.parametrize(("sig", "code", "text"), [("SIGTERM", 143, "terminated"), ("SIGINT", 130, "interrupted")])
def test_signal_while_writing_removes_the_temp_file(work, sig, code, text):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    argv = [sys.executable, "-c", _DRIVER, sig, "relight", "img", "--mask", "masks", "--preset", "studio", "-o", "out"]
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == code, proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.strip() and "image/s" not in x]  # not the progress bar
    assert len(lines) == 1 and lines[0].startswith(f"relight-rt: {text}"), proc.stderr
    assert list((work / "out").iterdir()) == []  # no partial file, no temporary file


_STARTUP_DRIVER = """
import os, runpy, signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # as at a terminal (see _DRIVER)


class SignalOnImport:  # the signal arrives while the runtime loads (numpy, OpenCV, onnxruntime: ~0.3 s)
    fired = False

    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and not SignalOnImport.fired:
            SignalOnImport.fired = True
            os.kill(os.getpid(), getattr(signal, sig))
        return None


sys.meta_path.insert(0, SignalOnImport())
sig = sys.argv[1]
sys.argv = ["relight-rt", "lights", "list"]
if os.environ["ENTRY"] == "module":  # python -m relight_rt
    runpy.run_module("relight_rt", run_name="__main__", alter_sys=True)
else:  # the console script: pyproject's [project.scripts] entry point
    import importlib, tomllib
    target = tomllib.load(open(os.environ["PYPROJECT"], "rb"))["project"]["scripts"]["relight-rt"]
    module, func = target.split(":")
    sys.exit(getattr(importlib.import_module(module), func)())
"""


@pytest.mark.parametrize("entry", ["module", "script"])
@pytest.mark.parametrize(("sig", "code", "text"), [("SIGTERM", 143, "terminated"), ("SIGINT", 130, "interrupted")])
def test_signal_while_starting_is_one_line(entry, sig, code, text):
    """issue 35 item 16: Ctrl-C while the runtime was still being imported printed a KeyboardInterrupt traceback,
    and SIGTERM then ended the process without a word: now one line and 130 / 143, from the first instant."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "ENTRY": entry, "PYPROJECT": str(REPO / "pyproject.toml")}
    proc = subprocess.run([sys.executable, "-c", _STARTUP_DRIVER, sig], capture_output=True, text=True, env=env,
                          timeout=60)  # fmt: skip
    assert proc.returncode == code and proc.stdout == "", (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"relight-rt: {text}"), proc.stderr


# ------------------------------------------------------------------------------------------- 7: messages


def test_messages(work, capsys, tmp_path_factory):
    write_person(work, "nomask", 2)
    (work / "nomask_mask.png").unlink()
    code, _, err = run(["relight", "nomask.png", "--preset", "studio", "-o", "o.png"], capsys)
    line = one_error(code, err, "--mask")
    assert "mask=PATH" not in line
    empty = tmp_path_factory.mktemp("empty_models")
    code, out, _ = cli.main(["doctor", "--models", str(empty)]), *capsys.readouterr()
    assert code == 1 and "problem: no relight_rt models found" in out and not out.rstrip().endswith("ok")
    wrong = tmp_path_factory.mktemp("wrong_kind")
    save(stage1_model(64, meta=meta_for("stage2", 0)), wrong / "stage1.onnx")
    code, _, err = run(["relight", "img/a.png", "--mask", "masks", "--preset", "studio", "--models", wrong,
                        "-o", "o.png"], capsys)  # fmt: skip
    one_error(code, err, "metadata relight_rt.kind is 'stage2', expected 'stage1'")
    code, out, _ = cli.main(["doctor", "--models", str(wrong)]), *capsys.readouterr()
    assert code == 1 and "expected 'stage1'" in out


def test_native_library_warnings_stay_off_stderr(work):
    """libpng's own 'libpng error: IDAT: CRC error' and OpenCV's [WARN] lines (run as a real process)."""
    import struct

    ok, buf = cv2.imencode(".png", (person()[0] * 255).astype(np.uint8))
    data = bytearray(buf.tobytes())
    i = data.find(b"IDAT")
    data[i + 4 + struct.unpack(">I", data[i - 4 : i])[0]] ^= 0xFF  # break the CRC
    (work / "img" / "a.png").write_bytes(bytes(data))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-m", "relight_rt", "relight", "img", "--mask", "masks", "--preset",
                           "studio", "-o", "out"], capture_output=True, text=True, env=env, timeout=120)  # fmt: skip
    assert proc.returncode == 2
    lines = [x for x in proc.stderr.splitlines() if x.strip() and "image/s" not in x]  # not the progress bar
    assert len(lines) == 2 and "cannot decode" in lines[0] and "1 failed, 1 written" in lines[1], proc.stderr
    proc = subprocess.run([sys.executable, "-m", "relight_rt", "-v", "relight", "img/a.png", "--mask", "masks",
                           "--preset", "studio", "-o", "o.png"], capture_output=True, text=True, env=env, timeout=120)
    assert "libpng" in proc.stderr  # -v shows them


def test_onnxruntime_warnings_stay_off_stderr(work, tmp_path_factory):
    from onnx import numpy_helper

    folder = tmp_path_factory.mktemp("warn_models")
    model = stage1_model(64)
    model.graph.initializer.append(numpy_helper.from_array(np.zeros(3, np.float32), "unused"))  # ort warns
    save(model, folder / "stage1.onnx")
    # no graph cache: the second run would load the optimised graph, which has no unused initializer to warn about
    env = {**os.environ, "PYTHONPATH": str(REPO), "RELIGHT_RT_CACHE": "off"}
    argv = [sys.executable, "-m", "relight_rt", "relight", "img/a.png", "--mask", "masks", "--preset", "studio",
            "--models", str(folder), "-o", "o.png"]  # fmt: skip
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0 and "onnxruntime" not in proc.stderr, proc.stderr
    proc = subprocess.run([*argv[:3], "-v", *argv[3:-1], "o2.png"], capture_output=True, text=True, env=env,
                          timeout=120)  # fmt: skip
    assert "Removing initializer 'unused'" in proc.stderr  # it is there to be silenced


def test_models_are_protected(work, capsys, tmp_path_factory):
    folder = make_models_dir(tmp_path_factory.mktemp("m"), 64, stage2=False)
    before = (folder / "stage1.onnx").read_bytes()
    code, _, err = run(["lights", "from-photo", "img/a.png", "--mask", "masks/a_mask.png", "--models", folder,
                        "-o", folder / "stage1.json"], capsys)  # fmt: skip
    assert code == 0, err  # another name: fine
    json.loads((folder / "stage1.json").read_text())
    (work / "alias.npy").symlink_to(folder / "stage1.onnx")
    code, _, err = run(["lights", "from-photo", "img/a.png", "--mask", "masks/a_mask.png", "--models", folder,
                        "-o", "alias.npy"], capsys)  # fmt: skip
    one_error(code, err, "refusing to overwrite the input")
    assert (folder / "stage1.onnx").read_bytes() == before


def test_protected_paths_follow_links_and_inodes(tmp_path):
    from relight_rt.engine.files import ProtectedPaths, check_target

    (tmp_path / "a.png").write_bytes(b"a")
    (tmp_path / "sym.png").symlink_to(tmp_path / "a.png")
    os.link(tmp_path / "a.png", tmp_path / "hard.png")
    protect = ProtectedPaths([tmp_path / "a.png", tmp_path / "not_yet.png"])
    for alias in ("a.png", "sym.png", "hard.png", "./a.png", "x/../a.png", "not_yet.png"):
        assert protect.find(tmp_path / alias) is not None, alias
        with pytest.raises(Exception, match="refusing to overwrite the input"):
            check_target(tmp_path / alias, protect)
    assert protect.find(tmp_path / "b.png") is None and len(protect) == 2
    check_target(tmp_path / "b.png", [tmp_path / "a.png"])  # plain iterables work too
