"""The argument types and checks of the ``rlsfilt`` commands, in one place.

`rlsfilt.cli` and its ``identify-many`` command (`rlsfilt._cli_fleet`) read
their options with these argparse ``type=`` functions, whose messages
follow argparse's ``argument --na:`` as ``must be >= 0; got -1``, and raise
`CLIError` for what a command checks after parsing. The two CSV readers
share `csv_fields_of_any_length`, `CSV_ENCODING` and `shown_cell`.
"""

import argparse
import contextlib
import csv

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
#: a step size (``--mu``): finite and positive
step_size = float_where(lambda v: 0.0 < v < float("inf"), "a positive number")


def per_input(values, n_in, option):
    """`values` (a list from `int_list`) for each of `n_in` inputs: one value for all, or
    one per input; `option` names the option in the message."""
    if len(values) == 1:
        return values * n_in
    if len(values) != n_in:
        raise CLIError(f"{option} must give one value or one per input ({n_in}); "
                       f"got {len(values)} values")
    return list(values)


#: The encoding every CSV file the commands read is decoded with: UTF-8, with or
#: without the byte order mark that spreadsheet programs write first ("utf-8-sig"
#: drops it; otherwise it would stick to the first column's name)
CSV_ENCODING = "utf-8-sig"

#: The field size limit while a command reads a CSV file: the largest a C long holds on
#: every platform (the csv module's default, 131,072 characters, made a long cell a
#: traceback; the line holding it is in memory anyway)
_FIELD_LIMIT = 2**31 - 1


@contextlib.contextmanager
def csv_fields_of_any_length():
    """Lift the csv module's field size limit while a command reads its file.

    The limit is process-wide: it is raised on entry and put back on exit, so
    the only effect on other code is that it may meanwhile read longer
    fields. A long field then reaches the command's own checks, which name
    the file, row and column (a number with 140,000 digits is no number).
    """
    before = csv.field_size_limit(_FIELD_LIMIT)
    try:
        yield
    finally:
        csv.field_size_limit(before)


def shown_cell(text, width=40):
    """A cell as an error message quotes it: in full when short, else its start and length."""
    if len(text) <= width:
        return repr(text)
    return f"{text[:width - 10]!r}... ({len(text):,} characters)"
