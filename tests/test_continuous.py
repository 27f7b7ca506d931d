"""d2c: MATLAB's published example, and exact round trips through control.sample_system."""

import control
import numpy as np
import pytest

from rlsfilt.continuous import d2c

T = 0.1


def _sig(x, digits=4):
    """Round to `digits` significant digits (what MATLAB prints)."""
    x = np.asarray(x, dtype=float)
    mag = np.where(x == 0, 1.0, 10.0 ** (digits - 1 - np.floor(np.log10(np.abs(x) + 1e-300))))
    return np.round(x * mag) / mag


def _random_ss(rng, n, nu, ny, feedthrough=True):
    """A stable continuous system whose poles sit below the Nyquist frequency pi/T."""
    blocks, k = [], 0
    while k < n:
        sigma = -rng.uniform(0.2, 8.0)
        if n - k >= 2 and rng.random() < 0.6:
            w = rng.uniform(0.5, 0.8 * np.pi / T)
            blocks.append(np.array([[sigma, w], [-w, sigma]]))
            k += 2
        else:
            blocks.append(np.array([[sigma]]))
            k += 1
    from scipy.linalg import block_diag

    Lam = block_diag(*blocks)
    S = np.eye(n) + 0.3 * rng.standard_normal((n, n))  # a well-conditioned change of basis
    A = S @ Lam @ np.linalg.inv(S)
    B, C = rng.standard_normal((n, nu)), rng.standard_normal((ny, n))
    D = rng.standard_normal((ny, nu)) if feedthrough else np.zeros((ny, nu))
    return control.ss(A, B, C, D)


def _monic(num, den):
    num, den = np.asarray(num, float), np.asarray(den, float)
    return num / den[0], den / den[0]


def _assert_same_tf(G1, G2, rtol=1e-10):
    for i in range(G1.noutputs):
        for j in range(G1.ninputs):
            n1, d1 = _monic(G1.num[i][j], G1.den[i][j])
            n2, d2 = _monic(G2.num[i][j], G2.den[i][j])
            np.testing.assert_allclose(d1, d2, rtol=rtol, atol=rtol * np.abs(d2).max())
            L = max(len(n1), len(n2))
            n1 = np.r_[np.zeros(L - len(n1)), n1]
            n2 = np.r_[np.zeros(L - len(n2)), n2]
            np.testing.assert_allclose(n1, n2, rtol=rtol, atol=rtol * np.abs(n2).max())


def test_matlab_published_example():
    """MATLAB's d2c page: H = tf([1 -1], [1 1 0.3], 0.1) gives 121.7 s / (s^2 + 12.04 s + 776.7)."""
    H = control.tf([1, -1], [1, 1, 0.3], 0.1)
    for Hc in (d2c(H), control.tf(d2c(control.ss(H)))):
        num, den = _monic(Hc.num[0][0], Hc.den[0][0])
        num = np.trim_zeros(np.where(np.abs(num) < 1e-9, 0.0, num), "f")
        np.testing.assert_array_equal(_sig(den), [1.0, 12.04, 776.7])
        np.testing.assert_array_equal(_sig(num[:1]), [121.7])
        assert len(num) == 2 and abs(num[1]) < 1e-9   # the zero at z = 1 maps to s = 0
    assert Hc.isctime(strict=True)
    # the poles are the logarithms of the discrete poles
    np.testing.assert_allclose(np.sort_complex(d2c(H).poles()),
                               np.sort_complex(np.log(H.poles()) / 0.1), rtol=1e-12)


@pytest.mark.parametrize("method", ["zoh", "tustin"])
@pytest.mark.parametrize("seed", range(6))
def test_state_space_round_trip(method, seed):
    rng = np.random.default_rng(seed)
    n, nu, ny = 1 + seed % 5, 1 + seed % 3, 1 + (seed + 1) % 3
    Gc = _random_ss(rng, n, nu, ny)
    back = d2c(control.sample_system(Gc, T, method=method), method)
    for M, R in ((back.A, Gc.A), (back.B, Gc.B), (back.C, Gc.C), (back.D, Gc.D)):
        np.testing.assert_allclose(M, R, rtol=1e-10, atol=1e-10 * np.abs(R).max())
    assert isinstance(back, control.StateSpace) and back.isctime(strict=True)
    np.testing.assert_array_equal(back.input_delay, np.zeros(nu))


@pytest.mark.parametrize("method", ["zoh", "tustin"])
@pytest.mark.parametrize("seed", range(6))
def test_transfer_function_round_trip(method, seed):
    rng = np.random.default_rng(100 + seed)
    Gc = control.tf(_random_ss(rng, 1 + seed % 4, 1, 1, feedthrough=seed % 2 == 0))
    back = d2c(control.sample_system(Gc, T, method=method), method)
    assert isinstance(back, control.TransferFunction)
    _assert_same_tf(back, Gc, rtol=1e-10)


