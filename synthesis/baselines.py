"""
Former routes, kept as measured references
==========================================

The benchmarks (``python -m experiments bench-*``, ``experiments/bench/``) time each fast route beside the
route it replaced, in the same run, and time the pieces of one adaptive redesign one by one. This module gives
those former routes and pieces a public name, so that a benchmark (or a researcher repeating a measurement)
needs no private name of the library. They give the numbers of the public routes to rounding, they are not the
routes to use, and they may go with the benchmark that measures them.

   interleaved_gram_loop   -- ``ZZᵀ`` of interleaved Hankel data by the former block-row loop of (2.8)–(2.9)
   former_cholesky_fit     -- the Cholesky predictor fit before the fast paths (loop Gram, full factor, §2.2 pinv)
   predictor_from_gram     -- the predictor from a Gram ``AAᵀ`` with a choice of route (triangular or spectral)
   minimax_saddle          -- the engine's factorisation of one game: QR of ``M_u`` and γ_min (3.29)
   minimax_gains           -- the saddle-point gains (3.31) from that factorisation, with a choice of route
   adaptive_plan           -- the map plan an ``AdaptiveHinf`` keeps between redesigns (weights' blocks, built once)
   design_from_plan        -- one redesign of ``AdaptiveHinf`` from its plan (saddle, gains, expansion)
   FormerAdaptiveHinf      -- ``AdaptiveHinf`` with the redesign route before the fast paths
   discrete_mixsyn_grid    -- ``discrete_mixsyn`` with the former dense-grid level check

>>> import numpy as np
>>> from synthesis import baselines, fit_predictor
>>> rng = np.random.default_rng(0)
>>> u = rng.standard_normal(300)
>>> y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.01 * rng.standard_normal(300)
>>> Lw, Lu = baselines.former_cholesky_fit(u, y, 5)
>>> p = fit_predictor(u, y, 5)
>>> bool(np.allclose(Lw, p.Lw) and np.allclose(Lu, p.Lu))
True
"""
from __future__ import annotations

import time
import warnings

import numpy as np

from .adaptive import AdaptiveHinf, AdaptiveUpdate
from .hankel import _interleaved_gram_loop, hankel_order
from .hinf import _design_from_plan, hinf_design
from .infinite_horizon import _discrete_mixsyn
from .minimax import _gains, _saddle
from .predictor import _input_rank_from_factor, _predictor_from_gram, _solve_from_r, _split, default_rcond

__all__ = [
    "interleaved_gram_loop",
    "former_cholesky_fit",
    "predictor_from_gram",
    "minimax_saddle",
    "minimax_gains",
    "adaptive_plan",
    "design_from_plan",
    "FormerAdaptiveHinf",
    "discrete_mixsyn_grid",
]


def interleaved_gram_loop(z, rows: int, cols: int) -> np.ndarray:
    """``ZZᵀ`` of the block Hankel matrix of interleaved samples ``z`` by the former block-row loop.

    The route before the vectorised recursion of :func:`synthesis.hankel_gram`: ``rows`` BLAS products of
    ``c × cols`` slices and ``rows − 1`` Python iterations of (2.8)–(2.9).

    Parameters
    ----------
    z : ndarray, shape (n, c)
        Samples, one row per time step (``[u y]`` side by side), C-contiguous.
    rows : int
        Block rows of the Hankel matrix (``2i`` for a predictor of horizon ``i``).
    cols : int
        Columns ``j`` (``n ≥ rows + cols − 1``).

    Returns
    -------
    ndarray, shape (rows·c, rows·c)
        The Gram matrix in the interleaved row order (:func:`synthesis.hankel_order` permutes it).

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis.baselines import interleaved_gram_loop
    >>> z = np.random.default_rng(0).standard_normal((20, 2))
    >>> H = np.vstack([z[k:k + 17].T for k in range(4)])  # block row k: the samples k … k + 16
    >>> bool(np.allclose(interleaved_gram_loop(z, 4, 17), H @ H.T))
    True
    """
    return _interleaved_gram_loop(z, rows, cols)


