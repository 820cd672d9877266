"""relight_rt.cli: every command, and every bad input as one line on stderr + exit 2 + no output left."""

import json

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import OWN_LIGHT, meta_for, models_dir, save, stage1_model, write_person

from relight_rt import cli

__all__ = ["models_dir"]  # fixture


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    np.save(tmp_path / "light.npy", OWN_LIGHT.astype(np.float64))
    return tmp_path


def test_relight_one_file(work, capsys):
    photo = write_person(work)
    code, _, err = run(["relight", photo, "--light", "light.npy", "-o", "out.png", "--device", "cpu"], capsys)
    assert code == 0, err
    out = cv2.imread("out.png")
    assert out.shape == (150, 100, 3)
    np.testing.assert_allclose(out.astype(int), cv2.imread(str(photo)).astype(int), atol=1)  # own light: input back


@pytest.mark.parametrize(
    "light_args",
    [["--preset", "studio"], ["--light", "light.npy", "--rotate", "90"], ["--light-from", "p.png"],
     ["--envmap", "env.hdr"], ["--light", "light.npy", "--bgr"]],
)  # fmt: skip
def test_light_options(work, capsys, light_args):
    write_person(work)
    cv2.imwrite("env.hdr", np.full((8, 16, 3), 0.3, np.float32))
    code, _, err = run(["relight", "p.png", *light_args, "-o", "o.png"], capsys)
    assert code == 0, err
    assert cv2.imread("o.png").shape == (150, 100, 3)


def test_transparent_background(work, capsys):
    write_person(work)
    code, _, err = run(["relight", "p.png", "--preset", "front", "--background", "transparent", "-o", "o.png"], capsys)
    assert code == 0, err
    assert cv2.imread("o.png", cv2.IMREAD_UNCHANGED).shape == (150, 100, 4)


def test_folder_goes_on_past_bad_files_and_reports_all(work, capsys):
    (work / "in").mkdir()
    write_person(work / "in", "a", 1)
    write_person(work / "in", "b", 2)
    (work / "in" / "c.png").write_bytes(b"broken")
    cv2.imwrite(str(work / "in" / "d.png"), np.zeros((20, 20, 3), np.uint8))  # no mask, no alpha
    code, _, err = run(["relight", "in", "--light", "light.npy", "-o", "out"], capsys)
    assert code == 2
    assert sorted(p.name for p in (work / "out").iterdir()) == ["a_relit.png", "b_relit.png"]
    lines = [x for x in err.splitlines() if x.startswith("relight-rt: error:")]
    assert len(lines) == 2 and "c.png" in lines[0] and "d.png" in lines[1]
    assert "2 failed, 2 written" in err


def test_mask_folder_and_mask_file(work, capsys):
    write_person(work, "a")
    (work / "masks").mkdir()
    (work / "a_mask.png").rename(work / "masks" / "a_mask.png")
    code, _, err = run(["relight", "a.png", "--mask", "masks", "--preset", "studio", "-o", "o1.png"], capsys)
    assert code == 0, err
    code, _, err = run(["relight", "a.png", "--mask", "masks/a_mask.png", "--preset", "studio", "-o", "o2.png"], capsys)
    assert code == 0, err


def test_decompose(work, capsys):
    write_person(work)
    code, _, err = run(["decompose", "p.png", "-o", "dec"], capsys)
    assert code == 0, err
    names = sorted(p.name for p in (work / "dec").iterdir())
    assert names == ["albedo.png", "light.npy", "shading.png", "skin.png", "transport.npz"]
    np.testing.assert_allclose(np.load(work / "dec" / "light.npy"), OWN_LIGHT, rtol=1e-6)
    assert cv2.imread(str(work / "dec" / "skin.png"), cv2.IMREAD_UNCHANGED).ndim == 2


