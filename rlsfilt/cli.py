"""The ``rlsfilt`` command line (also ``python -m rlsfilt``).

Two commands:

``rlsfilt demo``
    Simulate a known plant, identify it recursively (the lecture notes'
    batch start followed by RLS updates) and in batch, validate the model
    and compare it with the true plant through python-control.
``rlsfilt identify FILE.csv --input U --output Y``
    Identify an ARX model from a CSV file with a header row and print the
    same report, or a JSON result with ``--json``.

The command line is a thin layer over the library: `rlsfilt.ARX` fits,
`rlsfilt.validate` validates (fit, residual tests, information criteria,
comparison with a true plant), `rlsfilt.select_order` chooses orders, and
`rlsfilt.datasets` provides the demo plants. Every failure the user can
cause (a missing file, an unknown column, a non-numeric cell, too few rows
for the orders, an invalid option) is one line on stderr and a non-zero
exit status, never a traceback. Work that takes more than a couple of
seconds shows a progress line on a terminal.

The ARX convention is MATLAB's ``[na nb nk]``::

    y(t) + a1 y(t-1) + ... + a_na y(t-na)
         = b1 u(t-nk) + ... + b_nb u(t-nk-nb+1) + e(t)

with one ``nb``, ``nk`` per input.
"""

import argparse
import contextlib
import csv
import json
import math
import os
import sys
import threading
import time
import warnings

import numpy as np

from . import __version__
from .datasets import PLANTS
from .exceptions import ForgettingSkippedWarning, NumericalWarning
from .models import ARX
from .validation import fit_percent, select_order, validate

__all__ = ["main"]

EXIT_OK = 0
EXIT_ERROR = 1   # the command could not do its work (bad file, bad data)
EXIT_USAGE = 2   # the command line itself is wrong (argparse's convention)

_PROGRESS_AFTER = 2.0    # seconds before a progress line appears
_FORGETTING_MODES = ("exponential", "directional", "constant_trace", "efra", "variable")
_DEFAULT_PLANT = "dc_motor"
_TRACKING_LAM = 0.98     # demo forgetting factor for the time-varying plant


class CLIError(Exception):
    """A user-facing failure: printed as one line, exit status 1."""


# ----------------------------------------------------------------------
# entry point
# ----------------------------------------------------------------------
def main(argv=None):
    """Run the ``rlsfilt`` command line.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name; ``sys.argv[1:]`` if omitted.

    Returns
    -------
    int
        The exit status: 0 on success, 1 when the command could not do its
        work (the reason is one line on stderr), 2 for a wrong command line.
    """
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, and usage errors
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    if args.command is None:
        parser.print_help()
        return EXIT_OK
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            if not sys.warnoptions:     # `python -W ...` keeps its own filters
                # rlsfilt's own warnings are shown (once each); other libraries' warnings
                # keep the interpreter's filters (DeprecationWarning stays hidden)
                for category in (NumericalWarning, ForgettingSkippedWarning):
                    warnings.simplefilter("default", category)
            return args.run(args)
    except CLIError as exc:
        _error(str(exc))
    except (ValueError, TypeError, np.linalg.LinAlgError) as exc:
        # a library check fired on data that passed the command's own checks
        _error(str(exc).splitlines()[0])
    except BrokenPipeError:  # the reader went away (`rlsfilt demo | head`)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except OSError as exc:
        _error(f"{exc.strerror or exc}: '{exc.filename}'" if exc.filename else str(exc))
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    return EXIT_ERROR


def _error(message):
    print(f"rlsfilt: error: {message}", file=sys.stderr)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """A warning is one line on stderr, like an error (no source path, no code line)."""
    text = str(message).splitlines()[0] if str(message) else category.__name__
    print(f"rlsfilt: warning: {text}", file=sys.stderr if file is None else file)


# ----------------------------------------------------------------------
# the command line
# ----------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and a pointer to --help."""

    def error(self, message):
        print(f"{self.prog}: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def _int(text):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer; got '{text}'") from None


def _float(text):
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got '{text}'") from None


def _int_at_least(minimum):
    """An argparse type: an integer ``>= minimum``."""
    def parse(text):
        value = _int(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}; got {value}")
        return value
    return parse


def _int_list(minimum):
    """An argparse type: comma-separated integers, each ``>= minimum``."""
    check = _int_at_least(minimum)
    return lambda text: [check(part.strip()) for part in text.split(",")]


def _float_where(accept, expected):
    """An argparse type: a number for which ``accept(value)`` holds."""
    def parse(text):
        value = _float(text)
        if not accept(value):
            raise argparse.ArgumentTypeError(f"must be {expected}; got {text}")
        return value
    return parse


