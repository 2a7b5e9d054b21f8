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


def test_the_memoised_reader_reads_what_h5netcdf_reads(fit_file):
    """open_netcdf (HDF5 look-ups memoised, for read_fit's speed) reads every group as a
    plain ``h5netcdf.File`` does: values, coordinates, attributes and their types, and the
    whole encoding (storage, source, original shapes)."""
    import h5netcdf
    from xarray.backends import H5NetCDFStore

    from are_stats.fitting._netcdf_file import open_netcdf

    def groups(f):
        out = {"/": xr.open_dataset(H5NetCDFStore(f, mode="r")).load()}
        for name in f.groups:
            out[name] = xr.open_dataset(H5NetCDFStore(f, group=name, mode="r")).load()
        return out

    with h5netcdf.File(str(fit_file), "r", decode_vlen_strings=True) as f:
        want = groups(f)
    with open_netcdf(fit_file) as f:
        got = groups(f)
    assert list(got) == list(want) and len(want) > 3
    for name, ds in want.items():
        xr.testing.assert_identical(got[name], ds)
        assert {k: type(v) for k, v in got[name].attrs.items()} == {
            k: type(v) for k, v in ds.attrs.items()
        }
        for var in ds.variables:
            np.testing.assert_equal(got[name][var].encoding, ds[var].encoding)  # NaN == NaN


def _write_plainly(idata: az.InferenceData, path) -> None:
    """_write_groups through a plain ``h5netcdf.File`` (before open_netcdf memoised the
    look-ups): the reference for the bytes."""
    import h5netcdf
    from xarray.backends import H5NetCDFStore

    with h5netcdf.File(str(path), "w", decode_vlen_strings=True) as f:
        if idata.attrs:
            xr.Dataset(attrs=idata.attrs).dump_to_store(H5NetCDFStore(f, mode="a"))
        for name in idata.groups():
            ds = getattr(idata, name)
            encoding = {k: {"zlib": True} for k, v in ds.variables.items()
                        if _fit_log._compressible(v.dtype)}  # fmt: skip
            ds.dump_to_store(H5NetCDFStore(f, group=name, mode="a"), encoding=encoding)


def test_the_memoised_writer_writes_the_same_bytes(fit_file, tmp_path):
    """_write_groups (open_netcdf: look-ups memoised, no chunk cache) writes the bytes a
    plain h5netcdf.File writes: for a fit, and for groups of many chunks (128 in one
    variable), integers, booleans, strings, coordinates and root attributes."""
    fit = az.from_netcdf(str(fit_file))
    fit.load()
    rng = np.random.default_rng(0)
    many = xr.Dataset(
        {
            "x": (("chain", "draw", "k"), rng.normal(size=(4, 1000, 71))),
            "n": (("chain", "draw"), rng.integers(0, 9, size=(4, 1000))),
            "flag": (("chain", "draw"), rng.random((4, 1000)) < 0.5),
            "label": (("k",), np.array([f"c{i}" for i in range(71)])),
        },
        coords={"chain": np.arange(4), "draw": np.arange(1000), "k": np.arange(71) * 0.5},
        attrs={"note": "text", "window": np.array([0.0, 3600.0]), "n": 3},
    )
    other = az.InferenceData(posterior=many, observed_data=fit.observed_data)
    other.attrs["root"] = "on the root group"
    for i, idata in enumerate((fit, other)):
        _fit_log._write_groups(idata, tmp_path / f"ours{i}.nc")
        _write_plainly(idata, tmp_path / f"plain{i}.nc")
        assert (tmp_path / f"ours{i}.nc").read_bytes() == (tmp_path / f"plain{i}.nc").read_bytes()
    assert h5py.File(tmp_path / "ours1.nc")["posterior/x"].chunks != (4, 1000, 71)


def test_without_h5netcdfs_private_track_order_the_writer_is_h5netcdfs_own(
    fit_file, tmp_path, monkeypatch
):
    """open_netcdf asks h5netcdf 1.8's private ``_get_track_order`` for the file's order
    tracking; a release without it gets h5netcdf's own writer (the same bytes here)."""
    import are_stats.fitting._netcdf_file as netcdf_file

    fit = az.from_netcdf(str(fit_file))
    fit.load()
    monkeypatch.setattr(netcdf_file, "_TRACK_ORDER", None)
    _fit_log._write_groups(fit, tmp_path / "ours.nc")
    _write_plainly(fit, tmp_path / "plain.nc")
    assert (tmp_path / "ours.nc").read_bytes() == (tmp_path / "plain.nc").read_bytes()
