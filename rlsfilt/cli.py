"""The ``rlsfilt`` command line (also ``python -m rlsfilt``).

Two commands:

``rlsfilt demo``
    Simulate a known plant, identify it recursively (the lecture notes'
    batch start followed by RLS updates) and in batch, validate the model
    and compare it with the true plant through python-control.
``rlsfilt identify FILE.csv --input U --output Y``
    Identify an ARX model from a CSV file with a header row and print the
    same report, or a JSON result with ``--json``.

Every failure the user can cause (a missing file, an unknown column, a
non-numeric cell, too few rows for the orders, an invalid option) is one
line on stderr and a non-zero exit status, never a traceback.

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

import numpy as np

from . import __version__
from .datasets import PLANTS
from .models import ARX

__all__ = ["main"]

EXIT_OK = 0
EXIT_ERROR = 1   # the command could not do its work (bad file, bad data)
EXIT_USAGE = 2   # the command line itself is wrong (argparse's convention)

_MAX_LAG = 20            # lags shown by the residual tests
_CONFIDENCE_Z = 2.5758   # two-sided 99 % normal quantile, as MATLAB's resid
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


# ----------------------------------------------------------------------
# the command line
# ----------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and a pointer to --help."""

    def error(self, message):
        print(f"{self.prog}: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def _positive_int(text):
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1; got {value}")
    return value


def _nonnegative_int(text):
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0; got {value}")
    return value


def _int(text):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer; got '{text}'") from None


def _int_list(minimum):
    def parse(text):
        parts = [p.strip() for p in text.split(",")]
        values = []
        for p in parts:
            v = _int(p)
            if v < minimum:
                raise argparse.ArgumentTypeError(f"must be >= {minimum}; got {v}")
            values.append(v)
        return values
    return parse


def _lam(text):
    value = _float(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be in (0, 1]; got {text}")
    return value


def _positive_float(text):
    value = _float(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be a positive number; got {text}")
    return value


def _nonnegative_float(text):
    value = _float(text)
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"must be a non-negative number; got {text}")
    return value


def _float(text):
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got '{text}'") from None


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
    ident.add_argument("--nk", type=_int_list(0), default=[1], metavar="NK[,NK...]",
                       help="input delay in samples, one value or one per input (default: 1)")
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
                       help="choose na and nb by BIC over 1..--max-order (nk as given)")
    ident.add_argument("--max-order", type=_positive_int, default=4, metavar="N",
                       help="largest na and nb tried by --select-order (default: 4)")
    ident.add_argument("--delimiter", default=None, metavar="CHAR",
                       help="field separator (default: detected among , ; tab)")
    ident.add_argument("--save-params", metavar="FILE.json", default=None,
                       help="also write the JSON result to this file")
    _add_output_options(ident)
    ident.set_defaults(run=_run_identify)
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
    data = read_csv(args.file, columns, delimiter=args.delimiter, progress=progress)
    progress.done()
    u = np.column_stack([data[c] for c in args.inputs])
    y = data[args.output]
    dt = args.dt if args.dt is not None else 1.0
    if args.time is not None:
        dt = _sample_time(data[args.time], args.time)
    n_in = u.shape[1]
    nb = _per_input(args.nb, n_in, "--nb")
    nk = _per_input(args.nk, n_in, "--nk")
    na = args.na
    selection = None
    if args.select_order:
        na, nb, selection = _select_order(y, u, nk, args.max_order, progress)
        progress.done()
    _check_rows(len(y), na, nb, nk, args.file)
    if args.forgetting != "exponential" and args.method != "rls":
        raise CLIError(f"--forgetting {args.forgetting} needs --method rls")
    if args.forgetting == "constant_trace" and args.lam == 1.0:
        raise CLIError("--forgetting constant_trace needs --lam < 1 (it holds trace(P) at "
                       "n_params * (1 - lam))")
    fit = _identify(y, u, na, nb, nk, method=args.method, lam=args.lam, dt=dt,
                    forgetting=args.forgetting, progress=progress)
    fit.update(inputs=list(args.inputs), output=args.output, source=args.file,
               forgetting=args.forgetting if args.method == "rls" else None,
               order_selection=selection)
    result = _result_dict(fit)
    if args.save_params:
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


def _run_demo(args):
    from .datasets import PLANTS

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
    plant = ds.plant_after if tracking else ds.plant
    fit.update(inputs=["u"], output="y", source=f"demo plant '{ds.name}'",
               forgetting="exponential", order_selection=None,
               theta_true=np.asarray(theta_true, dtype=float), theta_batch=batch["theta"],
               theta_true_history=ds.theta_true, truth_label="true at the end" if tracking
               else "true")
    fit["plant"] = _compare_with_plant(fit["model"], plant, ds.n_samples)
    result = _result_dict(fit)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"rlsfilt {__version__} demo: {ds.description}")
        print(f"  {ds.n_samples} samples, sample time {ds.dt:g} s, {ds.noise} noise of std "
              f"{ds.noise_std:g}, seed {args.seed}")
        print("  identified recursively (batch start, then one RLS update per sample) and by "
              "batch least squares\n")
        print(_report(fit))
    if args.plot:
        _plot(fit, args.plot)
        if not args.json:
            print(f"\nfigure saved to {args.plot}")
    return EXIT_OK


