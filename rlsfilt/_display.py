"""Display of results: rich HTML in Jupyter (``_repr_html_``), the text of their
``repr`` (`pretty_str`), and `Summary`, what every ``summary()`` returns.

One table a user can read at a glance instead of forty lines of matrices:
the dimensions and settings, the current estimate with its standard
deviations :math:`\\sqrt{\\operatorname{diag} P}` and a health verdict of
``P`` in words (finite, symmetric positive definite, condition number against
the filter's ``cond_max``).

``P`` is the covariance of the estimate in the units of the parameters when
``R`` is the variance of the measurement noise; with another ``R`` (the
default ``R = 1``) ``P = R (\\Phi^T \\Phi)^{-1}`` and the standard deviations
scale with :math:`\\sqrt{\\sigma^2 / R}` for a noise variance
:math:`\\sigma^2`. The table says so.
"""

import html

import numpy as np

__all__ = ["Summary"]

_MAX_ROWS = 20   # parameters listed before the table is cut (the rest is summarized)
_SETTINGS = (    # (attribute, label), shown when the filter has the attribute
    ("lam", "forgetting factor lam"),
    ("forgetting", "forgetting mode"),
    ("window", "window (samples)"),
    ("n_samples", "samples in the window"),
    ("gate", "outlier gate (std devs)"),
    ("n_gated", "gated samples"),
    ("R", "R (noise variance)"),
    ("Q", "Q (random walk)"),
    ("n_updates", "updates so far"),
)


class Summary:
    """A summary of a result: plain text to print, an HTML table in a notebook.

    Every ``summary()`` of rlsfilt returns one (a model's, a validation
    report's, a selection's, a bank's, ...). ``print(s)``, ``str(s)`` and
    ``s.as_text()`` give the text; Jupyter displays ``s.as_html()``.

    Parameters
    ----------
    text : str
        The plain text.
    html : str, optional
        The HTML, its texts already escaped; by default the escaped text in a
        ``<pre>`` block.

    Examples
    --------
    >>> from rlsfilt import Summary
    >>> s = Summary("a = 1 < 2")
    >>> print(s)
    a = 1 < 2
    >>> s.as_html()
    "<pre class='rlsfilt-summary'>a = 1 &lt; 2</pre>"
    """

    def __init__(self, text, html=None):
        if not isinstance(text, str):
            raise TypeError(f"`text` must be a str; got {type(text).__name__}")
        if html is not None and not isinstance(html, str):
            raise TypeError(f"`html` must be a str or None; got {type(html).__name__}")
        self._text = text
        self._html = html

    def as_text(self):
        """The summary as plain text (what ``print`` shows).

        Returns
        -------
        str
        """
        return self._text

    def as_html(self):
        """The summary as HTML (what a notebook shows).

        Returns
        -------
        str
        """
        if self._html is None:
            return f"<pre class='rlsfilt-summary'>{html.escape(self.as_text())}</pre>"
        return self._html

    def __str__(self):
        return self.as_text()

    def __repr__(self):
        return self.as_text()

    def _repr_html_(self):
        return self.as_html()


