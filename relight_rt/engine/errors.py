"""The one exception family of relight_rt."""


class RelightError(ValueError):
    """Bad input, a missing or broken model file, or a graph that breaks the contract.

    The message names the input and says what was expected.
    """
