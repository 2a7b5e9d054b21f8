"""read_fit checks a fit before it reads the rest of the file (issue 29): the posterior,
observed_data and constant_data groups are read and checked first, so a fit it refuses (a
newer format, a bad posterior) is refused without opening its other groups; a fit it
accepts reads as before, every group in the file's order."""

from __future__ import annotations

import shutil

import h5py
import jax
import numpy as np
import pytest
import xarray as xr

from are_stats.fitting import FitSettings, _fit_log, fit_log, read_fit, write_fit
from are_stats.inputs import InputError
from are_stats.traffic import simulate_lifecycle

AREA = 200.0
EM = FitSettings(
    method="em",
    num_samples=40,
    num_chains=2,
    n_bootstrap=8,
    k_max=2,
    arrivals="poisson",
    lifetimes="exponential",
    positions="uniform",
)


@pytest.fixture(scope="module")
def fit_file(tmp_path_factory):
    d = simulate_lifecycle(
        jax.random.key(0),
        1 / 30 / AREA,
        1 / 200,
        [0.5, 0.5],
        [2.0, 12.0],
        (0.0, 3600.0),
        area=AREA,
    )
    path = tmp_path_factory.mktemp("fit") / "em.nc"
    write_fit(fit_log(jax.random.key(3), d, EM).idata, path)
    return path


def _with_unreadable_group(src, dst, format_version=None, group="unreadable"):
    """A copy of the fit ``src`` with the group ``group`` (added, or in place of the fit's)
    one that no NetCDF reader opens (a variable without dimension scales), optionally
    stamped with ``format_version``."""
    shutil.copy(src, dst)
    with h5py.File(dst, "a") as f:
        if group in f:
            del f[group]
        f.create_group(group).create_dataset("x", data=np.zeros((3, 2)))
        if format_version is not None:
            f["posterior"].attrs["format_version"] = np.int64(format_version)
    return dst


@pytest.mark.parametrize("group", ["unreadable", "observed_data"])
def test_a_newer_format_is_refused_before_the_other_groups_are_read(fit_file, tmp_path, group):
    path = _with_unreadable_group(fit_file, tmp_path / "newer.nc", 99, group)
    with pytest.raises(InputError, match=r"posterior\.attrs\.format_version.*got 99"):
        read_fit(path)
    path = _with_unreadable_group(fit_file, tmp_path / "current.nc", group=group)
    with pytest.raises(InputError, match="could not read it"):  # the group alone refuses it
        read_fit(path)


def test_a_missing_posterior_names_every_group_of_the_file(fit_file, tmp_path):
    path = tmp_path / "no_posterior.nc"
    shutil.copy(fit_file, path)
    with h5py.File(path, "a") as f:
        names = [n for n in f if n != "posterior" and isinstance(f[n], h5py.Group)]
        del f["posterior"]
    with pytest.raises(InputError, match="posterior") as err:
        read_fit(path)
    assert f"groups {names}" in str(err.value)


def test_an_accepted_fit_reads_every_group_as_before(fit_file):
    fit = read_fit(fit_file)
    want = _fit_log._read_groups(fit_file)
    assert list(fit.idata.groups()) == list(want.groups())
    assert dict(fit.idata.attrs) == dict(want.attrs)
    for name in want.groups():
        xr.testing.assert_identical(getattr(fit.idata, name), getattr(want, name))
