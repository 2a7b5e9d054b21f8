"""The classes a log names (its ``label`` column, no marks): shares and stays per class.

A log that names each artefact's class (cyclists, pedestrians, skaters, carts on a shared
path; issue 31) needs no invented marks: the class is the label (DECISIONS 5), and each
class gets

* a **share** of the arrivals: the Dirichlet-multinomial posterior
  ``Dirichlet(1 + n_1, ..., 1 + n_K)`` of the classes of the artefacts that arrived inside
  the window (those present at ``t0`` are left out: long stayers are over-represented among
  them, so they are not a sample of the arrivals' classes);
* a **mean stay** ``m_c`` under the log's stay law (the pooled fit's choice, with one shape
  ``k`` shared by the classes and fitted with them: :mod:`are_stats.traffic` stay laws,
  censoring and truncation included), pooled
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

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import jax
import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.special import gammainc, gammaincc, gammaln, log_ndtr, logsumexp, ndtr

from are_stats._checks import check_in
from are_stats.fitting._class_traffic import uncompared
from are_stats.fitting._fit import fit_class_labels, traffic_draws
from are_stats.fitting._motion_checks import band_flags
from are_stats.fitting._traffic import choose_simplest, loo_pointwise
from are_stats.inputs import check_memory, check_work
from are_stats.scenarios import generate_scenarios
from are_stats.traffic import STAY_LAWS, LifecycleData, numpy_rng

if TYPE_CHECKING:
    import arviz as az

__all__ = [
    "CLASS_MOTION_STATISTICS",
    "CLASS_STATISTICS",
    "CLASS_STAY_MODELS",
    "ClassFit",
    "attach_classes",
    "class_checks",
    "class_motion_checks",
    "fit_classes",
]

#: Stay models of a labelled log, simplest first.
CLASS_STAY_MODELS = ("pooled", "per-class")

#: Grid of log mean stays: half-width (in log units) around the pooled estimate, and step.
_SPAN, _STEP = 7.0, 0.05
#: Between-class standard deviations of the log mean stay tried (half-normal(1) prior).
_TAUS = np.geomspace(0.03, 4.0, 32)
#: Rows of the log whose stay likelihood is tabulated at a time.
_BLOCK = 1024
#: Shapes tried per law (flat prior in log shape): coefficients of variation 0.05 to 2.
_SHAPES = {
    "exponential": np.ones(1),
    "gamma": np.geomspace(0.25, 400.0, 21),
    "weibull": np.geomspace(0.5, 26.0, 21),
    "lognormal": np.geomspace(0.05, 1.6, 21),
}


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
    stay_shape : (S,) float
        Draws of the law's shape, shared by the classes (1 for the exponential).
    pool_mean, pool_sd : (S,) float
        Draws of ``exp(m_0)`` and ``tau`` (the pool the classes shrink toward).
    pooled_mean, pooled_shape : (S,) float
        Draws of the one mean stay and shape of the pooled model.
    law : str
        The stay law.
    stay_model : {"pooled", "per-class"}
        The model PSIS-LOO chose.
    table : pandas.DataFrame
        The comparison (``elpd``, ``se``, ``elpd_diff``, ``dse``, ``chosen``).
    classes : (n,) int or None
        The class of each row of the log (stored with the observed data).
    """

    labels: tuple[str, ...]
    counts: np.ndarray
    n_rows: np.ndarray
    weights: np.ndarray
    stay_mean: np.ndarray
    stay_shape: np.ndarray
    pool_mean: np.ndarray
    pool_sd: np.ndarray
    pooled_mean: np.ndarray
    pooled_shape: np.ndarray
    law: str
    stay_model: str
    table: pd.DataFrame
    classes: np.ndarray | None = None


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


