"""The interaction of people fitted from a log's tracks (issue 26), stored in a fit.

:func:`fit_interaction` resamples the tracks to one step (the log's median) and estimates
the social force's strength ``A``, range ``B`` and relaxation time ``tau``
(:func:`~are_stats.behaviour.fit_social_force`; the members of the log's groups walk in
formation, so they are left out of its least squares) and the spacing of the log's groups
(:func:`fit_group_spacing`: members of an arrival group walk that far apart);
:func:`interaction_attrs` writes them as attributes of the fit's ``behaviour`` group and
:func:`interaction_from_attrs` reads them back (the only reader), so that every scene
generated from the fit walks with the log's interaction and groups
(:func:`~are_stats.scenarios.scenes_from_fit`).
"""

from __future__ import annotations

from collections.abc import Collection, Hashable, Mapping

import numpy as np
import pandas as pd

from are_stats.behaviour import SocialForce, fit_social_force, group_spacing, repulsion_evidence
from are_stats.logs import track_groups

__all__ = [
    "fit_group_spacing",
    "fit_interaction",
    "interaction_attrs",
    "interaction_evidence",
    "interaction_from_attrs",
    "learn_interaction",
]

_PREFIX = "interaction_"
_FITTED = ("strength", "range", "relaxation")
#: Level of the test of the published repulsion against none (:func:`interaction_evidence`).
_LEVEL = 0.01


def _on_one_step(
    tracks: pd.DataFrame, labels: Mapping[str, str]
) -> tuple[pd.DataFrame, dict[Hashable, str]]:
    """The tracks resampled to one step (the median), and the group of each track id
    (``labels``: :func:`~are_stats.logs.track_groups`'s)."""
    tab = tracks.sort_values(["id", "t"], kind="stable")
    ids = tab["id"].to_numpy()
    t = tab["t"].to_numpy(float)
    same = ids[1:] == ids[:-1]
    steps = np.diff(t)[same]
    if steps.size == 0:
        raise ValueError("tracks: expected tracks of at least three samples to fit interaction")
    dt = float(np.median(steps))
    # each track's times, x and y from the sorted columns (a slice per run of ids), its
    # grid interpolated by np.interp as before; one table at the end (issue 29: a table per
    # track was most of this function's CPU)
    xs, ys = tab["x"].to_numpy(float), tab["y"].to_numpy(float)
    codes, uniq = pd.factorize(ids)
    # runs in order of first appearance, as groupby(sort=False) visits them
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(uniq) + 1))
    kept, parts = [], {"t": [], "x": [], "y": []}
    for j, i in enumerate(uniq):
        rows = order[bounds[j] : bounds[j + 1]]
        tt = t[rows]
        grid_t = np.arange(np.ceil(tt[0] / dt - 1e-9), np.floor(tt[-1] / dt + 1e-9) + 1) * dt
        if grid_t.size >= 3:
            kept.append(i)
            parts["t"].append(grid_t)
            parts["x"].append(np.interp(grid_t, tt, xs[rows]))
            parts["y"].append(np.interp(grid_t, tt, ys[rows]))
    if not parts["t"]:
        raise ValueError("tracks: expected tracks of at least three samples to fit interaction")
    # the log's groups walk in formation: their members are left out of the repulsion's
    # least squares (fit_social_force's ``groups``)
    groups = {i: labels[str(i)] for i in pd.unique(ids) if str(i) in labels}
    # the ids typed as a table made of each id alone types them (pandas infers from values)
    n_rows = [len(v) for v in parts["t"]]
    out = {"id": pd.Series(kept).repeat(n_rows).reset_index(drop=True)}
    out |= {k: np.concatenate(v) for k, v in parts.items()}
    return pd.DataFrame(out), groups


def _standing_alone(tracks: pd.DataFrame, standing: Collection[str]) -> dict[Hashable, tuple]:
    """Each track id of a ``standing`` class in a group of its own: left out of the social
    force's least squares (:func:`~are_stats.behaviour.fit_social_force` leaves out group
    members' accelerations) while it still repels everybody (no pair of its group)."""
    if not standing or "label" not in tracks.columns:
        return {}
    still = tracks["label"].astype(str).isin([str(c) for c in standing]).to_numpy()
    return {i: ("standing", str(i)) for i in pd.unique(tracks["id"].to_numpy()[still])}


def _check_range(params: SocialForce) -> None:
    """Refuse a fitted force outside the model's range (a non-positive or infinite
    relaxation, a non-positive strength: no interaction in the data), as
    :func:`fit_interaction` and :func:`learn_interaction` both do."""
    if not (params.relaxation > 0 and np.isfinite(params.relaxation) and params.strength > 0):
        raise ValueError(
            f"tracks: the social force does not describe them (relaxation "
            f"{params.relaxation:.3g} s, strength {params.strength:.3g} m/s^2)"
        )


