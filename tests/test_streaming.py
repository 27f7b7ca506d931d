"""The streaming machinery alone (``rlsfilt.filters._streaming``), without a filter.

Blocks are views of one buffer; a block is reused only when nobody else holds
any of its arrays (a view, a row of a view, the buffer); the packed steps
compute the textbook step (``_reference``), and an update that runs a deferred
predict gives the bits of the predict then the update; the entry points give
the dispatcher's results, and the dispatcher serves when numba hides them.
"""

import sys

import _reference as ref
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt.filters import _streaming
from rlsfilt.filters._kernels import BAD_DIAGONAL, BAD_ROW, GATED
from rlsfilt.filters.forgetting import DIRECTIONAL, EXPONENTIAL, kernel_config

n, m = 4, 2


def _state(rng):
    A = rng.standard_normal((n, n))
    return rng.standard_normal((n, m)), A @ A.T + n * np.eye(n)


def test_blocks_are_contiguous_views_of_one_buffer():
    shapes = _streaming.update_shapes(n, m)
    block = _streaming._block(shapes, work=_streaming.update_work(n))
    buf, views = block[0], block[1:]
    assert buf.size == sum(r * c for r, c in shapes) + n + 1 + n * n
    assert [v.shape for v in views] == list(shapes)
    for v in views:
        assert v.base is buf and v.flags.c_contiguous and v.dtype == np.float64
    for a in range(len(views)):                   # disjoint: no array shares another's memory
        for b in range(a + 1, len(views)):
            assert not np.shares_memory(views[a], views[b])


@pytest.mark.skipif(_streaming._FREE_UPDATE < 0, reason="reference counts not trusted here")
def test_a_block_is_free_only_when_nobody_else_holds_it():
    """The full test (every array's count) sees anything held; the quick test (``x``
    and ``P``) sees those two: the filter marks the block as handed out when it
    gives out one of its views (a property read), and then runs the full test."""
    block = (np.empty((n, m)), np.empty((n, n))) + _streaming._block(_streaming.update_shapes(n, m))

    def full():
        return _streaming._counts(block) == _streaming._FREE_EACH

    def quick():
        return _streaming.quick_count(block) == _streaming._FREE_UPDATE

    assert full() and quick()
    for held, seen_quickly in (
            (lambda: block[0], True), (lambda: block[1][0], True),   # x, a row of P
            (lambda: block[4][0], False), (lambda: block[2], False),  # a row of a view, buffer
            (lambda: block[3], False), (lambda: [block[5]], False),  # a view, a list of one
            (lambda: block[-1], False)):                             # P_prior
        keep = held()
        assert not full()
        assert quick() is not seen_quickly
        del keep
        assert full() and quick()


def test_predict_writes_the_time_update_into_a_new_block(rng):
    x, P = _state(rng)
    Q = 1e-3 * np.eye(n)
    x0, P0 = x.copy(), P.copy()
    buf, Pn, x_prior, P_prior = _streaming.predict(x, P, 1.0 / 0.9, Q,
                                                   kernel_config(EXPONENTIAL, 0.9, ()), None)
    assert_allclose(Pn, ref.rls_predict(P, 0.9, Q), rtol=1e-14)
    assert_array_equal(P_prior, Pn)
    assert_array_equal(x_prior, x)
    assert_array_equal(x, x0)                      # inputs untouched
    assert_array_equal(P, P0)


