"""The ``rlsfilt identify-many`` command: one ARX model per channel of a CSV file.

The file is in long format, one row per sample: a channel column, the input
column(s) and the output column, each channel's rows in time order (the
channels may be interleaved and may have different lengths). The command
fits the same ARX structure to every channel with
:func:`rlsfilt.models.fit_many` and writes the per-channel summary (one row
per channel: parameters, standard errors, fit percentages, residual tests)
as CSV or JSON, to a file or to standard output.

The CSV is safe to open in a spreadsheet: it is written by the `csv` module
(fields holding a comma, a quote, a line feed or a carriage return are quoted;
lines end in CRLF as RFC 4180 says), and a text cell (a channel label, an
error message) that starts with ``=``, ``+``, ``-``, ``@``, a tab or a
carriage return, which spreadsheets would run as a formula, is written with a
leading single quote ``'`` (OWASP's advice for CSV injection), as is a text
cell that itself starts with ``'``. Numbers are never escaped (``-1.5`` stays
``-1.5``). To recover a label, remove one leading ``'`` from a text cell that
has one (:func:`unescape_cell`). Output files are written atomically.

`add_parser` adds the command to the ``rlsfilt`` parser; `run` executes it.
Errors the user can cause raise ``ValueError`` with a one-line message,
which the ``rlsfilt`` entry point prints (exit status 1).
"""

import csv
import io
import json
import numbers
import sys

import numpy as np

from ._atomic import atomic_write
from ._cli_args import (
    CSV_ENCODING,
    csv_fields_of_any_length,
    forgetting_factor,
    fraction,
    int_at_least,
    int_list,
    per_input,
    shown_cell,
    step_size,
)
from .filters.bank import MODES as BANK_MODES  # the forgetting modes RLSBank runs

__all__ = []