def fit_interaction(tracks: pd.DataFrame) -> tuple[SocialForce, dict[str, float]]:
    """Social force parameters of a log's tracks (see the module docstring).

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene (a tracks table), any sampling.

    Returns
    -------
    SocialForce
        The published defaults with ``strength``, ``range`` and ``relaxation`` estimated.
    dict
        :func:`~are_stats.behaviour.fit_social_force`'s ``rss``, ``n``, ``r2`` and ``dt``.

    Raises
    ------
    ValueError
        With too little walking to fit (fewer than 10 samples), or an estimate outside the
        model's range (a non-positive relaxation or strength: no interaction in the data).
    """
    labels = track_groups(tracks)
    grid, groups = _on_one_step(tracks, labels)
    params, info = fit_social_force(grid, groups=groups)
    _check_range(params)
    spacing, samples = group_spacing(tracks.assign(id=tracks["id"].astype(str)), labels)
    info = {**info, "group_samples": float(samples)}
    if samples > 0:
        params = params._replace(group_spacing=spacing)
    return params, info


def learn_interaction(
    tracks: pd.DataFrame,
    standing: Collection[str] = (),
) -> tuple[SocialForce | None, dict[str, float], str | None]:
    """What a fit keeps of a log's interaction: the fitted social force, else no repulsion
    when the log shows none, else the published one; with the log's group spacing.

    When the fit's estimate is out of the model's range, "too little data to fit" and "the
    data show no repulsion" are told apart by :func:`interaction_evidence`: if the
    published repulsion fits the accelerations of people near each other significantly
    worse (1%) than none, the force kept has strength 0 (nobody pushes; walls and group
    formation still act), else the published one.

    The groups' spacing is measured apart from the repulsion: a log whose people never push
    each other (no repulsion to fit) can still show how close its groups walk, and the
    scenes keep that spacing instead of the published 0.75 m.

    Only walkers are fitted: the people of ``standing`` classes (a vendor swaying at a
    stall, a guard stepping about) do not head for a destination, so their own
    accelerations are left out of the least squares and of the evidence, as a group
    member's are; they still push the walkers who pass them.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene (and ``label``, the class, with ``standing``).
    standing : collection of str
        The classes that only stand (:attr:`~are_stats.behaviour.BehaviourFit.standing`).

    Returns
    -------
    params : SocialForce or None
        :func:`fit_interaction`'s; or the published force, with strength 0 where the log
        shows no repulsion, and ``group_spacing`` measured (:func:`fit_group_spacing`); or
        None when nothing can be learned (the published force).
    info : dict
        :func:`fit_interaction`'s info; otherwise only ``group_samples`` (if any).
    note : str or None
        What was not learned and what scenes use instead, for the fit's notes.
    """
    # the log's groups, converted once for the fit, the evidence and the spacing (what
    # fit_interaction, interaction_evidence and fit_group_spacing each convert)
    labels = track_groups(tracks)
    spacing, samples = group_spacing(tracks.assign(id=tracks["id"].astype(str)), labels)
    step = None
    try:
        step = _on_one_step(tracks, labels)
        groups = {**step[1], **_standing_alone(tracks, standing)}
        params, info = fit_social_force(step[0], groups=groups)
        _check_range(params)
    except ValueError as err:  # too little walking together, or no interaction in the data
        try:
            if step is None:  # too little walking to resample
                raise ValueError(str(err)) from err
            evidence = repulsion_evidence(step[0], groups=groups, level=_LEVEL)
        except ValueError:  # too little walking to test either
            evidence = {"verdict": "too little", "close": 0.0}
        info = {"group_samples": float(samples)} if samples else {}
        if evidence["verdict"] == "none":
            params = SocialForce(strength=0.0)
            note = (
                f"interaction not fitted ({err}); the log shows no repulsion: on its "
                f"{evidence['close']:.0f} accelerations with someone within reach the "
                f"published repulsion fits worse than none (residual sum of squares "
                f"{evidence['rss_published']:.4g} against {evidence['rss_none']:.4g}; "
                f"strength {evidence['strength_hat']:.3g} +- {evidence['se']:.2g} m/s^2, "
                f"one-sided p {evidence['p']:.2g} < {_LEVEL}), so scenes walk with no "
                f"repulsion (strength 0)"
            )
        else:
            params = SocialForce()
            why = (
                f"too little walking near others to tell repulsion from none "
                f"({evidence['close']:.0f} accelerations with someone within reach)"
                if evidence["verdict"] == "too little"
                else f"the published repulsion fits better than none (one-sided p "
                f"{1.0 - evidence['p']:.2g})"
            )
            note = f"interaction not fitted ({err}); {why}; scenes use the published one"
            if samples == 0:
                return None, {}, note
        if samples > 0:
            params = params._replace(group_spacing=spacing)
            note += f", with the log's group spacing, {spacing:.2f} m"
        return params, info, note
    info = {**info, "group_samples": float(samples)}
    if samples > 0:
        params = params._replace(group_spacing=spacing)
    return params, info, None


