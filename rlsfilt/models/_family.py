r"""Orders and parameter layout of the general polynomial model family.

One structure for every model beyond ARX, the general family of MATLAB's
System Identification Toolbox (``polyest``; Ljung 1999, sec. 4.2):

.. math::

    A(q)\, y(t) = \sum_{i=1}^{n_u} \frac{B_i(q)}{F_i(q)}\, u_i(t)
                  + \frac{C(q)}{D(q)}\, e(t),

with monic :math:`A, C, D, F_i` in :math:`q^{-1}` and
:math:`B_i(q) = q^{-n_{k,i}}(b_{i,1} + b_{i,2} q^{-1} + \dots + b_{i,n_{b,i}}
q^{-n_{b,i}+1})`. The named models are special cases:

========  ==========================================  ================================
model     orders                                      equation
========  ==========================================  ================================
ARX       ``na, nb, nk``                              ``A y = B u + e``
ARMAX     ``na, nb, nc, nk``                          ``A y = B u + C e``
OE        ``nb, nf, nk``                              ``y = B/F u + e``
BJ        ``nb, nc, nd, nf, nk``                      ``y = B/F u + C/D e``
AR        ``na``                                      ``A y = e``
ARMA      ``na, nc``                                  ``A y = C e``
========  ==========================================  ================================

The parameter vector follows MATLAB's ``getpvec`` order,

.. math::

    \theta = [a_1 .. a_{n_a},\; b_{1,1} .. b_{1,n_{b,1}},\; \dots,\;
              c_1 .. c_{n_c},\; d_1 .. d_{n_d},\; f_{1,1} .. f_{1,n_{f,1}},\; \dots]^T.
"""

import numbers
from collections.abc import Sequence

import numpy as np

from .._validation import check_int

__all__ = []


class FamilyStructure:
    """Validated orders of ``A y = sum B_i/F_i u_i + C/D e`` for a known input count.

    Attributes
    ----------
    na, nc, nd : int
        Orders of ``A``, ``C``, ``D`` (number of coefficients after the leading 1).
    nb, nf, nk : tuple of int
        Per input: number of ``b`` coefficients, order of ``F``, input delay.
    n_inputs : int
        Number of inputs (0 for a time series: AR, ARMA).
    n_params : int
        ``na + sum(nb) + nc + nd + sum(nf)``.
    t0 : int
        ``max(na, max(nk + nb - 1))``: the first sample whose ``A y - B u``
        part uses measured data only; the prediction-error criterion sums
        from here (for ARX it is least squares on the rows of
        :func:`~rlsfilt.models.arx_regressors`).
    max_lag : int
        Largest lag of any signal in the pseudo-linear regressor.
    """

    __slots__ = ("na", "nb", "nc", "nd", "nf", "nk", "n_inputs", "n_params", "t0", "max_lag")

    def __init__(self, na, nb, nc, nd, nf, nk):
        self.na, self.nc, self.nd = na, nc, nd
        self.nb, self.nf, self.nk = tuple(nb), tuple(nf), tuple(nk)
        self.n_inputs = len(self.nb)
        self.n_params = na + sum(self.nb) + nc + nd + sum(self.nf)
        self.t0 = max([na] + [k + b - 1 for b, k in zip(self.nb, self.nk)])
        self.max_lag = max([self.t0, nc, nd] + list(self.nf))

    def slices(self):
        """Index ranges of the blocks of ``theta``: a dict with keys
        ``"a"``, ``"c"``, ``"d"`` (slices) and ``"b"``, ``"f"`` (lists of
        slices, one per input)."""
        out, start = {}, 0

        def take(n):
            nonlocal start
            sl = slice(start, start + n)
            start += n
            return sl

        out["a"] = take(self.na)
        out["b"] = [take(n) for n in self.nb]
        out["c"] = take(self.nc)
        out["d"] = take(self.nd)
        out["f"] = [take(n) for n in self.nf]
        return out

    @property
    def has_noise_model(self):
        """Whether ``C`` or ``D`` is estimated."""
        return self.nc > 0 or self.nd > 0

    @property
    def is_arx(self):
        """Whether the structure is ARX (or AR, FIR): linear in its parameters."""
        return self.nc == 0 and self.nd == 0 and not any(self.nf)

    def to_dict(self):
        """Plain ints and lists (for saving a model); :meth:`from_dict` rebuilds it."""
        return {"na": self.na, "nb": list(self.nb), "nc": self.nc, "nd": self.nd,
                "nf": list(self.nf), "nk": list(self.nk), "n_inputs": self.n_inputs}

    @classmethod
    def from_dict(cls, d):
        """The structure saved by :meth:`to_dict` (validated again)."""
        n = d["n_inputs"]
        return family_structure(na=d["na"], nb=list(d["nb"]) if n else 0, nc=d["nc"],
                                nd=d["nd"], nf=list(d["nf"]) if n else 0,
                                nk=list(d["nk"]) if n else 1, n_inputs=n)

    def __eq__(self, other):
        return isinstance(other, FamilyStructure) and all(
            getattr(self, k) == getattr(other, k) for k in ("na", "nb", "nc", "nd", "nf", "nk"))

    def __hash__(self):
        return hash((self.na, self.nb, self.nc, self.nd, self.nf, self.nk))

    def __repr__(self):
        return (f"FamilyStructure(na={self.na}, nb={self.nb}, nc={self.nc}, nd={self.nd}, "
                f"nf={self.nf}, nk={self.nk})")