def pretty_str(label, value):
    """``label = value`` as filterpy prints filter state: the later lines of an
    array aligned under its first, a column vector ``(n, 1)`` printed as a row
    followed by ``.T`` (without `label`: the value alone)."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and value.shape == (len(value), 1) \
            and len(value) > 1:
        text = str(value.T) + ".T"
    else:
        text = str(value)
    if not label:
        return text
    first, *rest = text.split("\n")
    pad = " " * (len(label) + 3)
    return f"{label} = {first}" + "".join("\n" + pad + line for line in rest)


def filter_html(f):
    """The HTML table of filter `f` (``RecursiveLeastSquares``, ``SlidingWindowRLS``,
    ``SquareRootRLS``)."""
    name = type(f).__name__
    n, m = int(f.dim_x), int(f.dim_z)
    x = np.asarray(f.x, dtype=float).reshape(n, m)
    P = np.asarray(f.P, dtype=float)
    verdict, details = health(P, getattr(f, "cond_max", None))
    sd = np.sqrt(np.clip(np.diag(P), 0.0, None)) if np.all(np.isfinite(np.diag(P))) \
        else np.full(n, np.nan)
    head = (f"<strong>{html.escape(name)}</strong>: {n} parameter{'s' * (n != 1)}, "
            f"{m} output{'s' * (m != 1)}; P is <strong>{html.escape(verdict)}</strong>")
    settings = []
    for attr, label in _SETTINGS:
        if not hasattr(type(f), attr) and attr not in vars(f):
            continue
        value = getattr(f, attr)
        if attr == "Q" and (value is None or not np.any(np.asarray(value))):
            continue
        if attr in ("gate", "n_gated") and getattr(f, "gate", None) is None:
            continue
        settings.append(_row(label, _fmt(value)))
    constraints = getattr(f, "constraints", None)
    if constraints is not None:
        settings.append(_row("equality constraints", f"{np.shape(constraints.A)[0]} rows"))
    settings.append(_row("health of P", details))
    # the estimate, one column per output, and the standard deviation shared by the columns
    cols = "".join(f"<th>x[:, {j}]</th>" for j in range(m)) if m > 1 else "<th>estimate</th>"
    rows = []
    for i in range(min(n, _MAX_ROWS)):
        cells = "".join(f"<td>{_fmt(x[i, j])}</td>" for j in range(m))
        rows.append(f"<tr><th>x[{i}]</th>{cells}<td>{_fmt(sd[i])}</td></tr>")
    if n > _MAX_ROWS:
        rows.append(f"<tr><td colspan='{m + 2}'>... {n - _MAX_ROWS} more parameters "
                    f"(largest std dev {_fmt(np.nanmax(sd))})</td></tr>")
    note = ("std dev = sqrt(diag P): the standard error of each parameter when R is the "
            "noise variance (otherwise multiply by sqrt(noise variance / R)).")
    return (f"<div class='rlsfilt-display'><p>{head}</p>"
            f"<table class='rlsfilt-display'><tr><th>parameter</th>{cols}<th>std dev</th></tr>"
            f"{''.join(rows)}</table>"
            f"<p style='font-size:90%'>{html.escape(note)}</p>"
            f"<details><summary>settings and health</summary>"
            f"<table class='rlsfilt-display'>{''.join(settings)}</table></details></div>")


def health(P, cond_max=None):
    """A verdict in words on a covariance matrix, and the numbers behind it.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        The covariance.
    cond_max : float, optional
        The largest condition number still called healthy (the filter's own
        ``cond_max``; 1e12 if None).

    Returns
    -------
    verdict : str
        ``"healthy"``, ``"not finite"``, ``"not symmetric"``, ``"not positive
        definite"`` or ``"ill-conditioned"``.
    details : str
        Smallest and largest eigenvalue and the condition number.
    """
    cond_max = 1e12 if cond_max is None else float(cond_max)
    if not np.all(np.isfinite(P)):
        return "not finite", "P contains NaN or infinity"
    scale = max(float(np.max(np.abs(P))), np.finfo(float).tiny)
    if np.max(np.abs(P - P.T)) > 1e-8 * scale:
        return "not symmetric", f"max |P - P^T| = {_fmt(np.max(np.abs(P - P.T)))}"
    eig = np.linalg.eigvalsh(0.5 * (P + P.T))
    lo, hi = float(eig[0]), float(eig[-1])
    numbers = f"eigenvalues {_fmt(lo)} .. {_fmt(hi)}"
    if lo <= 0.0:
        return "not positive definite", numbers
    cond = hi / lo
    numbers += f", condition number {_fmt(cond)} (limit cond_max = {cond_max:g})"
    if cond > cond_max:
        return "ill-conditioned", numbers
    return "healthy", numbers


def _row(name, value):
    return (f"<tr><th style='text-align:left'>{html.escape(name)}</th>"
            f"<td style='text-align:left'>{html.escape(value)}</td></tr>")


def _fmt(value):
    if value is None:
        return "none"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    arr = np.asarray(value)
    if arr.ndim == 0:
        v = arr.item()
        return f"{v:.6g}" if isinstance(v, float) else str(v)
    if arr.size <= 4:
        return np.array2string(arr.ravel(), precision=4)
    return f"array of shape {arr.shape}"


# ----------------------------------------------------------------------
# banks, selections and trends: the same look as the filters' table
# ----------------------------------------------------------------------
_EDGE = 5        # channels shown at each end of a long bank
_TOP = 10        # candidates of a selection listed


def table_html(header, rows):
    """An HTML table: `header` texts, then `rows` of cell texts (every text escaped);
    a row that is a plain string is one cell spanning the table."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = []
    for row in rows:
        if isinstance(row, str):
            body.append(f"<tr><td colspan='{len(header)}'>{html.escape(row)}</td></tr>")
        else:
            first, *rest = row
            cells = "".join(f"<td>{html.escape(str(c))}</td>" for c in rest)
            body.append(f"<tr><th>{html.escape(str(first))}</th>{cells}</tr>")
    return f"<table class='rlsfilt-display'><tr>{head}</tr>{''.join(body)}</table>"


def table_text(header, rows, indent="  "):
    """A plain-text table: `header` texts, then `rows` of cell texts, the first
    column left-aligned and the others right-aligned; a row that is a plain
    string is printed as it is."""
    cells = [list(map(str, header))] + [list(map(str, r)) for r in rows if not isinstance(r, str)]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]

    def line(r):
        first, *rest = r
        return indent + "  ".join([first.ljust(widths[0])]
                                  + [c.rjust(w) for c, w in zip(rest, widths[1:])]).rstrip()
    out = [line(cells[0])]
    for r in rows:
        out.append(indent + r if isinstance(r, str) else line(list(map(str, r))))
    return "\n".join(out)


