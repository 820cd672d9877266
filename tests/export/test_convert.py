"""Tests for export.convert: importing the reference checkpoints (BGR, batch-of-one BatchNorm) to ONNX."""

from __future__ import annotations

import hashlib
import json
import time

import numpy as np
import pytest

torch = pytest.importorskip("torch")
ort = pytest.importorskip("onnxruntime")

from _graphs import assert_batch_is_per_sample  # noqa: E402
from _reference_forward import contract_outputs, random_reference_weights, relative_error  # noqa: E402

from export.__main__ import main as export_main  # noqa: E402
from export.checkpoint import check_state_dict  # noqa: E402
from export.convert import bgr_to_rgb_state_dict, convert_reference, load_reference  # noqa: E402
from export.networks import DVPNet, Stage1Net, Stage2Net  # noqa: E402
from export.onnx_export import sample_inputs  # noqa: E402
from relight_rt import RelightError  # noqa: E402

torch.set_num_threads(1)
WIDTH, RES = 2, 128  # tiny networks for the default suite


def fake_reference(shapes: dict[str, list[int]], seed: int) -> dict[str, torch.Tensor]:
    """Random tensors in a reference layout, scaled like a trained network (conv weights ~0.02 as its init)."""
    gen = torch.Generator().manual_seed(seed)
    sd = {}
    for key, shape in shapes.items():
        if key.endswith("num_batches_tracked"):
            sd[key] = torch.tensor(1000)
        elif key.endswith("running_var"):
            sd[key] = torch.rand(shape, generator=gen) + 0.5
        elif len(shape) == 4:
            sd[key] = torch.randn(shape, generator=gen) * 0.1
        elif key.endswith("weight"):  # norm scales
            sd[key] = 1 + 0.2 * torch.randn(shape, generator=gen)
        else:
            sd[key] = 0.1 * torch.randn(shape, generator=gen)
    return sd


def _tiny_shapes(cls) -> dict[str, list[int]]:
    return {k: list(v.shape) for k, v in cls(width=WIDTH, resolution=RES).state_dict().items()}


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """Fake tiny reference checkpoints (torch.save of a plain state_dict, as the reference does), converted."""
    root = tmp_path_factory.mktemp("ref")
    sd1, sd2 = fake_reference(_tiny_shapes(Stage1Net), 1), fake_reference(_tiny_shapes(Stage2Net), 2)
    torch.save(sd1, root / "model_1st.pth")
    torch.save(sd2, root / "model_2nd.pth")
    summaries = convert_reference(
        root / "model_1st.pth", root / "out", stage2=root / "model_2nd.pth", width=WIDTH, resolution=RES
    )
    return {"root": root, "sd1": sd1, "sd2": sd2, "summaries": summaries}


def _bgr_reference(cls, state_dict):
    """The reference network as the reference code runs it (BGR weights, per-sample statistics, no dropout)."""
    net = cls(width=WIDTH, resolution=RES, norm="instance")
    net.load_state_dict(state_dict)
    return net.eval()


def _rel(a, b) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_stage1_rgb_graph_equals_bgr_reference(converted):
    sess = ort.InferenceSession(str(converted["root"] / "out" / "stage1.onnx"), providers=["CPUExecutionProvider"])
    inputs = sample_inputs("stage1", 1, RES, RES, seed=7)
    albedo, skin, transport, light = sess.run(None, inputs)
    ref = _bgr_reference(Stage1Net, converted["sd1"])
    bgr = inputs["image"][:, ::-1].copy()
    mask = torch.from_numpy(inputs["mask"])
    with torch.no_grad():
        t_ref, a_ref, s_ref, l_ref = ref((2 * torch.from_numpy(bgr) - 1) * mask)
    assert _rel(albedo, (a_ref * mask).numpy()[:, ::-1]) < 1e-4  # albedo comes out RGB
    assert _rel(skin, (s_ref * mask).numpy()) < 1e-4
    assert _rel(transport, (t_ref * mask).numpy()) < 1e-4
    assert _rel(light, l_ref.numpy()[:, :, ::-1]) < 1e-4  # light columns R, G, B
    assert not np.allclose(albedo, (a_ref * mask).numpy(), atol=1e-3)  # the swap is really there


