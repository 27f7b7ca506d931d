"""The gradient family against padasip and against a textbook NumPy reference.

Two independent oracles for every filter of `rlsfilt.filters.gradient` on the
same data and step sizes, to 1e-12: padasip (``FilterLMS``, ``FilterNLMS``,
``FilterSSLMS``, ``FilterAP``, zero initial weights; its ``run`` stores the
weights *before* each update, our ``means_p``), and the recursions of Haykin
(2002, ch. 5-6) written below as they read. The contract (streaming == batch,
freeze, update_block, copies, bad input) is in ``tests/test_contract_filters.py``.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import APA, LMS, NLMS, SignDataLMS, SignErrorLMS, SignSignLMS

pa = pytest.importorskip("padasip")

N, N_X = 400, 4
TOL = dict(rtol=1e-12, atol=1e-12)


def _record(seed=0, dim_z=1):
    rng = np.random.default_rng(seed)
    Hs = rng.standard_normal((N, N_X))
    theta = rng.standard_normal((N_X, dim_z))
    zs = Hs @ theta + 0.1 * rng.standard_normal((N, dim_z))
    return (zs[:, 0] if dim_z == 1 else zs), Hs


# ----------------------------------------------------------------------
# the textbook reference (Haykin 2002): one function per rule, as the equations read
# ----------------------------------------------------------------------
def reference_lms(zs, Hs, mu, rule, eps=0.0, leak=0.0):
    """``e = d - w^T u``; ``w <- (1 - mu a) w + mu f(u) g(e) / n`` per sample, with
    ``f``, ``g`` the identity or sign, ``n = eps + u^T u`` (NLMS) or 1. Returns the
    weights before and after each sample."""
    Z = np.asarray(zs, dtype=float).reshape(len(zs), -1)
    w = np.zeros((Hs.shape[1], Z.shape[1]))
    before, after = [], []
    for u, d in zip(Hs, Z, strict=True):
        before.append(w.copy())
        e = d - u @ w
        f = np.sign(u) if rule in ("sign_data", "sign_sign") else u
        g = np.sign(e) if rule in ("sign_error", "sign_sign") else e
        n = eps + u @ u if rule == "nlms" else 1.0
        w = (1.0 - mu * leak) * w + mu * np.outer(f, g) / n
        after.append(w.copy())
    return np.array(before), np.array(after)


def reference_apa(zs, Hs, mu, order, eps):
    """``A(n)`` the `order` newest inputs (zeros before the start), ``e = d - A w``,
    ``w <- w + mu A^T (A A^T + eps I)^-1 e`` (Haykin 2002, sec. 6.?: affine projection)."""
    Z = np.asarray(zs, dtype=float).reshape(len(zs), -1)
    n = Hs.shape[1]
    w = np.zeros((n, Z.shape[1]))
    A, D = np.zeros((order, n)), np.zeros((order, Z.shape[1]))
    before, after = [], []
    for u, d in zip(Hs, Z, strict=True):
        before.append(w.copy())
        A, D = np.vstack([u, A[:-1]]), np.vstack([d, D[:-1]])
        e = D - A @ w
        w = w + mu * A.T @ np.linalg.solve(A @ A.T + eps * np.eye(order), e)
        after.append(w.copy())
    return np.array(before), np.array(after)


CASES = [
    ("lms", lambda: LMS(N_X, mu=0.02), lambda: pa.filters.FilterLMS(N_X, mu=0.02, w="zeros"),
     dict(mu=0.02, rule="lms")),
    ("nlms", lambda: NLMS(N_X, mu=0.5, eps=0.01),
     lambda: pa.filters.FilterNLMS(N_X, mu=0.5, eps=0.01, w="zeros"),
     dict(mu=0.5, rule="nlms", eps=0.01)),
    ("sign_sign", lambda: SignSignLMS(N_X, mu=0.01),
     lambda: pa.filters.FilterSSLMS(N_X, mu=0.01, w="zeros"), dict(mu=0.01, rule="sign_sign")),
    ("sign_error", lambda: SignErrorLMS(N_X, mu=0.01), None, dict(mu=0.01, rule="sign_error")),
    ("sign_data", lambda: SignDataLMS(N_X, mu=0.01), None, dict(mu=0.01, rule="sign_data")),
    ("leaky_lms", lambda: LMS(N_X, mu=0.02, leak=0.5), None,
     dict(mu=0.02, rule="lms", leak=0.5)),
    ("leaky_nlms", lambda: NLMS(N_X, mu=0.5, eps=0.01, leak=0.2), None,
     dict(mu=0.5, rule="nlms", eps=0.01, leak=0.2)),
]


@pytest.mark.parametrize("name, make, make_pa, ref", CASES, ids=[c[0] for c in CASES])
def test_lms_family_against_padasip_and_the_textbook(name, make, make_pa, ref):
    zs, Hs = _record()
    f = make()
    means, covs, means_p, covs_p = f.batch_filter(zs, Hs)
    assert covs is None and covs_p is None
    before, after = reference_lms(zs, Hs, **ref)
    assert_allclose(means, after, **TOL)
    assert_allclose(means_p, before, **TOL)
    if make_pa is not None:
        p = make_pa()
        y, e, w = p.run(zs, Hs)
        assert_allclose(means_p[:, :, 0], w, **TOL)        # padasip: weights before each update
        assert_allclose(f.x[:, 0], p.w, **TOL)
        g = make()                                          # and step by step: adapt == update
        p = make_pa()
        for k in range(50):
            assert_allclose(g.measurement_of_state(g.x, Hs[k])[0, 0], p.predict(Hs[k]), **TOL)
            g.update(zs[k], Hs[k])
            p.adapt(zs[k], Hs[k])
            assert_allclose(g.x[:, 0], p.w, **TOL)


@pytest.mark.parametrize("order", [1, 3, 6, 8])   # 8: the loop for orders past the constant ones
def test_apa_against_padasip_and_the_textbook(order):
    zs, Hs = _record(1)
    f = APA(N_X, order=order, mu=0.4, eps=0.01)
    means, _, means_p, _ = f.batch_filter(zs, Hs)
    p = pa.filters.FilterAP(N_X, order=order, mu=0.4, ifc=0.01, w="zeros")
    y, e, w = p.run(zs, Hs)
    assert_allclose(means_p[:, :, 0], w, **TOL)
    assert_allclose(f.x[:, 0], p.w, **TOL)
    assert_allclose(f.y[0, 0], e[-1], **TOL)                # y: residual of the newest row
    assert f.K.shape == (N_X, order)
    before, after = reference_apa(zs, Hs, 0.4, order, 0.01)
    assert_allclose(means, after, **TOL)
    assert_allclose(means_p, before, **TOL)


def test_several_outputs_are_columns_of_one_filter():
    """``dim_z`` outputs sharing the regressor: each column is its own filter."""
    zs, Hs = _record(2, dim_z=2)
    for make in (lambda m: NLMS(N_X, m, mu=0.5, leak=0.1), lambda m: SignErrorLMS(N_X, m, 0.01),
                 lambda m: APA(N_X, m, order=2, mu=0.5)):
        means, *_ = make(2).batch_filter(zs, Hs)
        for j in range(2):
            one, *_ = make(1).batch_filter(zs[:, j], Hs)
            assert_array_equal(means[:, :, j], one[:, :, 0])


def test_streaming_equals_batch_and_block_bit_for_bit():
    zs, Hs = _record(3)
    zs[[7, 100]] = np.nan
    for make in (lambda: LMS(N_X, mu=0.02, leak=0.1), lambda: SignDataLMS(N_X, mu=0.01),
                 lambda: APA(N_X, order=4, mu=0.3), lambda: APA(N_X, order=8, mu=0.3)):
        a, b, c = make(), make(), make()
        means, *_ = a.batch_filter(zs, Hs)
        c.update_block(zs, Hs)
        for k in range(N):
            b.update(zs[k], Hs[k])
            assert_array_equal(b.x, means[k])
        for f in (a, c):
            assert_array_equal(f.x, b.x)
            assert_array_equal(f.K, b.K)
            assert_array_equal(f.y, b.y)
            assert f.log_likelihood == b.log_likelihood


def test_diagnostics_and_freeze():
    zs, Hs = _record(4)
    f = NLMS(N_X, mu=0.5, R=0.25)
    f.batch_filter(zs[:100], Hs[:100])
    assert_array_equal(f.S, [[0.25]])                       # S = R: no parameter covariance
    x = f.x.copy()
    f.freeze()
    f.update(zs[100], Hs[100])
    assert_array_equal(f.x, x)
    assert_array_equal(f.y[:, 0], zs[100] - Hs[100] @ x)
    assert not hasattr(f, "P") and f.has_covariance is False and f.forgets is False


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="`mu`"):
        LMS(3, mu=0.0)
    with pytest.raises(ValueError, match="`leak`"):
        NLMS(3, leak=-1.0)
    with pytest.raises(ValueError, match="`eps`"):
        APA(3, eps=0.0)
    with pytest.raises(ValueError, match="`order`"):
        APA(3, order=0)
    assert repr(APA(3, order=2)) == "APA(dim_x=3, dim_z=1, order=2, mu=0.1, eps=0.001)"