@pytest.mark.parametrize("z", ["column", "missing"])
def test_update_writes_the_textbook_step_into_a_new_block(rng, z):
    x, P = _state(rng)
    x0, P0 = x.copy(), P.copy()
    phi = rng.standard_normal(n)
    zc = None if z == "missing" else rng.standard_normal((m, 1))
    cfg = kernel_config(DIRECTIONAL, 0.95, (1e-12,))
    flags, arrays = _streaming.update(x, P, phi, zc, 0.5, cfg, 1.0, None)
    xn, Pn, buf, y, K, S, SI, H, zb, x_post, P_post, _, _ = arrays
    s, lam_t = S[0, 0], buf[_streaming.lam_t_at(n, m)]
    rx, rP, ry, rK, rs, rlam, rgated, _ = ref.rls_update(x, P, phi.reshape(1, -1), zc, 0.5,
                                                      DIRECTIONAL, (1e-12,), 0.95)
    assert flags == 0 and not rgated
    assert_allclose(xn, rx, rtol=1e-13)
    assert_allclose(Pn, rP, rtol=1e-13)
    assert_allclose(K, rK, rtol=1e-13, atol=1e-300)
    assert s == pytest.approx(rs, rel=1e-14) and lam_t == pytest.approx(rlam, rel=1e-14)
    assert_array_equal(S, s * np.eye(m))
    assert_array_equal(SI, np.eye(m) / s)
    assert_array_equal(H, phi.reshape(1, -1))
    assert_array_equal(x_post, xn)
    assert_array_equal(P_post, Pn)
    if zc is None:
        assert np.isnan(y).all() and np.isnan(zb).all()
    else:
        assert_allclose(y, ry, rtol=1e-13)
        assert_array_equal(zb, zc)
    assert_array_equal(x, x0)                      # inputs untouched
    assert_array_equal(P, P0)


def test_update_of_a_scalar_measurement_and_a_bad_row(rng):
    x, P = rng.standard_normal((n, 1)), np.eye(n)
    cfg = kernel_config(EXPONENTIAL, 1.0, ())
    flags, arrays = _streaming.update(x, P, np.ones(n), 2.5, 1.0, cfg, 1.0, None)
    assert flags == 0 and arrays[8][0, 0] == 2.5 and arrays[5][0, 0] == pytest.approx(n + 1.0)
    phi = np.ones(n)
    phi[2] = np.nan
    flags, _ = _streaming.update(x, P, phi, 2.5, 1.0, cfg, 1.0, None)
    assert flags == BAD_ROW                        # the caller raises; nothing is visible
    P_bad = -np.eye(n)
    flags, _ = _streaming.update(x, P_bad, np.ones(n) * 1e-3, 2.5, 1.0, cfg, 1.0, None)
    assert flags & BAD_DIAGONAL                    # the cheap check: a diagonal not positive
    gate = kernel_config(EXPONENTIAL, 1.0, (np.inf, np.inf), gate=1.0)
    flags, _ = _streaming.update(x, P, np.ones(n), 1e6, 1.0, gate, 1.0, None)
    assert flags == GATED


@pytest.mark.parametrize("constrained", [False, True])
@pytest.mark.parametrize("held_back", [False, True])
def test_a_deferred_predict_gives_the_bits_of_predict_then_update(rng, constrained, held_back):
    """``update(..., il, Q)`` runs the time update first: the same bits as
    ``predict`` then ``update``, and ``x_prior``, ``P_prior`` those of the predict."""
    x, P = _state(rng)
    Q = 1e-3 * np.eye(n)
    Pi = None
    if constrained:                                # the projector onto null([1, 1, 0, 0])
        a = np.array([[1.0, 1.0, 0.0, 0.0]]) / np.sqrt(2.0)
        Pi = np.eye(n) - a.T @ a
    cfg = kernel_config(EXPONENTIAL, 0.9, (1e15, 1e30), Pi=Pi)
    il, w = (1.0, 1.0 / 0.9) if held_back else (1.0 / 0.9, 1.0)
    phi = rng.standard_normal(n)
    z = rng.standard_normal((m, 1))
    _, Pm, x_prior, P_prior = _streaming.predict(x, P, il, Q, cfg, None)
    f1, eager = _streaming.update(x, Pm, phi, z, 0.5, cfg, w, None)
    f2, fused = _streaming.update(x, P, phi, z, 0.5, cfg, w, None, il=il, Q=Q)
    assert f1 == f2
    for i in (0, 1, *range(3, 11)):                # x, P and the diagonostics
        assert_array_equal(fused[i], eager[i])
    assert_array_equal(fused[11], x_prior)
    assert_array_equal(fused[12], P_prior)
    if not constrained:                            # the textbook step, to round-off
        rP = ref.rls_predict(P, 0.9, Q) if not held_back else P + Q
        assert_allclose(P_prior, rP, rtol=1e-14)


