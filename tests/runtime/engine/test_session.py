"""relight_rt.engine.session: device choice, contract checks at load, model lookup; CUDA tests are marked gpu."""

import numpy as np
import onnxruntime as ort
import pytest
from _graphs import dvp_model, make_models_dir, meta_for, save, stage1_model, stage2_model
from onnx import TensorProto

from relight_rt import RelightError
from relight_rt.engine.session import (
    CPU,
    CUDA,
    bundled_models_dir,
    create_session,
    find_models,
    load_model,
    thread_count,
    validate_session,
)

HAS_CUDA = CUDA in ort.get_available_providers()


@pytest.fixture
def stage1_path(tmp_path):
    return save(stage1_model(64), tmp_path / "stage1.onnx")


def test_cpu_session_runs_the_graph(stage1_path):
    sess = create_session(stage1_path, device="cpu")
    assert sess.get_providers() == [CPU]
    model = load_model(stage1_path, "stage1", device="cpu")
    assert model.config.kind == "stage1" and model.config.resolution == 64 and not model.on_cuda
    out = model.run({"image": np.full((2, 3, 64, 64), 0.5), "mask": np.ones((2, 1, 64, 64))})
    assert out["albedo"].shape == (2, 3, 64, 64) and out["light"].shape == (2, 9, 3)
    np.testing.assert_allclose(out["albedo"], 0.5)


def test_existing_session_is_checked_and_returned(stage1_path):
    sess = ort.InferenceSession(str(stage1_path), providers=[CPU])
    assert create_session(sess) is sess
    assert load_model(sess, "stage1").session is sess
    with pytest.raises(RelightError, match="kind is 'stage1', expected 'stage2'"):
        load_model(sess, "stage2")


def test_auto_picks_what_onnxruntime_offers(stage1_path):
    sess = create_session(stage1_path, device="auto")
    assert sess.get_providers()[0] == (CUDA if HAS_CUDA else CPU)


def test_explicit_providers_win(stage1_path):
    assert create_session(stage1_path, device="cuda", providers=[CPU]).get_providers() == [CPU]


@pytest.mark.skipif(HAS_CUDA, reason="this onnxruntime offers CUDA")
def test_cuda_without_cuda_says_why(stage1_path):
    with pytest.raises(RelightError, match="onnxruntime-gpu"):
        create_session(stage1_path, device="cuda")


def test_unknown_device(stage1_path):
    with pytest.raises(RelightError, match="device is 'tpu'"):
        create_session(stage1_path, device="tpu")


def test_threads_from_environment(stage1_path, monkeypatch):
    monkeypatch.setenv("RELIGHT_RT_THREADS", "1")
    assert thread_count() == 1
    sess = create_session(stage1_path, device="cpu")
    assert sess.get_session_options().intra_op_num_threads == 1
    for bad in ("two", "-3"):
        monkeypatch.setenv("RELIGHT_RT_THREADS", bad)
        with pytest.raises(RelightError, match="RELIGHT_RT_THREADS"):
            create_session(stage1_path, device="cpu")


def test_cpu_threads_do_not_spin(stage1_path):
    """Stage 1 and stage 2 take turns on the same cores: idle intra-op threads must not spin-wait."""
    sess = create_session(stage1_path, device="cpu")
    assert sess.get_session_options().get_session_config_entry("session.intra_op.allow_spinning") == "0"


def test_global_log_level_is_never_touched(stage1_path, monkeypatch):
    def forbidden(*args):
        raise AssertionError("set_default_logger_severity called")

    monkeypatch.setattr(ort, "set_default_logger_severity", forbidden)
    create_session(stage1_path, device="cpu", warmup=True)


def test_warmup_runs_every_kind(tmp_path):
    for kind, model in (("stage1", stage1_model(64)), ("stage2", stage2_model()), ("dvp", dvp_model())):
        m = load_model(save(model, tmp_path / f"{kind}.onnx"), kind, device="cpu", warmup=True)
        assert m.config.kind == kind


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(RelightError, match="not found"):
        create_session(tmp_path / "nope.onnx")
    (tmp_path / "junk.onnx").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(RelightError, match="junk.onnx: not a readable ONNX graph"):
        create_session(tmp_path / "junk.onnx")
    good = save(stage1_model(64), tmp_path / "good.onnx").read_bytes()
    (tmp_path / "cut.onnx").write_bytes(good[: len(good) // 2])
    with pytest.raises(RelightError, match="cut.onnx"):
        create_session(tmp_path / "cut.onnx")


@pytest.mark.parametrize(
    ("model", "match"),
    [
        (stage1_model(64, meta=meta_for("stage1", 64, kind=None)), "relight_rt.kind.*missing"),
        (stage1_model(64, meta={}), "missing; not a relight_rt graph"),
        (stage1_model(64, meta=meta_for("stage1", 64, color="BGR")), "color"),
        (stage1_model(64, meta=meta_for("stage1", 128)), "axis 2"),
        (stage1_model(64, image_name="photo"), r"inputs are \['mask', 'photo'\]"),
        (stage1_model(64, elem=TensorProto.DOUBLE), "tensor\\(double\\).*float32"),
        (stage1_model(64, rank=2), "rank 2"),
        (stage1_model(64, meta=meta_for("stage2", 64)), "stage2 graph inputs"),
    ],
)
def test_contract_breaking_graphs_are_refused(tmp_path, model, match):
    path = tmp_path / "bad.onnx"
    path.write_bytes(model.SerializeToString())
    with pytest.raises(RelightError, match=match):
        create_session(path, device="cpu")


def test_validate_names_the_graph(tmp_path):
    path = save(stage2_model(), tmp_path / "s2.onnx")
    sess = ort.InferenceSession(str(path), providers=[CPU])
    assert validate_session(sess, "s2").kind == "stage2"
    with pytest.raises(RelightError, match="^s2: .*expected 'stage1'"):
        validate_session(sess, "s2", "stage1")


def test_find_models_order(tmp_path, monkeypatch):
    explicit = make_models_dir(tmp_path / "a", 64, stage2=False)
    env = make_models_dir(tmp_path / "b", 64, stage2=False)
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(env))
    assert find_models(explicit) == explicit
    assert find_models() == env
    with pytest.raises(RelightError, match=r"looked in: .*nowhere \(no such folder\)$"):
        find_models(tmp_path / "nowhere")
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(tmp_path))  # set but empty: an error, no silent fallback
    with pytest.raises(RelightError, match=r"no stage1.onnx.*from \$RELIGHT_RT_MODELS"):
        find_models()
    monkeypatch.delenv("RELIGHT_RT_MODELS")
    assert find_models() == bundled_models_dir()


@pytest.mark.gpu
@pytest.mark.skipif(not HAS_CUDA, reason="needs onnxruntime-gpu and a CUDA device")
def test_cuda_session_is_really_on_cuda(stage1_path):
    model = load_model(stage1_path, "stage1", device="cuda")
    assert model.on_cuda