def frame_html(head, *parts):
    """The display's frame: a heading paragraph (already HTML) and its parts."""
    return f"<div class='rlsfilt-display'><p>{head}</p>{''.join(parts)}</div>"


def edge_indices(n, edge=_EDGE):
    """Indices shown of `n` items: all, or the first and last `edge` (and the gap)."""
    if n <= 2 * edge:
        return list(range(n)), None
    return list(range(edge)) + list(range(n - edge, n)), n - 2 * edge


def bank_html(bank, labels=None):
    """The HTML of an ``RLSBank``: its settings and the estimate +- std dev of the
    first and last channels (`labels`: optional names of the channels)."""
    name = type(bank).__name__
    C, n = int(bank.n_channels), int(bank.dim_x)
    x = np.asarray(bank.x, dtype=float).reshape(C, n)
    P = np.asarray(bank.P, dtype=float).reshape(C, n, n)
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0.0, None))
    failed = np.asarray(bank.failed_channels)
    head = (f"<strong>{html.escape(name)}</strong>: {C} channel{'s' * (C != 1)}, "
            f"{n} parameter{'s' * (n != 1)} each")
    shown, gap = edge_indices(C)
    rows = []
    for k, c in enumerate(shown):
        if gap and k == _EDGE:
            rows.append(f"... {gap} more channels ...")
        label = str(labels[c]) if labels is not None else str(c)
        cells = [f"{_fmt(x[c, i])} ± {_fmt(sd[c, i])}" for i in range(n)]
        rows.append([label, *cells, "yes" if c in failed else "no"])
    header = ["channel", *(f"x[{i}] ± std dev" for i in range(n)), "failed"]
    lam = np.asarray(bank.lam)
    settings = [_row("forgetting factor lam", _fmt(lam[0] if np.all(lam == lam.flat[0])
                                                   else lam)),
                _row("forgetting mode", _fmt(bank.forgetting)),
                _row("updates so far (n_updates)", _fmt(int(bank.n_updates))),
                _row("channels that failed the health check", _fmt(int(failed.size)))]
    return frame_html(head, table_html(header, rows),
                 f"<details><summary>settings</summary>"
                 f"<table class='rlsfilt-display'>{''.join(settings)}</table></details>")


def ranking_html(name, criterion, labels, columns, key, errors=None, top=_TOP):
    """The HTML of a selection: the candidates sorted by `key` (smaller is better;
    NaN last), the `top` first and a count of the rest.

    `labels` names each candidate, `columns` is a list of ``(header, values)``;
    `errors` (optional) is the refusal message of each candidate (or None)."""
    key = np.asarray(key, dtype=float)
    order = np.argsort(np.where(np.isnan(key), np.inf, key), kind="stable")
    rows = []
    for rank, i in enumerate(order[:top]):
        if errors is not None and errors[i]:
            rows.append(f"{labels[i]}: refused: {errors[i]}")
            continue
        mark = " (best)" if rank == 0 else ""
        rows.append([f"{labels[i]}{mark}", *(_fmt(vals[i]) for _, vals in columns)])
    if len(order) > top:
        rows.append(f"... {len(order) - top} more candidates ...")
    head = (f"<strong>{html.escape(name)}</strong> by {html.escape(str(criterion))}: "
            f"{len(order)} candidate{'s' * (len(order) != 1)}, best first")
    return frame_html(head, table_html(["candidate", *(h for h, _ in columns)], rows))


def trend_html(trend, names=None):
    """The HTML of a ``Trend``: intercept and slope of each segment of each signal."""
    name = type(trend).__name__
    n_cols = trend.n_columns
    if names is None:
        if trend.n_inputs is not None:
            names = ([f"u{i}" for i in range(trend.n_inputs)]
                     + [f"y{i}" for i in range(n_cols - trend.n_inputs)])
        else:
            names = [f"column {c}" for c in range(n_cols)]
    rows = []
    for e in range(trend.n_experiments):
        for m, start in enumerate(trend.breakpoints[e]):
            for c in range(n_cols):
                where = (f"experiment {e}, " if trend.n_experiments > 1 else "") + \
                    f"from sample {start}"
                row = [names[c], where, _fmt(trend.intercept[e][m, c])]
                if trend.type != "constant":
                    row.append(_fmt(trend.slope[e][m, c]))
                rows.append(row)
    total = len(rows)
    rows = rows[:4 * _TOP]
    if total > len(rows):
        rows.append(f"... {total - len(rows)} more coefficients ...")
    header = ["signal", "segment", "intercept"] + (["slope"] if trend.type != "constant" else [])
    head = (f"<strong>{html.escape(name)}</strong>: {html.escape(str(trend.type))}, "
            f"{trend.n_experiments} experiment{'s' * (trend.n_experiments != 1)}, "
            f"{n_cols} signal{'s' * (n_cols != 1)}")
    return frame_html(head, table_html(header, rows))
