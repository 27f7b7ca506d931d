"""The argument types and checks of the ``rlsfilt`` commands, in one place.

`rlsfilt.cli` and its ``identify-many`` command (`rlsfilt._cli_fleet`) read
their options with these argparse ``type=`` functions, whose messages
follow argparse's ``argument --na:`` as ``must be >= 0; got -1``, and raise
`CLIError` for what a command checks after parsing.
"""

import argparse

__all__ = []


class CLIError(ValueError):
    """A user-facing failure: printed as one line, exit status 1."""


def integer(text):
    """An argparse type: an integer."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer; got '{text}'") from None


def number(text):
    """An argparse type: a number."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got '{text}'") from None


def int_at_least(minimum):
    """An argparse type: an integer ``>= minimum``."""
    def parse(text):
        value = integer(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}; got {value}")
        return value
    return parse


def int_list(minimum):
    """An argparse type: comma-separated integers, each ``>= minimum``."""
    check = int_at_least(minimum)
    return lambda text: [check(part.strip()) for part in text.split(",")]


def float_where(accept, expected):
    """An argparse type: a number for which ``accept(value)`` holds."""
    def parse(text):
        value = number(text)
        if not accept(value):
            raise argparse.ArgumentTypeError(f"must be {expected}; got {text}")
        return value
    return parse


#: A forgetting factor, in (0, 1].
forgetting_factor = float_where(lambda v: 0.0 < v <= 1.0, "in (0, 1]")
#: A fraction or a probability, in (0, 1) (a split point, a significance level).
fraction = float_where(lambda v: 0.0 < v < 1.0, "in (0, 1)")


def per_input(values, n_in, option):
    """`values` (a list from `int_list`) for each of `n_in` inputs: one value for all, or
    one per input; `option` names the option in the message."""
    if len(values) == 1:
        return values * n_in
    if len(values) != n_in:
        raise CLIError(f"{option} must give one value or one per input ({n_in}); "
                       f"got {len(values)} values")
    return list(values)