def add_parser(subparsers):
    """Add ``identify-many`` to the ``rlsfilt`` sub-command parsers."""
    p = subparsers.add_parser(
        "identify-many", help="identify one ARX model per channel of a long-format CSV file",
        description="Fit the ARX model y(t) + a1 y(t-1) + ... = b1 u(t-nk) + ... + e(t) "
                    "(MATLAB's [na nb nk]) to every channel of a CSV file with one row per "
                    "sample and a channel column, and write one summary row per channel "
                    "(parameters, standard errors, fit percentages, residual tests).")
    p.add_argument("file", metavar="FILE.csv", help="CSV file with a header row")
    p.add_argument("--channel-column", "-c", required=True, metavar="COL",
                   help="column holding the channel label of each row")
    p.add_argument("--input", "-u", action="append", required=True, metavar="COL",
                   dest="inputs", help="input column (repeat for several inputs)")
    p.add_argument("--output", "-y", required=True, metavar="COL", help="output column")
    p.add_argument("--na", type=int_at_least(0), default=2,
                   help="number of poles, A(q) order (default: 2)")
    p.add_argument("--nb", type=int_list(1), default=[2], metavar="NB[,NB...]",
                   help="number of B coefficients, one value or one per input (default: 2)")
    p.add_argument("--nk", type=int_list(0), default=[1], metavar="NK[,NK...]",
                   help="input delay in samples, one value or one per input (default: 1)")
    p.add_argument("--method", choices=("ls", "rls", "nlms", "lms"), default="ls",
                   help="batch least squares, recursive least squares, or the gradient methods "
                        "(nlms: normalized least mean squares, lms: least mean squares; one "
                        "GradientBank per group of channels) (default: ls)")
    p.add_argument("--mu", type=step_size, default=None,
                   help="step size for --method nlms or lms (default: the filter's, 0.01)")
    p.add_argument("--lam", type=forgetting_factor, default=None,
                   help="forgetting factor in (0, 1] for --method rls (default: 1)")
    p.add_argument("--forgetting", choices=BANK_MODES, default=None,
                   help="forgetting scheme for --method rls (default: exponential)")
    p.add_argument("--max-lag", type=int_at_least(1), default=None, metavar="M",
                   help="largest lag of the residual tests (default: auto, as fit_many: "
                        "min(25, N/4), halved on a short record)")
    p.add_argument("--alpha", type=fraction, default=0.01,
                   help="significance level of the residual tests (default: 0.01)")
    p.add_argument("--no-residual-tests", action="store_true",
                   help="skip the whiteness and independence tests (much faster)")
    p.add_argument("--on-error", choices=("raise", "nan"), default="raise",
                   help="a channel that cannot be fitted stops the command (raise, the "
                        "default) or gets empty numbers and an error column (nan)")
    p.add_argument("--format", choices=("csv", "json"), default="csv",
                   help="output format (default: csv)")
    p.add_argument("-o", "--out", metavar="FILE", default=None,
                   help="write the summary to FILE (default: standard output); CSV text "
                        "cells starting with = + - @ tab, CR or ' get a leading ' (no "
                        "spreadsheet formulas)")
    p.add_argument("--delimiter", default=None, metavar="CHAR",
                   help="field separator (default: detected among , ; tab)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    p.set_defaults(run=run)
    return p


def run(args):
    """Execute ``identify-many``; returns the exit status (0)."""
    import pandas as pd

    from .models import ARX
    from .models.fleet import _summary_long

    if args.output in args.inputs:
        raise ValueError(f"column '{args.output}' is given as both --input and --output")
    if args.channel_column in [*args.inputs, args.output]:
        raise ValueError(f"column '{args.channel_column}' is the channel column; it cannot "
                         "be an input or the output")
    if args.method != "rls" and (args.lam is not None or args.forgetting is not None):
        raise ValueError(f"--{'lam' if args.lam is not None else 'forgetting'} needs "
                         "--method rls")
    if args.mu is not None and args.method not in ("nlms", "lms"):
        raise ValueError("--mu needs --method nlms or lms")
    n_in = len(args.inputs)
    nb, nk = per_input(args.nb, n_in, "--nb"), per_input(args.nk, n_in, "--nk")
    columns = [args.channel_column, *args.inputs, args.output]
    frame = _read_frame(args.file, args.delimiter, columns, args.channel_column)
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"column '{missing[0]}' is not in '{args.file}'")
    empty = (frame[args.channel_column] == "").to_numpy()
    if empty.any():
        raise ValueError(f"column '{args.channel_column}', data row {int(np.argmax(empty)) + 1} "
                         f"of '{args.file}' has no channel label")
    for col in [*args.inputs, args.output]:
        values = pd.to_numeric(frame[col], errors="coerce")
        bad = values.isna() & frame[col].notna()
        if bad.any():
            row = int(np.argmax(bad.to_numpy()))
            raise ValueError(f"column '{col}', data row {row + 1} of '{args.file}' is not a "
                             f"number: {shown_cell(str(frame[col].iloc[row]))}")
        frame[col] = values
    options = {"max_lag": "auto" if args.max_lag is None else args.max_lag, "alpha": args.alpha,
               "residual_tests": not args.no_residual_tests, "on_error": args.on_error,
               "progress": not args.quiet and sys.stderr.isatty()}
    if args.method == "rls":
        if args.lam is not None:
            options["lam"] = args.lam
        if args.forgetting is not None:
            options["forgetting"] = args.forgetting
    if args.mu is not None:
        options["mu"] = args.mu
    model = ARX(args.na, nb[0] if n_in == 1 else nb, nk[0] if n_in == 1 else nk)
    table = _summary_long(model, frame, args.channel_column, args.inputs, args.output,
                          args.method, **options)
    if table["error"].isna().all():
        table = table.drop(columns="error")
    else:
        failed = int(table["error"].notna().sum())
        print(f"rlsfilt: warning: {failed} of {len(table)} channel(s) could not be fitted "
              "(see the error column)", file=sys.stderr)
    text = _render(table, args.format)
    if args.out is None:
        sys.stdout.write(text)
    else:
        with atomic_write(args.out, newline="") as fh:
            fh.write(text)
    return 0