def test_stage2_rgb_graph_equals_bgr_reference(converted):
    sess = ort.InferenceSession(str(converted["root"] / "out" / "stage2.onnx"), providers=["CPUExecutionProvider"])
    inputs = sample_inputs("stage2", 1, RES, 192, seed=8)
    residual, relit = sess.run(None, inputs)
    ref = _bgr_reference(Stage2Net, converted["sd2"])
    mask = torch.from_numpy(inputs["mask"])
    with torch.no_grad():
        r_ref = ref((2 * torch.from_numpy(inputs["diffuse"][:, ::-1].copy()) - 1) * mask) * mask
    assert _rel(residual, r_ref.numpy()[:, ::-1]) < 1e-4
    with torch.no_grad():  # relit = clip(diffuse + r, 0, 1) * mask, r unmasked (the reference's rule; issue 34)
        r_raw = ref((2 * torch.from_numpy(inputs["diffuse"][:, ::-1].copy()) - 1) * mask).numpy()[:, ::-1]
    np.testing.assert_allclose(relit, np.clip(inputs["diffuse"] + r_raw, 0, 1) * inputs["mask"], atol=1e-5)


def test_converted_graph_is_per_sample(converted):
    sess = ort.InferenceSession(str(converted["root"] / "out" / "stage1.onnx"), providers=["CPUExecutionProvider"])
    inputs = sample_inputs("stage1", 2, RES, RES, seed=9)
    inputs["image"][1] *= 0.5
    assert_batch_is_per_sample(sess, inputs)


def test_metadata_names_the_checkpoint(converted):
    for kind, name in (("stage1", "model_1st.pth"), ("stage2", "model_2nd.pth")):
        path = converted["root"] / "out" / f"{kind}.onnx"
        meta = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).get_modelmeta().custom_metadata_map
        digest = hashlib.sha256((converted["root"] / name).read_bytes()).hexdigest()
        assert name in meta["relight_rt.source"] and f"sha256:{digest}" in meta["relight_rt.source"]
        assert (meta["relight_rt.kind"], meta["relight_rt.norm"], meta["relight_rt.color"]) == (kind, "instance", "RGB")
        assert meta["relight_rt.resolution"] == str(RES)
    assert [s["kind"] for s in converted["summaries"]] == ["stage1", "stage2"]
    assert all(max(s["parity"].values()) <= 1e-4 for s in converted["summaries"])


def test_bgr_to_rgb_is_an_involution_that_leaves_colour_free_weights(converted):
    sd = converted["sd1"]
    before = {k: v.clone() for k, v in sd.items()}
    once = bgr_to_rgb_state_dict(sd, "stage1")
    twice = bgr_to_rgb_state_dict(once, "stage1")
    assert all(torch.equal(twice[k], sd[k]) for k in sd)
    assert torch.equal(once["c0.weight"][:, 0], sd["c0.weight"][:, 2])
    assert torch.equal(once["dc5b.weight"][3], sd["dc5b.weight"][3])  # skin channel untouched
    assert torch.equal(once["dc5a.weight"], sd["dc5a.weight"])  # transport untouched
    assert torch.equal(once["c0l.bias"].reshape(9, 3), sd["c0l.bias"].reshape(9, 3).flip(1))
    assert all(torch.equal(sd[k], before[k]) for k in sd)  # input not modified


def test_wrong_keys_and_shapes_are_all_reported(tmp_path):
    sd = fake_reference(_tiny_shapes(Stage1Net), 3)
    del sd["bnc2.running_var"]
    sd["extra.weight"] = torch.zeros(1)
    sd["dc5b.weight"] = torch.zeros(3, 2 * WIDTH, 3, 3)  # a stage-2 decoder in a stage-1 file
    torch.save(sd, tmp_path / "bad.pth")
    with pytest.raises(RelightError) as info:
        load_reference(tmp_path / "bad.pth", "stage1", WIDTH, RES)
    msg = str(info.value)
    assert "bad.pth" in msg and "missing keys: bnc2.running_var" in msg and "unexpected keys: extra.weight" in msg
    assert "mis-shaped: dc5b.weight [3, 4, 3, 3] (expected [4, 4, 3, 3])" in msg
    with pytest.raises(RelightError, match="missing keys"):
        convert_reference(tmp_path / "bad.pth", tmp_path / "out", width=WIDTH, resolution=RES)
    assert not (tmp_path / "out").exists()


