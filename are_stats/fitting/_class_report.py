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


#: Each per-class statistic's x axis: what it measures, in which unit (times in seconds,
#: the log's unit).
_CLASS_XLABELS = {
    "share": "share of the arrivals",
    "stay median": "median stay (s)",
    "stay cv": "sd / mean of the stays",
    "median speed (m/s)": "median walking speed (m/s)",
    "fraction still": "share of tracks with net < 1 m",
}
#: What a panel says where every class's log value and model band are one value (nothing to
#: compare), where that value has a plain reading.
_CLASS_ALL_EQUAL = {
    ("fraction still", 0.0): "no track stands still\n(net < 1 m) in the log\nor in the model",
}


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
        rows = [
            (i, table.loc[(cls, stat)])
            for i, cls in enumerate(classes)
            if (cls, stat) in table.index
        ]
        ax.set_title(stat, fontsize=9)
        ax.set_xlabel(_CLASS_XLABELS.get(stat, stat), fontsize=8)
        ax.tick_params(labelsize=8)
        values = np.array(
            [float(r[c]) for _, r in rows for c in ("observed", "model_5%", "model_95%")]
        )
        values = values[np.isfinite(values)]
        if values.size and values.min() == values.max():  # every class, log and model agree
            v = float(values[0])
            text = _CLASS_ALL_EQUAL.get((stat, v), f"every class, the log and\nthe model: {v:g}")
            ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.35")
            ax.set_xticks([])
            continue
        for i, row in rows:
            lo, mid, hi = (float(row[f"model_{q}"]) for q in ("5%", "50%", "95%"))
            ax.plot(
                [lo, hi],
                [i, i],
                color="C0",
                lw=5,
                alpha=0.35,
                solid_capstyle="butt",
                label="model 90%",
            )
            ax.plot([mid], [i], "|", color="C0", ms=12, mew=2, label="model median")
            obs = float(row["observed"])
            if np.isfinite(obs):
                flag = bool(row["model_flag"])
                ax.plot(
                    [obs],
                    [i],
                    "x" if flag else "o",
                    color="C3" if flag else "k",
                    ms=7,
                    zorder=3,
                    label="log, outside the 90% band" if flag else "log",
                )
        ax.grid(axis="x", alpha=0.3)
    axes[0, 0].set_yticks(y, classes)
    axes[0, 0].set_ylim(-0.6, len(classes) - 0.4)
    axes[0, 0].invert_yaxis()
    axes[0, 0].set_ylabel("class", fontsize=8)
    entries: dict[str, object] = {}  # label -> handle, over every panel: only what is drawn
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    handles, names = list(entries.values()), list(entries)
    if entries:
        fig.legend(handles, names, fontsize=8, loc="lower center", ncol=len(entries), frameon=False)
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

    Each hour with arrivals gets one bar per class (side by side inside the hour), so a
    log of one hour shows its bands too; the x axis spans the hours the log covers (the
    whole day only for a log of 12 hours or more).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt  # lazy: +0.7 s CPU on `import are_stats.fitting`

    classes = list(dict.fromkeys(table.index.get_level_values(0)))
    fig, ax = plt.subplots(figsize=(8.0, 3.8))
    slot = 0.8 / max(len(classes), 1)  # each class's part of an hour
    seen = []  # hours with arrivals
    for c, name in enumerate(classes):
        sub = table.loc[name]
        n = sub["arrivals"].to_numpy(float)
        has = n > 0
        hours = sub.index.to_numpy(float)
        seen.append(hours[has])
        x = hours + 0.1 + (c + 0.5) * slot
        lo, hi = sub["model_5%"].to_numpy(float), sub["model_95%"].to_numpy(float)
        band = has & np.isfinite(lo) & np.isfinite(hi)
        color = f"C{c % 10}"
        if band.any():
            ax.bar(
                x[band],
                np.maximum(hi[band] - lo[band], 0.004),  # a band of one value: a visible line
                bottom=lo[band],
                width=slot * 0.9,
                color=color,
                alpha=0.3,
                lw=0,
                label=f"{name}: model 90%",
            )
        size = 16 + 44 * n / max(float(n.max()), 1.0)
        obs = sub["observed"].to_numpy(float)
        flag = sub["model_flag"].to_numpy(bool)
        for mark, sel, what in (("o", has & ~flag, "log"), ("x", has & flag, "log, outside")):
            if sel.any():
                ax.scatter(
                    x[sel],
                    obs[sel],
                    s=size[sel],
                    color=color,
                    marker=mark,
                    edgecolors="k" if mark == "o" else None,
                    linewidths=0.5 if mark == "o" else 1.5,
                    zorder=3,
                    label=f"{name}: {what}",
                )
    hours = np.concatenate(seen) if seen else np.zeros(0)
    if hours.size and hours.max() - hours.min() < 12:  # a short log: its hours, not the day
        first, last = int(hours.min()), int(hours.max()) + 1
        ax.set_xlim(first, last)
        ax.set_xticks(range(first, last + 1))
    else:
        ax.set_xlim(0, 24)
        ax.set_xticks(range(0, 25, 3))
    ax.set(ylim=(-0.02, 1.02), xlabel="hour of the day (h)", ylabel="share of the arrivals")
    ax.set_title(f"Class shares by hour ({model} shares; x: outside the band)", fontsize=10)
    if not hours.size:
        ax.text(
            0.5,
            0.5,
            "no arrivals in the log",
            ha="center",
            va="center",
            transform=ax.transAxes,
            color="0.35",
        )
    else:
        ax.legend(fontsize=7, ncol=1, loc="upper left", bbox_to_anchor=(1.0, 1.0))
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
        bar = fig.colorbar(im, ax=ax, shrink=0.8)
        bar.ax.tick_params(labelsize=7)
        bar.set_label("entry density (1/m^2)", fontsize=8)
        n_in = 0
        if have_xy:
            entered = np.isfinite(np.asarray(obs["t_arrive"].values, float))
            sel = entered & (np.asarray(obs["classes"].values) == c)
            n_in = int(sel.sum())
            # open rings over the image: seen on its dark and its bright cells alike, and
            # the density under them still shows
            ax.scatter(
                np.asarray(obs["x"].values)[sel],
                np.asarray(obs["y"].values)[sel],
                s=30,
                facecolors="none",
                edgecolors="cyan",
                linewidths=1.0,
                alpha=0.9,
                zorder=3,
                label="the log's entries",
            )
        ax.set_xlim(extent[0], extent[1])  # the rings do not widen the map's frame
        ax.set_ylim(extent[2], extent[3])
        what = f"{n_in} entr{'y' if n_in == 1 else 'ies'} in the log" if have_xy else "entries"
        ax.set_title(f"{labels[c]} ({what})", fontsize=9)
        ax.set_xlabel("x (m)", fontsize=8)
        ax.set_ylabel("y (m)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(
        f"Entry densities per class ({model} by LOO; rings: the log's entries)", fontsize=10
    )
    fig.tight_layout()
    return fig