#: First characters that make a spreadsheet read a cell as a formula (OWASP), and the quote
#: that marks an escaped cell (so that a label starting with ' round-trips too)
FORMULA_START = ("=", "+", "-", "@", "\t", "\r", "'")


def escape_cell(text):
    """A text cell as a spreadsheet shows it verbatim: a leading ``'`` before a text that
    starts with one of `FORMULA_START`."""
    return "'" + text if text.startswith(FORMULA_START) else text


def unescape_cell(text):
    """The text of a cell written by `escape_cell` (one leading ``'`` removed)."""
    return text[1:] if text.startswith("'") else text


def _cell(value):
    """A value as written: text escaped, numbers as Python writes them, NaN/None empty."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None:
        return ""
    if isinstance(value, str):
        return escape_cell(value)
    if isinstance(value, float) and not np.isfinite(value):
        return "" if np.isnan(value) else repr(value)
    if isinstance(value, (bool, numbers.Number)):
        return str(value)
    return escape_cell(str(value))


def _csv_text(table):
    """The summary as CSV: the csv module's minimal quoting with CRLF line ends (so a CR
    or LF inside a label is quoted and reads back), text cells escaped."""
    buf = io.StringIO(newline="")
    writer = csv.writer(buf, quoting=csv.QUOTE_MINIMAL, lineterminator="\r\n")
    writer.writerow([_cell(table.index.name or "")] + [_cell(c) for c in table.columns])
    for label, row in zip(table.index, table.itertuples(index=False, name=None)):
        writer.writerow([_cell(label)] + [_cell(v) for v in row])
    return buf.getvalue()


#: pandas' default missing-value markers (``pandas.read_csv``, ``na_values``), kept for the
#: data columns when the label column is read without them
_PANDAS_NA_MARKERS = ["", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan",
                      "1.#IND", "1.#QNAN", "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a",
                      "nan", "null"]


def _read_frame(path, delimiter, columns, channel):
    """`columns` of the CSV file `path` as a frame, the channel labels as text.

    Read as `rlsfilt identify` reads (`rlsfilt.cli._read_csv`): UTF-8 with or
    without a byte order mark, fields of any length (a long cell reaches the
    checks that name its row and column); a file that is no CSV is one line
    naming it.
    """
    import pandas as pd

    try:
        with csv_fields_of_any_length():
            return pd.read_csv(path, sep=delimiter, engine="python" if delimiter is None
                               else "c", usecols=lambda c: c in columns, encoding=CSV_ENCODING,
                               **_label_options(channel, columns))
    except UnicodeDecodeError:
        raise ValueError(f"'{path}' is not a UTF-8 text file") from None
    except pd.errors.ParserError as exc:
        raise ValueError(f"'{path}' cannot be read as CSV: "
                         f"{str(exc).strip().splitlines()[0]}") from None


def _label_options(channel, columns):
    """`pandas.read_csv` options that read the channel labels as the text they are.

    With type inference "01" and "1" (or "1e3" and "1000") were one number,
    so two plants' records were concatenated and fitted as one channel; and
    "NA", "None" or "null" were a missing label. The label column is read as
    strings with no missing-value markers; the data columns keep pandas'
    default markers (an "NA" sample is a missing sample there).
    """
    markers = _PANDAS_NA_MARKERS
    return {"dtype": {channel: str}, "keep_default_na": False,
            "na_values": {c: markers for c in columns if c != channel}}


def _render(table, fmt):
    if fmt == "csv":
        return _csv_text(table)
    records = []
    for label, row in table.iterrows():
        rec = {"channel": _plain(label)}
        rec.update({key: _plain(value) for key, value in row.items()})
        records.append(rec)
    return json.dumps(records, indent=1) + "\n"


def _plain(value):
    """A JSON value: NaN becomes null, NumPy scalars Python ones."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