_positive_int = _int_at_least(1)
_nonnegative_int = _int_at_least(0)
_lam = _float_where(lambda v: 0.0 < v <= 1.0, "in (0, 1]")
_positive_float = _float_where(lambda v: math.isfinite(v) and v > 0.0, "a positive number")
_nonnegative_float = _float_where(lambda v: math.isfinite(v) and v >= 0.0,
                                  "a non-negative number")


def _png(text):
    if not text.lower().endswith((".png", ".pdf", ".svg")):
        raise argparse.ArgumentTypeError(f"must be a .png, .pdf or .svg file name; got '{text}'")
    return text


def _build_parser():
    parser = _Parser(
        prog="rlsfilt",
        description="Recursive least-squares identification of dynamic systems.",
        epilog="Run 'rlsfilt demo' for a worked example, 'rlsfilt COMMAND --help' for options.")
    parser.add_argument("--version", action="version", version=f"rlsfilt {__version__}")
    sub = parser.add_subparsers(dest="command", title="commands", parser_class=_Parser)

    demo = sub.add_parser(
        "demo", help="identify a simulated plant and compare it with the truth",
        description="Simulate a known plant, identify it recursively and in batch, validate "
                    "the model and compare it with the true plant.")
    demo.add_argument("--plant", default=_DEFAULT_PLANT, choices=sorted(PLANTS),
                      help="the simulated plant, from rlsfilt.datasets "
                           f"(default: {_DEFAULT_PLANT})")
    demo.add_argument("--samples", type=_positive_int, default=None, metavar="N",
                      help="record length (default: the dataset's)")
    demo.add_argument("--noise", type=_nonnegative_float, default=None, metavar="STD",
                      help="noise standard deviation (default: the dataset's)")
    demo.add_argument("--lam", type=_lam, default=None,
                      help=f"RLS forgetting factor (default: 1, or {_TRACKING_LAM} for "
                           "time_varying)")
    demo.add_argument("--seed", type=_nonnegative_int, default=0, help="random seed (default: 0)")
    _add_output_options(demo)
    demo.set_defaults(run=_run_demo)

    ident = sub.add_parser(
        "identify", help="identify an ARX model from a CSV file",
        description="Identify the ARX model y(t) + a1 y(t-1) + ... + a_na y(t-na) = "
                    "b1 u(t-nk) + ... + b_nb u(t-nk-nb+1) + e(t) (MATLAB's [na nb nk]) "
                    "from a CSV file with a header row.")
    ident.add_argument("file", metavar="FILE.csv", help="CSV file with a header row")
    ident.add_argument("--input", "-u", action="append", required=True, metavar="COL",
                       dest="inputs", help="input column (repeat for several inputs)")
    ident.add_argument("--output", "-y", required=True, metavar="COL", help="output column")
    ident.add_argument("--na", type=_nonnegative_int, default=2,
                       help="number of poles, A(q) order (default: 2)")
    ident.add_argument("--nb", type=_int_list(1), default=[2], metavar="NB[,NB...]",
                       help="number of B coefficients, one value or one per input (default: 2)")
    ident.add_argument("--nk", type=_int_list(0), default=None, metavar="NK[,NK...]",
                       help="input delay in samples, one value or one per input (default: 1; "
                            "searched by --select-order unless given)")
    ident.add_argument("--method", choices=("ls", "rls"), default="ls",
                       help="batch least squares or recursive least squares (default: ls)")
    ident.add_argument("--lam", type=_lam, default=1.0,
                       help="forgetting factor in (0, 1] for --method rls (default: 1)")
    ident.add_argument("--forgetting", choices=_FORGETTING_MODES, default="exponential",
                       help="forgetting scheme for --method rls (default: exponential)")
    timing = ident.add_mutually_exclusive_group()
    timing.add_argument("--dt", type=_positive_float, default=None,
                        help="sample time in seconds (default: 1, or from --time)")
    timing.add_argument("--time", metavar="COL", default=None,
                        help="time column; the sample time is its (uniform) step")
    ident.add_argument("--select-order", action="store_true",
                       help="choose na, nb (and nk unless given) by BIC, up to --max-order")
    ident.add_argument("--max-order", type=_positive_int, default=4, metavar="N",
                       help="largest na, nb and nk tried by --select-order (default: 4)")
    ident.add_argument("--delimiter", default=None, metavar="CHAR",
                       help="field separator (default: detected among , ; tab)")
    ident.add_argument("--save-params", metavar="FILE.json", default=None,
                       help="also write the JSON result to this file")
    _add_output_options(ident)
    ident.set_defaults(run=_run_identify)
    from . import _cli_fleet  # identify-many: one ARX model per channel
    _cli_fleet.add_parser(sub)
    return parser


def _add_output_options(p):
    p.add_argument("--json", action="store_true",
                   help="print a machine-readable JSON result instead of the report")
    p.add_argument("--plot", type=_png, default=None, metavar="FILE.png",
                   help="save a figure (output fit, residual tests, parameters, response)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress messages")


