"""Tests for relight_rt.apps.reference_checkpoints: the torch-free reader and importer of the authors' checkpoints.

Most of it runs without torch: checkpoints are written by hand in torch's zip format (tests/_torch_zip.py)
and the graphs are checked against an independent numpy forward pass (tests/_reference_forward.py).
Where torch is installed, torch.save'd files, torch.load and ``python -m export convert-reference`` are
compared too.
"""

from __future__ import annotations

import json
import os
import pickle
import sys
import zipfile

import numpy as np
import onnxruntime as ort
import pytest
from _reference_forward import contract_outputs, random_reference_weights, relative_error
from _torch_zip import op_global, op_str, op_tuple, tensor_record, write_archive, write_state_dict

from relight_rt import RelightError
from relight_rt.apps.reference_checkpoints import bgr_to_rgb, import_reference, read_torch_checkpoint, reference_layout
from relight_rt.cli import main as cli_main

WIDTH, RES = 2, 128
KINDS = ("stage1", "stage2", "dvp")
try:
    import onnx  # noqa: F401

    HAS_ONNX = True
except ImportError:
    HAS_ONNX = False
# the reader needs numpy only; building graphs needs the importer's extra
needs_onnx = pytest.mark.skipif(not HAS_ONNX, reason='needs onnx: pip install "relight-rt[import]"')


def _session(path):
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])


def _feeds(kind: str, n: int, h: int, w: int, seed: int) -> dict[str, np.ndarray]:
    """Contract inputs: images in [0, 1], a soft elliptic mask with exact zeros and ones, lights for the DVP."""
    rng = np.random.default_rng(seed)
    yy, xx = np.meshgrid(np.linspace(-1, 1, h), np.linspace(-1, 1, w), indexing="ij")
    mask = np.clip((1 - (xx / 0.7) ** 2 - (yy / 0.9) ** 2) * 8, 0, 1).astype(np.float32)
    first = {"stage1": "image", "stage2": "diffuse", "dvp": "frame"}[kind]
    feeds = {first: rng.random((n, 3, h, w), dtype=np.float32), "mask": np.repeat(mask[None, None], n, 0)}
    if kind == "dvp":
        light = rng.uniform(-0.5, 0.5, (n, 9, 3)).astype(np.float32)
        light[:, 0] = rng.uniform(0.4, 1.4, (n, 3))
        feeds["light"] = light
    return feeds


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory):
    """Hand-written (torch-free) reference checkpoints with random BGR weights, small sizes."""
    root = tmp_path_factory.mktemp("ckpt")
    out = {}
    for i, kind in enumerate(KINDS):
        sd = random_reference_weights(reference_layout(kind, WIDTH, RES), seed=10 + i)
        out[kind] = (write_state_dict(root / f"{kind}.pth", sd), sd)
    return out


@pytest.fixture(scope="module")
def imported(checkpoints, tmp_path_factory):
    folder = tmp_path_factory.mktemp("imported")
    paths = {k: p for k, (p, _) in checkpoints.items()}
    summaries = import_reference(folder, **paths, width=WIDTH, resolution=RES)
    return folder, summaries


# ------------------------------------------------------------------------------------------ layout


def test_layout_is_the_reference_checkpoints(reference_dir):
    layout = json.loads((reference_dir / "checkpoint_layout.json").read_text())
    for kind in KINDS:
        got = reference_layout(kind)
        assert list(got) == list(layout[kind])
        assert {k: list(v) for k, v in got.items()} == layout[kind]


@pytest.mark.parametrize("resolution", [64, 128, 256, 512])
def test_layout_is_our_torch_network_at_other_sizes(resolution):
    pytest.importorskip("torch")
    from export.networks import build_network

    for kind in KINDS:
        net = build_network(kind, {"width": 3, "resolution": resolution, "norm": "instance"})
        want = {k: tuple(v.shape) for k, v in net.state_dict().items()}
        got = reference_layout(kind, 3, resolution)
        assert got == want and list(got) == list(want)


# ------------------------------------------------------------------------------------------ reader


def test_hand_written_zip_reads_back_exactly(tmp_path):
    sd = {
        "w": np.arange(24, dtype=np.float32).reshape(2, 3, 4) / 7,
        "n": np.array(1000, np.int64),
        "h": np.linspace(-1, 1, 5).astype(np.float16),
        "d": np.array([1e-300, 3.5]),
        "flag": np.array([True, False]),
        "empty": np.zeros((0, 3), np.float32),
    }
    for order in ("little", "big"):
        got = read_torch_checkpoint(write_state_dict(tmp_path / f"{order}.pth", sd, byteorder=order))
        assert list(got) == list(sd)
        for k, v in sd.items():
            assert got[k].dtype == v.dtype and got[k].shape == v.shape and np.array_equal(got[k], v), k


