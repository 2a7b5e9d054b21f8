"""The fit file (issue 29): write_fit writes every group through one open file and read_fit
reads them through one. The file holds what ArviZ's own writer writes (each group
``xarray``-identical, attributes included, compressed alike), ArviZ reads it back, a file
ArviZ wrote (every fit before issue 29) reads as ``arviz.from_netcdf`` reads it, and
read_fit leaves no file open."""

from __future__ import annotations

import warnings

import h5py
import jax
import numpy as np
import pytest
import xarray as xr

from are_stats.fitting import FitSettings, _fit_log, fit_log, read_fit, write_fit
from are_stats.traffic import simulate_lifecycle

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

AREA = 200.0
EM = FitSettings(method="em", num_samples=40, num_chains=2, n_bootstrap=8, k_max=2,
                 arrivals="poisson", lifetimes="exponential", positions="uniform")  # fmt: skip
#: What a reader sees of a variable's storage: the same for both writers.
STORAGE = ("dtype", "zlib", "compression", "compression_opts", "shuffle", "chunksizes")


@pytest.fixture(scope="module")
def fit_file(tmp_path_factory):
    d = simulate_lifecycle(
        jax.random.key(0), 1 / 30 / AREA, 1 / 200, [0.5, 0.5], [2.0, 12.0], (0.0, 3600.0),
        area=AREA,
    )  # fmt: skip
    path = tmp_path_factory.mktemp("fit") / "em.nc"
    write_fit(fit_log(jax.random.key(3), d, EM).idata, path)
    return path


def _assert_same(a: az.InferenceData, b: az.InferenceData) -> None:
    assert list(a.groups()) == list(b.groups())
    assert dict(a.attrs) == dict(b.attrs)
    for name in a.groups():
        x, y = getattr(a, name).load(), getattr(b, name).load()
        xr.testing.assert_identical(x, y)  # values, coordinates and attributes
        for k, v in x.attrs.items():  # and the attributes' types (a str stays a str)
            assert type(v) is type(y.attrs[k]), (name, k)
        for var in x.variables:
            got = {e: x[var].encoding.get(e) for e in STORAGE}
            assert got == {e: y[var].encoding.get(e) for e in STORAGE}, (name, var)


def test_the_file_is_the_one_arviz_writes_and_arviz_reads_it(fit_file, tmp_path):
    ours = az.from_netcdf(str(fit_file))
    ours.load()
    theirs = tmp_path / "arviz.nc"
    ours.to_netcdf(str(theirs))  # ArviZ's writer, one open per group
    assert any(getattr(ours, g)[v].encoding.get("zlib") for g in ours.groups() for v in
               getattr(ours, g).variables)  # fmt: skip
    _assert_same(ours, az.from_netcdf(str(theirs)))
    _assert_same(read_fit(theirs).idata, ours)  # a file ArviZ wrote reads as before
    assert int(ours.posterior.attrs["format_version"]) == _fit_log.FIT_FORMAT_VERSION


def test_the_root_attributes_are_written_and_read_as_arviz_does(fit_file, tmp_path):
    idata = az.from_netcdf(str(fit_file))
    idata.load()
    idata.attrs["note"] = "on the root group"
    idata.to_netcdf(str(tmp_path / "arviz.nc"))
    _fit_log._write_groups(idata, tmp_path / "ours.nc")
    want = az.from_netcdf(str(tmp_path / "arviz.nc"))
    assert want.attrs["note"] == "on the root group"
    _assert_same(_fit_log._read_groups(tmp_path / "ours.nc"), want)
    _assert_same(_fit_log._read_groups(tmp_path / "arviz.nc"), want)
    _assert_same(az.from_netcdf(str(tmp_path / "ours.nc")), want)


def test_read_fit_loads_the_fit_and_closes_the_file(fit_file, tmp_path):
    open_before = h5py.h5f.get_obj_ids(types=h5py.h5f.OBJ_FILE)
    fit = read_fit(fit_file)
    assert h5py.h5f.get_obj_ids(types=h5py.h5f.OBJ_FILE) == open_before
    rate = fit.idata.posterior["arrival_rate"]
    assert isinstance(rate.variable._data, np.ndarray)  # in memory, not read on access
    copy = tmp_path / "copy.nc"
    write_fit(fit, copy)
    before = rate.values.copy()
    write_fit(read_fit(copy), copy, force=True)  # the file read from is replaced
    np.testing.assert_array_equal(read_fit(copy).idata.posterior["arrival_rate"], before)
