"""GradientBank: C channels of NLMS (LMS, sign-LMS) in one compiled call.

Oracles: one single filter of the same rule per channel (`NLMS`, `LMS`, ...),
run step by step (bit for bit: the bank's kernel does the same operations in
the same order), and padasip's ``FilterNLMS``/``FilterLMS``/``FilterSSLMS``
per channel (1e-12). The filter contract (streaming == batch, freeze,
update_block, copies, bad input) runs on the bank in
``tests/test_contract_filters.py`` (``GradientBank-*``).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import LMS, NLMS, GradientBank, SignDataLMS, SignErrorLMS, SignSignLMS

pa = pytest.importorskip("padasip")

SINGLE = {"lms": LMS, "nlms": NLMS, "sign_error": SignErrorLMS, "sign_data": SignDataLMS,
          "sign_sign": SignSignLMS}


def _record(seed=0, N=300, C=5, n=3, missing=True):
    rng = np.random.default_rng(seed)
    H = rng.standard_normal((N, C, n))
    theta = rng.standard_normal((C, n))
    Z = np.einsum("kci,ci->kc", H, theta) + 0.1 * rng.standard_normal((N, C))
    if missing:
        Z[rng.random((N, C)) < 0.05] = np.nan
        rows = rng.random((N, C)) < 0.03
        H[rows, rng.integers(0, n, rows.sum())] = np.nan
    return Z, H


def _options(method, C):
    mu = np.linspace(0.05, 0.5, C) if method in ("nlms",) else np.linspace(0.005, 0.03, C)
    return dict(mu=mu, method=method, eps=np.linspace(0.001, 0.1, C), leak=0.01)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("method", list(SINGLE))
def test_channels_equal_single_filters(method, update_first):
    """Every channel equals its own single filter bit for bit (a missing sample:
    the filter is not updated at that step), with per-channel step sizes."""
    Z, H = _record()
    N, C, n = H.shape
    opts = _options(method, C)
    bank = GradientBank(C, n, **opts)
    hist = bank.batch_filter(Z, H, update_first=update_first)
    for c in range(C):
        kw = {"leak": 0.01} | ({"eps": opts["eps"][c]} if method == "nlms" else {})
        f = SINGLE[method](n, 1, opts["mu"][c], **kw)
        for k in range(N):
            ok = not (np.isnan(Z[k, c]) or np.isnan(H[k, c]).any())
            if ok:
                f.update(Z[k, c], H[k, c])
                assert_array_equal(hist.residuals[k, c], f.y[0, 0])
            else:
                assert np.isnan(hist.residuals[k, c])
            assert_array_equal(hist.means[k, c], f.x[:, 0])
        assert_array_equal(bank.x[c], f.x[:, 0])


@pytest.mark.parametrize("method, padasip_filter", [("nlms", "FilterNLMS"),
                                                    ("lms", "FilterLMS"),
                                                    ("sign_sign", "FilterSSLMS")])
def test_channels_equal_padasip(method, padasip_filter):
    """padasip's filter per channel (zero start; its ``run`` returns the weights
    before each sample, the bank's ``means_p``) to 1e-12."""
    Z, H = _record(seed=1, missing=False)
    N, C, n = H.shape
    mu = np.linspace(0.1, 0.9, C) if method == "nlms" else np.linspace(0.005, 0.02, C)
    bank = GradientBank(C, n, mu=mu, method=method, eps=0.01)
    hist = bank.batch_filter(Z, H)
    for c in range(C):
        kw = {"eps": 0.01} if method == "nlms" else {}
        p = getattr(pa.filters, padasip_filter)(n, mu=mu[c], w="zeros", **kw)
        _, e, w = p.run(Z[:, c], H[:, c])
        assert_allclose(hist.means_p[:, c], w, rtol=1e-12, atol=1e-12)
        assert_allclose(hist.residuals[:, c], e, rtol=1e-12, atol=1e-12)


def test_streaming_channel_and_block_equal_batch():
    """``predict``/``update`` per row, ``update_block`` in frames and ``channel(i)``
    continuing a run all give the bits of ``batch_filter``."""
    Z, H = _record(seed=2)
    N, C, n = H.shape
    opts = _options("nlms", C)
    batch, stream, block = (GradientBank(C, n, **opts) for _ in range(3))
    hist = batch.batch_filter(Z, H)
    for k in range(N):
        stream.predict_update(Z[k], H[k])
    for lo in range(0, N, 37):
        block.update_block(Z[lo:lo + 37], H[lo:lo + 37])
    for other in (stream, block):
        for name in ("x", "x_prior", "x_post", "y", "S", "K", "z", "H"):
            assert_array_equal(getattr(other, name), getattr(batch, name), err_msg=name)
    half = GradientBank(C, n, **opts)
    half.batch_filter(Z[:150], H[:150])
    for c in range(C):
        f = half.channel(c)
        assert isinstance(f, NLMS) and f.mu == opts["mu"][c]
        keep = ~(np.isnan(Z[150:, c]) | np.isnan(H[150:, c]).any(axis=1))
        means, *_ = f.batch_filter(np.where(keep, Z[150:, c], np.nan),
                                   np.where(keep[:, None], H[150:, c], 0.0))
        assert_array_equal(means[:, :, 0], hist.means[150:, c])


