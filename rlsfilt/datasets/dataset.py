"""`Dataset`: a simulated record (an `IOData`) together with the truth behind it."""

import numpy as np

from ..data.iodata import IOData, _experiments, _signal

__all__ = ["Dataset"]


class Dataset(IOData):
    """A simulated identification experiment with its true plant.

    A `Dataset` is an `IOData` (``u``, ``y``, ``dt``, names, units, one or
    several experiments), so it can be passed wherever a record is taken,
    and it carries what generated it.

    Parameters
    ----------
    name, description, u, y, dt, plant, na, nb, nk, a, b, noise_std, noise, y_clean
        The attributes below (`u`, `y` and `y_clean` may be lists, one
        array per experiment).
    theta_true, change_time, plant_after : optional
        `time_varying` only.
    u0, y0 : float, default 0.0
        Operating point: the input and output levels around which the plant
        acts (``y - y0 = G(q) (u - u0) + noise``).
    **iodata_options
        ``input_names``, ``output_names``, ``input_units``,
        ``output_units``, ``experiment_names``, ``tstart`` of `IOData`.

    Attributes
    ----------
    name : str
        Generator name (a key of `PLANTS`, or ``"heat_exchanger"``).
    description : str
        One line describing the plant and the experiment.
    u, y : ndarray, shape (N,)
        Input and measured output of a one-experiment record (time on
        axis 0, read-only); see `IOData` for several experiments.
    dt : float
        Sampling period in seconds.
    plant : control.TransferFunction
        The true discrete plant ``B(z)/A(z)`` with sampling time ``dt`` (for
        `time_varying`, the plant before the change; for a plant with an
        operating point, the plant of the deviations from it).
    na, nb, nk : int
        True ARX orders in the ``[na nb nk]`` convention of `rlsfilt.ARX`.
    a, b : ndarray
        True ``[a1, .., a_na]`` (without the leading 1) and ``[b1, .., b_nb]``
        (before the change for `time_varying`), the layout of ``ARX.a_``
        and ``ARX.b_``.
    noise_std : float
        Standard deviation of the white noise ``e``.
    noise : str
        ``"white"``, ``"colored"`` or ``"output"`` (see `rlsfilt.datasets`).
    y_clean : ndarray, shape (N,)
        The noise-free output (one experiment; use :meth:`getexp` for each
        experiment of several).
    u0, y0 : float
        The operating point (0 for the plants without one).
    theta_true : ndarray, shape (N, n_params), optional
        `time_varying` only: the true ``[a1, .., b_nb]`` in force at each
        sample (None for the time-invariant plants).
    change_time : int, optional
        `time_varying` with ``kind="jump"``: first sample of the new
        parameters.
    plant_after : control.TransferFunction, optional
        `time_varying` only: the plant at the end of the record.
    """

    def __init__(self, name, description, u, y, dt, plant, na, nb, nk, a, b, noise_std, noise,
                 y_clean, theta_true=None, change_time=None, plant_after=None, *, u0=0.0,
                 y0=0.0, **iodata_options):
        super().__init__(u, y, dt, **iodata_options)
        cleans, _ = _experiments(y_clean, "y_clean")
        if len(cleans) != self.n_experiments:
            raise ValueError(f"`y_clean` must hold {self.n_experiments} experiment(s) like `y`; "
                             f"got {len(cleans)}")
        clean = []
        for i, yc in enumerate(cleans):
            Yc, _ = _signal(yc, "y_clean")
            if Yc.shape != (self.lengths[i], self.n_outputs):
                raise ValueError(f"`y_clean` must have the shape of `y` in experiment {i}; got "
                                 f"{Yc.shape}")
            Yc.setflags(write=False)
            clean.append(Yc)
        truth = {"name": name, "description": description, "plant": plant, "na": na, "nb": nb,
                 "nk": nk, "a": np.asarray(a), "b": np.asarray(b), "noise_std": noise_std,
                 "noise": noise, "theta_true": theta_true, "change_time": change_time,
                 "plant_after": plant_after, "u0": float(u0), "y0": float(y0)}
        for key, value in truth.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "_clean", tuple(clean))

    @property
    def y_clean(self):
        """The noise-free output of a one-experiment record."""
        self._single("y_clean")
        Yc = self._clean[0]
        return Yc[:, 0] if Yc.shape[1] == 1 else Yc

    def getexp(self, which):
        """The dataset restricted to some experiments, with its truth (see `IOData.getexp`)."""
        from ..data.iodata import _exp_indices

        picks = _exp_indices(which, self.experiment_names)
        rec = IOData.getexp(self, which)
        new = Dataset.__new__(Dataset)
        new._init(rec._U, rec._Y, rec.dt, rec.input_names, rec.output_names, rec.input_units,
                  rec.output_units, rec.experiment_names, rec.tstart)
        for key in ("name", "description", "plant", "na", "nb", "nk", "a", "b", "noise_std",
                    "noise", "theta_true", "change_time", "plant_after", "u0", "y0"):
            object.__setattr__(new, key, getattr(self, key))
        object.__setattr__(new, "_clean", tuple(self._clean[i] for i in picks))
        return new

    @property
    def theta(self):
        """True parameter vector ``[a1, .., a_na, b1, .., b_nb]`` (regressor order)."""
        return np.concatenate([self.a, self.b])

    @property
    def orders(self):
        """``(na, nb, nk)``, ready for ``ARX(*ds.orders)``."""
        return self.na, self.nb, self.nk

    @property
    def noise_variance(self):
        """``noise_std ** 2``: the variance of ``e``."""
        return self.noise_std ** 2

    def true_model(self):
        """The true plant as a fitted-like `rlsfilt.ARX` (``ARX.from_polynomials``).

        Returns
        -------
        ARX
            With the true coefficients, ``dt`` and ``noise_variance_ =
            noise_std ** 2``, the variance of ``e``. That is the variance of
            the ARX equation error only for ``noise="white"``; for the colored
            and output-error noise models ``e`` is filtered before it enters
            the equation (see the module notes). For a plant with an
            operating point it is the model of the deviations from
            ``(u0, y0)``.
        """
        from ..models import ARX

        return ARX.from_polynomials(self.a, self.b, nk=self.nk, dt=self.dt,
                                    noise_variance=self.noise_variance)

    def to_frame(self):
        """A one-experiment record as a pandas DataFrame indexed by time (needs pandas).

        Returns
        -------
        pandas.DataFrame
            One column per signal (named as the signals), index ``t`` in
            seconds. For several experiments use :meth:`IOData.to_dataframe`.
        """
        self._single("to_frame()")
        frame = self.to_dataframe(time="t")
        return frame.set_index("t")

    def __repr__(self):
        ne = self.n_experiments
        exps = f", {ne} experiments" if ne > 1 else ""
        text = (f"Dataset(name={self.name!r}, N={self.n_samples}{exps}, dt={self.dt}, "
                f"ARX orders (na, nb, nk)=({self.na}, {self.nb}, {self.nk}), "
                f"noise={self.noise!r}, noise_std={self.noise_std})\n  {self.description}")
        if self.u0 or self.y0:
            text += f"\n  operating point: u0 = {self.u0:g}, y0 = {self.y0:g}"
        return text
