"""Saving fitted models to JSON and loading them back.

A model file is plain JSON, read against a declared schema: loading never
imports a module, looks up an attribute by a name from the file, or calls
anything the file names. What a file may hold is fixed here:

- the format tag ``"format": "rlsfilt.model"`` and its version
  ``"format_version"`` (:data:`FORMAT_VERSION`, 2; files of version 1, the format before the
  schema, still load: their two kinds of stored object are matched against
  fixed strings, never imported);
- ``"class"``: one of the closed set :data:`MODEL_CLASSES` (``ARX``,
  ``ARMAX``, ``OE``, ``BJ``, ``AR``, ``ARMA``; the instrumental-variable and
  recursive fits are ``ARX`` or family models with their ``method_``), taken
  from a dict literal, never from a module;
- ``"params"``: every constructor parameter of that class, typed (orders are
  integers, ``dt`` is true or a positive number, ARX's ``offset`` is
  false, true or ``"mean"``);
- ``"fitted"``: the learned attributes the class declares, each typed and
  shaped from the structure (``theta_`` has the ``n_params`` that the orders in
  ``params`` give for ``n_inputs_`` inputs and ``n_outputs_`` outputs; the
  polynomials ``a_``, ``b_``, ... equal the ones ``theta_`` holds), every
  number finite; a name the class does not declare (or one that would shadow
  a method) is refused;
- ``"rlsfilt_version"`` and ``"omitted"`` (informative).

Anything else is a `ValueError` that names the field by its JSON path
(``"`fitted.theta_` must have shape (4,); got (5,)"``). Floats are written
with Python's shortest round-tripping representation, so a loaded model holds
bit-for-bit the numbers of the saved one. :func:`save_model` checks the
document it wrote against the same schema before the file is replaced, so a
file that cannot be loaded is never written, and the write is atomic (a
temporary file in the same folder, synced, then renamed over the target): a
save that fails midway leaves the previous file intact.

The pretreatment a model was fitted under travels with it: ``save_model(model,
path, trend=trend)`` stores the `rlsfilt.Trend` that :func:`rlsfilt.detrend`
removed from the estimation record (constant or piecewise linear) as the
learned attribute ``trend_``, and :func:`load_model` restores it, so
``trend_.remove(new_data)`` and ``retrend`` put predictions in the units of
the data exactly as before saving. A model that already holds a ``trend_``
(a loaded one) keeps it when saved again; ``fit`` drops it.
"""

from . import _model_file
from ._model_file import FORMAT_VERSION, MODEL_CLASSES

__all__ = ["save_model", "load_model", "MODEL_CLASSES", "FORMAT_VERSION"]


def _classes():
    """The closed set of classes a model file can hold, by the name it stores."""
    from .models import AR, ARMA, ARMAX, ARX, BJ, OE

    return {"ARX": ARX, "ARMAX": ARMAX, "OE": OE, "BJ": BJ, "AR": AR, "ARMA": ARMA}


def save_model(model, path, *, include_data=False, trend=None):
    """Write a fitted model to a JSON file, atomically.

    Parameters
    ----------
    model : ARX, ARMAX, OE, BJ, AR or ARMA
        A fitted model of one of the classes of :data:`MODEL_CLASSES`
        (subclasses are not: a file names its class from a closed set).
    path : str or os.PathLike
        File to write. It is replaced atomically: the document is written to
        a temporary file in the same folder, synced, then renamed over
        `path`; if anything fails, an existing file is left as it was.
    include_data : bool, default False
        Also write the per-sample diagnostics of the fit (``residuals_``,
        ``theta_history_``, ``recursive_residuals_``, as long as the record).
    trend : Trend, optional
        The trend :func:`rlsfilt.detrend` removed from the estimation record
        (``detrend(IOData(u, y, dt), type="linear")``), written as the
        learned attribute ``trend_`` that :func:`load_model` restores. It
        must be the trend of an `IOData` with the model's numbers of inputs
        and outputs (for a time-series model, also the trend of its output
        array). By default the model's own ``trend_``, if it has one.

    Returns
    -------
    dict
        The document written (``"class"``, ``"params"``, ``"fitted"``,
        ``"omitted"``: names of learned attributes that were not written,
        such as a live filter object, and the version tags).

    Raises
    ------
    TypeError
        If `model` is not of a class of :data:`MODEL_CLASSES`, or `trend`
        is not a `Trend`.
    ValueError
        If `model` was not fitted, `trend` describes other signals than the
        model's, or the model holds what a model file cannot (a non-finite
        number: the message names the field); nothing is written then.

    Examples
    --------
    An ARX model fitted on linearly detrended data keeps its trend:

    >>> import numpy as np, os, tempfile
    >>> from rlsfilt import ARX, IOData, detrend, load_model, retrend
    >>> path = os.path.join(tempfile.mkdtemp(), "model.json")
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.02 * np.arange(200) + 50.0
    >>> data_d, trend = detrend(IOData(u, y, dt=0.1), type="linear")
    >>> model = ARX(0, 2, 1, dt=0.1).fit(data_d)
    >>> _ = model.save(path, trend=trend)
    >>> loaded = ARX.load(path)
    >>> loaded.trend_.type, bool(np.array_equal(loaded.trend_.slope[0], trend.slope[0]))
    ('linear', True)
    >>> def in_units(m, trend):                       # one-step predictions, data units
    ...     return retrend(IOData(data_d.u, m.predict(data_d), dt=0.1), trend).y
    >>> bool(np.array_equal(in_units(loaded, loaded.trend_), in_units(model, trend)))
    True
    >>> bool(np.max(np.abs(in_units(loaded, loaded.trend_)[2:] - y[2:])) < 0.05)
    True
    >>> type(load_model(path)).__name__
    'ARX'
    """
    return _model_file.save_model(model, path, include_data=include_data, trend=trend,
                                  classes=_classes())


def load_model(path, cls=None):
    """Read a model written by :func:`save_model` (or ``model.save``).

    The file is read against the declared schema of the module notes:
    nothing it names is imported, looked up or called, and the model
    returned is always of a class of :data:`MODEL_CLASSES`.

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file.
    cls : type, optional
        One of the classes of :data:`MODEL_CLASSES`: the file must hold a
        model of that class. By default the class the file names.

    Returns
    -------
    ARX, ARMAX, OE, BJ, AR or ARMA
        A fitted model, usable as the saved one.

    Raises
    ------
    ValueError
        Not an rlsfilt model file, a format version this rlsfilt does not
        read, a class outside :data:`MODEL_CLASSES`, a file holding another
        class than `cls`, or any field missing, unknown, mistyped, of the
        wrong shape for the structure, inconsistent with the other fields
        or not finite (the message names the field by its JSON path, such
        as ```fitted.theta_```).
    TypeError
        If `cls` is given and is not a class of :data:`MODEL_CLASSES`.
    """
    return _model_file.load_model(path, cls=cls, classes=_classes())
