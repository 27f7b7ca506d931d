"""The health check of ``P``, shared by the three filters.

Every filter tests its covariance after an update: cheaply (the diagonal,
O(dim_x)) at every update and fully (definiteness, symmetry, condition
number, O(dim_x^3)) every ``check_every`` updates and at the end of
``batch_filter``. The compiled kernels make the decisions inside their
loops (``_kernels_shared.unhealthy``, ``unhealthy_on``,
``factor_unhealthy``); the functions here define them in NumPy, word the
problem and issue the one :class:`~rlsfilt.NumericalWarning` per
:meth:`reset`, pointing at the caller's line.
"""

import math
import os
import sys
import warnings

import numpy as np

from ..exceptions import NumericalWarning

__all__ = []

_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


#: The warning of an ``update()`` that follows an ``update()`` without ``predict()`` in a
#: filter that forgets (its time update, ``P / lam`` or ``+ Q``, was skipped): one wording
#: for every filter.
SKIPPED_FORGETTING = ("update() was called twice without predict() in between, so the "
                      "forgetting (lam < 1) or random walk (Q > 0) of this step was skipped; "
                      "call predict() before each update() or use predict_update().")

def symmetric_problem(P, cond_max, basis=None):
    """None if the symmetric ``P`` is healthy, else what is wrong with it.

    With `basis` (an orthonormal basis of the null space of the
    constraints) ``P`` is judged on that subspace, where it is invertible.
    """
    if not np.isfinite(P).all():
        return "`P` has non-finite entries"
    Pr = P if basis is None else basis.T @ P @ basis
    if Pr.size == 0:
        return None
    asym = float(np.max(np.abs(Pr - Pr.T)))
    scale = float(np.max(np.abs(Pr)))
    w = np.linalg.eigvalsh(0.5 * (Pr + Pr.T))
    if w[0] <= 0.0:
        return f"`P` is not positive definite (smallest eigenvalue {w[0]:.3g})"
    if asym > 1e-8 * scale:
        return f"`P` is not symmetric (max |P - P^T| = {asym:.3g})"
    if w[-1] > cond_max * w[0]:
        return f"`P` is ill-conditioned (condition number {w[-1] / w[0]:.3g} > {cond_max:.3g})"
    return None


def factor_problem(U, cond_max):
    """None if ``P = U^-1 U^-T`` is healthy, else what is wrong with it.

    ``P`` is positive definite exactly when the triangular ``U`` has a
    positive, finite diagonal, and ``cond(P) = cond(U)^2``, so ``P`` is never
    formed.
    """
    if not np.isfinite(U).all():
        return "`P` has non-finite entries"
    dmin = float(np.min(np.diagonal(U)))
    if not dmin > 0.0:
        return (f"`P` is not positive definite (smallest diagonal entry of its square root "
                f"U is {dmin:.3g})")
    sv = np.linalg.svd(U, compute_uv=False)
    ratio = float(sv[0] / sv[-1]) if sv[-1] > 0.0 else math.inf
    cond = ratio * ratio if ratio < 1e150 else math.inf
    if cond > cond_max:
        return f"`P` is ill-conditioned (condition number {cond:.3g} > {cond_max:.3g})"
    return None


def at_update(n_updates, batch_start=None):
    """Where a check failed: the update, and the step of a running batch_filter."""
    if batch_start is None:
        return f" at update {n_updates} since reset"
    return (f" at step {n_updates - batch_start - 1} of batch_filter (update {n_updates} "
            "since reset)")


def at_step(k, n_updates):
    """Where a check inside a compiled ``batch_filter`` failed."""
    return f" at step {k} of batch_filter (update {n_updates} since reset)"


def warn(problem, advice):
    """Issue the health warning ``problem + ". " + advice`` at the caller's line."""
    warn_at_caller(f"{problem}. {advice}", NumericalWarning)


def warn_at_caller(message, category):
    """``warnings.warn`` attributed to the first frame outside the rlsfilt package.

    That is the user's call of ``update``, ``predict_update``,
    ``batch_filter``, ``ARX.fit`` ..., however deep inside rlsfilt the
    warning is raised, so no caller counts stack levels by hand.
    """
    frame, level = sys._getframe(0), 1            # level 1: this function
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR + os.sep):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
