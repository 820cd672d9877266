"""Two numbers given as 'A,B' text or as a pair (command-line and API options such as a position or a key light)."""

from __future__ import annotations

from .errors import RelightError


def number_pair(value, what: str, form: str, example: str) -> tuple[float, float]:
    """'A,B' (spaces allowed) or a pair of numbers → (a, b) as floats; range checks are the caller's.

    Args:
        value: the text or the pair.
        what: the option's name in messages ("position").
        form: the expected form ("X,Y").
        example: an example ("0.5,0.9").

    Raises:
        RelightError: not two numbers.
    """
    if isinstance(value, str):
        parts = value.replace(" ", "").split(",")
        if len(parts) != 2:
            raise RelightError(f"{what}: expected {form} (e.g. {example}), got {value!r}")
        value = parts
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise RelightError(f"{what}: expected two numbers {form}, got {value!r}") from None
    return a, b