def test_hand_written_zip_is_what_torch_reads(tmp_path):
    """The test writer really writes torch's format: torch.load(weights_only=True) reads it the same."""
    torch = pytest.importorskip("torch")
    sd = {"w": np.arange(6, dtype=np.float32).reshape(2, 3), "n": np.array(3, np.int64)}
    loaded = torch.load(write_state_dict(tmp_path / "a.pth", sd, prefix="model_1st"), weights_only=True)
    assert list(loaded) == list(sd)
    assert all(np.array_equal(loaded[k].numpy(), v) and loaded[k].shape == v.shape for k, v in sd.items())


def test_torch_saved_files_read_like_torch_load(tmp_path):
    torch = pytest.importorskip("torch")

    base = torch.arange(30.0).reshape(5, 6)
    conv = torch.nn.Conv2d(3, 4, 3)
    sd = conv.state_dict()  # a real state_dict: it carries _metadata, which torch pickles with BUILD
    assert hasattr(sd, "_metadata")
    sd.update({"rows": base[1:], "bf16": torch.randn(4).bfloat16()})  # rows: a contiguous view at an offset
    sd.update({"p": torch.nn.Parameter(base[0]), "n": torch.tensor(7)})
    torch.save(sd, tmp_path / "x.pth")
    torch.save({"state_dict": conv.state_dict(), "epoch": 3}, tmp_path / "wrapped.pth")
    want = torch.load(tmp_path / "x.pth", weights_only=True)
    got = read_torch_checkpoint(tmp_path / "x.pth")
    assert list(got) == list(want)
    for k, v in want.items():
        assert got[k].shape == tuple(v.shape) and np.array_equal(got[k], v.detach().float().numpy()), k
    assert list(read_torch_checkpoint(tmp_path / "wrapped.pth")) == ["weight", "bias"]
    for name, view in (("t", base.t()), ("view", base[1:, 2:]), ("expand", base[:1].expand(5000, 6))):
        torch.save({name: view}, tmp_path / f"{name}.pth")  # torch reads them; the importer refuses them
        assert torch.load(tmp_path / f"{name}.pth", weights_only=True)[name].shape == view.shape
        with pytest.raises(RelightError, match="only contiguous tensors"):
            read_torch_checkpoint(tmp_path / f"{name}.pth")


class _RunsCode:
    """Unpickling this calls ``fn(arg)``: a checkpoint that carries it would run code when loaded unsafely."""

    def __init__(self, fn, arg):
        self.fn, self.arg = fn, arg

    def __reduce__(self):
        return self.fn, (self.arg,)


def _evil_files(tmp_path, marker) -> dict[str, object]:
    """Checkpoints whose pickle would create ``marker`` if anything in it ran."""
    command = f"touch {marker}"
    files = {}
    # protocol 2, GLOBAL posix.system inside an otherwise good state_dict (what torch.save writes)
    body = b"\x80\x02" + op_global("collections", "OrderedDict") + b")R(" + op_str("x")
    body += op_global(os.system.__module__, "system") + op_tuple([op_str(command)]) + b"R" + b"u."
    files["os.system"] = write_archive(tmp_path / "system.pth", body, {})
    # protocol 4, STACK_GLOBAL builtins.eval (what pickle.dumps writes)
    payload = _RunsCode(eval, f"__import__('os').system({command!r})")
    files["builtins.eval"] = write_archive(tmp_path / "eval.pth", pickle.dumps({"x": payload}, protocol=4), {})
    # a dotted name that would reach a function's globals through an allowed one
    body = b"\x80\x02" + op_global("torch._utils", "_rebuild_tensor_v2.__globals__") + b"."
    files["dotted"] = write_archive(tmp_path / "dotted.pth", body, {})
    return files


def test_malicious_checkpoints_are_refused_without_running_anything(tmp_path):
    marker = tmp_path / "marker"
    files = _evil_files(tmp_path, marker)
    for what, path in files.items():
        with pytest.raises(RelightError, match="refused"):
            read_torch_checkpoint(path)
        if HAS_ONNX:
            with pytest.raises(RelightError, match="refused"):
                import_reference(tmp_path / "out", stage2=path, width=WIDTH, resolution=RES)
        assert not marker.exists(), what
    assert not (tmp_path / "out").exists()
    # control: the payloads are real, an ordinary unpickler runs them (a harmless touch in tmp_path)
    for what in ("os.system", "builtins.eval"):
        with zipfile.ZipFile(files[what]) as z:
            pickle.loads(z.read("archive/data.pkl"))  # noqa: S301 - deliberately unsafe, to prove the point
        assert marker.exists(), what
        marker.unlink()