def interaction_evidence(tracks: pd.DataFrame) -> dict[str, float | str]:
    """Whether a log's accelerations show the published repulsion or none at all.

    The tracks are resampled and their groups left out as in :func:`fit_interaction`;
    :func:`~are_stats.behaviour.repulsion_evidence` then compares, on the accelerations of
    people with someone within the force's reach, the residual sums of squares under the
    published repulsion (:class:`~are_stats.behaviour.SocialForce`'s strength and range;
    from 2 cm of tracker noise on, read from the smoothed tracks and as the least squares
    sees it through the noise, ``strength_seen``: the log's people walked again under it)
    and under none, at the 1% level; where that cannot tell, how close the log's people
    come against the same people walked again under each (``passes``).
    :func:`learn_interaction` uses it when the fit's
    estimate is out of the model's range: ``"none"`` gives a force of strength 0, the rest
    keep the published one.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene, any sampling.

    Returns
    -------
    dict
        :func:`~are_stats.behaviour.repulsion_evidence`'s: ``verdict`` (``"none"``,
        ``"published"`` or ``"too little"``), ``close``, ``strength_hat``, ``se``,
        ``rss_published``, ``rss_none``, ``z``, ``p`` (and ``strength_seen`` where it
        decided), ``passes``, ``passes_published``, ``passes_none``.

    Raises
    ------
    ValueError
        With too little walking (as :func:`fit_interaction`).

    Examples
    --------
    >>> import pandas as pd
    >>> t = [0.1 * k for k in range(100)]
    >>> a = pd.DataFrame({"id": 0, "t": t, "x": [1.2 * s for s in t], "y": 0.0})
    >>> interaction_evidence(a)["verdict"]  # nobody near: nothing to tell
    'too little'
    """
    labels = track_groups(tracks)
    grid, groups = _on_one_step(tracks, labels)
    return repulsion_evidence(grid, groups=groups, level=_LEVEL)


def fit_group_spacing(tracks: pd.DataFrame) -> tuple[float, int]:
    """The spacing of the groups in a log's tracks (:func:`~are_stats.behaviour.group_spacing`).

    The groups are those the life-cycle conversion infers (people first seen together who
    move together: :func:`~are_stats.logs.tracks_to_lifecycle`), the spacing the median
    distance from a walking member to its nearest co-member.

    Parameters
    ----------
    tracks : pandas.DataFrame
        ``id, t, x, y`` of one scene.

    Returns
    -------
    spacing : float
        Metres; NaN without groups seen walking.
    samples : int
        Member samples the spacing is the median of (0: none).
    """
    labels = track_groups(tracks)
    return group_spacing(tracks.assign(id=tracks["id"].astype(str)), labels)


def interaction_attrs(params: SocialForce, info: Mapping[str, float]) -> dict[str, float]:
    """The fitted parameters and the fit's ``r2`` as attributes (``interaction_*``)."""
    out = {f"{_PREFIX}{k}": float(getattr(params, k)) for k in SocialForce._fields}
    out[f"{_PREFIX}r2"] = float(info.get("r2", np.nan))
    out[f"{_PREFIX}samples"] = float(info.get("n", np.nan))
    out[f"{_PREFIX}group_samples"] = float(info.get("group_samples", 0.0))
    return out


def interaction_info(attrs: Mapping[str, object]) -> dict[str, float]:
    """How a stored social force was estimated (:func:`interaction_attrs`): ``r2``, ``n``
    (accelerations), ``group_samples``."""
    keys = {"r2": "r2", "n": "samples", "group_samples": "group_samples"}
    return {
        k: float(np.asarray(attrs.get(f"{_PREFIX}{v}", np.nan)).ravel()[0]) for k, v in keys.items()
    }


def interaction_from_attrs(attrs: Mapping[str, object]) -> SocialForce | None:
    """The :class:`SocialForce` a fit stored (:func:`interaction_attrs`), or None.

    Raises
    ------
    ValueError
        If a stored parameter is not a finite positive number (the strength may be 0: a
        log that shows no repulsion, :func:`learn_interaction`).
    """
    if f"{_PREFIX}strength" not in attrs:
        return None
    values = {}
    for k in SocialForce._fields:
        v = float(np.asarray(attrs.get(f"{_PREFIX}{k}", getattr(SocialForce(), k))).ravel()[0])
        if k == "strength":
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(
                    f"behaviour.attrs.{_PREFIX}{k}: expected a finite number >= 0, got {v}"
                )
        elif not (np.isfinite(v) and v > 0):
            raise ValueError(f"behaviour.attrs.{_PREFIX}{k}: expected a finite number > 0, got {v}")
        values[k] = v
    return SocialForce(**values)
