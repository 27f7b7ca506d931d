r"""Summaries of fitted models: a statsmodels-like coefficient table, text and HTML.

For each parameter the table gives the estimate, its standard error, the
:math:`t` statistic, its two-sided p-value and the 95 % confidence interval,
with the Student :math:`t` distribution of ``n_samples_ - n_params``
degrees of freedom, as ``statsmodels``' OLS results do. The model supplies
the lines above the table (orders, method, equations) through its
``_summary_lines(style)``; nothing here knows a parameter layout.
"""

import html
import math

import numpy as np

from .._display import Summary

__all__ = ["ModelSummary", "coefficient_statistics"]


def coefficient_statistics(estimate, std_error, dof, level=0.95):
    r"""``t`` statistics, p-values and confidence intervals of estimates.

    Parameters
    ----------
    estimate, std_error : ndarray
        Same shape.
    dof : int
        Degrees of freedom of the residual variance (rows minus parameters).
    level : float, default 0.95
        Confidence level of the interval.

    Returns
    -------
    dict
        ``t``, ``pvalue``, ``lower``, ``upper`` (arrays of the shape of
        `estimate`) and ``quantile`` (float).

    Notes
    -----
    :math:`t_i = \hat\theta_i / \hat\sigma_i`, p-value
    :math:`2\,P(T_{dof} > |t_i|)` and interval
    :math:`\hat\theta_i \pm t_{(1+\gamma)/2}(dof)\,\hat\sigma_i`: exact for a
    static regression with Gaussian errors (statsmodels' OLS), asymptotic
    for dynamic models, where the Student distribution tends to the normal
    one of Ljung (1999, sec. 9.2). With no spare equations (``dof <= 0``)
    the quantile is infinite and ``t``, p-values are NaN. A zero standard
    error (an exact fit, or given coefficients) gives a zero-width interval,
    an infinite ``t`` and a p-value of 0 (the limit as the standard error
    goes to zero); a zero estimate with a zero standard error has NaN for both.
    A NaN standard error (no covariance: a gradient fit) gives NaN for all three.
    """
    from scipy.stats import t as student_t  # lazy: keeps `import rlsfilt` light
    estimate = np.asarray(estimate, dtype=float)
    se = np.asarray(std_error, dtype=float)
    quantile = float(student_t.ppf(0.5 + level / 2.0, dof)) if dof > 0 else math.inf
    half = np.zeros_like(se)
    # inf * 0 is never formed: a zero standard error has a zero-width interval
    np.multiply(quantile, se, out=half, where=se != 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tval = np.where(se > 0, estimate / np.where(se > 0, se, 1.0),
                        np.where(estimate != 0, np.copysign(np.inf, estimate), np.nan))
        tval = np.where(np.isnan(se), np.nan, tval)   # no standard error (a gradient fit)
    if dof > 0:
        # 2 P(T > |t|): 0 for an infinite t, NaN for a NaN t (0 / 0)
        pvalue = 2.0 * student_t.sf(np.abs(tval), dof)
    else:
        pvalue = np.full(estimate.shape, np.nan)
        tval = np.where(se > 0, np.nan, tval)
    return {"t": tval, "pvalue": pvalue, "lower": estimate - half, "upper": estimate + half,
            "quantile": quantile}


class ModelSummary(Summary):
    """Summary of a fitted model: ``print`` it, or display it in a notebook.

    A :class:`~rlsfilt.Summary` (``as_text()``, ``as_html()``) built from the model.

    The model's description (orders, method, equations) is followed by one
    coefficient table per output with the columns ``coef``, ``std err``,
    ``t``, ``P>|t|``, ``[0.025`` and ``0.975]``.

    Attributes
    ----------
    model : IdentifiedModel
        The summarized model.
    table : dict
        ``names`` (list of str), ``coef``, ``std_err``, ``t``, ``pvalue``,
        ``lower``, ``upper`` (arrays of shape ``(n_params, ny)``) and ``dof``
        (int); see :func:`coefficient_statistics`.
    """

    def __init__(self, model):
        self.model = model
        theta = np.asarray(model.theta_, dtype=float).reshape(model.n_params_, -1)
        se = np.asarray(model.std_errors_, dtype=float).reshape(theta.shape)
        dof = int(model.n_samples_) - int(model.n_params_)
        stats = coefficient_statistics(theta, se, dof)
        self.table = {"names": list(model.param_names_), "coef": theta, "std_err": se,
                      "t": stats["t"], "pvalue": stats["pvalue"], "lower": stats["lower"],
                      "upper": stats["upper"], "dof": dof}

    def as_text(self):
        """The summary as plain text, with the coefficient table."""
        m, tab = self.model, self.table
        lines = list(m._summary_lines("text"))
        if lines:
            lines.append("")
        head = (f"  {'':<12} {'coef':>12} {'std err':>10} {'t':>9} {'P>|t|':>7} "
                f"{'[0.025':>12} {'0.975]':>12}")
        for i in range(tab["coef"].shape[1]):
            if tab["coef"].shape[1] > 1:
                lines.append(f"  output {m._y_name(i)}")
            lines.append(head)
            lines.append("  " + "-" * (len(head) - 2))
            for p, name in enumerate(tab["names"]):
                lines.append(f"  {name:<12} {tab['coef'][p, i]:12.6g} "
                             f"{tab['std_err'][p, i]:10.4g} {_fmt_t(tab['t'][p, i]):>9} "
                             f"{_fmt_p(tab['pvalue'][p, i]):>7} {tab['lower'][p, i]:12.6g} "
                             f"{tab['upper'][p, i]:12.6g}")
        lines.append(f"  (t distribution with {tab['dof']} degrees of freedom)"
                     if tab["dof"] > 0 else "  (no spare equations: t and P>|t| undefined)")
        return "\n".join(lines)

    def as_html(self):
        """The summary as HTML: the model's description and the coefficient tables."""
        m, tab = self.model, self.table
        esc = html.escape
        parts = list(m._summary_lines("html"))
        ny = tab["coef"].shape[1]
        cols = ("coef", "std err", "t", "P>|t|", "[0.025", "0.975]")
        for i in range(ny):
            caption = f"<caption>output {esc(m._y_name(i))}</caption>" if ny > 1 else ""
            head = "".join(f"<th>{esc(c)}</th>" for c in cols)
            rows = []
            for p, name in enumerate(tab["names"]):
                cells = (f"{tab['coef'][p, i]:.6g}", f"{tab['std_err'][p, i]:.4g}",
                         _fmt_t(tab["t"][p, i]), _fmt_p(tab["pvalue"][p, i]),
                         f"{tab['lower'][p, i]:.6g}", f"{tab['upper'][p, i]:.6g}")
                rows.append(f"<tr><th>{esc(name)}</th>"
                            + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
            parts.append(f"<table>{caption}<tr><th></th>{head}</tr>{''.join(rows)}</table>")
        return "".join(parts)


def _fmt_t(value):
    # a huge t (an exact fit, noise-free data) in exponent form keeps its column
    if not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return f"{value:.3f}" if abs(value) < 1e5 else f"{value:.2e}"


def _fmt_p(value):
    return "nan" if math.isnan(value) else f"{value:.3f}"


# ----------------------------------------------------------------------
# difference equations as text, HTML and LaTeX (terms built by the models)
# ----------------------------------------------------------------------
def _latex_name(name):
    """``y1`` -> ``y_{1}``; other names in \\mathrm."""
    if len(name) > 1 and name[0] in "uy" and name[1:].isdigit():
        return f"{name[0]}_{{{name[1:]}}}"
    if len(name) == 1:
        return name
    special = {c: "\\" + c for c in "&%$#_{}"}
    special.update({"~": "\\textasciitilde{}", "^": "\\textasciicircum{}",
                    "\\": "\\textbackslash{}"})
    return "\\mathrm{" + "".join(special.get(c, c) for c in name) + "}"


def _signal(name, lag):
    return f"{name}(t)" if lag == 0 else f"{name}(t-{lag})"


def _sign(value):
    return "-" if value < 0 else "+"


# per style: how to write a signal at a lag, the equals sign, and a term
# "+/- coefficient (+/- standard error) signal"
EQUATION_STYLES = {
    "text": {"signal": _signal, "equals": " = ",
             "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g} (+/-{e:.2g}) {arg}"},
    "html": {"signal": lambda name, lag: _signal(html.escape(name), lag), "equals": " = ",
             "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g} (&plusmn;{e:.2g}) {arg}"},
    "latex": {"signal": lambda name, lag: _signal(_latex_name(name), lag), "equals": " &= ",
              "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g}\\,(\\pm {e:.2g})\\, {arg}"},
}