def _sample_entries(Gc, method="zoh"):
    """A MIMO discrete TF sampled entry by entry (python-control samples SISO TFs only)."""
    ny, nu = Gc.noutputs, Gc.ninputs
    nums = [[None] * nu for _ in range(ny)]
    dens = [[None] * nu for _ in range(ny)]
    for i in range(ny):
        for j in range(nu):
            e = control.sample_system(control.tf(Gc.num[i][j], Gc.den[i][j]), T, method=method)
            nums[i][j], dens[i][j] = e.num[0][0], e.den[0][0]
    return nums, dens


@pytest.mark.parametrize("method", ["zoh", "tustin"])
def test_mimo_transfer_function_with_delays(method, rng):
    """Delays of whole samples come back as input_delay (per input) plus io_delay."""
    Gc = control.tf(_random_ss(rng, 3, 2, 2))
    nums, dens = _sample_entries(Gc, method)
    delays = np.array([[2, 5], [3, 5]])  # input delays 2 and 5 samples, entry (1, 0) one more
    for i in range(2):
        for j in range(2):
            dens[i][j] = np.r_[dens[i][j], np.zeros(delays[i, j])]
    Gd = control.tf(nums, dens, T, inputs=["Q", "P"], outputs=["T1", "T2"])
    back = d2c(Gd, method)
    _assert_same_tf(back, Gc, rtol=1e-9)
    np.testing.assert_allclose(back.input_delay, [2 * T, 5 * T], rtol=1e-15)
    np.testing.assert_allclose(back.io_delay, [[0, 0], [T, 0]], rtol=1e-15, atol=0)
    assert list(back.input_labels) == ["Q", "P"] and list(back.output_labels) == ["T1", "T2"]


def test_pade_replaces_the_delay():
    Gc = control.tf([2.0], [1.0, 3.0])
    Gd = control.sample_system(Gc, T) * control.tf([1.0], [1.0, 0.0, 0.0, 0.0], T)
    plain = d2c(Gd)
    np.testing.assert_allclose(plain.input_delay, [3 * T], rtol=1e-15)
    approx = d2c(Gd, pade=2)
    np.testing.assert_array_equal(approx.input_delay, [0.0])
    pn, pd = control.pade(3 * T, 2)
    _assert_same_tf(approx, Gc * control.tf(pn, pd), rtol=1e-10)


def test_tustin_converts_what_zoh_cannot():
    neg = control.tf([1.0], [1.0, 0.5], T)          # real pole at z = -0.5
    with pytest.raises(ValueError, match=r"cannot convert a discrete model with real negative "
                                         r"poles \(z = -0.5\).*use method='tustin'"):
        d2c(neg)
    c = d2c(neg, "tustin")   # z = -0.5 -> s = (2/T)(z - 1)/(z + 1) = -60
    np.testing.assert_allclose(c.poles(), [-60.0], rtol=1e-12)
    np.testing.assert_allclose(control.sample_system(c, T, "tustin").poles(), [-0.5],
                               rtol=1e-12)


def test_errors():
    fir = control.tf([1.0, 1.0], [1.0, 0.0, 0.0], T)  # (z + 1)/z^2 = z^-1 (1 + z^-1)
    with pytest.raises(ValueError, match="poles near z=0; they are not whole-sample delays"):
        d2c(fir)
    ss0 = control.ss(control.tf([1.0], [1.0, -0.5, 0.0], T))
    with pytest.raises(ValueError, match=r"poles near z=0 \(whole-sample delays are extracted "
                                         r"from transfer functions: convert with control.tf"):
        d2c(ss0)
    with pytest.raises(ValueError, match="cannot convert poles at z = -1"):
        d2c(control.tf([1.0], [1.0, 1.0], T), "tustin")
    with pytest.raises(ValueError, match=r"must be discrete-time with a numeric sampling "
                                         r"period; got a system that is continuous-time"):
        d2c(control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ValueError, match=r"unspecified sampling period \(dt=True\)"):
        d2c(control.tf([1.0], [1.0, -0.5], True))
    with pytest.raises(ValueError, match="`method` must be 'zoh' or 'tustin'; got 'foh'"):
        d2c(control.tf([1.0], [1.0, -0.5], T), "foh")
    with pytest.raises(ValueError, match="`pade` must be None or an integer order >= 1"):
        d2c(control.tf([1.0], [1.0, -0.5], T), pade=0)
    with pytest.raises(TypeError, match="`sys` must be a discrete control.TransferFunction"):
        d2c(np.eye(2))


def test_zero_entry_and_static_gain():
    Gd = control.tf([[[0.5], [0.0]]], [[[1.0, -0.5], [1.0]]], T)
    Gc = d2c(Gd)
    assert np.all(np.asarray(Gc.num[0][1]) == 0)
    np.testing.assert_allclose(Gc.poles(), [np.log(0.5) / T], rtol=1e-12)
    static = d2c(control.tf([3.0], [1.0], T))
    np.testing.assert_allclose(static.num[0][0], [3.0])
