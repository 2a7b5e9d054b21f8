"""Fit files (issue 13): logs without marks fit, fit files validated where they enter, the
stored log-likelihood scales with the distinct data (LOO unchanged), same seed same bytes,
reports refused past the memory limit."""

from __future__ import annotations

import hashlib
import re
import warnings

import jax
import numpy as np
import pytest
import xarray as xr
from numpyro.infer.util import log_likelihood
from scipy.special import gammaln

from are_stats.fitting import (
    FIT_FORMAT_VERSION,
    FitFormatWarning,
    FitSettings,
    _fit_log,
    check_report_size,
    fit_log,
    fit_loo,
    pointwise_log_likelihood,
    posterior_draws,
    read_fit,
    write_fit,
    write_report,
)
from are_stats.inputs import InputError, LimitError
from are_stats.scenarios import generate_scenarios
from are_stats.traffic import LifecycleData, lifecycle_model, simulate_lifecycle

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

AREA = 200.0
# the paper's model alone: these tests are not about the choice of traffic models
PAPER = {"arrivals": "poisson", "lifetimes": "exponential", "positions": "uniform"}
EM = FitSettings(method="em", num_samples=40, num_chains=2, n_bootstrap=8, k_max=2, **PAPER)


def _data(marks: bool = True, labels: bool = False, seed: int = 0) -> LifecycleData:
    d = simulate_lifecycle(
        jax.random.key(seed),
        1 / 30 / AREA,
        1 / 200,
        [0.5, 0.5],
        [2.0, 12.0],
        (0.0, 3600.0),
        area=AREA,
    )
    if labels:
        return d
    return LifecycleData(d.t_arrive, d.t_leave, d.window, d.area, marks=d.marks if marks else None)


@pytest.fixture(scope="module")
def em_file(tmp_path_factory):
    idata = fit_log(jax.random.key(3), _data(), EM).idata
    path = tmp_path_factory.mktemp("fit") / "em.nc"
    write_fit(idata, path)
    return path


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_em_fit_of_a_log_without_marks_goes_end_to_end(tmp_path):
    data = _data(marks=False)
    idata = fit_log(jax.random.key(0), data, EM).idata
    assert "mix_weights" not in idata.posterior and "mix_rates" not in idata.posterior
    assert int(idata.posterior.attrs["n_components"]) == -1
    path = write_fit(idata, tmp_path / "nomarks.nc")
    back = read_fit(path).idata
    df = generate_scenarios(1, posterior_draws(back), 3, 600.0, area=AREA)
    assert len(df) and (df["mark"] == -1).all() and (df["class"] == -1).all()
    written = write_report(back, tmp_path / "report", n_replicates=3)
    assert "ppc_marks" not in written and written["criticism"].exists()


def test_report_of_a_log_without_arrivals_inside_the_window(tmp_path):
    # every artefact present from t0 to t1: no inter-arrival time, no stay seen from arrival
    n = 6
    data = LifecycleData(
        np.full(n, np.nan), np.full(n, np.nan), (0.0, 600.0), AREA, marks=np.arange(n)
    )
    idata = fit_log(jax.random.key(0), data, EM).idata
    written = write_report(idata, tmp_path / "report", n_replicates=3)
    assert written["ppc_interarrival"].exists() and written["ppc_dwell"].exists()