def former_cholesky_fit(u, y, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """The Cholesky predictor fit before the fast paths: ``(Lw, Lu)``, the numbers of :func:`synthesis.fit_predictor`.

    ``AAᵀ`` by the block-row loop (:func:`interleaved_gram_loop`), ``numpy.linalg.cholesky``, the
    eigendecomposition pseudo-inverse of §2.2 and the input rank from ``eigvalsh`` — always the rank-revealing
    route (``bench-predictor``'s baseline).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) / (n, l)
        Input and output samples.
    horizon : int
        Prediction horizon ``i``.

    Returns
    -------
    Lw, Lu : ndarray
        The predictor's blocks (2.6).

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import fit_predictor
    >>> from synthesis.baselines import former_cholesky_fit
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.01 * rng.standard_normal(200)
    >>> Lw, Lu = former_cholesky_fit(u, y, 4)
    >>> Lw.shape, Lu.shape, bool(np.allclose(Lu, fit_predictor(u, y, 4).Lu))
    ((4, 8), (4, 4), True)
    """
    i = horizon
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    m, l = u.shape[1], y.shape[1]
    j = u.shape[0] - 2 * i + 1
    n_reg = i * (2 * m + l)
    perm = hankel_order(i, m, l)
    G = _interleaved_gram_loop(np.ascontiguousarray(np.hstack([u, y])), 2 * i, j)[np.ix_(perm, perm)]
    R = np.linalg.cholesky(G)
    tol = default_rcond("cholesky", n_reg, j)
    L, _, q = _solve_from_r(R, n_reg, tol, squared=True)
    _input_rank_from_factor(R, i, m, l, tol, squared=True)
    return _split(L, i, m, l)


def predictor_from_gram(G, horizon: int, m: int, l: int, n_columns: int, rcond: float, method: str, *,
                        route: str = "auto"):
    """The :class:`~synthesis.Predictor` from the Gram matrix ``AAᵀ`` of the Hankel data (rows as (2.7)).

    Parameters
    ----------
    G : ndarray
        ``AAᵀ`` in the row order ``[U_p; Y_p; U_f; Y_f]``; only its lower triangle is read.
    horizon, m, l, n_columns : int
        ``i``, the input and output dimensions and the number of data columns ``j``.
    rcond : float
        Relative tolerance of the pseudo-inverse (:func:`synthesis.default_rcond`).
    method : str
        The fit method recorded in the predictor (``"cholesky"``, ``"recursive"``).
    route : {"auto", "spectral"}, optional
        ``"auto"``: the current route (two triangular solves on the regressor block's factor when it is well
        conditioned, as :func:`~synthesis.fit_predictor`); ``"spectral"``: the former rank-revealing route
        (eigendecomposition pseudo-inverse of §2.2) every time.

    Returns
    -------
    Predictor

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import default_rcond, fit_predictor, hankel_gram
    >>> from synthesis.baselines import predictor_from_gram
    >>> rng = np.random.default_rng(2)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.01 * rng.standard_normal(200)
    >>> i, j = 4, 200 - 2 * 4 + 1
    >>> tol = default_rcond("cholesky", i * 3, j)
    >>> p = predictor_from_gram(hankel_gram(u, y, i), i, 1, 1, j, tol, "cholesky", route="spectral")
    >>> bool(np.allclose(p.Lu, fit_predictor(u, y, i).Lu))
    True
    """
    return _predictor_from_gram(G, horizon, m, l, n_columns, rcond, method, stacklevel=4, route=route)


def minimax_saddle(Md, Mu, Mx=None):
    """The engine's factorisation of the game (3.31): QR of ``M_u`` and ``γ_min = ‖(I − P_u) M_d‖₂`` (3.29).

    :func:`synthesis.solve_minimax` is this followed by :func:`minimax_gains`; the benchmarks time the two
    apart.

    Parameters
    ----------
    Md, Mu : ndarray
        The disturbance and control maps of the performance map.
    Mx : ndarray, optional
        The map of the past data (needed for :func:`minimax_gains`).

    Returns
    -------
    object
        The factorisation; ``gamma_min`` is its γ_min (an internal record, read only by :func:`minimax_gains`).

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import minimax_gamma_min
    >>> from synthesis.baselines import minimax_saddle
    >>> rng = np.random.default_rng(0)
    >>> Md, Mu, Mx = rng.standard_normal((6, 3)), rng.standard_normal((6, 2)), rng.standard_normal((6, 4))
    >>> minimax_saddle(Md, Mu, Mx).gamma_min == minimax_gamma_min(Md, Mu)
    True
    """
    return _saddle(Md, Mu, Mx)


def minimax_gains(saddle, gamma: float, route: str = "auto"):
    """Saddle-point gains ``(u_gain, d_gain, route)`` (3.31) at ``gamma`` from :func:`minimax_saddle`.

    Parameters
    ----------
    saddle : object
        The factorisation of :func:`minimax_saddle` (with ``Mx``).
    gamma : float
        A level above the factorisation's ``gamma_min``.
    route : {"auto", "cholesky", "svd"}, optional
        ``"auto"``: the engine's choice (Cholesky of ``γ²I − XᵀX`` away from γ_min, else the SVD); the others
        force one (the SVD route is the former one, kept as the benchmarks' reference).

    Returns
    -------
    u_gain, d_gain : ndarray
        Control and worst-case disturbance gains on the past data.
    route : str
        The route taken.

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import solve_minimax
    >>> from synthesis.baselines import minimax_gains, minimax_saddle
    >>> rng = np.random.default_rng(0)
    >>> Md, Mu, Mx = rng.standard_normal((6, 3)), rng.standard_normal((6, 2)), rng.standard_normal((6, 4))
    >>> sd = minimax_saddle(Md, Mu, Mx)
    >>> u_c, _, r_c = minimax_gains(sd, 2 * sd.gamma_min)
    >>> u_s, _, r_s = minimax_gains(sd, 2 * sd.gamma_min, route="svd")
    >>> r_c, r_s, bool(np.allclose(u_c, u_s)), bool(np.allclose(u_c, solve_minimax(Md, Mu, Mx, 2 * sd.gamma_min).u_gain))
    ('cholesky', 'svd', True, True)
    """
    return _gains(saddle, gamma, route=route)


def adaptive_plan(adaptive: AdaptiveHinf):
    """The map plan ``adaptive`` keeps between redesigns (the weights' Toeplitz/observability blocks, built once).

    Its ``fill(Lw, Lu)`` is the full :class:`~synthesis.PerformanceMap`, ``saddle(Lu)`` the factorisation of
    the game on the reduced map; :func:`design_from_plan` uses it for one redesign.

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import AdaptiveHinf, makeweight
    >>> from synthesis.baselines import adaptive_plan
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.01 * rng.standard_normal(300)
    >>> ad = AdaptiveHinf.from_data(u, y, 5, makeweight(10.0, (0.5, 1.0), 0.5, 0.1), 0.1, period=50)
    >>> pred = ad.recursive.predictor()
    >>> pm = adaptive_plan(ad).fill(pred.Lw, pred.Lu)
    >>> pm.Mu.shape[1] == 5
    True
    """
    return adaptive._plan


def design_from_plan(pred, Lw, Lu, plan, gamma):
    """One redesign of :class:`~synthesis.AdaptiveHinf`: the :class:`~synthesis.HinfDesign` for ``pred`` from a plan.

    One saddle factorisation on the reduced map, the level, the gains and their expansion; equal to
    :func:`synthesis.hinf_design` on the same predictor to rounding (γ_min to the last bit).

    Parameters
    ----------
    pred : Predictor
        The predictor.
    Lw, Lu : ndarray
        Its blocks as float arrays.
    plan : object
        :func:`adaptive_plan` of an ``AdaptiveHinf`` built for the same horizon, sizes and weights.
    gamma : float or GammaPolicy
        The level, or the policy that picks it from γ_min.

    Returns
    -------
    HinfDesign

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import AdaptiveHinf, hinf_design, makeweight
    >>> from synthesis.baselines import adaptive_plan, design_from_plan
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> ad = AdaptiveHinf.from_data(u, y, 5, W1, 0.1, period=50)
    >>> pred = ad.recursive.predictor()
    >>> d = design_from_plan(pred, pred.Lw, pred.Lu, adaptive_plan(ad), ad.policy)
    >>> d.gamma_min == hinf_design(pred, W1, 0.1, gamma=ad.policy).gamma_min
    True
    """
    return _design_from_plan(pred, Lw, Lu, plan, gamma)


class FormerAdaptiveHinf(AdaptiveHinf):
    """:class:`~synthesis.AdaptiveHinf` with the redesign route before the fast paths (``bench-adaptive``'s baseline).

    Each update: the rank-revealing (spectral) predictor from the Gram, :func:`~synthesis.hinf_design` from
    scratch (weights validated and Toeplitz / observability blocks rebuilt) and the ``StateSpace`` built
    eagerly. The Gram push is the current one. Warnings of an update are silenced (not recorded).

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import AdaptiveHinf, makeweight
    >>> from synthesis.baselines import FormerAdaptiveHinf
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> old = FormerAdaptiveHinf.from_data(u, y, 5, W1, 0.1, period=50)
    >>> new = AdaptiveHinf.from_data(u, y, 5, W1, 0.1, period=50)
    >>> bool(np.isclose(old.design.gamma_min, new.design.gamma_min, rtol=1e-9))
    True
    """

    def _design(self, step, t0, t_push=0.0, c0=None):
        rp = self.recursive
        i, m, l, j = rp.horizon, rp.m, rp.l, rp.n_columns
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t1 = time.perf_counter()
            # rp's rcond was validated when it was built; None means the default
            tol = default_rcond("recursive", i * (2 * m + l), j) if rp._rcond is None else rp._rcond
            pred = _predictor_from_gram(rp.gram, i, m, l, j, tol, "recursive", route="spectral")
            t2 = time.perf_counter()
            design = hinf_design(pred, self.W1, self.W2, gamma=self.policy, **self._design_kwargs)
            design.controller  # built eagerly, as before
        t3 = time.perf_counter()
        cpu = time.thread_time() - c0 if c0 is not None else float("nan")
        rec = AdaptiveUpdate(step=step, gamma_min=float(design.gamma_min), gamma=float(design.gamma),
                             seconds=t3 - t0, n_columns=j, cpu_seconds=cpu,
                             phases=(("push", t_push), ("predictor", t2 - t1), ("design", t3 - t2)))
        return design, rec


def discrete_mixsyn_grid(P, W1, W2, gamma=None, *, gamma_ratio: float = 1.1, rtol: float = 1e-4, epsilon=None):
    """:func:`synthesis.discrete_mixsyn` with the former level check: the peak gain on a dense frequency grid.

    The public function proves each level (:func:`~synthesis.norm_below`) and brackets the result's norm
    (:func:`~synthesis.hinf_norm`); here a level counts as achieved when the grid's peak gain
    (:func:`~synthesis.peak_gain`) is below it — ``bench-norms``'s baseline.

    Parameters
    ----------
    P, W1, W2, gamma, gamma_ratio, rtol, epsilon
        As :func:`synthesis.discrete_mixsyn`.

    Returns
    -------
    MixsynResult
        ``bracket`` is None and ``norm`` the grid estimate.

    Examples
    --------
    >>> import control
    >>> from synthesis import discrete_mixsyn, makeweight
    >>> from synthesis.baselines import discrete_mixsyn_grid
    >>> P = control.ss([[0.8]], [[1.0]], [[0.5]], [[0.0]], 0.1)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> old, new = discrete_mixsyn_grid(P, W1, 0.1), discrete_mixsyn(P, W1, 0.1)
    >>> old.bracket is None, round(old.gamma_opt, 2) == round(new.gamma_opt, 2)
    (True, True)
    """
    return _discrete_mixsyn(P, W1, W2, gamma, gamma_ratio=gamma_ratio, rtol=rtol, epsilon=epsilon, route="grid")
