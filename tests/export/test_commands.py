"""Every ``python -m export`` command: a frozen config with one field per flag, defaulting as its parser does."""

from __future__ import annotations

import argparse
import dataclasses
import importlib

import pytest

from export.__main__ import COMMANDS


def _module(name: str):
    try:
        return importlib.import_module(COMMANDS[name][0])
    except ImportError as exc:  # an optional extra of that command (torch, trimesh, ...)
        pytest.skip(f"{name}: {exc}")


def _required_argv(parser: argparse.ArgumentParser) -> list[str]:
    """The fewest arguments the parser accepts: each required flag or positional with a value it takes."""
    argv: list[str] = []
    for action in parser._actions:
        if not action.required:
            continue
        value = str(action.choices[0]) if action.choices else "x"
        values = [value, value] if action.nargs in ("+", "*") else [value]
        argv += [*action.option_strings[:1], *values]
    return argv


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_a_command_config_mirrors_its_flags(name):
    module = _module(name)
    parser = argparse.ArgumentParser()
    module.add_arguments(parser)
    config = module.config_from_args(parser.parse_args(_required_argv(parser)))
    cls = type(config)
    assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, cls
    dests = {a.dest for a in parser._actions if a.dest != "help"}
    fields = {f.name for f in dataclasses.fields(cls)}
    assert fields == dests, (fields - dests, dests - fields)
    # the dataclass's own defaults are the parser's: built from the required values alone, it is the same config
    required = {a.dest for a in parser._actions if a.required}
    assert cls(**{k: getattr(config, k) for k in required}) == config
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(config, next(iter(fields)), None)


def test_a_config_built_in_code_is_checked_as_the_command_line_is(tmp_path, capsys):
    """The quickstart's way, a config made in code with no argv, meets the same refusal as the flag."""
    from export.__main__ import main
    from export.render.lights_cli import LightsConfig
    from relight_rt import RelightError

    with pytest.raises(RelightError, match="--white-balance: expected a value in"):
        LightsConfig(out=tmp_path / "lights", white_balance=2.0)
    assert main(["lights", "--out", str(tmp_path / "lights"), "--white-balance", "2"]) == 2
    assert not (tmp_path / "lights").exists()
    assert "--white-balance: expected a value in" in capsys.readouterr().err