# ----------------------------------------------------------------------
# reading data
# ----------------------------------------------------------------------
def read_csv(path, columns, delimiter=None, progress=None):
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
# numerics (the ARX regression, fits and residual tests)
# ----------------------------------------------------------------------
def _max_lag(na, nb, nk):
    return max([na] + [k + b - 1 for b, k in zip(nb, nk)])


def _regressors(y, u, na, nb, nk, start=None):
    """Rows ``[-y(t-1) .. -y(t-na), u_i(t-nk_i) .. u_i(t-nk_i-nb_i+1) ..]`` for t >= start."""
    lag = _max_lag(na, nb, nk)
    start = lag if start is None else start
    t = np.arange(start, len(y))
    cols = [-y[t - i] for i in range(1, na + 1)]
    for j in range(u.shape[1]):
        cols += [u[t - nk[j] - i, j] for i in range(nb[j])]
    return np.column_stack(cols), y[t]


def _identify(y, u, na, nb, nk, method="ls", lam=1.0, dt=1.0, forgetting="exponential",
              progress=None):
    """Fit ``ARX(na, nb, nk)``; return a dict of everything the report shows."""
    U = u if u.shape[1] > 1 else u[:, 0]
    model = ARX(na=na, nb=list(nb) if len(nb) > 1 else nb[0],
                nk=list(nk) if len(nk) > 1 else nk[0], dt=dt)
    kwargs = {"lam": lam} if method == "rls" else {}
    task = (f"recursive least squares over {len(y)} samples" if method == "rls"
            else f"least squares on {len(y)} samples")
    with (progress or _Progress(False)).task(task):
        model.fit(U, y, method=method, **kwargs)
        Phi, target = model.regressors(U, y)
        if method == "rls" and forgetting != "exponential":
            est = _refit_with_forgetting(model, Phi, target, lam, forgetting)
        else:
            est = dict(model=model, theta=np.asarray(model.theta_, dtype=float),
                       theta_std=np.asarray(model.std_errors_, dtype=float),
                       sigma2=float(model.noise_variance_),
                       history=getattr(model, "theta_history_", None),
                       recursive=getattr(model, "recursive_residuals_", None),
                       k0=getattr(model, "k0_", None))
    model = est["model"]
    lag = len(y) - len(Phi)
    a = np.atleast_1d(model.a_)
    b = list(model.b_) if isinstance(model.b_, list) else [model.b_]
    y_sim = np.asarray(model.simulate(U), dtype=float)
    y_pred = np.full(len(y), np.nan)
    theta_std, sigma2 = est["theta_std"], est["sigma2"]
    if method == "rls" and (lam < 1.0 or forgetting != "exponential"):
        # With forgetting the final estimate describes the end of the record only; judge
        # it by the recursive one-step residuals y(t) - phi(t) theta(t-1), the errors RLS
        # actually made, and scale the covariance by their variance.
        rows = np.flatnonzero(~np.isnan(est["recursive"]))
        resid = est["recursive"][rows]
        y_pred[lag + rows] = y[lag + rows] - resid
        old, sigma2 = sigma2, float(resid @ resid / len(resid))
        theta_std = theta_std * math.sqrt(sigma2 / old) if old > 0 else theta_std
        u_rows = u[lag + rows]
        residual_kind = "recursive"
    else:
        y_pred[lag:] = Phi @ est["theta"]
        resid = target - Phi @ est["theta"]
        u_rows = u[lag:]
        residual_kind = "final"
    history, k0 = est["history"], est["k0"]
    used = ~np.isnan(y_pred)
    return dict(
        model=model, na=na, nb=list(nb), nk=list(nk), method=method, lam=lam, dt=dt,
        theta=est["theta"], theta_std=theta_std,
        a=a, b=b, noise_variance=sigma2, n_samples=len(y),
        n_used=len(Phi), y=y, u=u, y_sim=y_sim, y_pred=y_pred, residuals=resid,
        residual_kind=residual_kind, fit_percent=_fit_percent(y, y_sim),
        fit_percent_prediction=_fit_percent(y[used], y_pred[used]),
        tests=_residual_tests(resid, u_rows), history=history, k0=k0)