def test_frozen_bank_keeps_the_weights():
    Z, H = _record(seed=3, missing=False)
    bank = GradientBank(Z.shape[1], H.shape[2], mu=0.5)
    bank.batch_filter(Z[:100], H[:100])
    x = bank.x.copy()
    bank.freeze()
    hist = bank.batch_filter(Z[100:150], H[100:150])
    assert_array_equal(bank.x, x)
    assert_allclose(hist.residuals, Z[100:150] - np.einsum("kci,ci->kc", H[100:150], x),
                    rtol=1e-14, atol=1e-14)
    assert bank.channel(0).frozen and not bank.K.any()
    bank.adapt = True
    bank.update(Z[150], H[150])
    assert not np.array_equal(bank.x, x)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="`method` must be one of"):
        GradientBank(3, 2, method="rls")
    with pytest.raises(ValueError, match="`mu` must be positive"):
        GradientBank(3, 2, mu=[0.1, 0.0, 0.1])
    with pytest.raises(ValueError, match=r"`mu` must be a scalar or have shape \(3,\)"):
        GradientBank(3, 2, mu=[0.1, 0.2])
    with pytest.raises(ValueError, match="`leak` must be non-negative"):
        GradientBank(3, 2, leak=-1.0)
    bank = GradientBank(3, 2)
    with pytest.raises(ValueError, match=r"`H` must have shape \(3, 2\)"):
        bank.update(np.zeros(3), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="`zs` must be finite or NaN"):
        bank.batch_filter(np.full((2, 3), np.inf), np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="rank-deficient in channel 0"):
        bank.initialize(np.zeros((3, 3)), np.ones((3, 3, 2)))
    assert bank.n_updates == 0 and not bank.x.any()


# ----------------------------------------------------------------------
# a fleet of gradient ARX fits: fit_many(method="nlms" | "lms")
# ----------------------------------------------------------------------
@pytest.mark.parametrize("method, options", [("nlms", {"eps": 0.01}), ("lms", {"leak": 0.01})])
def test_fit_many_gradient_equals_arx_fit(method, options):
    """Every channel of ``fit_many(..., method)`` is ``ARX.fit(..., method)`` of its
    record (the estimate bit for bit, the statistics to round-off), with one step
    size per channel; ``model(i)`` refits it."""
    from scipy.signal import lfilter

    from rlsfilt import ARX
    from rlsfilt.models import fit_many

    rng = np.random.default_rng(7)
    C, N = 6, 300
    u = rng.standard_normal((N, C))
    a = rng.uniform(-0.9, -0.5, C)
    y = np.column_stack([lfilter([0, 1.0], [1, a[c]], u[:, c]) for c in range(C)])
    y += 0.05 * rng.standard_normal((N, C))
    mu = np.linspace(0.2, 0.8, C) if method == "nlms" else np.linspace(0.01, 0.05, C)
    fleet = fit_many(ARX(1, 1), u, y, method, mu=mu, **options)
    assert fleet.method_ == method and np.isnan(fleet.std_errors_).all()
    for c in range(C):
        m = ARX(1, 1).fit(u[:, c], y[:, c], method=method, mu=mu[c], **options)
        assert_array_equal(fleet.theta_[c], m.theta_)
        assert_allclose(fleet.recursive_residuals_[:, c], m.recursive_residuals_, rtol=1e-12,
                        atol=1e-12)
        assert_allclose(fleet.noise_variance_[c], m.noise_variance_, rtol=1e-12)
        assert_allclose(fleet.residuals_[:, c], m.residuals_, rtol=1e-12, atol=1e-12)
    assert_array_equal(fleet.model(2).theta_, fleet.theta_[2])
    with pytest.raises(TypeError, match="`lam` is not an option of method="):
        fit_many(ARX(1, 1), u, y, method, lam=0.99)


def test_dask_fit_many_gradient_equals_fit_many():
    """`rlsfilt.dask.fit_many` with a gradient method: the per-channel step sizes are
    split with the channel blocks, and the table is that of `fit_many`."""
    import dask.array as da
    from scipy.signal import lfilter

    import rlsfilt.dask as rd
    from rlsfilt import ARX
    from rlsfilt.models import fit_many

    rng = np.random.default_rng(8)
    C, N = 8, 300
    u = rng.standard_normal((N, C))
    y = np.column_stack([lfilter([0, 1.0], [1, -0.6], u[:, c]) for c in range(C)])
    y += 0.05 * rng.standard_normal((N, C))
    mu = np.linspace(0.2, 0.8, C)
    table = rd.fit_many(ARX(1, 1), da.from_array(u, chunks=(N, 3)),
                        da.from_array(y, chunks=(N, 3)), "nlms", mu=mu, residual_tests=False)
    ref = fit_many(ARX(1, 1), u, y, "nlms", mu=mu, residual_tests=False).to_dataframe()
    assert_array_equal(table[["a1", "b1"]].to_numpy(), ref[["a1", "b1"]].to_numpy())
    assert_allclose(table["noise_variance"].to_numpy(), ref["noise_variance"].to_numpy(),
                    rtol=1e-12)
