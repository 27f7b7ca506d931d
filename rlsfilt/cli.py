"""The ``rlsfilt`` command line (also ``python -m rlsfilt``).

Two commands:

``rlsfilt demo``
    Simulate a known plant, identify it recursively (the lecture notes'
    batch start followed by RLS updates) and in batch, validate the model
    and compare it with the true plant through python-control.
``rlsfilt identify FILE.csv --input U --output Y``
    Identify an ARX model (or with ``--model armax|oe|bj`` a model of the
    prediction-error family) from a CSV file with a header row and print
    the same report, or a JSON result with ``--json``. Measured records are
    handled as such: the means are removed by default (``--detrend``) and
    the model predicts in the units of the data, several experiments can
    share a file (``--experiment-column``), the model can be validated on
    fresh data (``--validation FILE`` or ``--split 0.7``), the delay range
    of ``--select-order`` is its own (``--delay-range``, or around the
    delay ``rlsfilt.delayest`` finds) and the model can be saved
    (``--save-model``).

The command line is a thin layer over the library: it parses the options,
reads the CSV file and shows progress; `rlsfilt.ARX` fits,
`rlsfilt.validate` validates (fit, residual tests, information criteria,
comparison with a true plant), `rlsfilt.select_order` chooses orders, and
`rlsfilt.datasets` provides the demo plants. What is printed is the
library's: the text is ``ValidationReport.summary()`` (after a few lines of
context), ``--json`` prints ``json.dumps(report.to_dict())`` and ``--plot``
saves ``report.plot()``. Every failure the user can
cause (a missing file, an unknown column, a non-numeric cell, too few rows
for the orders, an invalid option) is one line on stderr and a non-zero
exit status, never a traceback; so is a lack of memory (``rlsfilt demo
--samples N`` estimates its memory before it starts, the library checks its
own before large allocations). Work that takes more than a couple of
seconds shows a progress line on a terminal. ``identify`` reads the CSV
file line by line into arrays of doubles and works in :math:`O(N)` memory:
about 170 bytes per sample for one input and output (tested below 300).

The ARX convention is MATLAB's ``[na nb nk]``::

    y(t) + a1 y(t-1) + ... + a_na y(t-na)
         = b1 u(t-nk) + ... + b_nb u(t-nk-nb+1) + e(t)

with one ``nb``, ``nk`` per input.
"""

import argparse
import array
import atexit
import contextlib
import csv
import inspect
import itertools
import json
import math
import os
import shutil
import sys
import tempfile
import threading
import time
import warnings

import numpy as np

from ._atomic import atomic_write
from ._cli_args import (
    CSV_ENCODING,
    CLIError,
    csv_fields_of_any_length,
    float_where,
    forgetting_factor,
    fraction,
    int_at_least,
    int_list,
    per_input,
    shown_cell,
)
from ._resources import check_memory
from ._version import __version__
from .data import IOData, Trend, detrend
from .datasets import PLANTS, heat_exchanger
from .exceptions import (
    ForgettingSkippedWarning,
    NumericalWarning,
    OperatingPointWarning,
    OrderSelectionWarning,
)
from .filters.forgetting import MODES
from .models import ARMAX, ARX, BJ, OE, arx_structure
from .models._family import family_structure
from .validation import delayest, select_order, validate

__all__ = ["main"]

EXIT_OK = 0
EXIT_ERROR = 1   # the command could not do its work (bad file, bad data)
EXIT_USAGE = 2   # the command line itself is wrong (argparse's convention)

_PROGRESS_AFTER = 2.0    # seconds before a progress line appears
_DEFAULT_PLANT = "dc_motor"
_TRACKING_LAM = 0.98     # demo forgetting factor for the time-varying plant
_DEMO_BYTES_PER_SAMPLE = 700   # the demo's peak per sample (measured about 500 at 2e5 samples)
_DETREND = {"constant": "mean", "linear": False, "none": False}   # -> ARX(offset=...)
# the largest na and nb --select-order tries by default: the library's own default range
_MAX_ORDER = max(inspect.signature(select_order).parameters["nb"].default.values)
_DELAY_SEARCH = 20       # largest delay delayest tries for --select-order without a range
#: the demo's records: the textbook plants and a measured-like record (operating point,
#: dead time, colored disturbance, two runs)
_DEMO_PLANTS = {**PLANTS, "heat_exchanger": heat_exchanger}
#: the methods of each --model (the first is the default), and the orders each one takes
_METHODS = {"arx": ("ls", "rls", "iv", "riv", "nlms", "lms"), "armax": ("pem", "rpem", "rplr"),
            "oe": ("pem", "rpem", "rplr"), "bj": ("pem", "rpem", "rplr")}
_ORDERS = {"arx": ("na",), "armax": ("na", "nc"), "oe": ("nf",), "bj": ("nc", "nd", "nf")}
_FAMILY = {"armax": ARMAX, "oe": OE, "bj": BJ}
#: methods that take --lam (a forgetting factor) and --forgetting (a forgetting scheme)
_LAM_METHODS = ("rls", "riv", "rpem", "rplr")
_FORGETTING_METHODS = ("rls", "rpem", "rplr")
#: methods that take --mu (a step size): the gradient methods of ARX.fit
_GRADIENT_METHODS = ("nlms", "lms")


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
    _writable_matplotlib_config()
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            if not sys.warnoptions:     # `python -W ...` keeps its own filters
                # rlsfilt's own warnings are shown (once each); other libraries' warnings
                # keep the interpreter's filters (DeprecationWarning stays hidden)
                for category in (NumericalWarning, ForgettingSkippedWarning,
                                 OperatingPointWarning, OrderSelectionWarning):
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
    except MemoryError as exc:
        # an up-front estimate of the library (rlsfilt._resources), or an allocation
        # that failed: one line either way
        text = str(exc).splitlines()[0] if str(exc) else "an allocation failed"
        _error(f"out of memory: {text}")
    except OSError as exc:
        _error(f"{exc.strerror or exc}: '{exc.filename}'" if exc.filename else str(exc))
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    return EXIT_ERROR


