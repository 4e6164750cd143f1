"""The compressed least-squares problem (benchmarks.lab.squeeze) tells scipy's trust region the
same ‖r‖, Jᵀr and JᵀJ as the full problem of n rows, also where J loses rank."""

import numpy as np
import pytest

from benchmarks.lab.squeeze import compress


def _problem(rng, n=2000, p=4, m=3):
    q = np.linalg.qr(rng.standard_normal((n, m)))[0]
    w = rng.uniform(0.5, 2.0, n)
    d = rng.standard_normal((n, p)) * np.array([1e-3, 1.0, 1e3, 1e-6])[:p]
    return q, w, rng.standard_normal(n), rng.standard_normal(n), d, rng.uniform(0.1, 10, p)


def _full(q, w, wmu, g, d, scales):
    project = np.eye(len(w)) - q @ q.T
    return project @ (wmu - w * g), project @ (-w[:, None] * d * scales)


@pytest.mark.parametrize("lose", [False, True])
def test_the_compressed_problem_has_the_full_ones_squares_gradient_and_gauss_newton_matrix(lose):
    q, w, wmu, g, d, scales = _problem(np.random.default_rng(4))
    if lose:            # a repeated column and one inside the linear basis: rank 2 of 4
        d[:, 3] = d[:, 1] * scales[1] / scales[3]
        d[:, 0] = q[:, 0] / (-w * scales[0])
    r, jac = _full(q, w, wmu, g, d, scales)
    rt, jt, r_out = compress(wmu, w, g, d, scales, q)
    np.testing.assert_allclose(r_out, r, rtol=0, atol=1e-12)
    assert rt @ rt == pytest.approx(r @ r, rel=1e-12)
    gram = jac.T @ jac
    np.testing.assert_allclose(jt.T @ jt, gram, rtol=0, atol=1e-10 * np.abs(gram).max())
    np.testing.assert_allclose(jt.T @ rt, jac.T @ r, rtol=0,
                               atol=1e-9 * np.abs(jac.T @ r).max())
    assert jt.shape == (5, 4) and rt.shape == (5,)
