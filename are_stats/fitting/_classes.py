"""The classes a log names (its ``label`` column, no marks): shares and stays per class.

A log that names each artefact's class (cyclists, pedestrians, skaters, carts on a shared
path; issue 31) needs no invented marks: the class is the label (DECISIONS 5), and each
class gets

* a **share** of the arrivals: the Dirichlet-multinomial posterior
  ``Dirichlet(1 + n_1, ..., 1 + n_K)`` of the classes of the artefacts that arrived inside
  the window (those present at ``t0`` are left out: long stayers are over-represented among
  them, so they are not a sample of the arrivals' classes);
* a **mean stay** ``m_c`` under the log's stay law (the pooled fit's choice, its shape
  ``k`` kept: :mod:`are_stats.traffic` stay laws, censoring and truncation included), pooled
  hierarchically across classes: ``log m_c ~ Normal(m_0, tau)`` with a flat prior on
  ``m_0`` and ``tau ~ HalfNormal(1)``. A class seen twice borrows strength from the others:
  its mean shrinks toward the pool.

The posterior of the hierarchical model is computed by quadrature on a grid of log means
(no sampler, no compiled program): each class's likelihood is tabulated on the grid, the
hyper-parameters' posterior follows by summing over it, and the draws are exact draws of
the discretised posterior (jittered inside their grid cell). The pooled model (one mean for
every class) is fitted on the same grid, and the two are compared by PSIS-LOO over the
artefacts' stays like the other model choices (:func:`~are_stats.fitting.choose_simplest`:
the simplest within two standard errors of the best).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from are_stats._checks import check_in
from are_stats.traffic import STAY_LAWS, LifecycleData, numpy_rng, stay_loglik

__all__ = ["CLASS_STAY_MODELS", "ClassFit", "attach_classes", "fit_classes"]

#: Stay models of a labelled log, simplest first.
CLASS_STAY_MODELS = ("pooled", "per-class")

#: Grid of log mean stays: half-width (in log units) around the pooled estimate, and step.
_SPAN, _STEP = 7.0, 0.05
#: Between-class standard deviations of the log mean stay tried (half-normal(1) prior).
_TAUS = np.geomspace(0.03, 4.0, 32)
#: Rows of the log whose stay likelihood is tabulated at a time.
_BLOCK = 2048


@dataclass(frozen=True)
class ClassFit:
    """Shares and stays of the classes of a labelled log (see the module docstring).

    Attributes
    ----------
    labels : tuple of str
        Class names, class ``c`` is ``labels[c]``.
    counts : (K,) int
        Artefacts of each class that arrived inside the window (the shares' data).
    n_rows : (K,) int
        Artefacts of each class in the log (stays' data).
    weights : (S, K) float
        Draws of the class shares (rows sum to 1).
    stay_mean : (S, K) float
        Draws of each class's mean stay under the hierarchical (per-class) model.
    pool_mean, pool_sd : (S,) float
        Draws of ``exp(m_0)`` and ``tau`` (the pool the classes shrink toward).
    pooled_mean : (S,) float
        Draws of the one mean stay of the pooled model.
    law : str
        The stay law.
    shape : float
        Its shape (the pooled fit's; 1 for the exponential).
    stay_model : {"pooled", "per-class"}
        The model PSIS-LOO chose.
    table : pandas.DataFrame
        The comparison (``elpd``, ``se``, ``elpd_diff``, ``dse``, ``chosen``).
    """

    labels: tuple[str, ...]
    counts: np.ndarray
    n_rows: np.ndarray
    weights: np.ndarray
    stay_mean: np.ndarray
    pool_mean: np.ndarray
    pool_sd: np.ndarray
    pooled_mean: np.ndarray
    law: str
    shape: float
    stay_model: str
    table: pd.DataFrame


def _exponential_loglik(
    dwell: np.ndarray, cen: np.ndarray, tru: np.ndarray, mean: np.ndarray, resolution: float
) -> np.ndarray:
    """:func:`~are_stats.traffic.stay_loglik` of the exponential law, in NumPy (broadcast).

    Memoryless: every row adds ``-dwell / m``, a departure ``- log m``; a whole stay
    shorter than the resolution is ``log(1 - e^{-delta / m})`` instead.
    """
    ll = -dwell / mean - np.where(cen, 0.0, np.log(mean))
    if resolution > 0:
        short = (dwell < resolution) & ~cen & ~tru
        ll = np.where(short, np.log(-np.expm1(-resolution / mean)), ll)
    return ll


def _loglik(
    law: str, dwell: Any, cen: Any, tru: Any, mean: Any, shape: float, resolution: float
) -> np.ndarray:
    """Pointwise stay log-likelihood (broadcast), NumPy for the exponential law."""
    if law == "exponential":
        return _exponential_loglik(dwell, cen, tru, mean, resolution)
    return np.asarray(stay_loglik(law, dwell, cen, tru, mean, shape, resolution), float)


def _class_loglik(
    data: LifecycleData, classes: np.ndarray, k: int, grid: np.ndarray, law: str, shape: float,
    resolution: float,
) -> np.ndarray:  # fmt: skip
    """``(K, G)`` stay log-likelihood of each class's rows at each grid log mean."""
    out = np.zeros((k, grid.size))
    mean = np.exp(grid)[None, :]
    dwell, cen, tru = data.dwell, data.censored, data.truncated
    for j in range(0, data.n, _BLOCK):
        sl = slice(j, j + _BLOCK)
        ll = _loglik(law, dwell[sl, None], cen[sl, None], tru[sl, None], mean, shape, resolution)
        np.add.at(out, classes[sl], ll)
    return out


def _pointwise(
    data: LifecycleData, law: str, shape: float, resolution: float, means: np.ndarray
) -> np.ndarray:
    """``(D, n)`` stay log-likelihood of each row under draws ``means`` (D, n)."""
    return _loglik(law, data.dwell[None, :], data.censored[None, :], data.truncated[None, :],
                   means, shape, resolution)  # fmt: skip


def _gumbel_pick(rng: np.random.Generator, logits: np.ndarray) -> np.ndarray:
    """Index drawn from ``softmax(logits)`` along the last axis (Gumbel-max)."""
    return np.argmax(logits + rng.gumbel(size=logits.shape), axis=-1)


def fit_classes(
    key: Any,
    data: LifecycleData,
    classes: Any,
    labels: Any,
    *,
    law: str = "exponential",
    shape: float = 1.0,
    n_draws: int = 4000,
    n_loo_draws: int = 1000,
    resolution: float = 0.0,
) -> ClassFit:
    """Fit class shares and hierarchical per-class mean stays of a labelled log.

    Parameters
    ----------
    key : jax PRNG key
        All randomness (reproducible from it).
    data : LifecycleData
        The log (its stays through the window: ``dwell``, ``censored``, ``truncated``).
    classes : (n,) int
        Class of each row, ``0..K-1``.
    labels : sequence of str
        The K class names.
    law : {"exponential", "gamma", "weibull", "lognormal"}
        The stay law (the pooled fit's choice).
    shape : float
        Its shape (the pooled fit's posterior median; unused by the exponential).
    n_draws : int
        Posterior draws returned.
    n_loo_draws : int
        Draws used by PSIS-LOO (a thinned subset).
    resolution : float
        The log's time resolution (stays shorter than it are interval-censored).

    Returns
    -------
    ClassFit

    Raises
    ------
    ValueError
        If ``classes`` does not match the log or names a class outside ``labels``.

    Examples
    --------
    >>> import jax, numpy as np
    >>> from are_stats.traffic import LifecycleData
    >>> d = LifecycleData(t_arrive=np.array([1.0, 2, 3, 4]), t_leave=np.array([3.0, 9, 5, 20]),
    ...                   window=(0.0, 30.0), area=10.0)
    >>> f = fit_classes(jax.random.key(0), d, [0, 1, 0, 1], ["person", "bicycle"], n_draws=10)
    >>> f.weights.shape, f.stay_mean.shape
    ((10, 2), (10, 2))
    """
    from scipy.special import logsumexp

    from are_stats.fitting._traffic import choose_simplest, loo_pointwise
    from are_stats.inputs import check_memory, check_work

    check_in("law", law, STAY_LAWS)
    names = tuple(str(v) for v in labels)
    k = len(names)
    cls = np.asarray(classes)
    if cls.shape != (data.n,) or cls.dtype.kind not in "iu":
        raise ValueError(f"classes: expected ({data.n},) integers, got {cls.dtype} {cls.shape}")
    if k < 1 or (cls.size and (cls.min() < 0 or cls.max() >= k)):
        raise ValueError(f"classes: expected codes in 0..{k - 1} (one per label), got others")
    rng = numpy_rng(key)
    shape = 1.0 if law == "exponential" else float(shape)
    n_rows = np.bincount(cls, minlength=k)
    counts = np.bincount(cls[~data.truncated], minlength=k)
    weights = rng.dirichlet(1.0 + counts.astype(float), n_draws)
    # the grid of log means, centred on the pooled exponential estimate
    departed = max(int(np.sum(~data.censored)), 1)
    centre = float(np.log(max(float(np.sum(data.dwell)) / departed, 1e-9)))
    grid = centre + np.arange(-_SPAN, _SPAN + _STEP / 2, _STEP)
    g = grid.size
    check_work(float(data.n) * g * 50.0 + float(n_loo_draws) * data.n * 100.0,
               f"the per-class stays of {data.n} artefacts")  # fmt: skip
    check_memory(float(_BLOCK) * g * 8.0 * 8 + float(n_loo_draws) * data.n * 8.0 * 6,
                 f"the per-class stays of {data.n} artefacts")  # fmt: skip
    lik = _class_loglik(data, cls, k, grid, law, shape, resolution)  # (K, G)
    # the discretised prior N(m0, tau) on the grid, normalised over it: (M, T, G)
    m0 = grid[::4]
    z = (grid[None, None, :] - m0[:, None, None]) / _TAUS[None, :, None]
    log_prior = -0.5 * z * z
    log_prior -= logsumexp(log_prior, axis=-1, keepdims=True)
    # log p(data_c | m0, tau) for every class: (K, M, T); then the hyper posterior
    marg = logsumexp(lik[:, None, None, :] + log_prior[None], axis=-1)
    log_tau_prior = -0.5 * _TAUS**2 + np.log(_TAUS)  # half-normal(1), grid uniform in log tau
    hyper = marg.sum(axis=0) + log_tau_prior[None, :]  # (M, T)
    flat = hyper.ravel()
    pick = rng.choice(flat.size, size=n_draws, p=np.exp(flat - logsumexp(flat)))
    im, it = np.unravel_index(pick, hyper.shape)
    # each class's log mean given the hyper draw: (S, K, G) in blocks of draws
    idx = np.empty((n_draws, k), np.int64)
    for j in range(0, n_draws, 512):
        sl = slice(j, j + 512)
        logits = lik[None, :, :] + log_prior[im[sl], it[sl]][:, None, :]
        idx[sl] = _gumbel_pick(rng, logits)
    jitter = lambda size: (rng.random(size) - 0.5) * _STEP  # noqa: E731
    stay_mean = np.exp(grid[idx] + jitter(idx.shape))
    pool_mean = np.exp(m0[im] + jitter(n_draws) * 4)
    pool_sd = _TAUS[it]
    # the pooled model: one mean for all, flat prior on the grid
    pooled = lik.sum(axis=0)
    pooled_idx = rng.choice(g, size=n_draws, p=np.exp(pooled - logsumexp(pooled)))
    pooled_mean = np.exp(grid[pooled_idx] + jitter(n_draws))
    # PSIS-LOO of the two over the artefacts' stays
    d = min(n_loo_draws, n_draws)
    if data.n:
        elpd = {
            "pooled": loo_pointwise(
                _pointwise(data, law, shape, resolution, pooled_mean[:d, None])[None]
            )[0],
            "per-class": loo_pointwise(
                _pointwise(data, law, shape, resolution, stay_mean[:d][:, cls])[None]
            )[0],
        }
        chosen, table = choose_simplest(elpd, list(CLASS_STAY_MODELS))
    else:
        chosen = "pooled"
        table = pd.DataFrame(
            {"elpd": [0.0, 0.0], "se": 0.0, "elpd_diff": 0.0, "dse": 0.0,
             "chosen": [True, False]}, index=pd.Index(CLASS_STAY_MODELS, name="model"),
        )  # fmt: skip
    return ClassFit(
        labels=names, counts=counts, n_rows=n_rows, weights=weights, stay_mean=stay_mean,
        pool_mean=pool_mean, pool_sd=pool_sd, pooled_mean=pooled_mean, law=law, shape=shape,
        stay_model=chosen, table=table,
    )  # fmt: skip


def attach_classes(idata: Any, fit: ClassFit) -> Any:
    """Store a :class:`ClassFit` in a fit's ``posterior``.

    Variables over ``(chain, draw, class)``: ``class_weights`` (the shares) and
    ``class_stay_mean`` (per-class mean stays); over ``(chain, draw)``:
    ``class_pool_stay_mean`` and ``class_pool_sd`` (the hierarchy's pool) and
    ``class_pooled_stay_mean`` (the pooled model). Attributes ``class_stay_model`` (the
    LOO choice), ``class_stay_law``, ``class_stay_shape``, ``class_counts`` (arrivals per
    class), ``class_rows`` (artefacts per class) and ``loo_class_stays`` (CSV text). The
    draws are reshaped to the posterior's ``(chain, draw)``.
    """
    import xarray as xr

    post = idata.posterior
    c, d = post.sizes["chain"], post.sizes["draw"]
    if fit.weights.shape[0] != c * d:
        raise ValueError(
            f"fit: expected {c * d} draws (the posterior's), got {fit.weights.shape[0]}"
        )
    k = len(fit.labels)
    for name, v in (("class_weights", fit.weights), ("class_stay_mean", fit.stay_mean)):
        post[name] = xr.DataArray(v.reshape(c, d, k), dims=("chain", "draw", "class"))
    for name, v in (
        ("class_pool_stay_mean", fit.pool_mean),
        ("class_pool_sd", fit.pool_sd),
        ("class_pooled_stay_mean", fit.pooled_mean),
    ):
        post[name] = xr.DataArray(np.asarray(v, float).reshape(c, d), dims=("chain", "draw"))
    a = post.attrs
    a["class_stay_model"] = fit.stay_model
    a["class_stay_law"] = fit.law
    a["class_stay_shape"] = float(fit.shape)
    a["class_counts"] = np.asarray(fit.counts, np.int64)
    a["class_rows"] = np.asarray(fit.n_rows, np.int64)
    a["loo_class_stays"] = fit.table.to_csv(float_format="%.6g")
    return idata