def test_stored_log_likelihood_scales_with_distinct_data_and_loo_is_unchanged(em_file, monkeypatch):
    idata = read_fit(em_file).idata
    ll = idata.log_likelihood
    assert "stays" not in ll
    assert all("artefact" not in ll[v].dims for v in ll.data_vars)
    data = _data()
    # the on-demand stays are the model's own pointwise terms
    flat = {n: idata.posterior[n].values[0] for n in ("arrival_rate", "leave_rate")}
    flat |= {n: idata.posterior[n].values[0] for n in ("mix_weights", "mix_rates")}
    assert "labels" not in idata.observed_data
    full = log_likelihood(
        lifecycle_model,
        flat,
        data=data,
        n_components=int(idata.posterior.attrs["n_components"]),
        stationary_start=False,
    )
    stays = pointwise_log_likelihood(idata)
    np.testing.assert_allclose(stays.values[0], np.asarray(full["stays"]), rtol=1e-12)
    # PSIS-LOO over distinct observations equals arviz.loo over every artefact
    expanded = idata.copy()
    expanded.log_likelihood["stays"] = stays
    expanded.log_likelihood["marks"] = pointwise_log_likelihood(idata, "marks")
    for name in ("stays", "marks"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want = az.loo(expanded, var_name=name, pointwise=True)
        for block in (_fit_log._LOO_BLOCK, 7 * 80):  # one block; blocks of 7 observations
            monkeypatch.setattr(_fit_log, "_LOO_BLOCK", block)
            got = fit_loo(idata, name)
            assert got.elpd == pytest.approx(float(want.elpd_loo), rel=1e-10)
            assert got.se == pytest.approx(float(want.se), rel=1e-8)
            assert got.p_eff == pytest.approx(float(want.p_loo), rel=1e-8)
    # marks: one log-probability per artefact, matching the per-distinct-mark histogram
    marks = pointwise_log_likelihood(idata, "marks").values
    hist = ll["mark_histogram"].values
    counts = idata.observed_data["mark_histogram"].values
    np.testing.assert_allclose(marks.sum(-1), hist.sum(-1), rtol=1e-10)
    assert marks.shape[-1] == data.n and hist.shape[-1] == counts.size == np.unique(data.marks).size
    # with class labels the distinct observations are (class, mark) pairs
    labelled = _data(labels=True)
    fit = fit_log(jax.random.key(5), labelled, EM).idata
    pairs = np.unique(np.stack([labelled.labels, labelled.marks], 1), axis=0)
    assert fit.log_likelihood["mark_histogram"].shape[-1] == len(pairs)
    per = pointwise_log_likelihood(fit, "marks").values
    w = fit.posterior["mix_weights"].values[..., labelled.labels]
    r = fit.posterior["mix_rates"].values[..., labelled.labels]
    want = np.log(w) + labelled.marks * np.log(r) - r - gammaln(labelled.marks + 1.0)
    np.testing.assert_allclose(per, want, rtol=1e-9)
    fit.log_likelihood["marks"] = pointwise_log_likelihood(fit, "marks")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want_loo = az.loo(fit, var_name="marks")
    assert fit_loo(fit, "marks").elpd == pytest.approx(float(want_loo.elpd_loo), rel=1e-10)


def test_same_seed_same_bytes(tmp_path, em_file):
    second = tmp_path / "again.nc"
    write_fit(fit_log(jax.random.key(3), _data(), EM).idata, second)
    assert _digest(second) == _digest(em_file)
    idata = read_fit(em_file).idata
    assert all("created_at" not in getattr(idata, g).attrs for g in idata.groups())


@pytest.fixture(scope="module")
def em_read(em_file):
    """``em_file`` as ArviZ reads it, loaded once for the module: each test that writes a
    changed copy of the file changes a deep copy of this (reading the file again per test
    took about half of each such test's second)."""
    idata = az.from_netcdf(em_file)
    idata.load()
    return idata


def _rewrite(src, dst, change):
    """Write ``change`` applied to a deep copy of ``src`` (``em_read``) to ``dst``."""
    idata = src.copy()  # a deep copy
    idata = change(idata) or idata
    idata.to_netcdf(str(dst))
    return dst


def _without_group(name):
    def change(idata):
        return az.InferenceData(**{g: getattr(idata, g) for g in idata.groups() if g != name})

    return change


def _set(group, name, fn):
    def change(idata):
        ds = getattr(idata, group)
        ds[name] = ds[name].copy(data=fn(ds[name].values.copy()))

    return change


def _at(index, value):
    def fn(a):
        a[index] = value
        return a

    return fn


def _attr(name, value=None, delete=False):
    def change(idata):
        if delete:
            del idata.posterior.attrs[name]
        else:
            idata.posterior.attrs[name] = value

    return change


BAD_FITS = [
    (_attr("area", delete=True), r"posterior\.attrs\.area: expected this attribute"),
    (_attr("window", delete=True), r"posterior\.attrs\.window: expected this attribute"),
    (
        _attr("window", np.array([10.0, 0.0])),
        r"posterior\.attrs\.window\[1\]: expected a finite number > 10",
    ),
    (
        _attr("window", np.array([0.0])),
        r"posterior\.attrs\.window: expected a list of 2 values, got 1",
    ),
    (_attr("area", np.nan), r"posterior\.attrs\.area: expected a finite number > 0, got nan"),
    (
        _attr("method", "mcmc"),
        r"posterior\.attrs\.method: expected one of 'nuts', 'em', got 'mcmc'",
    ),
    (
        _attr("class_labels", "a,b,c"),
        r"posterior\.attrs\.class_labels: expected 2 comma-separated names",
    ),
    (
        lambda i: i.posterior.__delitem__("arrival_rate"),
        r"posterior\.arrival_rate: expected this variable",
    ),
    (
        _set("posterior", "leave_rate", _at((0, 3), -1.0)),
        r"posterior\.leave_rate\[0, 3\]: expected finite numbers > 0, got -1\.0",
    ),
    (
        _set("posterior", "arrival_rate", _at((0, 0), np.inf)),
        r"posterior\.arrival_rate\[0, 0\]: expected finite numbers > 0, got inf",
    ),
    (
        _set("posterior", "mix_rates", _at((0, 1, 1), 1e30)),
        r"posterior\.mix_rates\[0, 1, 1\]: expected finite numbers > 0 and <= 1e\+18, got 1e\+30",
    ),
    (
        lambda i: i.posterior.__delitem__("mix_rates"),
        r"posterior: expected both mix_weights and mix_rates or neither",
    ),
    (
        _set("posterior", "mix_weights", lambda a: 2 * a),
        r"posterior\.mix_weights\[0, 0\]: expected weights summing to 1, got a sum of 2\.0",
    ),
    (
        _attr("format_version", np.int64(FIT_FORMAT_VERSION + 1)),
        r"posterior\.attrs\.format_version: expected a fit format are_stats .* reads",
    ),
    (
        _attr("format_version", "one"),
        r"posterior\.attrs\.format_version: expected an integer, got 'one'",
    ),
    (_without_group("observed_data"), r"observed_data: expected this group"),
    (_without_group("posterior"), r"posterior: expected this group"),
    (
        _set("observed_data", "censored", lambda a: ~a),
        r"observed_data\.censored\[0\]: expected censored exactly where t_leave is NaN",
    ),
    (
        _set("observed_data", "marks", lambda a: a.astype(float)),
        r"observed_data\.marks: expected integers, got dtype float64",
    ),
    (
        _set("observed_data", "t_arrive", lambda a: np.where(np.isnan(a), a, a + 1e6)),
        r"observed_data: expected a valid life-cycle log \(t_arrive",
    ),
]


@pytest.mark.parametrize(("change", "match"), BAD_FITS)
def test_read_fit_names_the_file_and_the_bad_field(tmp_path, em_read, change, match):
    bad = _rewrite(em_read, tmp_path / "bad.nc", change)
    with pytest.raises(InputError, match=re.escape(str(bad)) + ": " + match):
        read_fit(bad)


def test_fits_carry_their_format_and_an_unversioned_fit_is_read_with_a_warning(
    tmp_path, em_file, em_read
):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        idata = read_fit(em_file).idata  # written by this version: stamped, no warning
    assert int(idata.posterior.attrs["format_version"]) == FIT_FORMAT_VERSION
    old = _rewrite(em_read, tmp_path / "old.nc", _attr("format_version", delete=True))
    with pytest.warns(FitFormatWarning, match=r"old\.nc: the fit has no format_version"):
        back = read_fit(old).idata
    np.testing.assert_array_equal(back.posterior["arrival_rate"], idata.posterior["arrival_rate"])


def test_read_fit_refuses_what_is_not_a_fit(tmp_path):
    text = tmp_path / "log.nc"
    text.write_text("id,t_arrive\n")
    with pytest.raises(InputError, match=r"log\.nc: expected an ArviZ NetCDF fit written by"):
        read_fit(text)
    with pytest.raises(InputError, match=r"expected an ArviZ NetCDF fit file, not a directory"):
        read_fit(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"missing\.nc: no such fit file"):
        read_fit(tmp_path / "missing.nc")


def test_report_refuses_a_mark_panel_past_the_memory_limit(tmp_path, em_file, em_read):
    huge = _rewrite(em_read, tmp_path / "huge.nc", _set("observed_data", "marks", _at(0, 10**15)))
    idata = read_fit(huge).idata  # a valid fit ...
    with pytest.raises(LimitError, match=r"the marks panel \(marks up to 1000000000000000"):
        check_report_size(idata, 10, str(huge))  # ... whose report would need petabytes
    with pytest.raises(LimitError, match=r"--max-memory"):
        write_report(idata, tmp_path / "report", n_replicates=10)
    assert not (tmp_path / "report").exists()
    with pytest.raises(LimitError, match=r"expected about 1\.\d+e\+09 artefacts"):
        check_report_size(read_fit(em_file).idata, 10**7, "fit")


def test_write_fit_failure_leaves_nothing_under_the_final_name(tmp_path, em_file):
    idata = read_fit(em_file).idata
    target = tmp_path / "fit.nc"
    target.write_bytes(b"the earlier fit")
    broken = idata.copy()
    broken.posterior["bad"] = xr.DataArray(np.array([object()]), dims=["x"])  # not storable
    with pytest.raises((TypeError, ValueError)):
        write_fit(broken, target, force=True)
    assert target.read_bytes() == b"the earlier fit"
    assert [p.name for p in tmp_path.iterdir()] == ["fit.nc"]
