"""Display of the filters: rich HTML in Jupyter (``_repr_html_``) and the text of
their ``repr`` (`pretty_str`).

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

__all__ = []

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