def _writable_matplotlib_config():
    """Give matplotlib a temporary configuration directory when its own is not writable.

    With an unwritable ``HOME`` matplotlib (imported by python-control) does
    the same itself, after two lines of log on stderr; a command's stderr is
    for one-line errors and warnings.
    """
    if "MPLCONFIGDIR" in os.environ or "matplotlib" in sys.modules:
        return
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    path = os.path.join(base, "matplotlib")
    try:
        os.makedirs(path, exist_ok=True)
        if os.access(path, os.W_OK):
            return
    except OSError:
        pass
    try:
        tmp = tempfile.mkdtemp(prefix="rlsfilt-matplotlib-")
    except OSError:  # no writable temporary directory either: matplotlib will say so
        return
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    os.environ["MPLCONFIGDIR"] = tmp


def _error(message):
    print(f"rlsfilt: error: {_bounded(message)}", file=sys.stderr)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """A warning is one line on stderr, like an error (no source path, no code line)."""
    text = str(message).splitlines()[0] if str(message) else category.__name__
    print(f"rlsfilt: warning: {_bounded(text)}", file=sys.stderr if file is None else file)


_MESSAGE_MAX = 2000     # characters of an error or warning line


def _bounded(text):
    """A message as the terminal shows it: its start and end when it is longer than
    `_MESSAGE_MAX` (a channel label of 200,000 characters, quoted in a message)."""
    if len(text) <= _MESSAGE_MAX:
        return text
    return (f"{text[:_MESSAGE_MAX // 2]} ... ({len(text):,} characters) ... "
            f"{text[-_MESSAGE_MAX // 2:]}")