class _Payload:
    """Any class: unpickling it could run code, so weights_only loading must refuse the file."""


def test_pickle_bearing_checkpoint_is_refused(tmp_path):
    sd = fake_reference(_tiny_shapes(Stage1Net), 4)
    sd["payload"] = _Payload()
    torch.save(sd, tmp_path / "evil.pth")
    with pytest.raises(RelightError, match="evil.pth: refused: the checkpoint holds pickled objects"):
        load_reference(tmp_path / "evil.pth", "stage1", WIDTH, RES)


def test_not_a_checkpoint(tmp_path):
    (tmp_path / "junk.pth").write_bytes(b"not a torch file")
    with pytest.raises(RelightError, match="junk.pth: not a readable torch checkpoint"):
        load_reference(tmp_path / "junk.pth", "stage2", WIDTH, RES)
    with pytest.raises(RelightError, match="not found"):
        load_reference(tmp_path / "none.pth", "stage2", WIDTH, RES)
    with pytest.raises(RelightError, match="give --stage1, --stage2 and/or --dvp"):
        convert_reference(None, tmp_path / "out")


def test_cli_convert_reference(converted, tmp_path, capsys):
    root = converted["root"]
    argv = ["convert-reference", "--stage2", str(root / "model_2nd.pth"), "--out", str(tmp_path)]
    assert export_main([*argv, "--width", str(WIDTH), "--resolution", str(RES), "--fp16"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stage2.onnx", "stage2_fp16.onnx"]
    assert "PSNR vs fp32" in capsys.readouterr().out
    assert export_main(argv) == 2  # at the default 1024/64 the tiny file is refused with every mismatch
    assert "mis-shaped: c0.weight [2, 3, 4, 4] (expected [64, 3, 4, 4])" in capsys.readouterr().err


def test_reference_layout_checks_against_the_full_size_network(reference_dir):
    """The importer's key check accepts the real layout (built on the meta device: no memory, no time)."""
    layout = json.loads((reference_dir / "checkpoint_layout.json").read_text())
    for kind, cls in (("stage1", Stage1Net), ("stage2", Stage2Net)):
        with torch.device("meta"):
            net = cls(width=64, resolution=1024, norm="instance")
            fake = {k: torch.empty(shape) for k, shape in layout[kind].items()}
        check_state_dict(net, fake, kind)
        with pytest.raises(RelightError, match="mis-shaped: dc5b.weight"):
            check_state_dict(net, {**fake, "dc5b.weight": torch.empty(7, 128, 3, 3, device="meta")}, kind)


def _layout_of(cls, width: int, resolution: int) -> dict[str, list[int]]:
    return {k: list(v.shape) for k, v in cls(width=width, resolution=resolution).state_dict().items()}


def _run(path, feeds) -> dict[str, np.ndarray]:
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return dict(zip([o.name for o in sess.get_outputs()], sess.run(None, feeds), strict=True))


def _contract_feeds(kind: str, n: int, h: int, w: int, seed: int) -> dict[str, np.ndarray]:
    feeds = sample_inputs(kind, n, h, w, seed)
    if kind == "dvp":
        feeds["light"] = feeds["light"][:, :, [0, 2, 1]].copy()  # colour columns that differ from each other
    return feeds


@pytest.mark.parametrize(
    ("kind", "cls", "width", "resolution", "size"),
    [
        ("stage1", Stage1Net, 2, 128, (128, 128)),
        ("stage1", Stage1Net, 2, 256, (256, 256)),  # a light head with a hidden layer and norm
        ("stage2", Stage2Net, 2, 128, (128, 192)),
        ("dvp", DVPNet, 2, 128, (192, 128)),
    ],
)
def test_converted_graph_matches_the_independent_forward_pass(tmp_path, kind, cls, width, resolution, size):
    """The check that would have caught the tanh: a converted checkpoint against DESIGN.md §1 run in numpy
    (float64, BGR, the reference's weights as saved), relative error <= 1e-4 for every output."""
    sd = random_reference_weights(_layout_of(cls, width, resolution), seed=21)
    ckpt = tmp_path / f"{kind}.pth"
    torch.save({k: torch.from_numpy(v) for k, v in sd.items()}, ckpt)
    files = {k: (ckpt if k == kind else None) for k in ("stage1", "stage2", "dvp")}
    convert_reference(files.pop("stage1"), tmp_path, **files, width=width, resolution=resolution)
    feeds = _contract_feeds(kind, 2, *size, seed=4)
    got = _run(tmp_path / f"{kind}.onnx", feeds)
    want = contract_outputs(sd, kind, feeds)
    assert sorted(got) == sorted(want)
    errors = {name: relative_error(got[name], value) for name, value in want.items()}
    print(f"{kind} width {width} R {resolution} {size}: " + ", ".join(f"{k} {v:.1e}" for k, v in errors.items()))
    assert max(errors.values()) <= 1e-4, errors
    meta = ort.InferenceSession(str(tmp_path / f"{kind}.onnx"), providers=["CPUExecutionProvider"])
    meta = meta.get_modelmeta().custom_metadata_map
    assert meta.get("relight_rt.output_activation") == (None if kind == "stage1" else "none")


@pytest.mark.slow
def test_full_size_fidelity_and_torch_free_import(reference_dir, tmp_path):
    """1024², width 64, the reference's own layout: convert-reference and the torch-free importer against the
    independent numpy forward pass (<= 1e-4) and against each other (<= 1e-6). Prints the errors (-s)."""
    from relight_rt.apps.reference_checkpoints import import_reference

    layout = json.loads((reference_dir / "checkpoint_layout.json").read_text())
    paths = {}
    for i, kind in enumerate(("stage1", "stage2", "dvp")):
        paths[kind] = tmp_path / f"{kind}.pth"
        torch.save({k: torch.from_numpy(v) for k, v in random_reference_weights(layout[kind], 30 + i).items()},
                   paths[kind])
    convert_reference(paths["stage1"], tmp_path / "conv", stage2=paths["stage2"], dvp=paths["dvp"])
    import_reference(tmp_path / "imp", **paths)
    for kind in ("stage1", "stage2", "dvp"):
        sd = {k: np.asarray(v) for k, v in torch.load(paths[kind], weights_only=True).items()}
        feeds = _contract_feeds(kind, 1, 1024, 1024, seed=5)
        conv, imp = _run(tmp_path / "conv" / f"{kind}.onnx", feeds), _run(tmp_path / "imp" / f"{kind}.onnx", feeds)
        want = contract_outputs(sd, kind, feeds)
        del sd
        for name, value in want.items():
            e_conv, e_imp = relative_error(conv[name], value), relative_error(imp[name], value)
            e_pair = relative_error(imp[name], conv[name])
            print(f"{kind} {name}: convert-reference {e_conv:.2e}, import-reference {e_imp:.2e}, between {e_pair:.2e}")
            assert e_conv <= 1e-4 and e_imp <= 1e-4 and e_pair <= 1e-6, (kind, name)


@pytest.mark.long
def test_full_size_end_to_end(reference_dir, tmp_path):
    """The done criterion: fake reference checkpoints at 1024 / width 64 convert (with fp16), and our own
    full-size checkpoint exports with ``python -m export onnx``, within a few minutes on 2 CPU cores."""
    from export.checkpoint import save_checkpoint
    from export.networks import DVPNet

    layout = json.loads((reference_dir / "checkpoint_layout.json").read_text())
    torch.save(fake_reference(layout["stage1"], 1), tmp_path / "model_1st.pth")
    torch.save(fake_reference(layout["stage2"], 2), tmp_path / "model_2nd.pth")
    start = time.perf_counter()
    argv = [
        "convert-reference",
        "--stage1",
        str(tmp_path / "model_1st.pth"),
        "--stage2",
        str(tmp_path / "model_2nd.pth"),
    ]
    assert export_main([*argv, "--out", str(tmp_path / "out"), "--fp16"]) == 0
    save_checkpoint(tmp_path / "dvp.pt", DVPNet(width=64, resolution=1024, norm="instance"))
    out = tmp_path / "out" / "dvp.onnx"
    assert export_main(["onnx", "--checkpoint", str(tmp_path / "dvp.pt"), "--kind", "dvp", "--out", str(out)]) == 0
    elapsed = time.perf_counter() - start
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == ["dvp.onnx", "stage1.onnx", "stage1_fp16.onnx", "stage2.onnx", "stage2_fp16.onnx"]
    print(f"full-size conversion and export took {elapsed:.0f} s")  # reported with -s; tests never assert timings
