"""Typed configs of the ``python -m export`` commands: the one conversion from argparse.

Every command module provides ``add_arguments(parser)``, a frozen keyword-only dataclass of its settings (e.g.
``TrainStage1Config``), ``config_from_args(args) -> Config`` (``config_from_args = reader(TrainStage1Config)``)
and ``run(config) -> int``; ``export/__main__.py``
runs ``module.run(module.config_from_args(args))`` and :mod:`export.quickstart` builds the configs itself and
calls ``run`` directly. A config's fields are named as the command's argparse destinations and default to the
same values (``tests/export/test_commands.py`` holds each pair in step). A config checks its own settings when it
is made (``__post_init__``), so one built in code is refused as the command line would be.
"""

from __future__ import annotations

import argparse
import dataclasses
import typing
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from relight_rt import RelightError

C = TypeVar("C")

_PATHS = (Path, Path | None)


def from_namespace(cls: type[C], args: argparse.Namespace) -> C:
    """The config ``cls`` from parsed arguments: one field per destination of the same name.

    Fields annotated ``Path`` (or ``Path | None``) get a ``Path``; lists (``nargs``) become tuples, so that a
    config holds no mutable value of argparse's.
    """
    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        value = getattr(args, f.name)
        if value is not None and hints[f.name] in _PATHS:
            value = Path(value)
        elif isinstance(value, list):
            value = tuple(Path(v) if hints[f.name] == tuple[Path, ...] else v for v in value)
        values[f.name] = value
    return cls(**values)


def check_fraction(flag: str, value: float) -> None:
    """A setting that must lie in [0, 1] (a probability, a share): one clear error otherwise."""
    if not 0.0 <= value <= 1.0:
        raise RelightError(f"{flag}: expected a value in [0, 1], got {value}")


def reader(cls: type[C]) -> Callable[[argparse.Namespace], C]:
    """A command's ``config_from_args``: ``config_from_args = reader(TrainStage1Config)``."""

    def config_from_args(args: argparse.Namespace) -> C:
        return from_namespace(cls, args)

    config_from_args.__doc__ = f"The {cls.__name__} of ``python -m export``'s parsed arguments."
    return config_from_args


def as_record(config) -> dict:
    """A config as JSON-ready values (paths as strings, tuples as lists), for a run's ``args.json``."""

    def plain(value):
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, tuple | list):
            return [plain(v) for v in value]
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        return value

    return {f.name: plain(getattr(config, f.name)) for f in dataclasses.fields(config)}
