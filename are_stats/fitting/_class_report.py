"""The report's per-class figures of a labelled log's fit (issue 31).

* :func:`plot_class_checks`: one panel per statistic (share, stay median and cv from
  :func:`~are_stats.fitting.class_checks`; median speed and fraction still from
  :func:`~are_stats.fitting.class_motion_checks` when the fit learned a behaviour), one row
  per class: the model's 90% posterior-predictive band with its median, the log's value as
  a dot (a red cross outside the band).
* :func:`class_share_checks` and :func:`plot_class_shares_by_hour`: each class's share of
  the arrivals in each hour of the day (a log with a clock), the log's against replicates
  drawn with the log's arrivals per hour from the chosen shares (by time of day, or the
  constant ones).
* :func:`plot_class_entries`: each class's entry density with the log's entry points of
  that class.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from are_stats.fitting._fit import fit_class_labels
from are_stats.traffic import numpy_rng

if TYPE_CHECKING:
    import arviz as az
    import jax
    from matplotlib.figure import Figure

__all__ = [
    "class_share_checks",
    "plot_class_checks",
    "plot_class_entries",
    "plot_class_shares_by_hour",
]


def plot_class_checks(traffic: pd.DataFrame, motion: pd.DataFrame | None = None) -> Figure:
    """Per-class posterior-predictive bands beside the log's values.

    Parameters
    ----------
    traffic : pandas.DataFrame
        :func:`~are_stats.fitting.class_checks`: indexed by ``(class, statistic)``, columns
        ``observed``, ``model_5%``, ``model_50%``, ``model_95%``, ``model_flag``.
    motion : pandas.DataFrame, optional
        :func:`~are_stats.fitting.class_motion_checks` (the same columns).

    Returns
    -------
    matplotlib.figure.Figure
        One panel per statistic.
    """
    import matplotlib.pyplot as plt  # lazy: +0.7 s CPU on `import are_stats.fitting`

    tables = [traffic] + ([motion] if motion is not None and len(motion) else [])
    table = pd.concat(tables)
    stats = list(dict.fromkeys(table.index.get_level_values(1)))
    classes = list(dict.fromkeys(traffic.index.get_level_values(0)))
    if motion is not None:
        classes += [c for c in dict.fromkeys(motion.index.get_level_values(0)) if c not in classes]
    fig, axes = plt.subplots(
        1,
        len(stats),
        figsize=(2.6 * len(stats) + 0.8, 0.45 * len(classes) + 1.6),
        sharey=True,
        squeeze=False,
    )
    y = np.arange(len(classes))
    for ax, stat in zip(axes[0], stats, strict=True):
        for i, cls in enumerate(classes):
            if (cls, stat) not in table.index:
                continue
            row = table.loc[(cls, stat)]
            lo, mid, hi = (float(row[f"model_{q}"]) for q in ("5%", "50%", "95%"))
            ax.plot(
                [lo, hi],
                [i, i],
                color="C0",
                lw=5,
                alpha=0.35,
                solid_capstyle="butt",
                label="model 90%" if i == 0 else None,
            )
            ax.plot(
                [mid], [i], "|", color="C0", ms=12, mew=2, label="model median" if i == 0 else None
            )
            obs = float(row["observed"])
            if np.isfinite(obs):
                flag = bool(row["model_flag"])
                ax.plot(
                    [obs],
                    [i],
                    "x" if flag else "o",
                    color="C3" if flag else "k",
                    ms=7,
                    label=None if i else "log",
                )
        ax.set_title(stat, fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        ax.tick_params(labelsize=8)
    axes[0, 0].set_yticks(y, classes)
    axes[0, 0].set_ylim(-0.6, len(classes) - 0.4)
    axes[0, 0].invert_yaxis()
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, fontsize=8, loc="lower center", ncol=3, frameon=False)
    fig.suptitle(
        "Per class: the log against posterior-predictive replicates (red x: outside)", fontsize=10
    )
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    return fig


def class_share_checks(
    key: int | jax.Array, idata: az.InferenceData, n_replicates: int = 200
) -> pd.DataFrame | None:
    """Each class's share of the arrivals in each hour of the day, log against model.

    Replicates keep the log's arrivals per hour ``n_p`` and draw their classes from the
    chosen shares (``Multinomial(n_p, w_p)`` with a posterior draw of the hour's shares
    under the time-of-day model, of the day's under the constant one).

    Parameters
    ----------
    key : int or jax PRNG key
        Seed of the replicates.
    idata : arviz.InferenceData
        A fit with classes and shares by time of day
        (:func:`~are_stats.fitting.attach_class_shares_by_time`).
    n_replicates : int
        Replicates.

    Returns
    -------
    pandas.DataFrame or None
        Indexed by ``(class, hour)``: ``arrivals`` (the log's in that hour), ``observed``,
        ``model_5%``, ``model_50%``, ``model_95%``, ``model_flag``; None for a fit
        without shares by time of day.
    """
    post = idata.posterior
    if "class_tod_weights" not in post or "class_tod_counts" not in post.attrs:
        return None
    labels = fit_class_labels(idata) or []
    tw = np.asarray(post["class_tod_weights"].values, float)
    s = tw.shape[0] * tw.shape[1]
    p, k = tw.shape[2], tw.shape[3]
    counts = np.asarray(post.attrs["class_tod_counts"], np.int64).reshape(p, k)
    if post.attrs.get("class_share_model") == "time-of-day":
        draws = tw.reshape(s, p, k)
    else:
        w = np.asarray(post["class_weights"].values, float).reshape(s, 1, k)
        draws = np.broadcast_to(w, (s, p, k))
    rng = np.random.default_rng(int(key)) if isinstance(key, int | np.integer) else numpy_rng(key)
    pick = rng.integers(0, s, int(n_replicates))
    n_p = counts.sum(1)
    reps = np.stack([rng.multinomial(n_p, draws[i]) for i in pick]).astype(float)  # (R, P, K)
    with np.errstate(invalid="ignore", divide="ignore"):
        share_reps = reps / n_p[None, :, None]
        observed = counts / n_p[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # hours without arrivals: all nan
        q = np.nanquantile(share_reps, [0.05, 0.5, 0.95], axis=0)  # (3, P, K)
    index = pd.MultiIndex.from_product([labels, range(p)], names=["class", "hour"])
    table = pd.DataFrame(index=index)
    table["arrivals"] = np.tile(n_p, k)
    table["observed"] = observed.T.ravel()
    for j, name in enumerate(("model_5%", "model_50%", "model_95%")):
        table[name] = q[j].T.ravel()
    o = table["observed"].to_numpy()
    table["model_flag"] = np.isfinite(o) & ((o < table["model_5%"]) | (o > table["model_95%"]))
    return table


def plot_class_shares_by_hour(table: pd.DataFrame, model: str = "time-of-day") -> Figure:
    """Each class's share of the arrivals by hour: the log's (dots, sized by the hour's
    arrivals) in the model's 90% band (:func:`class_share_checks`).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt  # lazy: +0.7 s CPU on `import are_stats.fitting`

    classes = list(dict.fromkeys(table.index.get_level_values(0)))
    fig, ax = plt.subplots(figsize=(8.0, 3.8))
    for c, name in enumerate(classes):
        sub = table.loc[name]
        h = sub.index.to_numpy(float) + 0.5
        color = f"C{c % 10}"
        ax.fill_between(
            h,
            sub["model_5%"],
            sub["model_95%"],
            color=color,
            alpha=0.2,
            lw=0,
            step="mid",
            label=f"{name}: model 90%",
        )
        n = sub["arrivals"].to_numpy(float)
        size = 8 + 40 * n / max(float(n.max()), 1.0)
        flag = sub["model_flag"].to_numpy(bool)
        ax.scatter(
            h[~flag],
            sub["observed"][~flag],
            s=size[~flag],
            color=color,
            zorder=3,
            label=f"{name}: log",
        )
        if flag.any():
            ax.scatter(
                h[flag], sub["observed"][flag], s=size[flag], color=color, marker="x", zorder=3
            )
    ax.set(
        xlim=(0, 24), ylim=(-0.02, 1.02), xlabel="hour of the day", ylabel="share of the arrivals"
    )
    ax.set_xticks(range(0, 25, 3))
    ax.set_title(f"Class shares by hour ({model} shares; x: outside the band)", fontsize=10)
    ax.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    return fig


def plot_class_entries(idata: az.InferenceData) -> Figure | None:
    """Each class's entry density (image) with the log's entry points of that class.

    Parameters
    ----------
    idata : arviz.InferenceData
        A fit with per-class entry densities
        (:func:`~are_stats.fitting.attach_class_positions`).

    Returns
    -------
    matplotlib.figure.Figure or None
        One panel per class; None without per-class densities.
    """
    import matplotlib.pyplot as plt  # lazy: +0.7 s CPU on `import are_stats.fitting`

    if "constant_data" not in idata.groups() or "class_entry_density" not in idata.constant_data:
        return None
    cd = idata.constant_data
    dens = np.asarray(cd["class_entry_density"].values, float)
    res = float(np.asarray(cd.attrs["class_position_resolution"]).ravel()[0])
    o = np.asarray(cd.attrs["class_position_origin"], float).ravel()
    labels = fit_class_labels(idata) or [str(c) for c in range(dens.shape[0])]
    obs = idata.observed_data
    have_xy = all(n in obs for n in ("x", "y", "classes"))
    k, (h, w) = dens.shape[0], dens.shape[1:]
    extent = (o[0], o[0] + w * res, o[1], o[1] + h * res)
    cols = min(k, 3)
    rows = int(np.ceil(k / cols))
    aspect = h / max(w, 1)
    fig, axes = plt.subplots(
        rows, cols, figsize=(4.0 * cols, 4.0 * rows * aspect + 0.8), squeeze=False
    )
    model = str(idata.posterior.attrs.get("class_position_model", "?"))
    for c in range(rows * cols):
        ax = axes.flat[c]
        if c >= k:
            ax.axis("off")
            continue
        im = ax.imshow(dens[c] / res**2, origin="lower", extent=extent, cmap="magma")
        fig.colorbar(im, ax=ax, shrink=0.8).ax.tick_params(labelsize=7)
        if have_xy:
            entered = np.isfinite(np.asarray(obs["t_arrive"].values, float))
            sel = entered & (np.asarray(obs["classes"].values) == c)
            ax.scatter(
                np.asarray(obs["x"].values)[sel],
                np.asarray(obs["y"].values)[sel],
                s=2,
                color="c",
                alpha=0.3,
                lw=0,
            )
        ax.set_title(f"{labels[c]} (entry density, per m^2)", fontsize=9)
        ax.tick_params(labelsize=7)
    fig.suptitle(
        f"Entry densities per class ({model} by LOO; dots: the log's entries)", fontsize=10
    )
    fig.tight_layout()
    return fig
