"""Rank-1 Cholesky update / downdate (§2.3.1) against numpy.linalg.cholesky of the modified matrix."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synthesis import DataError, DowndateError, choldowndate, cholupdate


def _spd(rng, N, extra=3):
    M = rng.standard_normal((N, N + extra))
    return M @ M.T


@pytest.mark.parametrize("N", [1, 2, 7, 40])
def test_update_matches_numpy_cholesky(N):
    rng = np.random.default_rng(N)
    G = _spd(rng, N)
    x = rng.standard_normal(N)
    L = np.linalg.cholesky(G)
    Lu = cholupdate(L, x)
    ref = np.linalg.cholesky(G + np.outer(x, x))
    np.testing.assert_allclose(Lu, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.allclose(np.triu(Lu, 1), 0.0)  # still lower triangular
    np.testing.assert_array_equal(L, np.linalg.cholesky(G))  # input untouched by default


@pytest.mark.parametrize("N", [1, 2, 7, 40])
def test_downdate_matches_numpy_cholesky(N):
    rng = np.random.default_rng(100 + N)
    G = _spd(rng, N)
    x = 0.5 * np.linalg.cholesky(G) @ rng.standard_normal(N) / np.sqrt(N)  # keeps G - x xᵀ positive definite
    assert np.all(np.linalg.eigvalsh(G - np.outer(x, x)) > 0)
    Ld = choldowndate(np.linalg.cholesky(G), x)
    ref = np.linalg.cholesky(G - np.outer(x, x))
    np.testing.assert_allclose(Ld, ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    assert np.all(np.diag(Ld) > 0)


def test_upper_convention_and_in_place():
    rng = np.random.default_rng(5)
    G = _spd(rng, 9)
    x = rng.standard_normal(9)
    R = np.linalg.cholesky(G).T.copy()  # thesis convention: G = Rᵀ R, R upper
    Ru = cholupdate(R, x, lower=False, overwrite=True)
    assert Ru is R
    np.testing.assert_allclose(Ru.T @ Ru, G + np.outer(x, x), rtol=1e-12, atol=1e-12 * np.abs(G).max())
    Rd = choldowndate(Ru, x, lower=False)
    np.testing.assert_allclose(Rd, np.linalg.cholesky(G).T, atol=1e-11 * np.abs(G).max() ** 0.5)


def test_downdate_refuses_loss_of_definiteness_without_modifying():
    rng = np.random.default_rng(7)
    G = _spd(rng, 6)
    L = np.linalg.cholesky(G)
    v = rng.standard_normal(6)
    x = 1.0001 * L @ v / np.linalg.norm(v)  # ‖L⁻¹x‖ > 1: G − x xᵀ is indefinite
    assert np.linalg.eigvalsh(G - np.outer(x, x)).min() < 0
    L0 = L.copy()
    with pytest.raises(DowndateError, match="positive definiteness"):
        choldowndate(L, x, overwrite=True)
    np.testing.assert_array_equal(L, L0)
    # exactly singular result is refused too (‖L⁻¹x‖ = 1)
    with pytest.raises(DowndateError):
        choldowndate(L, L @ v / np.linalg.norm(v))


def test_downdate_refuses_singular_factor():
    L = np.diag([1.0, 0.0, 2.0])
    with pytest.raises(DowndateError, match="singular"):
        choldowndate(L, [0.1, 0.0, 0.1])
    assert issubclass(DowndateError, np.linalg.LinAlgError)


def test_update_of_singular_factor():
    """A rank-deficient factor (zero pivots) can still be updated (the §6.3 start-up case)."""
    rng = np.random.default_rng(11)
    M = rng.standard_normal((5, 2))
    G = M @ M.T  # rank 2
    L = np.hstack([np.linalg.qr(M.T, mode="r").T, np.zeros((5, 3))])
    np.testing.assert_allclose(L @ L.T, G, atol=1e-12)  # lower factor with three zero columns
    x = rng.standard_normal(5)
    Lu = cholupdate(L, x)
    np.testing.assert_allclose(Lu @ Lu.T, G + np.outer(x, x), atol=1e-12)
    assert np.allclose(np.triu(Lu, 1), 0.0)


def test_bad_arguments():
    with pytest.raises(ValueError, match="square"):
        cholupdate(np.ones((2, 3)), [1.0, 2.0])
    with pytest.raises(ValueError, match="entries"):
        cholupdate(np.eye(3), [1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        choldowndate(np.eye(2), [np.nan, 0.0])


@pytest.mark.parametrize("rtol, match", [(-1, "rtol must be a finite number >= 0"),
                                         ("1", "rtol must be a finite number >= 0"),
                                         (1.0, r"rtol must lie in \[0, 1\).*leave it None")])
def test_downdate_rtol_is_checked(rtol, match):
    """rtol=-1 had been accepted; rtol="1" had been read as 1.0 and reported as a loss of positive definiteness."""
    L = np.linalg.cholesky(np.array([[4.0, 1.0], [1.0, 3.0]]))
    with pytest.raises(DataError, match=match):
        choldowndate(L, [0.1, 0.1], rtol=rtol)
    assert np.allclose(choldowndate(L, [0.1, 0.1], rtol=0), choldowndate(L, [0.1, 0.1]))


def test_complex_factor_or_column_is_refused():
    """A complex L had lost its imaginary part (ComplexWarning), a complex x had raised a bare TypeError."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DataError, match="Cholesky factor L is complex.*real part"):
            cholupdate(np.eye(2) + 0j, [1.0, 0.0])
        with pytest.raises(DataError, match="x is complex"):
            cholupdate(np.eye(2), [1j, 0.0])
        with pytest.raises(DataError, match="Cholesky factor L is complex"):
            choldowndate(2 * np.eye(2) + 0j, [0.1, 0.0])


@settings(max_examples=25, deadline=None)
@given(
    N=st.integers(1, 12),
    n_updates=st.integers(1, 6),
    seed=st.integers(0, 2**31 - 1),
)
def test_update_then_downdate_sequence_property(N, n_updates, seed):
    """Updating by k vectors and downdating them again (any order) returns the original factor."""
    rng = np.random.default_rng(seed)
    G = _spd(rng, N)
    L0 = np.linalg.cholesky(G)
    X = rng.standard_normal((n_updates, N)) * rng.uniform(0.1, 3.0)
    L = L0.copy()
    for x in X:
        L = cholupdate(L, x)
    np.testing.assert_allclose(L, np.linalg.cholesky(G + X.T @ X), atol=1e-10 * np.sqrt(np.abs(G + X.T @ X).max()))
    for x in X[rng.permutation(n_updates)]:
        L = choldowndate(L, x)
    np.testing.assert_allclose(L, L0, atol=1e-8 * np.sqrt(np.abs(G + X.T @ X).max()))