def _law_terms(law: str, kind: str, t: np.ndarray, m: np.ndarray, k: np.ndarray) -> np.ndarray:
    """One term of :func:`~are_stats.traffic.stay_loglik` in NumPy/SciPy (broadcast).

    ``kind``: ``pdf`` (log density), ``cdf`` (log distribution), ``sf`` (log survival) or
    ``excess`` (log mean excess); the formulas of :mod:`are_stats.traffic` stays, each
    evaluated only on the rows that need it (the JAX function evaluates all four).
    """
    tiny = np.finfo(float).tiny
    t = np.maximum(t, 0.0)
    with np.errstate(divide="ignore", over="ignore", under="ignore", invalid="ignore"):
        if law == "gamma":
            x = k / m * t
            if kind == "pdf":
                return k * np.log(k / m) + (k - 1.0) * np.log(np.maximum(t, tiny)) - x - gammaln(k)
            if kind == "cdf":
                return np.log(np.maximum(gammainc(k, x), tiny))
            if kind == "sf":
                return np.log(np.maximum(gammaincc(k, x), tiny))
            a, b = m * gammaincc(k + 1.0, x), t * gammaincc(k, x)
        elif law == "weibull":
            scale = m / np.exp(gammaln(1.0 + 1.0 / k))
            z = t / scale
            if kind == "pdf":
                zk = np.maximum(z, tiny)
                return np.log(k) - np.log(scale) + (k - 1.0) * np.log(zk) - z**k
            if kind == "cdf":
                return np.log(np.maximum(-np.expm1(-(z**k)), tiny))
            if kind == "sf":
                return -(z**k)
            a, b = m * gammaincc(1.0 + 1.0 / k, z**k), t * np.exp(-(z**k))
        else:  # lognormal
            mu = np.log(m) - 0.5 * k * k
            lt = np.log(np.maximum(t, tiny))
            if kind == "pdf":
                zz = (lt - mu) / k
                return -lt - np.log(k) - 0.5 * np.log(2.0 * np.pi) - 0.5 * zz * zz
            if kind == "cdf":
                return log_ndtr((lt - mu) / k)
            if kind == "sf":
                return log_ndtr(-(lt - mu) / k)
            a, b = m * ndtr((mu + k * k - lt) / k), t * ndtr((mu - lt) / k)
        ratio = np.clip(b / np.maximum(a, tiny), 0.0, 1.0 - 1e-16)
        return np.log(np.maximum(a, tiny)) + np.log1p(-ratio)


def _loglik(
    law: str,
    dwell: npt.ArrayLike,
    cen: npt.ArrayLike,
    tru: npt.ArrayLike,
    mean: npt.ArrayLike,
    shape: npt.ArrayLike,
    resolution: float,
) -> np.ndarray:
    """Pointwise stay log-likelihood (broadcast over rows, draws, grids), in NumPy.

    Equal to :func:`~are_stats.traffic.stay_loglik` (the tests compare them); each row's
    term is evaluated only once, with SciPy's special functions.
    """
    if law == "exponential":
        return _exponential_loglik(dwell, cen, tru, mean, resolution)
    dwell, cen, tru, mean, shape = np.broadcast_arrays(
        np.asarray(dwell, float),
        np.asarray(cen, bool),
        np.asarray(tru, bool),
        np.asarray(mean, float),
        np.asarray(shape, float),
    )
    out = np.empty(dwell.shape)
    short = (dwell < resolution) if resolution > 0 else np.zeros(dwell.shape, bool)
    s_pos = np.maximum(dwell, 1e-12 * mean)
    for kind, sel, t, minus_log_m in (
        ("pdf", ~cen & ~tru & ~short, np.maximum(dwell, np.finfo(float).tiny), False),
        ("cdf", ~cen & ~tru & short, np.full(dwell.shape, float(resolution)), False),
        ("sf", cen & ~tru, s_pos, False),
        ("sf", ~cen & tru, s_pos, True),
        ("excess", cen & tru, s_pos, True),
    ):
        if sel.any():
            v = _law_terms(law, kind, t[sel], mean[sel], shape[sel])
            out[sel] = v - np.log(mean[sel]) if minus_log_m else v
    return out


def _class_loglik(
    data: LifecycleData,
    classes: np.ndarray,
    k: int,
    grid: np.ndarray,
    law: str,
    shapes: np.ndarray,
    resolution: float,
) -> np.ndarray:
    """``(H, K, G)`` stay log-likelihood of each class's rows at each shape and log mean."""
    out = np.zeros((shapes.size, k, grid.size))
    mean = np.exp(grid)[None, None, :]
    shape = shapes[None, :, None]
    dwell, cen, tru = (v[:, None, None] for v in (data.dwell, data.censored, data.truncated))
    onehot = np.eye(k)[classes]  # (n, K)
    for j in range(0, data.n, _BLOCK):
        sl = slice(j, j + _BLOCK)
        ll = _loglik(law, dwell[sl], cen[sl], tru[sl], mean, shape, resolution)  # (B, H, G)
        out += np.einsum("bk,bhg->hkg", onehot[sl], ll)
    return out


def _pointwise(
    data: LifecycleData, law: str, shape: np.ndarray, resolution: float, means: np.ndarray
) -> np.ndarray:
    """``(D, n)`` stay log-likelihood of each row under draws ``means`` (D, n), ``shape``
    (D, 1)."""
    return _loglik(
        law,
        data.dwell[None, :],
        data.censored[None, :],
        data.truncated[None, :],
        means,
        shape,
        resolution,
    )


