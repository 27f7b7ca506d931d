r"""Parameter confidence intervals and frequency-response uncertainty bands.

Both start from the estimate :math:`\hat\theta` and its covariance
``theta_cov_`` :math:`= \hat\sigma^2 (\Phi^T \Phi)^{-1}`, the asymptotic
covariance of the least-squares estimate under white equation error
(Ljung 1999, sec. 9.2).
"""

import numpy as np

from .._display import Summary, table_html
from .._validation import as_float_array, as_generator, check_int, check_probability
from ..models._base import check_is_fitted
from ..models._summary import coefficient_statistics
from ..plotting import plot_bode, plot_frequency_band
from .plant import frequency_grid

__all__ = ["FrequencyBand", "ParameterIntervals", "frequency_response_band",
           "parameter_intervals"]


class ParameterIntervals:
    """Confidence intervals of a model's parameters.

    Attributes
    ----------
    names : list of str
        Parameter names (``a1``, ``b1``, ...), in ``theta_`` order.
    estimate, std_error, lower, upper : ndarray
        The shape of ``theta_``: ``(n_params,)`` or ``(n_params, ny)``.
    level : float
        Confidence level.
    dof : int
        Degrees of freedom of the Student t quantile (rows minus parameters).
    quantile : float
        The multiplier :math:`t_{(1+\\mathrm{level})/2}(\\mathrm{dof})`
        (infinite when there are no spare equations, ``dof <= 0``).
    """

    def __init__(self, names, estimate, std_error, level, dof):
        self.names = names
        self.estimate = estimate
        self.std_error = std_error
        self.level = level
        self.dof = dof
        # a zero standard error (a true model) gives a zero-width interval, even when
        # the quantile is infinite (no spare equations)
        stats = coefficient_statistics(estimate, std_error, dof, level)
        self.quantile = stats["quantile"]
        self.lower = stats["lower"]
        self.upper = stats["upper"]

    def contains(self, theta):
        """Which entries of `theta` lie inside their interval.

        Parameters
        ----------
        theta : array_like, the shape of ``estimate``
            Parameter values to test, for example the true ones.

        Returns
        -------
        ndarray of bool, the shape of ``estimate``
        """
        theta = as_float_array(theta, "theta")
        if theta.shape != self.estimate.shape:
            raise ValueError(f"`theta` must have the shape of the estimate "
                             f"{self.estimate.shape}; got {theta.shape}")
        return (self.lower <= theta) & (theta <= self.upper)

    def summary(self):
        """Table: estimate, standard error and interval per parameter.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        pct = f"{100 * self.level:g}%"
        lines = [f"{'parameter':>12} {'estimate':>12} {'std error':>11} "
                 f"{pct + ' lower':>12} {pct + ' upper':>12}"]
        est = self.estimate.reshape(len(self.names), -1)
        se = self.std_error.reshape(len(self.names), -1)
        lo = self.lower.reshape(len(self.names), -1)
        hi = self.upper.reshape(len(self.names), -1)
        rows = []
        for i, name in enumerate(self.names):
            for j in range(est.shape[1]):
                tag = name if est.shape[1] == 1 else f"{name} (y{j + 1})"
                lines.append(f"{tag:>12} {est[i, j]:>12.6g} {se[i, j]:>11.4g} "
                             f"{lo[i, j]:>12.6g} {hi[i, j]:>12.6g}")
                rows.append([tag, f"{est[i, j]:.6g}", f"{se[i, j]:.4g}", f"{lo[i, j]:.6g}",
                             f"{hi[i, j]:.6g}"])
        page = table_html(["parameter", "estimate", "std error", f"{pct} lower",
                           f"{pct} upper"], rows)
        return Summary("\n".join(lines), page)

    def __repr__(self):
        return f"<ParameterIntervals: {len(self.names)} parameters at level {self.level:g}>\n" \
            + self.summary().as_text()


class FrequencyBand:
    """Frequency response of a model with a sampled uncertainty band.

    Attributes
    ----------
    omega : ndarray, shape (n_points,)
        Frequencies (rad per time unit; rad/sample when ``dt`` is unspecified).
    response : ndarray of complex, shape (ny, nu, n_points)
        Nominal :math:`G(e^{j\\omega dt})` from each input to each output.
    magnitude_lower, magnitude_upper : ndarray, shape (ny, nu, n_points)
        Pointwise ``(1 - level)/2`` and ``(1 + level)/2`` quantiles of
        :math:`|G|` over the parameter draws.
    phase_lower, phase_upper : ndarray, shape (ny, nu, n_points)
        The same for the phase in degrees.
    magnitude_std : ndarray, shape (ny, nu, n_points)
        Standard deviation of :math:`|G|` over the draws.
    level : float
        Pointwise coverage of the band.
    n_draws : int
        Number of parameter draws.
    dt : float
        Sample time used for :math:`z = e^{j\\omega dt}` (1 when the model's
        ``dt`` is unspecified, ``dt_unspecified`` is then True).
    """

    def __init__(self, **fields):
        for key, value in fields.items():
            setattr(self, key, value)

    def __repr__(self):
        return (f"<FrequencyBand: {self.omega.size} frequencies, {self.n_draws} draws, "
                f"level {self.level:g}>")

    def contains(self, response):
        """Which points of a frequency response lie in the magnitude band.

        Parameters
        ----------
        response : array_like of complex, shape (ny, nu, n_points)
            A response on `omega` (for one input and output, shape
            ``(n_points,)`` works too).

        Returns
        -------
        ndarray of bool, shape (ny, nu, n_points)
        """
        response = np.asarray(response)
        if response.size != self.magnitude_lower.size:
            raise ValueError(f"`response` must have shape {self.magnitude_lower.shape}; got "
                             f"{response.shape}")
        mag = np.abs(response).reshape(self.magnitude_lower.shape)
        return (self.magnitude_lower <= mag) & (mag <= self.magnitude_upper)

    def plot(self, fig=None, plant=None):
        """Bode diagram with the band; optionally the true plant on top.

        Parameters
        ----------
        fig : matplotlib.figure.Figure, optional
            Figure to draw in (empty); a new one if omitted.
        plant : control.LTI, optional
            A discrete system with the model's sample time to overlay.

        Returns
        -------
        matplotlib.figure.Figure
        """
        return plot_frequency_band(self, fig, plant=plant)

    def plot_bode(self, ax_mag=None, ax_phase=None, plant=None):
        """Draw the band into magnitude and phase axes.

        Parameters
        ----------
        ax_mag, ax_phase : matplotlib.axes.Axes, optional
            Axes for magnitude and phase; a new figure with both is made
            unless both are given.
        plant : control.LTI, optional
            A discrete system with the model's sample time to overlay.

        Returns
        -------
        (matplotlib.axes.Axes, matplotlib.axes.Axes)
            The magnitude and phase axes.
        """
        return plot_bode(self, ax_mag, ax_phase, plant=plant)


def parameter_intervals(model, level=0.95):
    r"""Confidence intervals of the parameters from ``theta_cov_``.

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (`ARX` or any other `IdentifiedModel`).
    level : float, default 0.95
        Confidence level in (0, 1).

    Returns
    -------
    ParameterIntervals

    Notes
    -----
    :math:`\hat\theta_i \pm t_{(1+\gamma)/2}(N - d)\,\hat\sigma_{\theta_i}`
    with :math:`\hat\sigma_{\theta_i}^2` the diagonal of ``theta_cov_``,
    :math:`N` the number of regression rows and :math:`d` the number of
    parameters. The Student quantile is exact for a static regression with
    Gaussian errors and tends to the normal one used by Ljung (1999,
    sec. 9.2) for dynamic models, where the intervals are asymptotic.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.validation import parameter_intervals
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(1000)
    >>> y = np.zeros(1000)
    >>> for t in range(1, 1000):
    ...     y[t] = 0.8 * y[t - 1] + 0.5 * u[t - 1] + 0.1 * rng.standard_normal()
    >>> ci = parameter_intervals(ARX(1, 1).fit(u, y))
    >>> bool(ci.contains([-0.8, 0.5]).all())
    True
    """
    check_is_fitted(model, "parameter_intervals")
    level = check_probability(level, "level")
    theta = np.asarray(model.theta_, dtype=float)
    cov = np.asarray(model.theta_cov_, dtype=float)
    if cov.ndim == 2:
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    else:  # (ny, p, p): one covariance per output
        se = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None)).T
    names = list(model.param_names_)
    dof = int(model.n_samples_) - theta.shape[0]
    return ParameterIntervals(names, theta.copy(), se.reshape(theta.shape), level, dof)


def frequency_response_band(model, omega=None, level=0.95, n_draws=1000, rng=None):
    r"""Frequency response of a model with an uncertainty band from ``theta_cov_``.

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (any numbers of inputs and outputs).
    omega : array_like, optional
        Frequencies in rad per time unit; by default 300 points on a
        logarithmic grid from :math:`10^{-3}` times to the Nyquist frequency
        :math:`\pi / dt`.
    level : float, default 0.95
        Pointwise coverage of the band.
    n_draws : int, default 1000
        Number of parameter vectors drawn.
    rng : int or numpy.random.Generator, optional
        Seed or generator for the draws.

    Returns
    -------
    FrequencyBand
        Arrays of shape ``(ny, nu, n_points)``, as in
        :class:`PlantComparison`.

    Notes
    -----
    Parameter vectors are drawn from :math:`N(\hat\theta, \mathrm{cov})`
    (the asymptotic distribution of the estimate, Ljung 1999, sec. 9.2-9.4)
    and for each the response

    .. math::

        G(e^{j\omega T}) = A(e^{-j\omega T})^{-1}\, B(e^{-j\omega T}) /
                            F(e^{-j\omega T})

    is evaluated from the model's polynomials (``model.frequency_response``,
    a ratio of polynomials for one output); the band is the
    pointwise quantiles of its magnitude and (unwrapped) phase. Sampling
    avoids the linearization of the Gauss approximation formula (Ljung 1999,
    sec. 9.4), which fails near lightly damped poles where :math:`G` is far
    from linear in :math:`\theta`. With several outputs the columns of
    ``theta_`` share the regressor, so ``vec(theta_)`` has covariance
    :math:`\Sigma \otimes (\Phi^T\Phi)^{-1}` with :math:`\Sigma` the
    model's ``noise_covariance_``; draws are
    :math:`\hat\Theta + L_M Z L_\Sigma^T` with Cholesky-like factors of the
    two matrices and a standard normal :math:`Z`.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, ch. 9.

    Examples
    --------
    >>> from rlsfilt import ARX, datasets
    >>> from rlsfilt.validation import frequency_response_band
    >>> d = datasets.dc_motor()
    >>> band = frequency_response_band(ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y), rng=0)
    >>> band.magnitude_upper.shape
    (1, 1, 300)
    """
    check_is_fitted(model, "frequency_response_band")
    level = check_probability(level, "level")
    n_draws = check_int(n_draws, "n_draws", minimum=2)
    theta = np.asarray(model.theta_, dtype=float)
    Theta = theta.reshape(theta.shape[0], -1)                  # (p, ny)
    dt = 1.0 if model.dt is True else float(model.dt)
    omega = frequency_grid(omega, dt, 300)
    gen = as_generator(rng)
    draws = Theta + _parameter_noise(model, Theta.shape, n_draws, gen)   # (n, p, ny)
    G_nom = model.frequency_response(omega)
    G = np.stack([model.frequency_response(omega, theta=th.reshape(theta.shape))
                  for th in draws])                            # (n, ny, nu, n_points)
    mag = np.abs(G)
    phase = np.degrees(np.unwrap(np.angle(G), axis=-1))
    # align each draw's unwrapped phase with the nominal one (remove 360 deg jumps)
    nom_phase = np.degrees(np.unwrap(np.angle(G_nom), axis=-1))
    phase -= 360.0 * np.round((phase - nom_phase)[..., :1] / 360.0)
    lo, hi = 0.5 - level / 2.0, 0.5 + level / 2.0
    return FrequencyBand(
        omega=omega, response=G_nom,
        magnitude_lower=np.quantile(mag, lo, axis=0), magnitude_upper=np.quantile(mag, hi, axis=0),
        phase_lower=np.quantile(phase, lo, axis=0), phase_upper=np.quantile(phase, hi, axis=0),
        magnitude_std=mag.std(axis=0, ddof=1), level=level, n_draws=n_draws, dt=dt,
        dt_unspecified=model.dt is True)


def _factor(C):
    """``L`` with ``L L^T = C`` for a symmetric PSD `C` (eigen-decomposition, so a
    singular covariance is fine)."""
    C = 0.5 * (C + C.T)
    w, V = np.linalg.eigh(C)
    return V * np.sqrt(np.clip(w, 0.0, None))


def _parameter_noise(model, shape, n_draws, gen):
    """Draws of ``Theta - hat Theta``, shape (n_draws, p, ny)."""
    p, ny = shape
    cov = np.asarray(model.theta_cov_, dtype=float)
    Z = gen.standard_normal((n_draws, p, ny))
    if ny == 1:
        return _factor(cov.reshape(p, p)) @ Z
    nv = np.atleast_1d(np.asarray(getattr(model, "noise_variance_", np.nan), dtype=float))
    sigma = getattr(model, "noise_covariance_", None)
    if sigma is not None and np.all(np.isfinite(sigma)) and nv.size and nv[0] > 0:
        L_M = _factor(cov[0] / nv[0])                          # (Phi^T Phi)^-1
        L_S = _factor(np.asarray(sigma, dtype=float))
        return L_M @ Z @ L_S.T
    # no cross-covariance known: outputs drawn independently from their own blocks
    return np.stack([_factor(cov[i]) @ Z[:, :, i:i + 1] for i in range(ny)], axis=2)[..., 0]


def _db(x):
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(x)