def _refit_with_forgetting(model, Phi, target, lam, forgetting):
    """The recursive fit of `model` repeated with a forgetting mode other than exponential.

    Same batch start (``model.k0_`` rows), then ``RecursiveLeastSquares`` with
    ``forgetting=`` over the remaining rows. Returns the quantities
    `_identify` reports, with a coefficient-only ``ARX`` for simulation and
    transfer functions.
    """
    from .filters import RecursiveLeastSquares

    rows, n = Phi.shape
    k0 = model.k0_
    rls = RecursiveLeastSquares(n, lam=lam, forgetting=forgetting)
    rls.initialize(target[:k0], Phi[:k0])
    history = np.full((rows, n), np.nan)
    history[k0 - 1] = rls.x[:, 0]
    if k0 < rows:
        means = rls.batch_filter(target[k0:], Phi[k0:], store_covariances=False)[0]
        history[k0:] = means[:, :, 0]
    theta = rls.x[:, 0].copy()
    recursive = np.full(rows, np.nan)
    recursive[k0:] = target[k0:] - np.einsum("ij,ij->i", Phi[k0:], history[k0 - 1:-1])
    resid = target - Phi @ theta
    sigma2 = float(resid @ resid / (rows - n)) if rows > n else float("nan")
    na = model.structure_.na
    nb = list(model.structure_.nb)
    bs = np.split(theta[na:], np.cumsum(nb)[:-1])
    nk = list(model.structure_.nk)
    coef = ARX.from_polynomials(theta[:na], bs if len(bs) > 1 else bs[0],
                                nk=nk if len(nk) > 1 else nk[0], dt=model.dt,
                                noise_variance=sigma2)
    std = np.sqrt(np.maximum(np.diag(rls.P) / rls.R, 0.0) * sigma2)
    return dict(model=coef, theta=theta, theta_std=std, sigma2=sigma2, history=history,
                recursive=recursive, k0=k0)


def _fit_percent(y, yhat):
    """NRMSE fit ``100 (1 - ||y - yhat|| / ||y - mean(y)||)``, MATLAB's ``compare``."""
    ref = np.linalg.norm(y - np.mean(y))
    if ref == 0.0 or not np.all(np.isfinite(yhat)):
        return float("nan")
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / ref))


def _xcorr(a, b, lags):
    """Normalized cross-correlation ``r_ab(k) = sum a(t) b(t-k) / (N sd_a sd_b)``."""
    a = a - a.mean()
    b = b - b.mean()
    scale = len(a) * a.std() * b.std()
    if scale == 0.0:
        return np.zeros(len(lags))
    return np.array([(a[k:] @ b[:len(b) - k] if k >= 0 else a[:k] @ b[-k:]) / scale
                     for k in lags])