def _gumbel_pick(rng: np.random.Generator, logits: np.ndarray) -> np.ndarray:
    """Index drawn from ``softmax(logits)`` along the last axis (Gumbel-max)."""
    return np.argmax(logits + rng.gumbel(size=logits.shape), axis=-1)


def fit_classes(
    key: jax.Array,
    data: LifecycleData,
    classes: npt.ArrayLike,
    labels: Sequence[str],
    *,
    law: str = "exponential",
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
        The stay law (the pooled fit's choice); its shape, shared by the classes, is fitted
        with the means (a grid of 21 shapes, flat in log shape; the pooled fit's shape
        also holds the spread between classes, so it is not reused).
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
    check_in("law", law, STAY_LAWS)
    names = tuple(str(v) for v in labels)
    k = len(names)
    cls = np.asarray(classes)
    if cls.shape != (data.n,) or cls.dtype.kind not in "iu":
        raise ValueError(f"classes: expected ({data.n},) integers, got {cls.dtype} {cls.shape}")
    if k < 1 or (cls.size and (cls.min() < 0 or cls.max() >= k)):
        raise ValueError(f"classes: expected codes in 0..{k - 1} (one per label), got others")
    rng = numpy_rng(key)
    shapes = _SHAPES[law]
    n_rows = np.bincount(cls, minlength=k)
    counts = np.bincount(cls[~data.truncated], minlength=k)
    weights = rng.dirichlet(1.0 + counts.astype(float), n_draws)
    # the grid of log means, centred on the pooled exponential estimate
    departed = max(int(np.sum(~data.censored)), 1)
    centre = float(np.log(max(float(np.sum(data.dwell)) / departed, 1e-9)))
    grid = centre + np.arange(-_SPAN, _SPAN + _STEP / 2, _STEP)
    g, h = grid.size, shapes.size
    check_work(
        float(data.n) * g * h * 50.0 + float(n_loo_draws) * data.n * 100.0,
        f"the per-class stays of {data.n} artefacts",
    )
    check_memory(
        float(_BLOCK) * g * h * 8.0 * 8 + float(n_loo_draws) * data.n * 8.0 * 6,
        f"the per-class stays of {data.n} artefacts",
    )
    lik = _class_loglik(data, cls, k, grid, law, shapes, resolution)  # (H, K, G)
    # the discretised prior N(m0, tau) on the grid, normalised over it: (M, T, G)
    m0 = grid[::4]
    z = (grid[None, None, :] - m0[:, None, None]) / _TAUS[None, :, None]
    log_prior = -0.5 * z * z
    log_prior -= logsumexp(log_prior, axis=-1, keepdims=True)
    # log p(data_c | shape, m0, tau) summed over the classes, then the hyper posterior
    log_tau_prior = -0.5 * _TAUS**2 + np.log(_TAUS)  # half-normal(1), grid uniform in log tau
    hyper = (
        np.stack(
            [
                logsumexp(lik[i][:, None, None, :] + log_prior[None], axis=-1).sum(axis=0)
                for i in range(h)
            ]
        )
        + log_tau_prior[None, None, :]
    )  # (H, M, T)
    flat = hyper.ravel()
    pick = rng.choice(flat.size, size=n_draws, p=np.exp(flat - logsumexp(flat)))
    ih, im, it = np.unravel_index(pick, hyper.shape)
    # each class's log mean given the hyper draw: (S, K, G) in blocks of draws
    idx = np.empty((n_draws, k), np.int64)
    for j in range(0, n_draws, 512):
        sl = slice(j, j + 512)
        logits = lik[ih[sl]] + log_prior[im[sl], it[sl]][:, None, :]
        idx[sl] = _gumbel_pick(rng, logits)
    jitter = lambda size: (rng.random(size) - 0.5) * _STEP  # noqa: E731
    stay_mean = np.exp(grid[idx] + jitter(idx.shape))
    stay_shape = shapes[ih]
    pool_mean = np.exp(m0[im] + jitter(n_draws) * 4)
    pool_sd = _TAUS[it]
    # the pooled model: one mean and shape for all, flat priors on the grids
    pooled = lik.sum(axis=1).ravel()  # (H * G)
    pick = rng.choice(pooled.size, size=n_draws, p=np.exp(pooled - logsumexp(pooled)))
    ph, pg = np.unravel_index(pick, (h, g))
    pooled_mean = np.exp(grid[pg] + jitter(n_draws))
    pooled_shape = shapes[ph]
    # PSIS-LOO of the two over the artefacts' stays
    d = min(n_loo_draws, n_draws)
    if data.n:
        elpd = {
            "pooled": loo_pointwise(
                _pointwise(data, law, pooled_shape[:d, None], resolution, pooled_mean[:d, None])[
                    None
                ]
            )[0],
            "per-class": loo_pointwise(
                _pointwise(data, law, stay_shape[:d, None], resolution, stay_mean[:d][:, cls])[None]
            )[0],
        }
        chosen, table = choose_simplest(elpd, list(CLASS_STAY_MODELS))
    else:
        chosen, table = uncompared(CLASS_STAY_MODELS)
    return ClassFit(
        labels=names,
        counts=counts,
        n_rows=n_rows,
        weights=weights,
        stay_mean=stay_mean,
        stay_shape=stay_shape,
        pool_mean=pool_mean,
        pool_sd=pool_sd,
        pooled_mean=pooled_mean,
        pooled_shape=pooled_shape,
        law=law,
        stay_model=chosen,
        table=table,
        classes=cls.astype(np.int64),
    )


def attach_classes(idata: az.InferenceData, fit: ClassFit) -> az.InferenceData:
    """Store a :class:`ClassFit` in a fit's ``posterior``.

    Variables over ``(chain, draw, class)``: ``class_weights`` (the shares) and
    ``class_stay_mean`` (per-class mean stays); over ``(chain, draw)``:
    ``class_stay_shape`` (their law's shape), ``class_pool_stay_mean`` and
    ``class_pool_sd`` (the hierarchy's pool), ``class_pooled_stay_mean`` and
    ``class_pooled_stay_shape`` (the pooled model). Attributes ``class_stay_model`` (the
    LOO choice), ``class_stay_law``, ``class_counts`` (arrivals per
    class), ``class_rows`` (artefacts per class) and ``loo_class_stays`` (CSV text);
    ``observed_data`` gains ``classes`` over ``artefact`` (the report's per-class rows). The
    draws are reshaped to the posterior's ``(chain, draw)``.
    """
    import xarray as xr  # lazy: +0.16 s CPU on `import are_stats.fitting`

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
        ("class_stay_shape", fit.stay_shape),
        ("class_pool_stay_mean", fit.pool_mean),
        ("class_pool_sd", fit.pool_sd),
        ("class_pooled_stay_mean", fit.pooled_mean),
        ("class_pooled_stay_shape", fit.pooled_shape),
    ):
        post[name] = xr.DataArray(np.asarray(v, float).reshape(c, d), dims=("chain", "draw"))
    if "observed_data" in idata.groups() and fit.classes is not None:
        obs = idata.observed_data
        if obs.sizes.get("artefact") == fit.classes.size:
            obs["classes"] = xr.DataArray(fit.classes.astype(np.int64), dims=("artefact",))
    a = post.attrs
    a["class_stay_model"] = fit.stay_model
    a["class_stay_law"] = fit.law
    a["class_counts"] = np.asarray(fit.counts, np.int64)
    a["class_rows"] = np.asarray(fit.n_rows, np.int64)
    a["loo_class_stays"] = fit.table.to_csv(float_format="%.6g")
    return idata


#: Per-class statistics of the report (issue 31): traffic ones, then motion ones.
CLASS_STATISTICS = ("share", "stay median", "stay cv")
CLASS_MOTION_STATISTICS = ("median speed (m/s)", "fraction still")


def _class_stats(
    cls: np.ndarray, arrived: np.ndarray, stay: np.ndarray, whole: np.ndarray, k: int
) -> np.ndarray:
    """``(K, 3)`` share of the arrivals, median and cv of the whole stays, per class."""
    out = np.full((k, 3), np.nan)
    n_arr = max(int(arrived.sum()), 1)
    for c in range(k):
        out[c, 0] = np.sum(arrived & (cls == c)) / n_arr
        s = stay[whole & (cls == c)]
        if s.size:
            out[c, 1] = np.median(s)
        if s.size > 1 and s.mean() > 0:
            out[c, 2] = s.std(ddof=1) / s.mean()
    return out


def _band_table(
    labels: Sequence[str], stats: Sequence[str], observed: np.ndarray, reps: np.ndarray
) -> pd.DataFrame:
    """Rows (class, statistic): observed, the model's 5/50/95% and the flag."""
    index = pd.MultiIndex.from_product([list(labels), list(stats)], names=["class", "statistic"])
    table = pd.DataFrame(index=index)
    table["observed"] = observed.ravel()
    flat = reps.reshape(reps.shape[0], -1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a class absent from every replicate
        q = np.nanquantile(flat, [0.05, 0.5, 0.95], axis=0)
    table["model_5%"], table["model_50%"], table["model_95%"] = q
    # each statistic's difference that matters (MOTION_TOLERANCE; 0 for the traffic rows)
    table["model_flag"] = band_flags(
        index.get_level_values("statistic"), table["observed"].to_numpy(), q[0], q[2]
    )
    return table


def class_checks(
    key: int | jax.Array, idata: az.InferenceData, n_replicates: int = 200
) -> pd.DataFrame | None:
    """Per-class posterior-predictive rows of a labelled log's fit: share, stay median, cv.

    Replicated windows of the log's length are drawn from the fit's chosen models (class
    shares and per-class stays included, :func:`~are_stats.scenarios.generate_scenarios`);
    in each, every class's share of the arrivals and the median and coefficient of
    variation of its stays seen whole are set beside the log's.

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicated windows.
    idata : arviz.InferenceData
        A fit with classes (:func:`attach_classes`).
    n_replicates : int
        Replicated windows.

    Returns
    -------
    pandas.DataFrame or None
        Indexed by ``(class, statistic)`` (:data:`CLASS_STATISTICS`): ``observed``,
        ``model_5%``, ``model_50%``, ``model_95%``, ``model_flag``; None for a fit without
        classes.
    """
    post = idata.posterior
    obs = idata.observed_data
    if "class_weights" not in post or "classes" not in obs:
        return None
    labels = fit_class_labels(idata) or []
    k = len(labels)
    w = np.asarray(post.attrs["window"], float)
    t0, t1 = float(w[0]), float(w[1])
    ta = np.asarray(obs["t_arrive"].values, float)
    tl = np.asarray(obs["t_leave"].values, float)
    cls = np.asarray(obs["classes"].values, np.int64)
    whole = np.isfinite(ta) & np.isfinite(tl)
    observed = _class_stats(cls, np.isfinite(ta), np.where(whole, tl - ta, 0.0), whole, k)
    draws, laws = traffic_draws(idata, "chosen")
    df = generate_scenarios(
        key,
        draws,
        int(n_replicates),
        t1 - t0,
        area=float(post.attrs["area"]),
        draw="random",
        laws=laws,
    )
    reps = np.full((int(n_replicates), k, 3), np.nan)
    for r, sc in df.groupby("scenario", sort=True):
        a = ~sc["truncated"].to_numpy()
        st = (sc["t_leave"] - sc["t_arrive"]).to_numpy(float)
        wh = a & ~sc["censored"].to_numpy()
        reps[int(r)] = _class_stats(sc["class"].to_numpy(), a, st, wh, k)
    return _band_table(labels, CLASS_STATISTICS, observed, reps)


def class_motion_checks(
    observed_tracks: pd.DataFrame, replicates: Mapping[str, np.ndarray | pd.DataFrame]
) -> pd.DataFrame | None:
    """Per-class rows of the motion checks: median speed and fraction still.

    Parameters
    ----------
    observed_tracks : pandas.DataFrame
        ``id, t, x, y, label``: the log's tracks.
    replicates : dict
        What :func:`~are_stats.fitting.motion_checks` returns beside its table
        (``"tracks"``: per-track statistics of each replicate, ``"observed"``: the log's).

    Returns
    -------
    pandas.DataFrame or None
        Indexed by ``(class, statistic)`` (:data:`CLASS_MOTION_STATISTICS`), columns as
        :func:`class_checks`; None without a ``label`` column.
    """
    if "label" not in observed_tracks.columns:
        return None
    first = observed_tracks.sort_values(["id", "t"], kind="stable").groupby("id").first()
    label_of = first["label"].astype(str)
    labels = sorted(label_of.unique())

    def stats(st: pd.DataFrame, ids: npt.ArrayLike) -> np.ndarray:
        lab = label_of.reindex(np.asarray(ids)).to_numpy()
        out = np.full((len(labels), 2), np.nan)
        for i, name in enumerate(labels):
            sel = lab == name
            sp = st["speed"].to_numpy(float)[sel]
            sp = sp[np.isfinite(sp)]
            if sp.size:
                out[i, 0] = np.median(sp)
            if sel.any():
                out[i, 1] = float(np.mean(st["still"].to_numpy(bool)[sel]))
        return out

    obs_st = replicates["observed"]
    observed = stats(obs_st, obs_st.index.get_level_values("id"))
    rep_st = replicates["tracks"]
    scen = rep_st.index.get_level_values("scenario").to_numpy()
    ids = rep_st.index.get_level_values("id")
    reps = np.asarray([stats(rep_st[scen == r], ids[scen == r]) for r in np.unique(scen)])
    return _band_table(labels, CLASS_MOTION_STATISTICS, observed, reps)