def test_entry_points_give_the_dispatchers_results(rng):
    x, P = _state(rng)
    cfg = kernel_config(EXPONENTIAL, 0.9, ())
    _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, None)     # resolve the entry point
    assert _streaming._update_kernel is not _streaming.kernels().update_kernel
    phi = rng.standard_normal(n)
    a = _streaming._block(_streaming.update_shapes(n, m), _streaming.update_work(n))
    b = _streaming._block(_streaming.update_shapes(n, m), _streaming.update_work(n))
    xa, Pa, xb, Pb = np.empty((n, m)), np.empty((n, n)), np.empty((n, m)), np.empty((n, n))
    Q = np.zeros((0, 0))
    ra = _streaming._update_kernel(x, P, phi, 0.0, 2, 1.0, cfg, 1.0, 1.0 / 0.9, Q, xa, Pa, a[0])
    rb = _streaming.kernels().update_kernel(x, P, phi, 0.0, 2, 1.0, cfg, 1.0, 1.0 / 0.9, Q, xb,
                                            Pb, b[0])
    assert ra == rb
    assert_array_equal(xa, xb)
    assert_array_equal(Pa, Pb)
    for va, vb in zip(a[1:], b[1:], strict=True):   # the arrays (not the work space)
        assert_array_equal(va, vb)


def test_entry_point_falls_back_to_the_dispatcher(monkeypatch):
    import numba

    dispatcher = _streaming.kernels().predict_kernel
    monkeypatch.setattr(numba, "typeof", lambda a: (_ for _ in ()).throw(RuntimeError))
    assert _streaming._entry_point(dispatcher, (1.0,)) is dispatcher


def test_c_array_copies_only_when_needed():
    a = np.zeros((3, 2))
    assert _streaming.c_array(a) is a
    for b in (np.asfortranarray(np.ones((3, 2))), np.arange(6).reshape(3, 2), a[:, :1]):
        c = _streaming.c_array(b)
        assert c is not b and c.flags.c_contiguous and c.dtype == np.float64
        assert_array_equal(c, b)
    r = np.zeros(3)
    r.setflags(write=False)
    assert _streaming.c_array(r).flags.writeable


def test_free_sums_match_the_blocks():
    if _streaming._FREE_UPDATE < 0:
        pytest.skip("reference counts not trusted here")
    predict = _streaming._block(_streaming.predict_shapes(n, m))
    assert sum(map(sys.getrefcount, predict)) == _streaming._FREE_PREDICT
    update = ((np.empty((n, m)), np.empty((n, n)))
              + _streaming._block(_streaming.update_shapes(n, m)))
    assert [sys.getrefcount(a) for a in update] == _streaming._FREE_EACH
    assert _streaming.quick_count(update) == _streaming._FREE_UPDATE


@pytest.mark.skipif(_streaming._FREE_UPDATE < 0, reason="reference counts not trusted here")
def test_renew_keeps_what_is_free(rng):
    """A held estimate makes a new x, P pair but keeps the block, and the reverse."""
    x, P = _state(rng)
    cfg = kernel_config(EXPONENTIAL, 0.9, ())
    _, spare = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, None)
    held = spare[0]                                # a caller keeps the estimate
    _, again = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, spare)
    assert again[0] is not held and again[2:] == spare[2:]
    del spare, held
    row = again[3][0]                              # a caller keeps a row of y: the buffer
    _, third = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, again,
                                 handed=_streaming.VIEWS)
    assert third[:2] == again[:2] and third[2] is not again[2]
    del row, again
    view = third[4]                                # a caller keeps K itself
    ids = [id(a) for a in third]
    _, fourth = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, third,
                                  handed=_streaming.VIEWS)
    assert [id(a) for a in fourth[:2]] == ids[:2] and id(fourth[2]) != ids[2]
    del view, third
    ids = [id(a) for a in fourth]
    _, fifth = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, fourth,
                                 handed=_streaming.STATE)
    assert [id(a) for a in fifth] == ids           # nobody holds anything: all reused
    held = fifth[0]
    _, sixth = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, fifth,
                                 handed=_streaming.STATE)
    assert sixth[0] is not held and sixth[2:] == fifth[2:]   # x held: x, P made anew
    del held, fifth
    ids = [id(a) for a in sixth]
    _, seventh = _streaming.update(x, P, np.ones(n), None, 1.0, cfg, 1.0, sixth,
                                   handed=_streaming.NOTHING)
    assert [id(a) for a in seventh] == ids         # nothing handed out: no test at all