# ----------------------------------------------------------------------
# the command line
# ----------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and a pointer to --help."""

    def error(self, message):
        print(f"{self.prog}: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


_positive_int = int_at_least(1)
_nonnegative_int = int_at_least(0)
_positive_float = float_where(lambda v: math.isfinite(v) and v > 0.0, "a positive number")
_nonnegative_float = float_where(lambda v: math.isfinite(v) and v >= 0.0,
                                 "a non-negative number")


def _delay_range(text):
    """An argparse type: ``LO:HI`` (or ``LO,HI``, or one delay ``K``), integers ``>= 0``."""
    parts = text.replace(",", ":").split(":")
    if len(parts) > 2:
        raise argparse.ArgumentTypeError(f"must be LO:HI or one delay; got '{text}'")
    lo, hi = (_nonnegative_int(p.strip()) for p in (parts if len(parts) == 2 else parts * 2))
    if hi < lo:
        raise argparse.ArgumentTypeError(f"must have LO <= HI; got '{text}'")
    return range(lo, hi + 1)


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
    demo.add_argument("--plant", default=_DEFAULT_PLANT, choices=sorted(_DEMO_PLANTS),
                      help="the simulated plant, from rlsfilt.datasets (default: "
                           f"{_DEFAULT_PLANT}); heat_exchanger is a record of two runs "
                           "around an operating point: the model removes the means, is "
                           "estimated on the first run and validated on the second")
    demo.add_argument("--samples", type=_positive_int, default=None, metavar="N",
                      help="record length (default: the dataset's; for heat_exchanger, "
                           "the length of each of its two runs)")
    demo.add_argument("--noise", type=_nonnegative_float, default=None, metavar="STD",
                      help="noise standard deviation (default: the dataset's)")
    demo.add_argument("--lam", type=forgetting_factor, default=None,
                      help=f"RLS forgetting factor (default: 1, or {_TRACKING_LAM} for "
                           "time_varying)")
    demo.add_argument("--seed", type=_nonnegative_int, default=0, help="random seed (default: 0)")
    _add_output_options(demo)
    demo.set_defaults(run=_run_demo)

    ident = sub.add_parser(
        "identify", help="identify an ARX (or ARMAX, OE, BJ) model from a CSV file",
        description="Identify the ARX model y(t) + a1 y(t-1) + ... + a_na y(t-na) = "
                    "b1 u(t-nk) + ... + b_nb u(t-nk-nb+1) + e(t) (MATLAB's [na nb nk]) "
                    "from a CSV file with a header row; --model armax, oe or bj fits "
                    "A y = B u + C e, y = B/F u + e or y = B/F u + C/D e by prediction error "
                    "(MATLAB's armax, oe, bj).")
    ident.add_argument("file", metavar="FILE.csv", help="CSV file with a header row")
    ident.add_argument("--input", "-u", action="append", required=True, metavar="COL",
                       dest="inputs", help="input column (repeat for several inputs)")
    ident.add_argument("--output", "-y", required=True, metavar="COL", help="output column")
    ident.add_argument("--model", choices=tuple(_METHODS), default="arx",
                       help="model structure: arx (least squares), armax, oe or bj (prediction "
                            "error; the orders --nc, --nd, --nf) (default: arx)")
    ident.add_argument("--na", type=_nonnegative_int, default=None,
                       help="number of poles, A(q) order, for arx and armax (default: 2)")
    ident.add_argument("--nc", type=_nonnegative_int, default=None,
                       help="C(q) order, noise numerator, for armax and bj (default: 1)")
    ident.add_argument("--nd", type=_nonnegative_int, default=None,
                       help="D(q) order, noise denominator, for bj (default: 1)")
    ident.add_argument("--nf", type=int_list(0), default=None, metavar="NF[,NF...]",
                       help="F(q) order, one value or one per input, for oe and bj "
                            "(default: 2)")
    ident.add_argument("--nb", type=int_list(1), default=[2], metavar="NB[,NB...]",
                       help="number of B coefficients, one value or one per input (default: 2)")
    ident.add_argument("--nk", type=int_list(0), default=None, metavar="NK[,NK...]",
                       help="input delay in samples, one value or one per input (default: 1; "
                            "searched by --select-order unless given)")
    ident.add_argument("--method", choices=("ls", "rls", "iv", "riv", "nlms", "lms", "pem",
                                            "rpem", "rplr"),
                       default=None,
                       help="arx: batch or recursive least squares (ls, rls), instrumental "
                            "variables (iv, riv) or the gradient methods (nlms: normalized "
                            "least mean squares, lms: least mean squares); armax, oe, bj: batch "
                            "or recursive prediction error (pem, rpem) or pseudo-linear "
                            "regression (rplr) (default: ls for arx, pem for the others)")
    ident.add_argument("--mu", type=_positive_float, default=None,
                       help="step size for --method nlms or lms (MATLAB's AdaptationGain; "
                            "default: the filter's, 0.01)")
    ident.add_argument("--window", type=_positive_int, default=None, metavar="N",
                       help="finite history for --method rls: least squares over the last N "
                            "regressor rows (MATLAB's WindowLength; at least the number of "
                            "parameters)")
    ident.add_argument("--lam", type=forgetting_factor, default=1.0,
                       help="forgetting factor in (0, 1] for --method rls, riv, rpem or rplr "
                            "(default: 1)")
    ident.add_argument("--forgetting", choices=MODES, default="exponential",
                       help="forgetting scheme for --method rls, rpem or rplr (default: "
                            "exponential)")
    timing = ident.add_mutually_exclusive_group()
    timing.add_argument("--dt", type=_positive_float, default=None,
                        help="sample time in seconds (default: 1, or from --time)")
    timing.add_argument("--time", metavar="COL", default=None,
                        help="time column; the sample time is its (uniform) step")
    ident.add_argument("--experiment-column", metavar="COL", default=None,
                       help="column labelling the experiment of each row: the rows of each "
                            "label are one experiment (no regressor spans two)")
    ident.add_argument("--detrend", choices=("constant", "linear", "none"), default="constant",
                       help="operating point: remove the means (the model keeps them and "
                            "predicts in the data's units), a line per record, or nothing "
                            "(default: constant)")
    fresh = ident.add_mutually_exclusive_group()
    fresh.add_argument("--validation", metavar="FILE.csv", default=None,
                       help="validate (and with --select-order, choose the orders) on this "
                            "record, with the same columns")
    fresh.add_argument("--split", type=fraction, default=None, metavar="FRACTION",
                       help="estimate on the first FRACTION of each experiment, validate on "
                            "the rest (e.g. 0.7)")
    ident.add_argument("--select-order", action="store_true",
                       help="choose na, nb (and nk unless given) by BIC, up to --max-order "
                            "(--model arx); with several inputs nb and nk per input, each "
                            "input's delays around its own delayest estimate")
    ident.add_argument("--max-order", type=_positive_int, default=_MAX_ORDER, metavar="N",
                       help="largest na and nb tried by --select-order (default: "
                            f"{_MAX_ORDER}, as rlsfilt.select_order)")
    ident.add_argument("--delay-range", type=_delay_range, default=None, metavar="LO:HI",
                       help="delays tried by --select-order, for every input (default: "
                            "around the delay delayest estimates for each input)")
    ident.add_argument("--save-model", metavar="FILE.json", default=None,
                       help="save the fitted model (ARX.load reads it back)")
    ident.add_argument("--delimiter", default=None, metavar="CHAR",
                       help="field separator (default: detected among , ; tab)")
    ident.add_argument("--save-params", metavar="FILE.json", default=None,
                       help="also write the JSON result to this file")
    _add_output_options(ident)
    ident.set_defaults(run=_run_identify)
    from . import _cli_fleet  # identify-many: one ARX model per channel
    _cli_fleet.add_parser(sub)

    warm = sub.add_parser(
        "warmup", help="compile the common kernels ahead (for images and CI)",
        description="Compile the kernels the usual calls reach (every filter, the model "
                    "family, RLSBank) into numba's disk cache, so that later processes "
                    "start warm. Set NUMBA_CACHE_DIR to choose where the cache goes.")
    warm.add_argument("--quiet", action="store_true", help="print nothing")
    warm.set_defaults(run=_run_warmup)
    return parser


def _add_output_options(p):
    p.add_argument("--json", action="store_true",
                   help="print a machine-readable JSON result instead of the report")
    p.add_argument("--plot", type=_png, default=None, metavar="FILE.png",
                   help="save a figure (output fit, residual tests, parameters, response)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress messages")


# ----------------------------------------------------------------------
# commands: read, fit, validate, then print what the library made
# ----------------------------------------------------------------------
def _run_identify(args):
    progress = _Progress(enabled=not args.quiet)
    _check_identify_options(args)
    data = _load(args.file, args, progress)
    if args.validation:
        val = _load(args.validation, args, progress)
        if val.dt != data.dt:
            raise CLIError(f"'{args.validation}' has sample time {val.dt:g}; '{args.file}' has "
                           f"{data.dt:g}")
        est, where = data, f"the record in '{args.validation}'"
    elif args.split:
        try:
            est, val = data.split(args.split)
        except ValueError as exc:
            raise CLIError(f"--split {args.split:g}: {str(exc).split('; ')[-1]}") from None
        where = f"the last {100 * (1 - args.split):.3g} % of each experiment"
    else:
        est, val, where = data, None, "the estimation data"
    progress.done()
    n_in = len(args.inputs)
    na = 2 if args.na is None else args.na
    nb = per_input(args.nb, n_in, "--nb")
    nk = per_input(args.nk if args.nk is not None else [1], n_in, "--nk")
    offset = _DETREND[args.detrend]
    family = args.model != "arx"
    lines = [_describe(args.file, data), _detrend_line(args.detrend, est, family)]
    trend = None   # what the model's deviations are about, saved with it (--save-model)
    if args.detrend == "linear":   # each record about its own line; the model about zero
        est, trend = detrend(est, "linear")
        val = None if val is None else detrend(val, "linear")[0]
    elif family and args.detrend == "constant":
        # the family has no operating-point option: the estimation means are removed
        # from both records, and the model describes the deviations
        u_op, y_op = (np.vstack(x).mean(axis=0) for x in zip(*est.arrays()))
        est = _minus(est, u_op, y_op)
        val = None if val is None else _minus(val, u_op, y_op)
        trend = Trend("constant", [[0]], [np.hstack([u_op, y_op])[None]],
                      [np.zeros((1, len(u_op) + len(y_op)))], len(u_op), len(y_op),
                      lengths=[est.n_samples])
    metadata = {"source": args.file, "inputs": list(args.inputs), "output": args.output,
                "detrend": args.detrend, "experiments": list(data.experiment_names),
                "experiment_lengths": list(data.lengths), "validated_on": where}
    if args.select_order:
        if args.delay_range is not None:
            nks = args.delay_range                      # the user's: one range for all inputs
        elif args.nk is not None:
            nks = [nk[0]] if n_in == 1 else [[k] for k in nk]   # the given delay(s)
        else:
            nks, found = _delay_search(est, args, progress)
            metadata["delay_estimate"] = found
            searched = f"{nks.start}..{nks.stop - 1}" if n_in == 1 else "; ".join(
                f"{name} {r.start}..{r.stop - 1}" for name, r in zip(args.inputs, nks))
            lines.append(f"delay: delayest finds nk = {_fmt_list(list(np.atleast_1d(found)))};"
                         f" orders searched with nk in {searched}")
        # several inputs with their own delays: per-input nb and nk, as select_order does
        nbs = range(1, args.max_order + 1)
        if n_in > 1 and not isinstance(nks, range):
            nbs = [nbs] * n_in
        with progress.task("order selection"), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", OrderSelectionWarning)
            selection = select_order(est, na=range(0, args.max_order + 1), nb=nbs, nk=nks,
                                     criterion="bic", validation=val, dt=est.dt,
                                     offset=offset)
        _reissue(caught, args)
        na, nb_best, nk_best = selection.best
        nb = list(nb_best) if isinstance(nb_best, tuple) else [nb_best] * n_in
        nk = list(nk_best) if isinstance(nk_best, tuple) else [nk_best] * n_in
        metadata["order_selection"] = selection.to_dict()
        lines += ["", selection.summary().as_text()]
    if family:
        model, orders = _family_model(args, na, nb, nk, n_in, est.dt)
        s = family_structure(n_inputs=n_in, **orders)
        _check_rows(max(est.lengths), s, orders, f"'{args.file}'")
    else:
        _check_rows(max(est.lengths), arx_structure(na, nb, nk, n_in, 1),
                    {"na": na, "nb": nb, "nk": nk}, f"'{args.file}'")
        model = ARX(na, nb[0] if n_in == 1 else nb, nk[0] if n_in == 1 else nk, dt=est.dt,
                    offset=offset)
    options = {}
    if args.window is not None:                # least squares over a window: no forgetting
        options["window"] = args.window
    else:
        if args.method in _LAM_METHODS:
            options["lam"] = args.lam
        if args.method in _FORGETTING_METHODS:
            options["forgetting"] = args.forgetting
    if args.mu is not None:
        options["mu"] = args.mu
    task = {"ls": "least squares", "rls": "recursive least squares",
            "iv": "instrumental variables", "riv": "recursive instrumental variables",
            "nlms": "normalized least mean squares", "lms": "least mean squares",
            "pem": "prediction-error minimization", "rpem": "recursive prediction error",
            "rplr": "recursive pseudo-linear regression"}[args.method]
    if args.window is not None:
        task = f"least squares over a window of {args.window} rows"
    with progress.task(f"{task} on {est.n_samples} samples"):
        try:
            with warnings.catch_warnings():
                # an ignored operating point (--detrend none) is warned about once, by
                # validate below, as the command's own warnings are (not by the fit too)
                warnings.simplefilter("ignore", OperatingPointWarning)
                model.fit(est, method=args.method, **options)
        except ValueError as exc:    # e.g. an input that is not exciting for these orders
            raise CLIError(f"{type(model).__name__}: {exc}") from None
    if args.method in _GRADIENT_METHODS and not np.isfinite(model.theta_).all():
        raise CLIError(f"--method {args.method} diverged (the estimate is not finite): lower "
                       f"--mu{'' if args.mu is None else f' (got {args.mu:g})'}")
    if args.save_model:
        try:
            model.save(args.save_model, trend=trend)
        except OSError as exc:
            raise CLIError(f"cannot write '{args.save_model}': {exc.strerror}") from None
        metadata["model_file"] = args.save_model
        metadata["model_file_trend"] = None if trend is None else trend.type
    report = _validate(model, val if val is not None else est, None,
                       args.lam if args.method in _LAM_METHODS else 1.0, metadata, progress,
                       window=args.window)
    after = [f"\nmodel saved to {args.save_model}"] if args.save_model else []
    if args.save_model and trend is not None:
        after[0] += (f" with the {trend.type} trend removed from the estimation data "
                     "(load it back as its trend_)")
    return _emit(report, args, lines + [""], after)


def _check_identify_options(args):
    methods = _METHODS[args.model]
    if args.method is None:
        args.method = methods[0]
    elif args.method not in methods:
        raise CLIError(f"--method {args.method} does not apply to --model {args.model}; its "
                       f"methods are {', '.join(methods)}")
    for name in ("na", "nc", "nd", "nf"):
        if getattr(args, name) is not None and name not in _ORDERS[args.model]:
            takes = [m for m, orders in _ORDERS.items() if name in orders]
            raise CLIError(f"--{name} does not apply to --model {args.model} (it is an order "
                           f"of --model {' and '.join(takes)})")
    for col in args.inputs:
        if col == args.output:
            raise CLIError(f"column '{col}' is given as both --input and --output")
    if len(set(args.inputs)) != len(args.inputs):
        dup = next(c for c in args.inputs if args.inputs.count(c) > 1)
        raise CLIError(f"column '{dup}' is given twice as --input")
    if args.experiment_column is not None and \
            args.experiment_column in list(args.inputs) + [args.output, args.time]:
        raise CLIError(f"column '{args.experiment_column}' is given as --experiment-column "
                       "and as a signal")
    recursive = [m for m in methods if m in _LAM_METHODS]
    if args.lam != 1.0 and args.method not in _LAM_METHODS:   # batch fits have no forgetting
        raise CLIError(f"--lam {args.lam:g} needs --method {' or '.join(recursive)}")
    if args.forgetting != "exponential" and args.method not in _FORGETTING_METHODS:
        with_scheme = [m for m in methods if m in _FORGETTING_METHODS]
        raise CLIError(f"--forgetting {args.forgetting} needs --method "
                       f"{' or '.join(with_scheme)}")
    if args.mu is not None and args.method not in _GRADIENT_METHODS:
        raise CLIError(f"--mu needs --method {' or '.join(_GRADIENT_METHODS)} (--model arx)")
    if args.window is not None:
        if args.method != "rls":
            raise CLIError(f"--window needs --method rls (--model arx); got --method "
                           f"{args.method}")
        if args.lam != 1.0 or args.forgetting != "exponential":
            raise CLIError(f"--window replaces forgetting: give --window or "
                           f"--{'lam' if args.lam != 1.0 else 'forgetting'}, not both")
    if args.select_order and args.model != "arx":
        raise CLIError(f"--select-order searches ARX orders; give the orders of --model "
                       f"{args.model} (or rank structures with rlsfilt.select_structure)")
    if args.forgetting == "constant_trace" and args.lam == 1.0:
        raise CLIError("--forgetting constant_trace needs --lam < 1 (it holds trace(P) at "
                       "n_params * (1 - lam))")
    if args.delay_range is not None and not args.select_order:
        raise CLIError("--delay-range needs --select-order (give the delay itself with --nk)")


def _load(path, args, progress):
    """The numeric columns of a CSV file as an `IOData` (one experiment per label)."""
    exp_col = args.experiment_column
    columns = list(args.inputs) + [args.output] + ([args.time] if args.time else [])
    columns += [exp_col] if exp_col else []
    table = _read_csv(path, columns, delimiter=args.delimiter, progress=progress,
                      text_columns=(exp_col,) if exp_col else ())
    n = len(table[args.output])
    if exp_col:
        labels = table[exp_col]
        names = list(dict.fromkeys(labels.tolist()))
        groups = [np.flatnonzero(labels == name) for name in names]
    else:
        names, groups = None, [np.arange(n)]
    dts, t0 = [], []
    for name, rows in zip(names or [None], groups):
        if args.time:
            where = f" (experiment '{name}')" if name is not None else ""
            t = table[args.time][rows]
            dts.append(_sample_time(t, args.time, where) if len(t) > 1 else None)
            t0.append(float(t[0]))
    if args.time:
        known = [d for d in dts if d is not None]
        if not known:
            raise CLIError(f"time column '{args.time}' needs at least 2 rows in an experiment "
                           "to give a sample time")
        if max(known) - min(known) > 1e-6 * max(known):
            raise CLIError(f"the experiments of '{path}' have different sample times "
                           f"({min(known):g} to {max(known):g}); resample them to one rate")
        dt = float(np.mean(known))
    else:
        dt = args.dt or 1.0
    us = [np.column_stack([table[c][rows] for c in args.inputs]) for rows in groups]
    ys = [table[args.output][rows] for rows in groups]
    return IOData(us if exp_col else us[0], ys if exp_col else ys[0], dt,
                  input_names=list(args.inputs), output_names=[args.output],
                  experiment_names=names, tstart=t0 or None)


def _describe(path, data):
    dt = "unspecified" if data.dt is True else f"{data.dt:g} s"
    exps = ""
    if data.n_experiments > 1:
        exps = (f" in {data.n_experiments} experiments ("
                + ", ".join(f"{n}: {k}" for n, k in zip(data.experiment_names, data.lengths))
                + ")")
    return f"data: '{path}', {data.n_samples} samples{exps}, sample time {dt}"


def _detrend_line(mode, data, family=False):
    if mode == "none":
        return "detrend: none (the data are used as they are)"
    if mode == "linear":
        return ("detrend: linear (a least-squares line removed from every signal of every "
                "record; the model describes the deviations)")
    records = data.arrays()
    means = np.vstack([np.hstack(r) for r in records]).mean(axis=0)
    names = list(data.input_names) + list(data.output_names)
    shown = ", ".join(f"{n} = {m:.6g}" for n, m in zip(names, means))
    if family:
        return (f"detrend: constant (means removed: {shown}, from the validation data too; "
                "the model describes the deviations)")
    return (f"detrend: constant (means removed: {shown}; the model keeps them and predicts in "
            "the units of the data)")


def _minus(data, u_op, y_op):
    """`data` (IOData) with the operating point ``(u_op, y_op)`` subtracted."""
    U, Y = zip(*data.arrays())
    return IOData([X - u_op for X in U], [X - y_op for X in Y], data.dt,
                  input_names=data.input_names, output_names=data.output_names,
                  input_units=data.input_units, output_units=data.output_units,
                  experiment_names=data.experiment_names, tstart=data.tstart)


def _reissue(caught, args):
    """The warnings of select_order, its edge warning in the command's option names
    (``--max-order``, ``--delay-range``) rather than the library's ``na``/``nb``/``nk``."""
    for w in caught:
        message = str(w.message)
        if issubclass(w.category, OrderSelectionWarning):
            message = _option_names(message, args)
        warnings.warn_explicit(message, w.category, w.filename, w.lineno)


def _option_names(message, args):
    """``the upper edge of the `nb` range (1..4): widen `nb` upwards`` -> ``... of
    --max-order 4: raise --max-order``."""
    import re

    def edge(m):
        which, name = m.group(1), m.group(2)
        if name.split("[")[0] in ("na", "nb"):     # nb[fan]: a per-input range
            if which == "upper":
                return (f"the upper edge of `{name}` (--max-order {args.max_order}): raise "
                        "--max-order")
            return f"the lower edge of `{name}` (0 or 1, the smallest order)"
        option = "--delay-range" if args.delay_range is not None else "--delay-range LO:HI"
        return (f"the {which} edge of the delays tried (`{name}` {m.group(3)}): widen them "
                f"with {option}")

    return re.sub(r"the (upper|lower) edge of the `(\w+(?:\[[^\]]*\])?)` range (\([^)]*\)): "
                  r"widen `[^`]+` (?:upwards|downwards)", edge, message)


def _family_model(args, na, nb, nk, n_in, dt):
    """The ARMAX/OE/BJ model of the options and its orders (``nb``, ``nf``, ``nk`` per input)."""
    nf = per_input(args.nf if args.nf is not None else [2], n_in, "--nf")
    nc = 1 if args.nc is None else args.nc
    nd = 1 if args.nd is None else args.nd
    one = n_in == 1
    orders = {"armax": {"na": na, "nb": nb, "nc": nc, "nk": nk},
              "oe": {"nb": nb, "nf": nf, "nk": nk},
              "bj": {"nb": nb, "nc": nc, "nd": nd, "nf": nf, "nk": nk}}[args.model]
    given = {k: (v[0] if one and isinstance(v, list) else v) for k, v in orders.items()}
    return _FAMILY[args.model](**given, dt=dt), orders


def _delay_search(data, args, progress):
    """``(delays to try, delayest's answer)`` for --select-order without a delay range: a
    range around the delay of one input, a list of ranges (one per input, each around that
    input's delay) for several inputs."""
    nu = data.n_inputs
    nk_max = _DELAY_SEARCH
    while nk_max > 1:   # the largest delay the record can test with ARX(2, 2) models
        t_max = nk_max + 1
        if sum(max(n - t_max, 0) for n in data.lengths) > 2 + nu * (nk_max + 2) + 1:
            break
        nk_max -= 1
    test = detrend(data)[0] if args.detrend == "constant" else data
    with progress.task("delay estimation"):
        with warnings.catch_warnings():   # the edge of this search is not the user's range
            warnings.simplefilter("ignore", OrderSelectionWarning)
            found = delayest(test, nk_max=nk_max)
    ks = np.atleast_1d(found)
    if nu == 1:
        return range(max(0, int(ks[0]) - 2), int(ks[0]) + 3), found
    # per input d - 1 .. d + 1 around its own delay (select_order's own seeding)
    return [range(max(0, int(k) - 1), int(k) + 2) for k in ks], found


def _run_warmup(args):
    from . import _warmup

    log = None if args.quiet else print
    if log:
        log("rlsfilt warmup: compiling the common kernels into numba's disk cache "
            "(CPU seconds per class)")
    spent = _warmup.warmup(log=log)
    if log:
        log(f"done: {sum(spent.values()):.1f} s; later processes load the kernels from the cache")
    return EXIT_OK


def _run_demo(args):
    if args.samples is not None:
        # the record, two fits and the validation together (measured with tracemalloc
        # at 2e5 samples: about 500 bytes per sample, rounded up)
        check_memory(_DEMO_BYTES_PER_SAMPLE * args.samples,
                     f"the demo with --samples {args.samples}")
    kwargs = {"rng": args.seed}
    if args.samples is not None:
        kwargs["n_samples"] = (args.samples if args.plant != "heat_exchanger"
                               else (args.samples, args.samples))
    if args.noise is not None:
        kwargs["noise_std"] = args.noise
    ds = _DEMO_PLANTS[args.plant](**kwargs)
    tracking = ds.theta_true is not None
    lam = args.lam if args.lam is not None else (_TRACKING_LAM if tracking else 1.0)
    # a record of several runs: estimate on all but the last, validate on the last (fresh data)
    if ds.n_experiments > 1:
        est, val = ds.getexp(list(range(ds.n_experiments - 1))), ds.getexp(-1)
    else:
        est, val = ds, None
    _check_rows(min(est.lengths), arx_structure(ds.na, [ds.nb], [ds.nk]),
                {"na": ds.na, "nb": [ds.nb], "nk": [ds.nk]}, "the simulated record")
    offset = "mean" if (ds.u0, ds.y0) != (0.0, 0.0) else False
    progress = _Progress(enabled=not args.quiet)
    with progress.task(f"recursive least squares over {est.n_samples} samples"):
        model = ARX(ds.na, ds.nb, ds.nk, dt=ds.dt, offset=offset).fit(est, method="rls",
                                                                       lam=lam)
        batch = ARX(ds.na, ds.nb, ds.nk, dt=ds.dt, offset=offset).fit(est)
    # a time-varying plant is compared with the plant in force at the end of the record
    theta_true = ds.theta_true[-1] if tracking else ds.theta
    label = "true at the end" if tracking else "true"
    metadata = {"source": f"demo plant '{ds.name}'", "inputs": list(ds.input_names),
                "output": ds.output_names[0], "seed": args.seed, "theta_true": theta_true,
                "theta_batch": batch.theta_}
    lines = [f"rlsfilt {__version__} demo: {ds.description}",
             f"  {ds.n_samples} samples, sample time {ds.dt:g} s, {ds.noise} noise of std "
             f"{ds.noise_std:g}, seed {args.seed}"]
    if offset:
        lines.append("  operating point: " + _detrend_line("constant", est).split(": ", 1)[1])
    if val is not None:
        metadata["validated_on"] = f"experiment {val.experiment_names[0]}"
        lines.append(f"  estimated on {', '.join(est.experiment_names)} ({est.n_samples} "
                     f"samples), validated on {val.experiment_names[0]} ({val.n_samples} "
                     "samples, fresh data)")
    lines += ["  identified recursively (batch start, then one RLS update per sample) and by "
              "batch least squares", ""]
    report = _validate(model, val if val is not None else est, None, lam, metadata, progress,
                       plant=ds.plant_after if tracking else ds.plant)
    return _emit(report, args, lines, _truth_table(model, theta_true, batch, label, lam))


def _validate(model, u, y, lam, metadata, progress, plant=None, window=None):
    """`rlsfilt.validate` on the whole record, or with forgetting on its end.

    With ``lam < 1`` the final estimate describes the end of the record only,
    so it is validated on the last three memory lengths ``3 / (1 - lam)``
    samples; with a `window` of rows, on the samples of the last window (each
    at least 100 rows with a complete regressor).
    """
    local = lam < 1.0 or window is not None
    if isinstance(u, IOData) and local and u.n_experiments > 1:
        u = u.getexp(-1)  # the estimate describes the end of the last experiment
    N = u.n_samples if isinstance(u, IOData) else len(y)
    start = 0
    floor = 100 + model.max_lag + model.n_params if local else 0
    if window is not None:
        start = max(0, N - max(window + model.max_lag, floor))
        what = f"the last window of {window} rows"
    elif lam < 1.0:
        start = max(0, N - max(int(round(3.0 / (1.0 - lam))), floor))
        what = f"three memory lengths of lam = {lam:g}"
    metadata["validation_start"] = start
    if start:
        metadata["validation_note"] = f"validation (on the last {N - start} samples, {what})"
        if isinstance(u, IOData):
            u = u[start:]
        else:
            u = {k: v[start:] for k, v in u.items()} if isinstance(u, dict) else u[start:]
            y = y[start:]
    with progress.task("validating the model"):
        return validate(model, u, y, plant=plant, skip_undefined=True,  # the library's
                        metadata=metadata)                            # max_lag, initial


def _truth_table(model, theta_true, batch, label, lam):
    """The demo's comparison of the recursive estimate with the truth and batch LS."""
    width = max(11, len(label) + 2)
    head = f"  {'param':<10}{'estimate':>12}{'std err':>11}{label:>{width}}{'batch LS':>12}"
    lines = ["", "Recursive estimate against the truth", head, "  " + "-" * (len(head) - 2)]
    for name, est, sd, true, ls in zip(model.param_names_, model.theta_, model.std_errors_,
                                       theta_true, batch.theta_):
        lines.append(f"  {name:<10}{est:12.6g}{sd:11.2e}{true:{width}.5g}{ls:12.6g}")
    if lam == 1.0:
        gap = float(np.max(np.abs(model.theta_ - batch.theta_)))
        lines.append(f"  max |RLS - batch LS| = {gap:.1e}  (after the batch start, recursive = "
                     "batch)")
    else:
        lines.append(f"  RLS with forgetting (lam = {lam:g}) tracks the plant at the end; batch "
                     "LS averages over the whole record")
    return lines


def _emit(report, args, before=(), after=()):
    """Print ``report.summary()`` (with the command's context lines) or ``report.to_dict()``
    as JSON; save the JSON and ``report.plot()``."""
    result = report.to_dict()
    if getattr(args, "save_params", None):
        _write_json(args.save_params, result)
    if args.json:
        print(json.dumps(result))
    else:
        note = report.metadata.get("validation_note")
        print("\n".join([*before, *([note, ""] if note else []), report.summary().as_text(),
                         *after]))
    if args.plot:
        _save_figure(report, args.plot)
        if not args.json:
            print(f"\nfigure saved to {args.plot}")
    return EXIT_OK



# ----------------------------------------------------------------------
# reading data
# ----------------------------------------------------------------------
def _read_csv(path, columns, delimiter=None, progress=None, text_columns=()):
    """Read numeric `columns` (and the labels in `text_columns`) of a CSV file with a header row.

    Returns a dict mapping each column name to a float array (an array of
    strings for the text columns). Raises `CLIError` with a one-line message
    naming the file, row and column for every problem a user can cause. The
    file is read line by line, the numbers into arrays of doubles (8 bytes
    per value), never held as text.
    """
    if not os.path.exists(path):
        raise CLIError(f"file '{path}' not found")
    if os.path.isdir(path):
        raise CLIError(f"'{path}' is a directory; expected a CSV file")
    try:
        with open(path, newline="", encoding=CSV_ENCODING) as fh, csv_fields_of_any_length():
            return _parse_csv(fh, path, columns, delimiter, progress, text_columns)
    except UnicodeDecodeError:
        raise CLIError(f"'{path}' is not a UTF-8 text file") from None


def _parse_csv(fh, path, columns, delimiter, progress, text_columns):
    first = 0           # lines before the header (blank lines and comments)
    for header_line in fh:
        if header_line.strip() and not header_line.startswith("#"):
            break
        first += 1
    else:
        raise CLIError(f"'{path}' is empty; expected a header row and data rows")
    if delimiter is None:
        delimiter = _detect_delimiter(header_line.rstrip("\r\n"))
    reader = csv.reader(itertools.chain([header_line], fh), delimiter=delimiter)
    records = _records(reader, path, first)
    header = [h.strip() for h in next(records)]
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
    values = [[] if c in text_columns else array.array("d") for c in columns]
    row = 0
    for fields in records:
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
            if c in text_columns:
                values[k].append(cell)
                continue
            try:
                v = float(cell)
            except ValueError:
                shown = shown_cell(cell) if cell else "an empty cell"
                raise CLIError(f"'{path}' line {line} (data row {row}), column '{c}': "
                               f"expected a number; got {shown}") from None
            if not math.isfinite(v):
                raise CLIError(f"'{path}' line {line} (data row {row}), column '{c}': "
                               f"expected a finite number; got {shown_cell(cell)}")
            values[k].append(v)
        if progress is not None and row % 20000 == 0:
            progress.show(f"reading '{path}': {row} rows")
    if row == 0:
        raise CLIError(f"'{path}' has a header but no data rows")
    return {c: np.array(v, dtype=object) if c in text_columns else np.frombuffer(v, dtype=float)
            for c, v in zip(columns, values)}


def _records(reader, path, first):
    """The rows of a csv `reader`, its errors (a NUL byte, a field longer than the csv
    module's limit if another thread lowered it meanwhile) one line naming the file line."""
    while True:
        try:
            fields = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            raise CLIError(f"'{path}' line {first + reader.line_num} cannot be read as CSV: "
                           f"{exc}") from None
        yield fields


def _detect_delimiter(header_line):
    counts = {d: header_line.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    if counts[best]:
        return best
    return "," if " " not in header_line.strip() else " "


def _sample_time(t, name, where=""):
    if len(t) < 2:
        raise CLIError(f"time column '{name}'{where} needs at least 2 rows to give a sample "
                       "time")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise CLIError(f"time column '{name}'{where} must be strictly increasing; row {i + 2} "
                       f"has {t[i + 1]:g} after {t[i]:g}")
    dt = float(np.median(steps))
    if np.max(np.abs(steps - dt)) > 1e-6 * max(dt, abs(t[-1])):
        raise CLIError(f"time column '{name}'{where} is not uniformly sampled: steps range "
                       f"from {steps.min():g} to {steps.max():g}; resample the data first")
    return float((t[-1] - t[0]) / (len(t) - 1))


def _check_rows(n_rows, s, orders, source):
    """At least one equation more than parameters, so that the noise variance exists
    (`s` the structure, with ``n_params`` and ``max_lag``; `orders` as given)."""
    d, lag = s.n_params, s.max_lag
    need = lag + d + 1
    if n_rows < need:
        text = ", ".join(f"{k}={_fmt_list(v) if isinstance(v, list) else v}"
                         for k, v in orders.items())
        raise CLIError(f"too few rows for the orders {text} ({d} parameters, largest lag "
                       f"{lag}): need at least {need} data rows; {source} has {n_rows}")


def _fmt_list(v):
    return str(v[0]) if len(v) == 1 else ",".join(str(x) for x in v)


# ----------------------------------------------------------------------
# writing results
# ----------------------------------------------------------------------
def _write_json(path, result):
    """Write `result` as JSON, atomically (the old file stays whole if the write fails)."""
    text = json.dumps(result, indent=2, allow_nan=False) + "\n"
    try:
        with atomic_write(path) as fh:
            fh.write(text)
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None


def _save_figure(report, path):
    """Save ``report.plot()``, the library's figure of the validation."""
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = report.plot()
    try:
        # atomically, as every file rlsfilt writes (`--plot` takes .png, .pdf or .svg)
        with atomic_write(path, "wb") as fh:
            fig.savefig(fh, format=os.path.splitext(path)[1][1:].lower(), dpi=110)
    except OSError as exc:
        raise CLIError(f"cannot write '{path}': {exc.strerror}") from None
    finally:
        plt.close(fig)



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