# ----------------------------------------------------------------------
# commands
# ----------------------------------------------------------------------
def _run_identify(args):
    progress = _Progress(enabled=not args.quiet)
    columns = list(args.inputs) + [args.output] + ([args.time] if args.time else [])
    for col in args.inputs:
        if col == args.output:
            raise CLIError(f"column '{col}' is given as both --input and --output")
    if len(set(args.inputs)) != len(args.inputs):
        dup = next(c for c in args.inputs if args.inputs.count(c) > 1)
        raise CLIError(f"column '{dup}' is given twice as --input")
    if args.lam != 1.0 and args.method != "rls":   # batch least squares has no forgetting
        raise CLIError(f"--lam {args.lam:g} needs --method rls")
    if args.forgetting != "exponential" and args.method != "rls":
        raise CLIError(f"--forgetting {args.forgetting} needs --method rls")
    if args.forgetting == "constant_trace" and args.lam == 1.0:
        raise CLIError("--forgetting constant_trace needs --lam < 1 (it holds trace(P) at "
                       "n_params * (1 - lam))")
    data = _read_csv(args.file, columns, delimiter=args.delimiter, progress=progress)
    progress.done()
    u = np.column_stack([data[c] for c in args.inputs])
    y = data[args.output]
    dt = args.dt if args.dt is not None else 1.0
    if args.time is not None:
        dt = _sample_time(data[args.time], args.time)
    n_in = u.shape[1]
    nb = _per_input(args.nb, n_in, "--nb")
    nk = _per_input(args.nk if args.nk is not None else [1], n_in, "--nk")
    na = args.na
    selection = None
    if args.select_order:
        if args.nk is not None and len(set(nk)) > 1:
            raise CLIError("--select-order uses one delay for all inputs; give one --nk value "
                           "or none (then nk = 1 .. --max-order is searched too)")
        with progress.task("order selection"):
            selection = _select_order(y, u, None if args.nk is None else nk[0], args.max_order,
                                      dt, args.file)
        na, nb, nk = selection["na"], [selection["nb"]] * n_in, [selection["nk"]] * n_in
    _check_rows(len(y), na, nb, nk, f"'{args.file}'")
    fit = _identify(y, u, na, nb, nk, method=args.method, lam=args.lam, dt=dt,
                    forgetting=args.forgetting, progress=progress)
    fit.update(inputs=list(args.inputs), output=args.output, source=args.file,
               forgetting=args.forgetting if args.method == "rls" else None,
               order_selection=selection)
    _validate_fit(fit, progress=progress)
    return _emit(fit, args)


def _run_demo(args):
    kwargs = {"rng": args.seed}
    if args.samples is not None:
        kwargs["n_samples"] = args.samples
    if args.noise is not None:
        kwargs["noise_std"] = args.noise
    ds = PLANTS[args.plant](**kwargs)
    tracking = ds.theta_true is not None
    lam = args.lam if args.lam is not None else (_TRACKING_LAM if tracking else 1.0)
    na, nb, nk = ds.na, [ds.nb], [ds.nk]
    _check_rows(len(ds.y), na, nb, nk, "the simulated record")
    progress = _Progress(enabled=not args.quiet)
    u = ds.u[:, None]
    fit = _identify(ds.y, u, na, nb, nk, method="rls", lam=lam, dt=ds.dt, progress=progress)
    batch = _identify(ds.y, u, na, nb, nk, method="ls", lam=1.0, dt=ds.dt, progress=progress)
    # a time-varying plant is compared with the plant in force at the end of the record
    theta_true = ds.theta_true[-1] if tracking else ds.theta
    fit.update(inputs=["u"], output="y", source=f"demo plant '{ds.name}'",
               forgetting="exponential", order_selection=None,
               theta_true=np.asarray(theta_true, dtype=float), theta_batch=batch["theta"],
               theta_true_history=ds.theta_true,
               truth_label="true at the end" if tracking else "true",
               preamble=[f"rlsfilt {__version__} demo: {ds.description}",
                         f"  {ds.n_samples} samples, sample time {ds.dt:g} s, {ds.noise} noise "
                         f"of std {ds.noise_std:g}, seed {args.seed}",
                         "  identified recursively (batch start, then one RLS update per "
                         "sample) and by batch least squares", ""])
    _validate_fit(fit, plant=ds.plant_after if tracking else ds.plant, progress=progress)
    return _emit(fit, args)


def _emit(fit, args):
    """Print the report or the JSON result, save the parameters and the figure."""
    result = _result_dict(fit)
    if getattr(args, "save_params", None):
        _write_json(args.save_params, result)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(_report(fit))
    if args.plot:
        _plot(fit, args.plot)
        if not args.json:
            print(f"\nfigure saved to {args.plot}")
    return EXIT_OK