def test_decompose_stores_the_transport_at_the_network_size(work, capsys, models_dir):
    """issue 34: transport.npz held the float32 map at the photo's size (51 MB for 2.5 megapixels); now the
    network's (R, R, 9) float16 with the crop geometry, brought back to the photo's size on reading."""
    from relight_rt import Relighter, RuntimeConfig
    from relight_rt.relight.transport_file import load_transport

    photo = write_person(work, h=600, w=400)
    code, _, err = run(["decompose", photo, "-o", "dec"], capsys)
    assert code == 0, err
    dec = Relighter(RuntimeConfig(models=models_dir, device="cpu")).decompose(photo, "p_mask.png")
    r = dec.resolution
    with np.load(work / "dec" / "transport.npz") as z:
        assert z["transport"].shape == (r, r, 9) and z["transport"].dtype == np.float16
    full = dec.to_input(np.ascontiguousarray(dec.transport))
    assert (work / "dec" / "transport.npz").stat().st_size < full.nbytes / 20  # the photo's map was 8.6 MB
    got = load_transport(work / "dec" / "transport.npz")
    assert got.shape == (600, 400, 9) and got.dtype == np.float32
    np.testing.assert_allclose(got, full, rtol=2**-10, atol=1e-6)  # float16: 11 significant bits


@pytest.mark.parametrize("form", ["gray", "gray16", "colour16"])
def test_black_and_white_and_16_bit_photos_are_relit_and_decomposed(work, capsys, form):
    """issue 34: relight and decompose refused them ("expected an (H, W, 3) colour image, got grayscale")."""
    photo = write_person(work)
    rgb = cv2.imread(str(photo))
    gray = cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY)
    image = {"gray": gray, "gray16": gray.astype(np.uint16) * 257, "colour16": rgb.astype(np.uint16) * 257}[form]
    cv2.imwrite(str(photo), image)
    code, _, err = run(["relight", photo, "--light", "light.npy", "-o", "out.png"], capsys)
    assert code == 0, err
    out = cv2.imread("out.png")
    expected = rgb if form == "colour16" else np.repeat(gray[..., None], 3, axis=2)
    np.testing.assert_allclose(out.astype(int), expected.astype(int), atol=1)  # own light: the photo back, as colour
    code, _, err = run(["decompose", photo, "-o", "dec"], capsys)
    assert code == 0, err
    assert cv2.imread("dec/albedo.png").shape == (150, 100, 3)