def _per_input(value, name, n_inputs, minimum):
    """A scalar order or one per input, as a tuple of validated ints."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return (check_int(value, name, minimum=minimum),) * n_inputs
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        check_int(value, name, minimum=minimum)  # raises the TypeError
    if not isinstance(value, (Sequence, np.ndarray)):
        raise TypeError(f"`{name}` must be an integer or a sequence of integers (one per "
                        f"input, in input order); got {type(value).__name__}")
    values = list(value)
    if len(values) != n_inputs:
        raise ValueError(f"`{name}` must be an integer or have one entry per input "
                         f"({n_inputs}); got {len(values)} entries")
    return tuple(check_int(v, f"{name}[{i}]", minimum=minimum) for i, v in enumerate(values))


def family_structure(na=0, nb=0, nc=0, nd=0, nf=0, nk=1, n_inputs=1):
    """Validate the orders of the general family and return a `FamilyStructure`.

    Parameters
    ----------
    na, nc, nd : int, default 0
        Orders of ``A``, ``C``, ``D`` (``>= 0``).
    nb : int or sequence of int, default 0
        Number of ``b`` coefficients per input (``>= 1`` when there are
        inputs); ignored for a time series (``n_inputs = 0``).
    nf : int or sequence of int, default 0
        Order of ``F`` per input (``>= 0``).
    nk : int or sequence of int, default 1
        Input delay per input (``>= 0``).
    n_inputs : int, default 1
        Number of inputs; ``0`` for a time series.

    Raises
    ------
    ValueError
        For negative orders, ``nb < 1``, lists of the wrong length, or a
        structure without parameters.
    TypeError
        For non-integer orders.

    Examples
    --------
    An ARMAX(2, 2, 2, 1) structure has six parameters; its criterion starts
    at ``t0 = 2``:

    >>> from rlsfilt.models._family import family_structure
    >>> s = family_structure(na=2, nb=2, nc=2, nk=1)
    >>> s.n_params, s.t0
    (6, 2)
    """
    n_inputs = check_int(n_inputs, "n_inputs", minimum=0)
    na = check_int(na, "na", minimum=0)
    nc = check_int(nc, "nc", minimum=0)
    nd = check_int(nd, "nd", minimum=0)
    if n_inputs:
        nb_t = _per_input(nb, "nb", n_inputs, minimum=1)
        nf_t = _per_input(nf, "nf", n_inputs, minimum=0)
        nk_t = _per_input(nk, "nk", n_inputs, minimum=0)
    else:
        nb_t = nf_t = nk_t = ()
    s = FamilyStructure(na, nb_t, nc, nd, nf_t, nk_t)
    if s.n_params == 0:
        raise ValueError("the model must have at least one parameter; got all orders zero")
    return s


def split_theta(theta, s):
    r"""The polynomials of ``theta`` in MATLAB's form (ascending powers of ``q^{-1}``).

    Parameters
    ----------
    theta : ndarray, shape (n_params,)
    s : FamilyStructure

    Returns
    -------
    A, C, D : ndarray
        ``[1, a_1, ..]``, ``[1, c_1, ..]``, ``[1, d_1, ..]``.
    B, F : list of ndarray
        Per input: ``[0]*nk + [b_1, ..]`` and ``[1, f_1, ..]``.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models._family import family_structure, split_theta
    >>> s = family_structure(na=1, nb=2, nc=1, nk=2)
    >>> A, B, C, D, F = split_theta(np.array([-0.5, 1.0, 0.3, 0.2]), s)
    >>> A, B[0], C, D, F[0]
    (array([ 1. , -0.5]), array([0. , 0. , 1. , 0.3]), array([1. , 0.2]), array([1.]), array([1.]))
    """
    theta = np.asarray(theta, dtype=float)
    sl = s.slices()
    one = np.ones(1)
    A = np.concatenate([one, theta[sl["a"]]])
    C = np.concatenate([one, theta[sl["c"]]])
    D = np.concatenate([one, theta[sl["d"]]])
    B = [np.concatenate([np.zeros(k), theta[b]]) for k, b in zip(s.nk, sl["b"])]
    F = [np.concatenate([one, theta[f]]) for f in sl["f"]]
    return A, B, C, D, F


def join_theta(s, A=None, B=None, C=None, D=None, F=None):
    """``theta`` from MATLAB-form polynomials (the inverse of `split_theta`).

    Missing polynomials are taken as 1 (``A``, ``C``, ``D``, ``F``) or
    zeros (``B``); the leading 1 and the ``nk`` leading zeros are dropped.
    """
    theta = np.zeros(s.n_params)
    sl = s.slices()
    if A is not None:
        theta[sl["a"]] = np.asarray(A, dtype=float)[1:1 + s.na]
    if C is not None:
        theta[sl["c"]] = np.asarray(C, dtype=float)[1:1 + s.nc]
    if D is not None:
        theta[sl["d"]] = np.asarray(D, dtype=float)[1:1 + s.nd]
    for i in range(s.n_inputs):
        if B is not None:
            theta[sl["b"][i]] = np.asarray(B[i], dtype=float)[s.nk[i]:s.nk[i] + s.nb[i]]
        if F is not None:
            theta[sl["f"][i]] = np.asarray(F[i], dtype=float)[1:1 + s.nf[i]]
    return theta


def param_names(s, u_names=None):
    """Names of the entries of ``theta``: ``a1``, ``b2``, ``c1``, ``f1[u2]`` ...

    With one input the ``b`` and ``f`` names carry no tag; with several they
    carry the input's name (`u_names`, or ``u1``, ``u2`` ...).
    """
    names = [f"a{k}" for k in range(1, s.na + 1)]
    tags = [""] if s.n_inputs == 1 else [
        f"[{u_names[i] if u_names else f'u{i + 1}'}]" for i in range(s.n_inputs)]
    for i, n in enumerate(s.nb):
        names += [f"b{k}{tags[i]}" for k in range(1, n + 1)]
    names += [f"c{k}" for k in range(1, s.nc + 1)]
    names += [f"d{k}" for k in range(1, s.nd + 1)]
    for i, n in enumerate(s.nf):
        names += [f"f{k}{tags[i]}" for k in range(1, n + 1)]
    return names