# ----------------------------------------------------------------------
# reading data
# ----------------------------------------------------------------------
def _read_csv(path, columns, delimiter=None, progress=None):
    """Read numeric `columns` of a CSV file with a header row.

    Returns a dict mapping each column name to a float array. Raises
    `CLIError` with a one-line message naming the file, row and column for
    every problem a user can cause.
    """
    if not os.path.exists(path):
        raise CLIError(f"file '{path}' not found")
    if os.path.isdir(path):
        raise CLIError(f"'{path}' is a directory; expected a CSV file")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            text = fh.read()
    except UnicodeDecodeError:
        raise CLIError(f"'{path}' is not a UTF-8 text file") from None
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")), None)
    if first is None:
        raise CLIError(f"'{path}' is empty; expected a header row and data rows")
    if delimiter is None:
        delimiter = _detect_delimiter(lines[first])
    reader = csv.reader(lines[first:], delimiter=delimiter)
    header = [h.strip() for h in next(reader)]
    where = {}
    for j, name in enumerate(header):
        where.setdefault(name, j)
    missing = [c for c in columns if c not in where]
    if missing:
        shown = ", ".join(h for h in header if h) or "(none)"
        raise CLIError(f"column '{missing[0]}' not found in '{path}'; available columns: {shown}")
    for c in columns:
        if header.count(c) > 1:
            raise CLIError(f"column '{c}' appears {header.count(c)} times in the header of "
                           f"'{path}'; rename the duplicates")
    idx = [where[c] for c in columns]
    values = [[] for _ in columns]
    row = 0
    for fields in reader:
        line = first + reader.line_num
        if not fields or all(not f.strip() for f in fields):
            continue
        if fields[0].startswith("#"):
            continue
        row += 1
        if len(fields) != len(header):
            raise CLIError(f"'{path}' line {line} (data row {row}) has {len(fields)} fields; "
                           f"the header has {len(header)}")
        for k, (c, j) in enumerate(zip(columns, idx)):
            cell = fields[j].strip()
            try:
                v = float(cell)
            except ValueError:
                shown = f"'{cell}'" if cell else "an empty cell"
                raise CLIError(f"'{path}' line {line} (data row {row}), column '{c}': "
                               f"expected a number; got {shown}") from None
            if not math.isfinite(v):
                raise CLIError(f"'{path}' line {line} (data row {row}), column '{c}': "
                               f"expected a finite number; got '{cell}'")
            values[k].append(v)
        if progress is not None and row % 20000 == 0:
            progress.show(f"reading '{path}': {row} rows")
    if row == 0:
        raise CLIError(f"'{path}' has a header but no data rows")
    return {c: np.array(v, dtype=float) for c, v in zip(columns, values)}