def test_decompose_writes_all_layers_or_none(work, capsys, monkeypatch):
    """issue 35 item 10: decompose wrote albedo.png and shading.png, then failed at skin.png (an input of that
    name in the output folder) or at a full disk (a message naming no file): now all five layers or none."""
    (work / "dec").mkdir()
    write_person(work / "dec", "skin")  # the photo is dec/skin.png: the skin layer would replace it
    before = {p.name: p.read_bytes() for p in (work / "dec").iterdir()}
    code, _, err = run(["decompose", "dec/skin.png", "-o", "dec"], capsys)
    assert code == 2 and "refusing to overwrite the input" in err and "skin.png" in err, err
    assert {p.name: p.read_bytes() for p in (work / "dec").iterdir()} == before  # nothing written, nothing left

    write_person(work)
    real_save = np.save

    def full_disk(file, arr, allow_pickle=True):  # light.npy, the fourth file: no space left
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "save", full_disk)
    code, _, err = run(["decompose", "p.png", "-o", "out"], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "light.npy" in lines[0] and "No space left" in lines[0], err
    assert list((work / "out").iterdir()) == []  # no layer, no temporary file
    monkeypatch.setattr(np, "save", real_save)
    assert run(["decompose", "p.png", "-o", "out"], capsys)[0] == 0
    assert len(list((work / "out").iterdir())) == 5


def test_lights_commands(work, capsys):
    code, out, _ = run(["lights", "list"], capsys)
    assert code == 0 and out.splitlines()[0].split()[0] == "studio"
    code, _, err = run(["lights", "show", "studio", "--size", "32", "-o", "s.png"], capsys)
    assert code == 0, err
    assert cv2.imread("s.png").shape == (32, 32, 3)
    code, _, err = run(["lights", "show", "light.npy", "-o", "s2.png"], capsys)
    assert code == 0, err
    cv2.imwrite("env.hdr", np.ones((8, 16, 3), np.float32))
    for target in ("l.npy", "l.json"):
        code, _, err = run(["lights", "from-envmap", "env.hdr", "-o", target], capsys)
        assert code == 0, err
    np.testing.assert_allclose(np.load("l.npy")[0], np.sqrt(4 * np.pi), rtol=0.02)
    assert len(json.loads((work / "l.json").read_text())["sh"]) == 9
    code, _, err = run(["lights", "show", "nope", "-o", "x.png"], capsys)
    assert code == 2 and "known presets" in err and not (work / "x.png").exists()


def test_lights_from_photo_takes_the_model_options(work, capsys, models_dir, monkeypatch):
    """Every command takes --models/--device; from-photo is the lights command that runs stage 1."""
    monkeypatch.delenv("RELIGHT_RT_MODELS")
    write_person(work)
    for target in ("own.npy", "own.json"):
        code, _, err = run(["lights", "from-photo", "p.png", "--models", models_dir, "--device", "cpu", "-o", target],
                           capsys)
        assert code == 0, err
    np.testing.assert_allclose(np.load("own.npy"), OWN_LIGHT, rtol=1e-6)  # the test stage 1 returns OWN_LIGHT
    code, _, err = run(["lights", "list", "--models", models_dir, "--device", "cpu"], capsys)
    assert code == 0, err
    code, _, err = run(["lights", "from-photo", "p.png", "--models", models_dir, "-o", "own.png"], capsys)
    assert code == 2 and "expected a .npy or .json" in err and not (work / "own.png").exists()
    code, _, err = run(["lights", "from-photo", "missing.png", "--models", models_dir, "-o", "m.npy"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (work / "m.npy").exists()


def test_doctor(work, capsys):
    code, out, _ = run(["doctor", "--device", "cpu"], capsys)
    assert code == 0 and "onnxruntime" in out and "stage1: resolution 64" in out and out.rstrip().endswith("ok")


def test_help_and_usage_errors(capsys):
    assert cli.main([]) == 0
    assert cli.main(["--version"]) == 0
    assert cli.main(["relight", "x.png"]) == 2  # no light, no -o: argparse usage error


def _log_lines(argv: list[str], cwd) -> tuple[int, list[str]]:
    """Run the CLI in a fresh interpreter (logging set up from scratch); its exit code and stderr lines."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = {**os.environ, "PYTHONPATH": str(Path(cli.__file__).parents[2])}  # relight_rt/cli/__init__.py
    proc = subprocess.run([sys.executable, "-m", "relight_rt", *argv], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=120)  # fmt: skip
    return proc.returncode, proc.stderr.splitlines()


def test_quiet_and_verbose_are_accepted_before_or_after_the_command(tmp_path):
    """issue 34: ``relight-rt lights show studio -o s.png -q`` said "unrecognized arguments: -q"."""
    show = ["lights", "show", "studio", "--size", "16", "-o", "s.png"]
    code, lines = _log_lines(show, tmp_path)
    assert code == 0 and lines == ["studio -> s.png"], lines  # the INFO line
    for argv in (["-q", *show], [*show, "-q"], ["lights", "-q", *show[1:]], [*show, "--quiet"]):
        code, lines = _log_lines(argv, tmp_path)
        assert code == 0 and lines == [], (argv, lines)
    for argv in (["-v", *show], [*show, "-v"], [*show, "--verbose"]):
        assert cli.build_parser().parse_args(argv).verbose is True, argv
        assert cli.build_parser().parse_args(argv).quiet is False, argv
    args = cli.build_parser().parse_args(["-q", *show])
    assert args.quiet is True and args.verbose is False  # a subcommand's default does not undo the top level's


def _every_parser(parser):
    import argparse

    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _every_parser(sub)


def test_help_texts_are_plain_text():
    """issue 34: ``relight-rt video --help`` began with reST markup (two backquotes around the command)."""
    import re

    markup = re.compile(r"``|:(func|class|meth|mod|attr|data):`")
    for p in _every_parser(cli.build_parser()):
        text = p.format_help()
        assert not markup.search(text), (p.prog, markup.search(text).group(0), text[:300])


@pytest.mark.parametrize(("argv", "words"), [
    (["relight", "x.png"], ["required: -o/--output", "see relight-rt relight -h"]),
    (["relight", "x.png", "-o", "o.png", "--max-pixels", "many"], ["invalid int value", "see relight-rt relight -h"]),
    (["lights", "show"], ["required: LIGHT", "see relight-rt lights show -h"]),
    (["video", "in", "-o", "o.mp4", "--bogus"], ["unrecognized arguments: --bogus", "see relight-rt video -h"]),
    (["frobnicate"], ["invalid choice: 'frobnicate'", "see relight-rt -h"]),
])  # fmt: skip
def test_usage_errors_are_one_line(capsys, argv, words):
    """issue 35 item 17: a usage error was argparse's 12 lines of usage; now one ``relight-rt: error:`` line that
    says what is wrong and where the help is."""
    assert cli.main(argv) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1 and lines[0].startswith("relight-rt: error: "), err
    assert all(w in lines[0] for w in words), lines[0]


def bad_case(work, kind):
    """Make one bad input in ``work``; return the relight arguments (without -o)."""
    photo = write_person(work)
    args = [photo, "--light", "light.npy"]
    if kind == "size-mismatch":
        cv2.imwrite("p_mask.png", np.full((10, 10), 255, np.uint8))
    elif kind == "empty-mask":
        cv2.imwrite("p_mask.png", np.zeros((150, 100), np.uint8))
    elif kind == "full-mask":
        cv2.imwrite("p_mask.png", np.full((150, 100), 255, np.uint8))
    elif kind == "light-shape":
        np.save("light.npy", np.zeros((9, 4)))
    elif kind == "light-nan":
        np.save("light.npy", np.full((9, 3), np.nan))
    elif kind == "no-models":
        args += ["--models", work / "nowhere"]
    elif kind == "corrupt-onnx":
        (work / "m").mkdir()
        (work / "m" / "stage1.onnx").write_bytes(b"\x08\x01garbage")
        args += ["--models", work / "m"]
    elif kind == "contract-onnx":
        (work / "m").mkdir()
        save(stage1_model(64, meta=meta_for("stage1", 64, sh_degree="3")), work / "m" / "stage1.onnx")
        args += ["--models", work / "m"]
    elif kind == "unreadable":
        (work / "p.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    return args


MATCH = {
    "size-mismatch": "10x10",
    "empty-mask": "empty",
    "full-mask": "whole image",
    "light-shape": r"\(9, 3\)",
    "light-nan": "NaN",
    "no-models": "looked in",
    "corrupt-onnx": "not a readable ONNX",
    "contract-onnx": "sh_degree",
    "unreadable": "cannot decode",
}
BAD = list(MATCH)


@pytest.mark.parametrize("kind", BAD)
def test_bad_input_is_one_line_and_exit_2(work, capsys, kind):
    import re

    args = bad_case(work, kind)
    code, _, err = run(["relight", *args, "-o", "out.png"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("relight-rt: error: "), err
    assert re.search(MATCH[kind], lines[0]), lines[0]
    assert not (work / "out.png").exists()
    assert not [p for p in work.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_refuses_to_overwrite_inputs(work, capsys):
    photo = write_person(work)
    before = photo.read_bytes()
    cv2.imwrite("bg.png", np.zeros((150, 100, 3), np.uint8))
    for target in ("p.png", "p_mask.png", "bg.png", "./p.png"):
        argv = ["relight", "p.png", "--light", "light.npy", "--background", "bg.png", "-o", target]
        code, _, err = run(argv, capsys)
        assert code == 2 and "refusing to overwrite" in err, err
    assert photo.read_bytes() == before
    code, _, err = run(["relight", "p.png", "--light", "light.npy", "-o", "o.xyz"], capsys)
    assert code == 2 and "unknown image type" in err


def test_same_stem_twice_is_reported(work, capsys):
    (work / "x").mkdir()
    (work / "y").mkdir()
    write_person(work / "x", "a")
    write_person(work / "y", "a")
    code, _, err = run(["relight", "x", "y", "--preset", "studio", "-o", "out"], capsys)
    assert code == 2 and "would both write" in err
    assert [p.name for p in (work / "out").iterdir()] == ["a_relit.png"]


def test_reference_photo_from_the_cli(work, capsys, reference_dir):
    """Done-criterion of issue 5: sample.jpg relit from the CLI (its mask found beside it) keeps its size and
    its background outside the mask, bit for bit."""
    photo = reference_dir / "photo" / "sample.jpg"
    code, _, err = run(["relight", photo, "--preset", "golden-hour", "-o", work / "sample_relit.png"], capsys)
    assert code == 0, err
    out, src = cv2.imread(str(work / "sample_relit.png")), cv2.imread(str(photo))
    mask = cv2.imread(str(reference_dir / "photo" / "sample_mask.png"), cv2.IMREAD_GRAYSCALE)
    assert out.shape == src.shape
    np.testing.assert_array_equal(out[mask == 0], src[mask == 0])


def test_one_set_of_light_flags_in_every_command(work, capsys):
    """issue 18 item 8: the same light options everywhere, a preset named as a file points to --preset, and an
    unknown option shows the subcommand's own usage."""
    write_person(work)
    code, _, err = run(["relight", "p.png", "--light", "studio", "-o", "o.png"], capsys)
    assert code == 2 and "use --preset studio" in err and not (work / "o.png").exists()
    code, _, err = run(["relight", "p.png", "--preset", "studio", "--bgr", "-o", "o.png"], capsys)
    assert code == 2 and "--bgr" in err  # --bgr says how to read a light file; with a preset it is a mistake
    for command in (["relight", "p.png", "-o", "o.png"], ["video", ".", "-o", "o.mp4"],
                    ["composite", "p.png", "--background", "p.png", "-o", "o.png"]):
        code, _, err = run([*command, "--preset", "studio", "--rotate", "10", "--no-such-option"], capsys)
        assert code == 2 and f"see relight-rt {command[0]} -h" in err, err  # the subcommand's help
        assert "unrecognized arguments: --no-such-option" in err
    code, out, _ = run(["lights", "show", "light.npy", "--bgr", "--rotate", "90", "-o", "s.png"], capsys)
    assert code == 0 and cv2.imread("s.png") is not None
    code, _, err = run(["lights", "show", "studio", "--bgr", "-o", "s2.png"], capsys)
    assert code == 2 and "--bgr" in err


def test_relight_says_when_a_mask_beside_the_photo_is_used(work, capsys, caplog):
    """A NAME_mask.png left beside the photo (say by an earlier `relight-rt mask`) decides the result: the
    one-line report names it, and says nothing when the mask was given with --mask."""
    photo = write_person(work)
    assert (work / "p_mask.png").is_file()
    caplog.set_level("INFO", logger="relight_rt")
    code, _, err = run(["relight", photo, "--preset", "studio", "-o", "out.png", "--device", "cpu"], capsys)
    assert code == 0, err
    assert "mask: p_mask.png beside it" in caplog.text
    caplog.clear()
    code, _, err = run(["relight", photo, "--mask", "p_mask.png", "--preset", "studio", "-o", "out2.png",
                        "--device", "cpu"], capsys)  # fmt: skip
    assert code == 0, err
    assert "beside it" not in caplog.text and "out2.png" in caplog.text


@pytest.mark.parametrize("argv, dest, value", [
    (["composite", "p.png", "--background", "b.jpg", "--key-light", "-90,30", "-o", "o.png"], "key_light", "-90,30"),
    (["lights", "from-background", "b.jpg", "--key-light", "-45,-10", "-o", "l.npy"], "key_light", "-45,-10"),
    (["relight", "p.png", "--preset", "studio", "--exposure", "-1e-05", "-o", "o.png"], "exposure", "-1e-05"),
    (["relight", "p.png", "--preset", "studio", "--exposure", "-.5", "-o", "o.png"], "exposure", "-.5"),
])  # fmt: skip
def test_values_that_start_with_a_minus_and_a_digit_are_values(argv, dest, value):
    """Issue 50 bug 12: ``--key-light -90,30`` (the documented "from the image's left") was a usage error, and so
    was ``--exposure -1e-05``: argparse before 3.13 took only plain negative numbers for values."""
    assert getattr(cli.build_parser().parse_args(argv), dest) == value


def test_an_unknown_option_is_still_a_usage_error(capsys):
    assert cli.main(["relight", "p.png", "--preset", "studio", "--nonsense", "-o", "o.png"]) == 2
    assert "unrecognized arguments: --nonsense" in capsys.readouterr().err
