"""Does the count panel agree with the life-cycle log? (issue 14, count panels)

``are-stats fit LOG --counts PANEL`` fits the same scene twice: the life-cycle model gives a
posterior of ``arrival_rate`` (lambda, per m^2 per second) and ``leave_rate`` (mu, per
second); the exact panel MLE of :func:`are_stats.fit_birth_death` gives the birth rate
``lambda * area`` and the death rate ``mu`` of N(t) (DECISIONS 1-2). Both estimate the same
numbers when the paper's model holds, so their differences, in units of their combined
errors, say whether it does. The panel's errors are the robust (HAC) ones, which stay
honest under overdispersion and autocorrelation; the life-cycle errors are posterior
standard deviations.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any  # Any: a fit file's attribute values, converted where read

import numpy as np

from are_stats._checks import check_positive, describe

if TYPE_CHECKING:
    import arviz as az

__all__ = ["PanelComparison", "compare_panel", "panel_estimates"]

#: What is compared: the birth rate, the death rate and their ratio (the mean count).
PANEL_QUANTITIES = ("birth_rate", "death_rate", "mean_count")


@dataclass(frozen=True)
class PanelComparison:
    """Life-cycle posterior against the count panel's MLE, quantity by quantity.

    Every array has shape ``(3,)``, in the order of ``names``: the birth rate
    ``lambda * area`` (artefacts per second on the whole free area), the death rate ``mu``
    (per second) and the stationary mean count ``lambda * area / mu``.

    Attributes
    ----------
    names : tuple of str
        ``("birth_rate", "death_rate", "mean_count")``.
    lifecycle_mean, lifecycle_sd : (3,) ndarray of float64
        Posterior mean and standard deviation of the life-cycle fit.
    panel_estimate, panel_stderr : (3,) ndarray of float64
        Panel MLE and its standard error (robust when the fit stored one, see
        ``stderr_kind``; the mean count's by the delta method from the log-rates).
    z : (3,) ndarray of float64
        ``(panel_estimate - lifecycle_mean) / sqrt(panel_stderr^2 + lifecycle_sd^2)``: the
        two fits are treated as independent. When the panel was counted from the log
        itself they are positively correlated and ``|z|`` comes out smaller (conservative:
        measured ``|z| < 0.05`` on the paper's own data, 10-11 for group arrivals).
    threshold : float
        ``|z|`` above which the two disagree.
    stderr_kind : {"robust", "model"}
        Which panel errors were used (``"model"`` only for fit files written before the
        robust errors existed: they are 1.2-3x too small on overdispersed counts).
    warning : str or None
        One line for the user when some ``|z| > threshold``, else None.
    """

    names: tuple[str, ...]
    lifecycle_mean: np.ndarray
    lifecycle_sd: np.ndarray
    panel_estimate: np.ndarray
    panel_stderr: np.ndarray
    z: np.ndarray
    threshold: float
    stderr_kind: str
    warning: str | None

    @property
    def disagree(self) -> bool:
        """Whether some ``|z|`` exceeds ``threshold``."""
        return self.warning is not None


def _attr(attrs: Mapping[str, Any], name: str) -> Any:
    if name not in attrs:
        raise ValueError(
            f"idata: expected a fit with a count panel (posterior attribute {name!r}; "
            f"are-stats fit LOG --counts PANEL), got attributes {sorted(attrs)}"
        )
    return attrs[name]


def compare_panel(idata: az.InferenceData, threshold: float = 3.0) -> PanelComparison:
    """Compare the life-cycle posterior of a fit with its count panel's birth-death MLE.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit from :func:`~are_stats.fitting.fit_log` with ``counts_panel`` (or read back by
        :func:`~are_stats.fitting.read_fit`): posterior ``arrival_rate`` and ``leave_rate``
        (any draw shape), attributes ``area`` and ``birth_death_*``.
    threshold : float
        ``|z|`` above which a warning is returned (default 3: a false alarm about once in
        370 for one quantity when both fits are right and their errors Gaussian).

    Returns
    -------
    PanelComparison
        The z-scores and, when they exceed ``threshold``, a one-line ``warning``.

    Raises
    ------
    ValueError
        ``idata`` without a posterior, the rates, ``area`` or the panel's attributes;
        ``threshold`` not positive.

    Notes
    -----
    On the paper's own data the z-scores are standard normal. With group arrivals the panel
    model (single Poisson arrivals, independent exponential stays) explains jumps of whole
    groups by faster turnover: both panel rates come out too large by a similar factor
    (about 2.5x for groups of 1-4 counted every tenth of a mean stay) while the mean count
    agrees, and the warning says so. Other causes of disagreement: a panel and a log that
    cover different times or areas, or time units that differ.

    Examples
    --------
    >>> import arviz as az, numpy as np
    >>> from are_stats.fitting import compare_panel
    >>> rng = np.random.default_rng(0)
    >>> idata = az.from_dict(posterior={
    ...     "arrival_rate": rng.normal(0.01, 0.0005, (2, 500)),
    ...     "leave_rate": rng.normal(0.1, 0.005, (2, 500))})
    >>> idata.posterior.attrs.update(area=200.0, birth_death_birth_rate=2.05,
    ...     birth_death_death_rate=0.102, birth_death_stderr=np.array([0.1, 0.005]),
    ...     birth_death_stderr_robust=np.array([0.12, 0.006]),
    ...     birth_death_log_cov_robust=np.array([0.0034, 0.003, 0.003, 0.0035]))
    >>> cmp = compare_panel(idata)
    >>> cmp.warning is None, cmp.stderr_kind
    (True, 'robust')
    """
    thr = check_positive("threshold", threshold)
    if thr.ndim:
        raise ValueError(f"threshold: expected a scalar, got {describe(threshold)}")
    post = getattr(idata, "posterior", None)
    if post is None:
        raise ValueError(
            f"idata: expected an InferenceData with a posterior, got {describe(idata)}"
        )
    for name in ("arrival_rate", "leave_rate"):
        if name not in post:
            raise ValueError(
                f"idata: expected posterior variable {name!r}, got {sorted(post.data_vars)}"
            )
    attrs = post.attrs
    area = float(_attr(attrs, "area"))
    birth = np.asarray(post["arrival_rate"].values, dtype=float).ravel() * area
    death = np.asarray(post["leave_rate"].values, dtype=float).ravel()
    draws = np.stack([birth, death, birth / death])
    life_mean = draws.mean(axis=1)
    life_sd = draws.std(axis=1, ddof=1) if draws.shape[1] > 1 else np.zeros(3)

    est = np.array([float(_attr(attrs, f"birth_death_{n}_rate")) for n in ("birth", "death")])
    if "birth_death_stderr_robust" in attrs and "birth_death_log_cov_robust" in attrs:
        kind = "robust"
        se2 = np.asarray(attrs["birth_death_stderr_robust"], dtype=float).reshape(2)
        log_cov = np.asarray(attrs["birth_death_log_cov_robust"], dtype=float).reshape(2, 2)
    else:
        kind = "model"
        se2 = np.asarray(_attr(attrs, "birth_death_stderr"), dtype=float).reshape(2)
        log_cov = np.diag((se2 / est) ** 2)  # no covariance stored: the ratio's is approximate
    d = np.array([1.0, -1.0])
    ratio = est[0] / est[1]
    panel = np.array([est[0], est[1], ratio])
    panel_se = np.array([se2[0], se2[1], ratio * np.sqrt(max(float(d @ log_cov @ d), 0.0))])
    z = (panel - life_mean) / np.sqrt(panel_se**2 + life_sd**2)

    warning = None
    if np.any(np.abs(z) > float(thr)):
        parts = [
            f"{label} {panel[i]:.3g} +- {panel_se[i]:.2g} (panel) vs {life_mean[i]:.3g} "
            f"+- {life_sd[i]:.2g} (life-cycle), z = {z[i]:+.1f}"
            for i, label in enumerate(("birth rate", "death rate", "mean count"))
        ]
        both_up = z[0] > thr and z[1] > thr and abs(z[2]) <= thr
        cause = (
            "both panel rates are too high while the mean count agrees: the signature of "
            "group arrivals or departures, which the panel model (single Poisson arrivals, "
            "independent exponential stays) reads as faster turnover"
            if both_up
            else "the panel and the log may cover different times, areas or time units, "
            "or the counts do not follow the paper's model"
        )
        warning = (
            f"count panel and life-cycle fit disagree beyond their errors (|z| > {float(thr):g}"
            f"; panel errors {kind}): " + "; ".join(parts) + f". Likely cause: {cause}."
        )
    return PanelComparison(
        names=PANEL_QUANTITIES,
        lifecycle_mean=life_mean,
        lifecycle_sd=life_sd,
        panel_estimate=panel,
        panel_stderr=panel_se,
        z=z,
        threshold=float(thr),
        stderr_kind=kind,
        warning=warning,
    )


def panel_estimates(idata: az.InferenceData) -> str | None:
    """One line on the birth-death MLE of a fit's count panel (``birth_death_*``
    attributes, :func:`~are_stats.fitting.fit_log` with ``counts_panel``), or None.

    Parameters
    ----------
    idata : arviz.InferenceData or Fit

    Returns
    -------
    str or None
        Birth and death rates with their model-based and robust standard errors.
    """
    idata = getattr(idata, "idata", idata)
    a = idata.posterior.attrs
    if "birth_death_birth_rate" not in a:
        return None
    se = np.asarray(a["birth_death_stderr"], float).ravel()
    se_r = np.asarray(a.get("birth_death_stderr_robust", se), float).ravel()
    return (
        f"birth rate {float(a['birth_death_birth_rate']):.4g} +- {se[0]:.2g} (robust "
        f"{se_r[0]:.2g}), death rate {float(a['birth_death_death_rate']):.4g} +- {se[1]:.2g} "
        f"(robust {se_r[1]:.2g})"
    )
