"""The motion criticism stored in a fit (issue 26), so ``are-stats report FIT`` shows it.

The log's tracks are not stored in a fit, so what ``report`` prints about motion is
computed at fit time from them and kept as attributes of the fit's ``behaviour`` group (CSV
text, as the model comparison tables ``loo_*`` are kept in the posterior's):

* ``motion_realism``: the realism table (:func:`~are_stats.scenarios.realism_table`: every
  feature's score and the weighted realism score of constant velocity, the catalogue
  behaviour and the fitted model, side by side);
* ``motion_observed``: the summaries of the log's own feature values the scores are taken
  against (:func:`~are_stats.scenarios.realism_summary`);
* ``motion_displacement``: the ADE/FDE table
  (:func:`~are_stats.fitting.displacement_errors`: constant velocity, the model's mean and
  best of K).

:func:`motion_attrs` writes them, :func:`motion_tables` reads them back (the only reader).
"""

from __future__ import annotations

import io
from collections.abc import Mapping

import pandas as pd

__all__ = ["MOTION_TABLES", "motion_attrs", "motion_tables"]

#: Attribute of each stored table (in the fit's ``behaviour`` group).
MOTION_TABLES = {
    "realism": "motion_realism",
    "observed": "motion_observed",
    "displacement": "motion_displacement",
    "class_motion": "motion_class_checks",  # per class (issue 31), flat: class, statistic
}


def motion_attrs(**tables: pd.DataFrame) -> dict[str, str]:
    """The tables as attributes (CSV text), by name (keys of :data:`MOTION_TABLES`).

    Raises
    ------
    ValueError
        On a name that is not one of :data:`MOTION_TABLES`.
    """
    unknown = sorted(set(tables) - set(MOTION_TABLES))
    if unknown:
        raise ValueError(f"tables: expected names among {list(MOTION_TABLES)}, got {unknown}")
    return {MOTION_TABLES[k]: t.to_csv(float_format="%.6g") for k, t in tables.items()}


def motion_tables(attrs: Mapping[str, object]) -> dict[str, pd.DataFrame]:
    """The stored tables of a fit's ``behaviour`` attributes, by name (those present).

    Raises
    ------
    ValueError
        If a stored table is not CSV text with an index column.
    """
    out = {}
    for name, key in MOTION_TABLES.items():
        text = attrs.get(key)
        if text is None:
            continue
        try:
            out[name] = pd.read_csv(io.StringIO(str(text)), index_col=0)
        except (ValueError, pd.errors.ParserError) as err:
            raise ValueError(f"behaviour.attrs.{key}: expected a CSV table, got {err}") from None
    return out