def _detect_delimiter(header_line):
    counts = {d: header_line.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    if counts[best]:
        return best
    return "," if " " not in header_line.strip() else " "


def _sample_time(t, name):
    if len(t) < 2:
        raise CLIError(f"time column '{name}' needs at least 2 rows to give a sample time")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise CLIError(f"time column '{name}' must be strictly increasing; row {i + 2} has "
                       f"{t[i + 1]:g} after {t[i]:g}")
    dt = float(np.median(steps))
    if np.max(np.abs(steps - dt)) > 1e-6 * max(dt, abs(t[-1])):
        raise CLIError(f"time column '{name}' is not uniformly sampled: steps range from "
                       f"{steps.min():g} to {steps.max():g}; resample the data first")
    return float((t[-1] - t[0]) / (len(t) - 1))


def _per_input(values, n_in, option):
    if len(values) == 1:
        return values * n_in
    if len(values) != n_in:
        raise CLIError(f"{option} must give one value or one per input ({n_in}); "
                       f"got {len(values)} values")
    return list(values)


def _check_rows(n_rows, na, nb, nk, source):
    d = na + sum(nb)
    if d == 0:
        raise CLIError("the model has no parameters (na = 0 and no input terms)")
    lag = _max_lag(na, nb, nk)
    need = lag + d + 1
    if n_rows < need:
        orders = f"na={na}, nb={_fmt_list(nb)}, nk={_fmt_list(nk)}"
        raise CLIError(f"too few rows for the orders {orders} ({d} parameters, largest lag "
                       f"{lag}): need at least {need} data rows; {source} has {n_rows}")


def _fmt_list(v):
    return str(v[0]) if len(v) == 1 else ",".join(str(x) for x in v)


# ----------------------------------------------------------------------
# numerics: thin layers over ARX, RecursiveLeastSquares and rlsfilt.validation
# ----------------------------------------------------------------------
def _max_lag(na, nb, nk):
    return max([na] + [k + b - 1 for b, k in zip(nb, nk)])


def _identify(y, u, na, nb, nk, method="ls", lam=1.0, dt=1.0, forgetting="exponential",
              progress=None):
    """Fit ``ARX(na, nb, nk)``; return a dict with the model and its estimates."""
    U = u if u.shape[1] > 1 else u[:, 0]
    model = ARX(na=na, nb=list(nb) if len(nb) > 1 else nb[0],
                nk=list(nk) if len(nk) > 1 else nk[0], dt=dt)
    kwargs = {"lam": lam, "forgetting": forgetting} if method == "rls" else {}
    task = (f"recursive least squares over {len(y)} samples" if method == "rls"
            else f"least squares on {len(y)} samples")
    with (progress or _Progress(False)).task(task):
        model.fit(U, y, method=method, **kwargs)
    fit = dict(model=model, theta=np.asarray(model.theta_, dtype=float),
               theta_std=np.asarray(model.std_errors_, dtype=float),
               noise_variance=float(model.noise_variance_),
               history=getattr(model, "theta_history_", None),
               k0=getattr(model, "k0_", None))
    a = np.atleast_1d(model.a_)
    b = list(model.b_) if isinstance(model.b_, list) else [model.b_]
    fit.update(na=na, nb=list(nb), nk=list(nk), a=a, b=b, method=method, lam=lam, dt=dt,
               forgetting=forgetting, y=y, u=u, U=U, n_samples=len(y),
               n_used=len(y) - _max_lag(na, nb, nk))
    return fit


def _validate_fit(fit, plant=None, progress=None):
    """Validate the fitted model with :func:`rlsfilt.validation.validate`.

    Without forgetting the whole record is used. With forgetting the final
    estimate describes the end of the record only, so it is validated on the
    last three memory lengths ``3 / (1 - lam)`` samples (at least 100 rows),
    and the standard errors and noise variance are rescaled to the residual
    variance there.
    """
    y, U = fit["y"], fit["U"]
    N, lag, d = len(y), fit["n_samples"] - fit["n_used"], len(fit["theta"])
    start = 0
    if fit["method"] == "rls" and fit["lam"] < 1.0:
        memory = 1.0 / (1.0 - fit["lam"])
        length = max(int(round(3 * memory)), 100 + lag + d)
        start = max(0, N - length)
    rows = N - start - lag
    max_lag = max(1, min(25, rows // 4))
    report, skipped = None, None
    with (progress or _Progress(False)).task("validating the model"):
        while True:  # the residual tests need enough rows for their lags: shorten if not
            try:
                report = validate(fit["model"], U[start:], y[start:], plant=plant,
                                  max_lag=max_lag)
                break
            except ValueError as exc:
                if "exact fit" in str(exc):   # noise-free data: nothing left to test
                    skipped = "the residuals are zero or constant (an exact fit)"
                    break
                if "max_lag" not in str(exc):
                    raise
                if max_lag == 1:
                    skipped = f"only {rows} residuals, too few for the residual tests"
                    break
                max_lag = max(1, max_lag // 2)
    if report is None:
        ys, Us = y[start:], U[start:]
        y_sim = np.asarray(fit["model"].simulate(Us, y0=ys[:lag] if lag else None))
        fit.update(report=None, segment_start=start, validation_skipped=skipped,
                   simulation_fit=fit_percent(ys[lag:], y_sim[lag:]), y_simulated=y_sim)
        return None
    fit.update(report=report, segment_start=start, simulation_fit=report.simulation_fit,
               y_simulated=report.y_simulated)
    if start:
        v = float(report.criteria.loss)
        old = fit["noise_variance"]
        if old > 0 and math.isfinite(old):
            fit["theta_std"] = fit["theta_std"] * math.sqrt(v / old)
        fit["noise_variance"] = v
    return report


def _select_order(y, u, nk, max_order, dt, source):
    """BIC order selection with :func:`rlsfilt.validation.select_order`."""
    nks = range(1, max_order + 1) if nk is None else [nk]
    need = max_order + max(nks) + max_order * (1 + u.shape[1]) + 2
    if len(y) < need:
        raise CLIError(f"too few rows for --select-order up to order {max_order}: need at "
                       f"least {need}; {source} has {len(y)}")
    U = u if u.shape[1] > 1 else u[:, 0]
    sel = select_order(U, y, na=range(0, max_order + 1), nb=range(1, max_order + 1), nk=nks,
                       criterion="bic", dt=dt)
    na, nb, nk_best = (int(v) for v in sel.best)
    names = sel.table.dtype.names
    table = [{k: (int(r[k]) if k in ("na", "nb", "nk", "n_params") else _num(r[k]))
              for k in names} for r in sel.table]
    return dict(na=na, nb=nb, nk=nk_best, criterion="BIC", max_order=max_order,
                searched_nk=list(nks), candidates=table, summary=sel.summary())


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


# ----------------------------------------------------------------------
# output
# ----------------------------------------------------------------------
def _param_names(fit):
    names = [f"a{i}" for i in range(1, fit["na"] + 1)]
    multi = len(fit["b"]) > 1
    for col, bj in zip(fit["inputs"], fit["b"]):
        names += [f"b{i}" + (f"[{col}]" if multi else "") for i in range(1, len(bj) + 1)]
    return names


def _result_dict(fit):
    """The JSON result (plain lists, floats and None)."""
    rep = fit["report"]
    out = dict(
        rlsfilt_version=__version__, source=fit["source"], inputs=fit["inputs"],
        output=fit["output"], dt=fit["dt"], method=fit["method"], lam=fit["lam"],
        forgetting=fit["forgetting"], na=fit["na"], nb=fit["nb"], nk=fit["nk"],
        a=fit["a"].tolist(), b=[np.asarray(bj).tolist() for bj in fit["b"]],
        theta_names=_param_names(fit), theta=fit["theta"].tolist(),
        theta_std=fit["theta_std"].tolist(), noise_variance=fit["noise_variance"],
        fit_percent=_num(fit["simulation_fit"]),
        fit_percent_prediction=None if rep is None else _num(rep.prediction_fit),
        n_samples=fit["n_samples"], n_used=fit["n_used"], k0=fit["k0"],
        validation_start=fit["segment_start"],
        validation_skipped=fit.get("validation_skipped"),
        transfer_functions=[_tf_dict(fit["a"], bj, k, fit["dt"])
                            for bj, k in zip(fit["b"], fit["nk"])],
    )
    sel = fit.get("order_selection")
    if sel:
        out["order_selection"] = {k: v for k, v in sel.items() if k != "summary"}
    if "theta_true" in fit:
        out["theta_true"] = fit["theta_true"].tolist()
        out["theta_batch"] = fit["theta_batch"].tolist()
    if rep is None:
        return out
    res = rep.residuals[0]
    crit = rep.criteria
    out.update(
        residual_tests=dict(
            alpha=res.alpha, max_lag=int(res.max_lag),
            ljung_box=_num(res.q_statistic), ljung_box_df=int(res.df_white),
            ljung_box_pvalue=_num(res.pvalue_white), white=bool(res.is_white),
            independence_f=_num(res.f_statistic), independence_df=int(res.df_independent),
            independence_pvalue=_num(res.pvalue_independent),
            independent=bool(res.is_independent),
            autocorr_max=_num(np.max(np.abs(res.autocorrelation[1:]))),
            autocorr_band=_num(res.autocorrelation_band)),
        information_criteria={k: _num(v) if isinstance(v, float) else v
                              for k, v in crit.as_dict().items()},
    )
    pc = rep.plant_comparison
    if pc is not None:
        out["plant_comparison"] = dict(
            poles_true=[[z.real, z.imag] for z in np.sort_complex(np.ravel(pc.poles_plant))],
            poles_model=[[z.real, z.imag] for z in np.sort_complex(np.ravel(pc.poles_model))],
            dc_gain_true=_num(np.real(np.ravel(pc.dc_gain_plant)[0])),
            dc_gain_model=_num(np.real(np.ravel(pc.dc_gain_model)[0])),
            dc_gain_error=_num(pc.dc_gain_error), frequency_error=_num(pc.frequency_error),
            step_error=_num(pc.step_error), max_pole_distance=_num(pc.max_pole_distance))
    return out


def _tf_dict(a, b, nk, dt):
    num = np.concatenate([np.zeros(nk), b])
    den = np.concatenate([[1.0], a])
    n = max(len(num), len(den))
    return dict(num=np.pad(num, (0, n - len(num))).tolist(),
                den=np.pad(den, (0, n - len(den))).tolist(), dt=dt, variable="z")


def _write_json(path, result):
    try:
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
            fh.write("\n")
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None


def _report(fit):
    """The text report: model, estimates with standard errors, fit, residual tests, plant."""
    rep = fit["report"]
    lines = list(fit.get("preamble", []))
    method = ("batch least squares (QR)" if fit["method"] == "ls"
              else f"recursive least squares, lam = {fit['lam']:g}")
    if fit["method"] == "rls" and fit.get("forgetting") not in (None, "exponential"):
        method += f", {fit['forgetting']} forgetting"
    lines.append(f"ARX model  na={fit['na']}  nb={_fmt_list(fit['nb'])}  "
                 f"nk={_fmt_list(fit['nk'])}   ({fit['source']})")
    lines.append("  y(t) + a1 y(t-1) + ... + a_na y(t-na) = b1 u(t-nk) + ... + e(t)")
    lines.append(f"  output {fit['output']}, input {', '.join(fit['inputs'])}, "
                 f"sample time {fit['dt']:g} s")
    lines.append(f"  {method}; {fit['n_used']} of {fit['n_samples']} samples in the regression")
    if fit.get("k0"):
        lines.append(f"  batch start on the first {fit['k0']} regressor rows, then one update "
                     "per sample")
    sel = fit.get("order_selection")
    if sel:
        nk_text = ("" if len(sel["searched_nk"]) == 1
                   else f", nk in {sel['searched_nk'][0]}..{sel['searched_nk'][-1]}")
        lines.append(f"  orders chosen by {sel['criterion']} over na in 0..{sel['max_order']}, "
                     f"nb in 1..{sel['max_order']}{nk_text}")
    lines.append("")
    names = _param_names(fit)
    has_true = "theta_true" in fit
    label = fit.get("truth_label", "true")
    width = max(11, len(label) + 2)
    head = f"  {'param':<10}{'estimate':>12}{'std err':>11}{'t':>9}"
    if has_true:
        head += f"{label:>{width}}{'batch LS':>12}"
    lines.append(head)
    lines.append("  " + "-" * (len(head) - 2))
    for i, name in enumerate(names):
        est, sd = fit["theta"][i], fit["theta_std"][i]
        tval = est / sd if sd > 0 else float("inf")
        # a huge t (an exact fit, noise-free data) in exponent form keeps its column
        ttext = f"{tval:.1f}" if abs(tval) < 1e5 else f"{tval:.1e}"
        row = f"  {name:<10}{est:12.6g}{sd:11.2e}{ttext:>9}"
        if has_true:
            row += f"{fit['theta_true'][i]:{width}.5g}{fit['theta_batch'][i]:12.6g}"
        lines.append(row)
    lines.append("")
    where = ""
    if fit["segment_start"]:
        where = (f" (on the last {fit['n_samples'] - fit['segment_start']} samples, three "
                 f"memory lengths of lam = {fit['lam']:g})")
    lines.append(f"  validation{where}")
    lines.append(f"    noise variance      {fit['noise_variance']:.4g}")
    lines.append(f"    fit (simulation)    {fit['simulation_fit']:.2f} %")
    if rep is None:
        lines.append(f"    (residual tests skipped: {fit['validation_skipped']})")
        return "\n".join(lines)
    lines.append(f"    fit (1-step pred.)  {rep.prediction_fit:.2f} %")
    crit = rep.criteria
    lines.append(f"    AIC {crit.aic:.6g}   BIC {crit.bic:.6g}   FPE {crit.fpe:.4g}")
    res = rep.residuals[0]
    lines.append(f"    residual tests at alpha = {res.alpha:g}, lags 1..{res.max_lag}:")
    lines.append(f"      whiteness     Ljung-Box Q = {res.q_statistic:.2f} ({res.df_white} df), "
                 f"p = {res.pvalue_white:.3g}   {'pass' if res.is_white else 'FAIL'}")
    lines.append(f"      independence  F = {res.f_statistic:.3g} ({res.df_independent} df), "
                 f"p = {res.pvalue_independent:.3g}   "
                 f"{'pass' if res.is_independent else 'FAIL'}")
    pc = rep.plant_comparison
    if pc is not None:
        lines.append("")
        lines.append("  comparison with the true plant (python-control)")
        lines.append(f"    poles true    {_fmt_poles(np.ravel(pc.poles_plant))}")
        lines.append(f"    poles model   {_fmt_poles(np.ravel(pc.poles_model))}")
        lines.append(f"    DC gain       true {np.real(np.ravel(pc.dc_gain_plant)[0]):.4g}   "
                     f"model {np.real(np.ravel(pc.dc_gain_model)[0]):.4g}")
        lines.append(f"    relative errors: frequency response {pc.frequency_error:.2%} (max "
                     f"up to Nyquist), step response {pc.step_error:.2%}")
    if has_true:
        gap = float(np.max(np.abs(fit["theta"] - fit["theta_batch"])))
        if fit["lam"] == 1.0:
            lines.append(f"    max |RLS - batch LS| = {gap:.1e}  (after the batch start, "
                         "recursive = batch)")
        else:
            lines.append(f"    RLS with forgetting (lam = {fit['lam']:g}) tracks the plant at "
                         "the end; batch LS averages over the whole record")
    return "\n".join(lines)


def _fmt_poles(poles):
    poles = np.sort_complex(np.asarray(poles, dtype=complex))
    at_origin = int(np.sum(np.abs(poles) < 1e-12))
    out = []
    for z in poles[np.abs(poles) >= 1e-12]:
        if abs(z.imag) < 1e-12:
            out.append(f"{z.real:.4f}")
        else:
            out.append(f"{z.real:.4f}{z.imag:+.4f}j")
    if at_origin:
        out.append(f"({at_origin} at z = 0)")
    return ", ".join(out)


def _plot(fit, path):
    """Save a 2x2 figure: output fit, residual autocorrelation, parameters, response."""
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rep = fit["report"]
    start = fit["segment_start"]
    dt = fit["dt"]
    t = np.arange(fit["n_samples"]) * dt
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), layout="constrained")
    ax = axes[0, 0]
    ax.plot(t, fit["y"], lw=0.8, label=f"measured {fit['output']}")
    ax.plot(t[start:], fit["y_simulated"], lw=0.8,
            label=f"simulated, fit {fit['simulation_fit']:.1f} %")
    ax.set(xlabel="time t [s]", ylabel="y(t)", title="Output")
    ax.legend(loc="upper right", fontsize="small")
    ax = axes[0, 1]
    res = rep.residuals[0] if rep is not None else None
    if res is None:
        ax.text(0.5, 0.5, "residual tests skipped:\ntoo few samples", ha="center",
                va="center", transform=ax.transAxes)
    else:
        _plot_autocorrelation(ax, res)
    ax = axes[1, 0]
    names = _param_names(fit)
    _plot_parameters(ax, fit, t, names)
    ax = axes[1, 1]
    pc = rep.plant_comparison if rep is not None else None
    _plot_response(ax, fit, pc, dt)
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None
    finally:
        plt.close(fig)
    return fig


def _plot_autocorrelation(ax, res):
    ax.stem(res.lags[1:], res.autocorrelation[1:], basefmt=" ")
    band = res.autocorrelation_band
    ax.axhline(band, color="r", ls="--", lw=0.8)
    ax.axhline(-band, color="r", ls="--", lw=0.8, label=f"{1 - res.alpha:.0%} band")
    ax.set(xlabel="lag k", ylabel=r"$r_{ee}(k)$", title="Residual autocorrelation")
    ax.legend(loc="upper right", fontsize="small")


def _plot_parameters(ax, fit, t, names):
    if fit["history"] is not None:
        t_rows = t[-fit["n_used"]:]
        truth = fit.get("theta_true_history")
        for i, name in enumerate(names):
            line, = ax.plot(t_rows, fit["history"][:, i], lw=0.8, label=name)
            if truth is not None:
                ax.plot(t, truth[:, i], color=line.get_color(), ls=":", lw=0.8)
            elif "theta_true" in fit:
                ax.axhline(fit["theta_true"][i], color=line.get_color(), ls=":", lw=0.8)
        dotted = " (dotted: true)" if "theta_true" in fit else ""
        ax.set(title="RLS parameter estimates" + dotted, xlabel="time t [s]")
        ax.legend(loc="upper right", fontsize="small", ncol=2)
    else:
        ax.errorbar(np.arange(len(names)), fit["theta"], yerr=2 * fit["theta_std"], fmt="o")
        ax.set_xticks(np.arange(len(names)), names)
        ax.set(title="Estimates with 2 std errors", xlabel="parameter")
    ax.set(ylabel=r"$\hat\theta$")


def _plot_response(ax, fit, pc, dt):
    if pc is not None:
        ax.loglog(pc.omega, np.abs(np.ravel(pc.response_plant)), label="true plant")
        ax.loglog(pc.omega, np.abs(np.ravel(pc.response_model)), "--", label="identified")
        ax.set(xlabel=r"frequency $\omega$ [rad/s]", ylabel=r"$|G(e^{j\omega\,dt})|$",
               title="Bode magnitude")
    else:
        n = min(200, fit["n_samples"])
        T = np.arange(n) * dt
        for j, col in enumerate(fit["inputs"]):
            step = np.zeros((n, len(fit["inputs"])))
            step[:, j] = 1.0
            y_step = fit["model"].simulate(step if step.shape[1] > 1 else step[:, 0])
            ax.plot(T, y_step, label=f"from {col}")
        ax.set(xlabel="time t [s]", ylabel="y(t)", title="Step response of the model")
    ax.legend(loc="best", fontsize="small")


class _Progress:
    """One updating progress line on stderr, shown only for work that takes a while."""

    def __init__(self, enabled=True):
        self.enabled = enabled and sys.stderr.isatty()
        self.start = time.monotonic()
        self.last = 0.0
        self.shown = False

    def show(self, message):
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self.start < _PROGRESS_AFTER or now - self.last < 0.25:
            return
        self.last = now
        self.shown = True
        sys.stderr.write(f"\rrlsfilt: {message} ...\033[K")
        sys.stderr.flush()

    def done(self):
        """Erase the progress line, if one was shown."""
        if self.shown:
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()
            self.shown = False

    @contextlib.contextmanager
    def task(self, message):
        """Show ``message`` with the elapsed time while a single long call runs."""
        if not self.enabled:
            yield
            return
        stop = threading.Event()
        t0 = time.monotonic()

        def tick():
            while not stop.wait(0.25):
                elapsed = time.monotonic() - t0
                if elapsed >= _PROGRESS_AFTER:
                    self.shown = True
                    sys.stderr.write(f"\rrlsfilt: {message} ... {elapsed:.0f} s\033[K")
                    sys.stderr.flush()

        thread = threading.Thread(target=tick, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()
            self.done()
