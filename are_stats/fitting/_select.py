"""Number of components of the Poisson mixture of eq. (1): BIC, WAIC and PSIS-LOO.

The NUTS fits store the log-likelihood of each DISTINCT mark per posterior draw. Every
one of the ``c_j`` marks equal to ``v_j`` has the same pointwise WAIC term and the same
leave-one-out predictive density (leaving out any one of them gives the same posterior),
so the per-observation sums of WAIC and PSIS-LOO are sums over distinct marks weighted by
their counts, and the standard errors use the count-weighted variance over observations.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pandas as pd
from jax import random
from scipy.special import logsumexp

from are_stats._checks import check_in
from are_stats._lazy import arviz as az
from are_stats.fitting._em import (
    MixtureEMResult,
    _check_positive_int,
    fit_mixture_em,
    marks_histogram,
)
from are_stats.fitting._mixture_mcmc import fit_mixture_nuts
from are_stats.fitting._psis import psislw

if TYPE_CHECKING:
    import jax
    import numpy.typing as npt

__all__ = ["InformationCriterion", "mixture_waic", "mixture_loo", "select_n_components"]


class InformationCriterion(NamedTuple):
    """WAIC or PSIS-LOO of a fit over a histogram of marks, per observation.

    Attributes
    ----------
    elpd : float
        Expected log pointwise predictive density, summed over all marks.
    se : float
        Its standard error.
    p_eff : float
        Effective number of parameters.
    deviance : float
        ``-2 elpd`` (lower is better; the scale of BIC).
    pointwise : (m,) float64
        elpd of ONE mark equal to each distinct value.
    counts : (m,) float64
        Count of each distinct value.
    pareto_k : (m,) float64 or None
        PSIS shape estimate per distinct value (LOO only; above 0.7 is unreliable).
    """

    elpd: float
    se: float
    p_eff: float
    deviance: float
    pointwise: np.ndarray
    counts: np.ndarray
    pareto_k: np.ndarray | None


def _loglik_and_counts(idata: az.InferenceData) -> tuple[np.ndarray, np.ndarray]:
    if "log_likelihood" not in idata.groups() or "marks" not in idata.log_likelihood:
        raise ValueError(
            "idata: expected a log_likelihood group with variable 'marks' "
            "(as written by fit_mixture_nuts), got groups " + repr(idata.groups())
        )
    if "constant_data" not in idata.groups() or "mark_count" not in idata.constant_data:
        raise ValueError("idata: expected constant_data 'mark_count' (from fit_mixture_nuts)")
    ll = np.asarray(idata.log_likelihood["marks"].transpose("chain", "draw", "mark_value"))
    counts = np.asarray(idata.constant_data["mark_count"], dtype=np.float64)
    return ll, counts


def _weighted_total(e: np.ndarray, counts: np.ndarray) -> tuple[float, float]:
    """Sum over observations and its standard error ``sqrt(N var_obs)``."""
    n = counts.sum()
    total = float(np.sum(counts * e))
    mean = total / n
    var = float(np.sum(counts * (e - mean) ** 2) / n)
    return total, float(np.sqrt(n * var))


def mixture_waic(idata: az.InferenceData) -> InformationCriterion:
    """WAIC of a :func:`fit_mixture_nuts` fit, counting every mark (not every distinct one).

    Parameters
    ----------
    idata : arviz.InferenceData
        Output of :func:`are_stats.fitting.fit_mixture_nuts`.

    Returns
    -------
    InformationCriterion
        ``elpd_waic = sum_j c_j (lppd_j - var_s log p(v_j | theta_s))``.

    Raises
    ------
    ValueError
        If ``idata`` lacks the pointwise log-likelihood or the counts.
    """
    ll, counts = _loglik_and_counts(idata)
    flat = ll.reshape(-1, ll.shape[-1])  # (S, m)
    s = flat.shape[0]
    lppd = logsumexp(flat, axis=0) - np.log(s)
    p = flat.var(axis=0)
    e = lppd - p
    elpd, se = _weighted_total(e, counts)
    return InformationCriterion(elpd, se, float(np.sum(counts * p)), -2.0 * elpd, e, counts, None)


def mixture_loo(idata: az.InferenceData) -> InformationCriterion:
    """PSIS-LOO of a :func:`fit_mixture_nuts` fit, counting every mark.

    Parameters
    ----------
    idata : arviz.InferenceData
        Output of :func:`are_stats.fitting.fit_mixture_nuts`.

    Returns
    -------
    InformationCriterion
        ``elpd_loo = sum_j c_j log sum_s w_js p(v_j | theta_s)`` with Pareto-smoothed
        importance weights ``w_js`` (:func:`psislw`, ArviZ's estimator) for leaving out
        one mark equal to ``v_j``. The relative efficiency passed to ``psislw`` is the
        mean over marks of ``ess(p(v_j | theta)) / S`` (the R ``loo`` package's
        ``relative_eff``; ``arviz.loo`` instead uses the ESS of the parameters).

    Raises
    ------
    ValueError
        If ``idata`` lacks the pointwise log-likelihood or the counts.
    """
    ll, counts = _loglik_and_counts(idata)
    n_chains, n_draws, m = ll.shape
    s = n_chains * n_draws
    flat = ll.reshape(s, m)
    if n_chains > 1:
        ess = np.array([float(az.ess(np.exp(ll[:, :, j]), method="mean")) for j in range(m)])
        reff = float(np.sum(counts * ess) / counts.sum()) / s
    else:
        reff = 1.0
    log_w, k_hat = psislw(-flat.T, reff)  # (m, S), normalised
    e = logsumexp(log_w + flat.T, axis=1)
    lppd = logsumexp(flat, axis=0) - np.log(s)
    elpd, se = _weighted_total(e, counts)
    p_loo = float(np.sum(counts * (lppd - e)))
    return InformationCriterion(
        elpd, se, p_loo, -2.0 * elpd, e, counts, np.asarray(k_hat, dtype=np.float64)
    )


def _parsimonious_choice(ks: list[int], ics: dict[int, InformationCriterion]) -> int:
    """Smallest k whose elpd is within one standard error of the difference of the best."""
    best = max(ks, key=lambda k: ics[k].elpd)
    counts = ics[best].counts
    for k in sorted(ks):
        diff = ics[best].pointwise - ics[k].pointwise
        _, se_diff = _weighted_total(diff, counts)
        if ics[best].elpd - ics[k].elpd <= se_diff:
            return k
    return best


def select_n_components(
    key: jax.Array,
    marks: npt.ArrayLike,
    k_max: int,
    method: Sequence[str] = ("bic", "waic", "loo"),
    *,
    counts: npt.ArrayLike | None = None,
    n_restarts: int = 16,
    num_warmup: int = 500,
    num_samples: int = 500,
    num_chains: int = 2,
    chain_method: str = "parallel",
    return_fits: bool = False,
) -> pd.DataFrame | tuple[pd.DataFrame, dict[int, tuple[MixtureEMResult, az.InferenceData | None]]]:
    """Choose the number of components of eq. (1) by BIC (EM) and WAIC / PSIS-LOO (NUTS).

    Parameters
    ----------
    key : jax.Array
        PRNG key.
    marks : (N,) int
        Non-negative integer marks (with ``counts``: the values of a histogram).
    k_max : int
        Largest number of components tried (``k = 1 .. k_max``); at most the number of
        distinct marks.
    method : sequence of {"bic", "waic", "loo"}
        Criteria to compute. BIC needs only EM; WAIC and LOO run one NUTS fit per ``k``.
    counts : (N,) float, optional
        Multiplicity of each entry of ``marks``.
    n_restarts : int
        EM restarts per ``k``.
    num_warmup, num_samples, num_chains, chain_method
        Passed to :func:`fit_mixture_nuts`.
    return_fits : bool
        Also return the fits: a dict ``k -> (MixtureEMResult, InferenceData or None)``.

    Returns
    -------
    pandas.DataFrame
        One row per ``k`` (index ``n_components``), columns ``loglik`` (EM maximum),
        ``bic``, ``waic``, ``waic_se``, ``p_waic``, ``loo``, ``loo_se``, ``p_loo``,
        ``pareto_k_max`` (WAIC and LOO on the deviance scale ``-2 elpd``, like BIC: lower
        is better; NaN when not computed) and the flags ``chosen_bic``, ``chosen_waic``,
        ``chosen_loo``. BIC picks its minimum. WAIC and LOO pick the smallest ``k`` whose
        elpd is within one standard error of the elpd difference to the best ``k``
        (extra components of a mixture barely change the elpd, so the plain maximum
        would often pick too many by chance). With ``return_fits``: ``(table, fits)``.

    Raises
    ------
    ValueError
        On bad marks, ``k_max < 1`` or above the number of distinct marks, an empty or
        unknown ``method``.

    Examples
    --------
    >>> import jax, numpy as np
    >>> from are_stats import select_n_components
    >>> rng = np.random.default_rng(0)
    >>> marks = np.concatenate([rng.poisson(2, 500), rng.poisson(25, 500)])
    >>> table = select_n_components(jax.random.key(0), marks, 3, method=("bic",))
    >>> int(table.index[table["chosen_bic"]][0])
    2
    """
    k_max = _check_positive_int("k_max", k_max)
    if isinstance(method, str):
        method = (method,)
    method = tuple(method)
    if not method:
        raise ValueError("method: expected at least one of 'bic', 'waic', 'loo', got none")
    for m in method:
        check_in("method", m, ("bic", "waic", "loo"))
    hist = marks_histogram(marks, counts)
    if k_max > hist.n_distinct:
        raise ValueError(
            f"k_max: expected at most the number of distinct marks ({hist.n_distinct}), got {k_max}"
        )
    ks = list(range(1, k_max + 1))
    nan = float("nan")
    rows: dict[int, dict[str, float]] = {k: {} for k in ks}
    waics: dict[int, InformationCriterion] = {}
    loos: dict[int, InformationCriterion] = {}
    fits: dict[int, tuple[MixtureEMResult, az.InferenceData | None]] = {}
    key_em, key_nuts = random.split(key)
    for k in ks:
        em = fit_mixture_em(
            hist.values,
            k,
            random.fold_in(key_em, k),
            counts=hist.counts,
            n_restarts=n_restarts,
        )
        rows[k]["loglik"] = em.loglik
        fits[k] = (em, None)
        rows[k]["bic"] = em.bic if "bic" in method else nan
        for col in ("waic", "waic_se", "p_waic", "loo", "loo_se", "p_loo", "pareto_k_max"):
            rows[k][col] = nan
        if "waic" in method or "loo" in method:
            idata = fit_mixture_nuts(
                random.fold_in(key_nuts, k),
                hist.values,
                k,
                counts=hist.counts,
                num_warmup=num_warmup,
                num_samples=num_samples,
                num_chains=num_chains,
                chain_method=chain_method,
            )
            fits[k] = (em, idata)
            if "waic" in method:
                w = waics[k] = mixture_waic(idata)
                rows[k].update(waic=w.deviance, waic_se=2.0 * w.se, p_waic=w.p_eff)
            if "loo" in method:
                lo = loos[k] = mixture_loo(idata)
                rows[k].update(
                    loo=lo.deviance,
                    loo_se=2.0 * lo.se,
                    p_loo=lo.p_eff,
                    pareto_k_max=float(np.max(lo.pareto_k)),
                )
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "n_components"
    table["chosen_bic"] = False
    table["chosen_waic"] = False
    table["chosen_loo"] = False
    if "bic" in method:
        table.loc[int(table["bic"].idxmin()), "chosen_bic"] = True
    if "waic" in method:
        table.loc[_parsimonious_choice(ks, waics), "chosen_waic"] = True
    if "loo" in method:
        table.loc[_parsimonious_choice(ks, loos), "chosen_loo"] = True
    if return_fits:
        return table, fits
    return table