def _residual_tests(e, u):
    """Whiteness (autocorrelation, Ljung-Box) and input independence of the residuals."""
    from scipy.stats import chi2

    N = len(e)
    L = max(1, min(_MAX_LAG, N // 4))
    lags = np.arange(1, L + 1)
    r = _xcorr(e, e, lags)
    bound = _CONFIDENCE_Z / math.sqrt(N)
    q = float(N * (N + 2) * np.sum(r**2 / (N - lags)))
    xl = np.arange(0, L + 1)
    cross = [_xcorr(e, u[:, j], xl) for j in range(u.shape[1])]
    return dict(
        lags=lags, autocorr=r, bound=bound, ljung_box=q, ljung_box_lags=int(L),
        ljung_box_pvalue=float(chi2.sf(q, L)),
        white=bool(np.all(np.abs(r) <= bound)),
        cross_lags=xl, crosscorr=cross,
        independent=bool(all(np.all(np.abs(c) <= bound) for c in cross)))


def _select_order(y, u, nk, max_order, progress):
    """Choose ``na`` and a common ``nb`` by BIC on one common estimation sample."""
    n_in = u.shape[1]
    start = max(max_order, max(k + max_order - 1 for k in nk))
    if len(y) - start <= max_order * (1 + n_in) + 1:
        raise CLIError(f"too few rows for --select-order up to order {max_order}: need more "
                       f"than {start + max_order * (1 + n_in) + 1}; got {len(y)}")
    rows = []
    for na in range(0, max_order + 1):
        for nb in range(1, max_order + 1):
            Phi, z = _regressors(y, u, na, [nb] * n_in, nk, start=start)
            theta = np.linalg.lstsq(Phi, z, rcond=None)[0]
            N, d = Phi.shape
            v = float(np.sum((z - Phi @ theta) ** 2) / N)
            rows.append(dict(na=na, nb=nb, bic=N * math.log(v) + d * math.log(N), loss=v))
            if progress is not None:
                progress.show(f"order selection: na={na}, nb={nb}")
    best = min(rows, key=lambda r: r["bic"])
    return best["na"], [best["nb"]] * n_in, dict(criterion="BIC", max_order=max_order,
                                                   candidates=rows)


def _compare_with_plant(model, plant, n_samples):
    """Poles, DC gain, frequency and step responses of the model beside the true plant."""
    import control

    dt = float(plant.dt)
    est = model.to_tf()
    w = np.logspace(math.log10(math.pi / dt) - 3, math.log10(math.pi / dt), 300)
    g_true = np.ravel(plant(np.exp(1j * w * dt)))
    g_model = np.ravel(est(np.exp(1j * w * dt)))
    n = min(400, n_samples)
    T = np.arange(n) * dt
    step_true = np.ravel(control.step_response(plant, T).outputs)
    step_model = np.ravel(control.step_response(est, T).outputs)
    scale = max(float(np.max(np.abs(step_true))), np.finfo(float).tiny)
    return dict(
        poles_true=np.sort_complex(plant.poles()), poles_model=np.sort_complex(est.poles()),
        dc_gain_true=float(np.real(plant.dcgain())), dc_gain_model=float(np.real(est.dcgain())),
        freq=w, mag_true=np.abs(g_true), mag_model=np.abs(g_model),
        max_mag_error_db=float(np.max(np.abs(20 * np.log10(np.abs(g_model) / np.abs(g_true))))),
        T=T, step_true=step_true, step_model=step_model,
        step_error=float(np.max(np.abs(step_model - step_true)) / scale))


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
    """The JSON result (plain lists and floats)."""
    tests = fit["tests"]
    out = dict(
        rlsfilt_version=__version__, source=fit["source"], inputs=fit["inputs"],
        output=fit["output"], dt=fit["dt"], method=fit["method"], lam=fit["lam"],
        forgetting=fit["forgetting"], na=fit["na"], nb=fit["nb"], nk=fit["nk"],
        a=fit["a"].tolist(), b=[bj.tolist() for bj in fit["b"]],
        theta_names=_param_names(fit), theta=fit["theta"].tolist(),
        theta_std=fit["theta_std"].tolist(), noise_variance=fit["noise_variance"],
        fit_percent=fit["fit_percent"], fit_percent_prediction=fit["fit_percent_prediction"],
        n_samples=fit["n_samples"], n_used=fit["n_used"],
        residual_tests=dict(
            autocorr_max=float(np.max(np.abs(tests["autocorr"]))),
            crosscorr_max=[float(np.max(np.abs(c))) for c in tests["crosscorr"]],
            bound_99=tests["bound"], white=tests["white"], independent=tests["independent"],
            ljung_box=tests["ljung_box"], ljung_box_lags=tests["ljung_box_lags"],
            ljung_box_pvalue=tests["ljung_box_pvalue"]),
        transfer_functions=[_tf_dict(fit["a"], bj, k, fit["dt"])
                            for bj, k in zip(fit["b"], fit["nk"])],
    )
    if fit.get("order_selection"):
        sel = fit["order_selection"]
        out["order_selection"] = dict(criterion=sel["criterion"], max_order=sel["max_order"],
                                      candidates=sel["candidates"])
    if "theta_true" in fit:
        out["theta_true"] = fit["theta_true"].tolist()
        out["theta_batch"] = fit["theta_batch"].tolist()
    if "plant" in fit:
        p = fit["plant"]
        out["plant_comparison"] = dict(
            poles_true=[[z.real, z.imag] for z in p["poles_true"]],
            poles_model=[[z.real, z.imag] for z in p["poles_model"]],
            dc_gain_true=p["dc_gain_true"], dc_gain_model=p["dc_gain_model"],
            max_mag_error_db=p["max_mag_error_db"], step_error=p["step_error"])
    return out


def _tf_dict(a, b, nk, dt):
    num = np.concatenate([np.zeros(nk), b])
    den = np.concatenate([[1.0], a])
    n = max(len(num), len(den))
    return dict(num=np.pad(num, (0, n - len(num))).tolist(),
                den=np.pad(den, (0, n - len(den))).tolist(), dt=dt,
                variable="z")


def _write_json(path, result):
    try:
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
            fh.write("\n")
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None


def _fmt(x, width=10):
    return f"{x:{width}.4g}" if math.isfinite(x) else f"{'nan':>{width}}"


def _report(fit):
    """The text report: model, estimates with standard errors, fit, residual tests."""
    lines = []
    method = ("batch least squares (QR)" if fit["method"] == "ls"
              else f"recursive least squares, batch start, lam = {fit['lam']:g}")
    if fit["method"] == "rls" and fit.get("forgetting") not in (None, "exponential"):
        method += f", {fit['forgetting']} forgetting"
    ins = ", ".join(fit["inputs"])
    lines.append(f"ARX model  na={fit['na']}  nb={_fmt_list(fit['nb'])}  "
                 f"nk={_fmt_list(fit['nk'])}   ({fit['source']})")
    lines.append(f"  output {fit['output']}, input {ins}, sample time {fit['dt']:g} s")
    lines.append(f"  {method}; {fit['n_used']} of {fit['n_samples']} samples in the regression")
    if fit.get("k0"):
        lines.append(f"  batch start on the first {fit['k0']} regressor rows, then one update "
                     "per sample")
    if fit.get("order_selection"):
        sel = fit["order_selection"]
        lines.append(f"  orders chosen by {sel['criterion']} over na in 0..{sel['max_order']}, "
                     f"nb in 1..{sel['max_order']}")
    lines.append("  y(t) + a1 y(t-1) + ... = b1 u(t-nk) + ... + e(t)")
    lines.append("")
    names = _param_names(fit)
    has_true = "theta_true" in fit
    head = f"  {'param':<10}{'estimate':>12}{'std err':>11}{'t':>9}"
    if has_true:
        label = fit.get("truth_label", "true")
        head += f"{label:>{max(11, len(label) + 2)}}{'batch LS':>12}"
    lines.append(head)
    lines.append("  " + "-" * (len(head) - 2))
    for i, name in enumerate(names):
        est, sd = fit["theta"][i], fit["theta_std"][i]
        tval = est / sd if sd > 0 else float("inf")
        row = f"  {name:<10}{est:12.6g}{sd:11.2e}{tval:9.1f}"
        if has_true:
            width = max(11, len(label) + 2)
            row += f"{fit['theta_true'][i]:{width}.5g}{fit['theta_batch'][i]:12.6g}"
        lines.append(row)
    lines.append("")
    lines.append(f"  noise variance      {fit['noise_variance']:.4g}")
    lines.append(f"  fit (simulation)    {fit['fit_percent']:.2f} %")
    lines.append(f"  fit (1-step pred.)  {fit['fit_percent_prediction']:.2f} %")
    t = fit["tests"]
    lines.append("")
    kind = ("recursive one-step residuals y(t) - phi(t) theta(t-1)"
            if fit.get("residual_kind") == "recursive" else "residuals of the final model")
    lines.append(f"  residual tests on the {kind}")
    lines.append(f"    99 % bound {t['bound']:.3f}, lags 1..{t['lags'][-1]}")
    ok = "pass" if t["white"] else "FAIL"
    lines.append(f"    whiteness     max |r_ee(k)| = {np.max(np.abs(t['autocorr'])):.3f}   "
                 f"Ljung-Box Q = {t['ljung_box']:.1f}, p = {t['ljung_box_pvalue']:.3f}   {ok}")
    for col, c in zip(fit["inputs"], t["crosscorr"]):
        ok = "pass" if np.all(np.abs(c) <= t["bound"]) else "FAIL"
        lines.append(f"    independence  max |r_e{col}(k)| = {np.max(np.abs(c)):.3f} "
                     f"(lags 0..{t['cross_lags'][-1]})   {ok}")
    if "plant" in fit:
        p = fit["plant"]
        lines.append("")
        lines.append("  comparison with the true plant (python-control)")
        lines.append(f"    poles true    {_fmt_poles(p['poles_true'])}")
        lines.append(f"    poles model   {_fmt_poles(p['poles_model'])}")
        lines.append(f"    DC gain       true {p['dc_gain_true']:.4g}   "
                     f"model {p['dc_gain_model']:.4g}")
        lines.append(f"    max Bode magnitude error {p['max_mag_error_db']:.2f} dB up to the "
                     f"Nyquist frequency")
        lines.append(f"    max step-response error {100 * p['step_error']:.2f} % of the peak")
        gap = float(np.max(np.abs(fit["theta"] - fit["theta_batch"])))
        if fit["lam"] == 1.0:
            lines.append(f"    max |RLS - batch LS| = {gap:.1e}  (recursive = batch, as the "
                         "notes promise)")
        else:
            lines.append(f"    RLS with forgetting (lam = {fit['lam']:g}) tracks the plant at the "
                         "end; batch LS averages over the whole record")
    return "\n".join(lines)


def _fmt_poles(poles):
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

    dt = fit["dt"]
    t = np.arange(fit["n_samples"]) * dt
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), layout="constrained")
    ax = axes[0, 0]
    ax.plot(t, fit["y"], lw=0.8, label=f"measured {fit['output']}")
    ax.plot(t, fit["y_sim"], lw=0.8, label=f"simulated, fit {fit['fit_percent']:.1f} %")
    ax.set(xlabel="time t [s]", ylabel="y(t)", title="Output")
    ax.legend(loc="upper right", fontsize="small")
    ax = axes[0, 1]
    tests = fit["tests"]
    ax.stem(tests["lags"], tests["autocorr"], basefmt=" ")
    ax.axhline(tests["bound"], color="r", ls="--", lw=0.8)
    ax.axhline(-tests["bound"], color="r", ls="--", lw=0.8, label="99 % bound")
    ax.set(xlabel="lag k", ylabel=r"$r_{ee}(k)$", title="Residual autocorrelation")
    ax.legend(loc="upper right", fontsize="small")
    ax = axes[1, 0]
    if fit["history"] is not None:
        t_rows = t[-fit["n_used"]:]
        truth = fit.get("theta_true_history")
        for i, name in enumerate(_param_names(fit)):
            line, = ax.plot(t_rows, fit["history"][:, i], lw=0.8, label=name)
            if truth is not None:
                ax.plot(t, truth[:, i], color=line.get_color(), ls=":", lw=0.8)
            elif "theta_true" in fit:
                ax.axhline(fit["theta_true"][i], color=line.get_color(), ls=":", lw=0.8)
        ax.set(title="RLS parameter estimates" + (" (dotted: true)" if "theta_true" in fit
                                                 else ""))
    else:
        names = _param_names(fit)
        ax.errorbar(np.arange(len(names)), fit["theta"], yerr=2 * fit["theta_std"], fmt="o")
        ax.set_xticks(np.arange(len(names)), names)
        ax.set(title="Estimates with 2 std errors")
    ax.set(xlabel="time t [s]" if fit["history"] is not None else "parameter",
           ylabel=r"$\hat\theta$")
    if fit["history"] is not None:
        ax.legend(loc="upper right", fontsize="small", ncol=2)
    ax = axes[1, 1]
    if "plant" in fit:
        p = fit["plant"]
        ax.loglog(p["freq"], p["mag_true"], label="true plant")
        ax.loglog(p["freq"], p["mag_model"], "--", label="identified")
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
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None
    finally:
        plt.close(fig)
    return fig


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