@pytest.mark.filterwarnings("ignore:Detected pickle protocol")  # torch.load notes the protocol-4 file, then refuses it
def test_malicious_checkpoints_are_refused_by_the_torch_path_too(tmp_path):
    """export.convert reads with torch.load(weights_only=True): the same files, and one written by torch.save."""
    torch = pytest.importorskip("torch")
    from export.convert import load_reference

    marker = tmp_path / "marker"
    files = _evil_files(tmp_path, marker)
    torch.save({"c0.weight": torch.zeros(1), "x": _RunsCode(os.system, f"touch {marker}")}, tmp_path / "saved.pth")
    for path in [*files.values(), tmp_path / "saved.pth"]:
        with pytest.raises(RelightError):
            load_reference(path, "stage2", WIDTH, RES)
        assert not marker.exists(), path
    with pytest.raises(RelightError, match="refused.*posix.system|refused.*os.system"):
        read_torch_checkpoint(tmp_path / "saved.pth")
    assert not marker.exists()


def _one_tensor(tmp_path, name, *, numel=4, nbytes=16, offset=0, size=(4,), stride=(1,), key="0"):
    body = b"\x80\x02" + op_global("collections", "OrderedDict") + b")R(" + op_str("w")
    body += tensor_record(key, "FloatStorage", numel, offset, size, stride) + b"u."
    return write_archive(tmp_path / name, body, {"0": bytes(nbytes)})


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"offset": 2}, "reaches past its storage"),
        ({"size": (2, 3), "stride": (3, 1)}, "reaches past its storage"),
        ({"nbytes": 12}, "holds 12 bytes, expected 4 x 4"),
        ({"key": "1"}, "storage archive/data/1 is missing"),
        ({"key": "../x"}, "not a plain name"),
        ({"stride": (-1,)}, "malformed tensor record"),
    ],
)
def test_malformed_tensor_records(tmp_path, kwargs, match):
    with pytest.raises(RelightError, match=match):
        read_torch_checkpoint(_one_tensor(tmp_path, "bad.pth", **kwargs))


def test_unreadable_files(tmp_path):
    with pytest.raises(RelightError, match="not found"):
        read_torch_checkpoint(tmp_path / "none.pth")
    (tmp_path / "legacy.pth").write_bytes(pickle.dumps({"a": 1}))
    with pytest.raises(RelightError, match="not a PyTorch zip checkpoint.*convert-reference"):
        read_torch_checkpoint(tmp_path / "legacy.pth")
    with zipfile.ZipFile(tmp_path / "nopkl.pth", "w") as z:
        z.writestr("archive/version", "3")
    with pytest.raises(RelightError, match="expected one PREFIX/data.pkl"):
        read_torch_checkpoint(tmp_path / "nopkl.pth")
    write_archive(tmp_path / "trunc.pth", b"\x80\x02" + op_global("collections", "OrderedDict"), {})
    with pytest.raises(RelightError, match="not a readable torch checkpoint"):
        read_torch_checkpoint(tmp_path / "trunc.pth")
    write_archive(tmp_path / "list.pth", b"\x80\x02](K\x01e.", {})  # a list, not a state_dict
    with pytest.raises(RelightError, match="expected a state_dict"):
        read_torch_checkpoint(tmp_path / "list.pth")
    write_archive(tmp_path / "num.pth", b"\x80\x02}(X\x01\x00\x00\x00aK\x01u.", {})  # {"a": 1}
    with pytest.raises(RelightError, match="entry 'a' is not a named tensor"):
        read_torch_checkpoint(tmp_path / "num.pth")


# ---------------------------------------------------------------------------------------- importer


@needs_onnx
@pytest.mark.parametrize("kind", KINDS)
def test_imported_graph_matches_the_independent_forward_pass(checkpoints, imported, kind):
    """The done criterion (small size): relative error <= 1e-4 against DESIGN.md §1 run in numpy float64."""
    folder, _ = imported
    sess = _session(folder / f"{kind}.onnx")
    h, w = (RES, RES) if kind == "stage1" else (RES, RES + 64)
    feeds = _feeds(kind, 2, h, w, seed=5)
    got = dict(zip([o.name for o in sess.get_outputs()], sess.run(None, feeds), strict=True))
    want = contract_outputs(checkpoints[kind][1], kind, feeds)
    errors = {name: relative_error(got[name], value) for name, value in want.items()}
    print(f"{kind} width {WIDTH} R {RES} {h}x{w}: " + ", ".join(f"{k} {v:.1e}" for k, v in errors.items()))
    assert max(errors.values()) <= 1e-4, errors
    if kind == "stage2":  # a tanh on the residual (the old bug) is far outside that tolerance
        mask = feeds["mask"]
        assert 0.05 < ((mask > 0) & (mask < 1)).mean() < 0.5  # soft edges, where the two rules differ
        masked_first = np.clip(feeds["diffuse"] + want["residual"], 0, 1) * mask  # r ⊙ mask added (issue 34)
        assert relative_error(masked_first, want["relit"]) > 1e-3
        assert relative_error(np.tanh(want["residual"]) * mask, want["residual"]) > 1e-3
        assert np.abs(want["residual"]).max() > 0.05  # not a residual so small that tanh would not show


@needs_onnx
def test_stage1_light_head_with_hidden_layers(tmp_path):
    """At 256² the light head has two convs and a norm between them (1024²: four convs)."""
    sd = random_reference_weights(reference_layout("stage1", 2, 256), seed=3)
    import_reference(tmp_path, stage1=write_state_dict(tmp_path / "s1.pth", sd), width=2, resolution=256)
    feeds = _feeds("stage1", 1, 256, 256, seed=6)
    sess = _session(tmp_path / "stage1.onnx")
    got = dict(zip([o.name for o in sess.get_outputs()], sess.run(None, feeds), strict=True))
    for name, value in contract_outputs(sd, "stage1", feeds).items():
        assert relative_error(got[name], value) <= 1e-4, name


def test_bgr_fold_is_an_involution_and_touches_only_colour(checkpoints):
    sd = checkpoints["dvp"][1]
    once = bgr_to_rgb(sd, "dvp")
    twice = bgr_to_rgb(once, "dvp")
    assert all(np.array_equal(twice[k], sd[k].astype(np.float32)) for k in sd)
    assert np.array_equal(once["c0.weight"][:, 3 + 3 * 4 + 0], sd["c0.weight"][:, 3 + 3 * 4 + 2])  # light k=4
    assert np.array_equal(once["dc5a.weight"], sd["dc5a.weight"])  # transport is colour-free
    s1 = checkpoints["stage1"][1]
    assert np.array_equal(bgr_to_rgb(s1, "stage1")["dc5b.weight"][3], s1["dc5b.weight"][3])  # skin row kept


@needs_onnx
def test_metadata_and_summaries(checkpoints, imported):
    folder, summaries = imported
    assert [s["kind"] for s in summaries] == list(KINDS)
    for kind in KINDS:
        meta = _session(folder / f"{kind}.onnx").get_modelmeta().custom_metadata_map
        path = checkpoints[kind][0]
        assert meta["relight_rt.kind"] == kind and meta["relight_rt.norm"] == "instance"
        assert meta["relight_rt.resolution"] == str(RES) and meta["relight_rt.format"] == "1"
        assert path.name in meta["relight_rt.source"] and "BGR folded to RGB" in meta["relight_rt.source"]
        assert meta.get("relight_rt.output_activation") == (None if kind == "stage1" else "none")


@needs_onnx
def test_importer_graphs_equal_convert_reference(checkpoints, imported, tmp_path):
    """Same outputs (relative error <= 1e-6) and the same metadata as ``python -m export convert-reference``."""
    pytest.importorskip("torch")
    from export.convert import convert_reference

    paths = {k: p for k, (p, _) in checkpoints.items()}
    convert_reference(paths["stage1"], tmp_path, stage2=paths["stage2"], dvp=paths["dvp"], width=WIDTH, resolution=RES)
    folder, _ = imported
    for kind in KINDS:
        ours, theirs = _session(folder / f"{kind}.onnx"), _session(tmp_path / f"{kind}.onnx")
        assert ours.get_modelmeta().custom_metadata_map == theirs.get_modelmeta().custom_metadata_map
        h, w = (RES, RES) if kind == "stage1" else (192, 256)
        feeds = _feeds(kind, 2, h, w, seed=8)
        for name, a, b in zip([o.name for o in ours.get_outputs()], ours.run(None, feeds), theirs.run(None, feeds),
                              strict=True):
            assert relative_error(a, b) <= 1e-6, (kind, name)


@needs_onnx
def test_layout_mismatch_lists_every_problem(tmp_path):
    sd = random_reference_weights(reference_layout("stage2", WIDTH, RES), seed=1)
    del sd["bnc2.running_var"]
    sd["extra.weight"] = np.zeros(1, np.float32)
    sd["dc5b.weight"] = np.zeros((4, 2 * WIDTH, 3, 3), np.float32)  # a stage-1 decoder in a stage-2 file
    path = write_state_dict(tmp_path / "bad.pth", sd)
    with pytest.raises(RelightError) as info:
        import_reference(tmp_path / "out", stage2=path, width=WIDTH, resolution=RES)
    msg = str(info.value)
    assert "bad.pth" in msg and "missing keys: bnc2.running_var" in msg and "unexpected keys: extra.weight" in msg
    assert "mis-shaped: dc5b.weight [4, 4, 3, 3] (expected [3, 4, 3, 3])" in msg
    assert not (tmp_path / "out").exists()


@needs_onnx
def test_nothing_is_written_when_one_file_fails(checkpoints, tmp_path):
    (tmp_path / "junk.pth").write_bytes(b"junk")
    with pytest.raises(RelightError, match="junk.pth"):
        import_reference(tmp_path / "out", stage1=checkpoints["stage1"][0], stage2=tmp_path / "junk.pth",
                         width=WIDTH, resolution=RES)
    assert not (tmp_path / "out").exists()
    with pytest.raises(RelightError, match="give --stage1, --stage2 and/or --dvp"):
        import_reference(tmp_path / "out")


@needs_onnx
def test_an_output_never_replaces_an_input(checkpoints, tmp_path):
    target = tmp_path / "stage2.onnx"
    target.write_bytes(checkpoints["stage2"][0].read_bytes())  # a checkpoint that happens to be named so
    with pytest.raises(RelightError, match="refusing to overwrite the input"):
        import_reference(tmp_path, stage2=target, width=WIDTH, resolution=RES)
    assert target.read_bytes() == checkpoints["stage2"][0].read_bytes()


@needs_onnx
def test_cli(checkpoints, tmp_path, capsys):
    argv = ["import-reference", "--stage2", str(checkpoints["stage2"][0]), "--out", str(tmp_path / "m")]
    assert cli_main([*argv, "--width", str(WIDTH), "--resolution", str(RES)]) == 0
    assert "wrote" in capsys.readouterr().out and (tmp_path / "m" / "stage2.onnx").is_file()
    assert cli_main(argv) == 2  # at the default 64 / 1024 the small file does not fit
    err = capsys.readouterr().err
    assert err.startswith("relight-rt: error: ") and len(err.strip().splitlines()) == 1
    assert "mis-shaped: c0.weight [2, 3, 4, 4] (expected [64, 3, 4, 4])" in err


def test_without_onnx_the_error_names_the_extra(checkpoints, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnx", None)
    with pytest.raises(RelightError, match=r'pip install "relight-rt\[import\]"'):
        import_reference(tmp_path, stage2=checkpoints["stage2"][0], width=WIDTH, resolution=RES)


@pytest.mark.parametrize("protocol", range(pickle.HIGHEST_PROTOCOL + 1))
def test_pickle_scan_passes_ordinary_pickles_and_refuses_deep_ones(protocol):
    """issue 35 item 5: the opcode scan that runs before the unpickler knows every protocol's ops (marks,
    memo, in-place appends, BUILD, OBJ/INST) and measures nesting, not length."""
    from collections import OrderedDict

    from relight_rt.apps.torch_checkpoint import PICKLE_MAX_DEPTH, scan_pickle

    state = OrderedDict(a=[1] * 3000, b={"x": {"y": (1, (2, ()))}}, c={1, 2}, d=b"x" * 100, e=10**40)
    scan_pickle(pickle.dumps(state, protocol=protocol), "ok")
    scan_pickle(pickle.dumps(_RunsCode(len, "x"), protocol=protocol), "reduce")  # scanned only, never run
    deep = ()
    for _ in range(PICKLE_MAX_DEPTH + 1):
        deep = (deep,)
    with pytest.raises(RelightError, match="nests containers more than"):
        scan_pickle(pickle.dumps({deep: 1}, protocol=protocol), "deep")
    shallow = ()
    for _ in range(PICKLE_MAX_DEPTH - 2):
        shallow = (shallow,)
    scan_pickle(pickle.dumps({shallow: 1}, protocol=protocol), "shallow")
