"""traffic: the artefact life-cycle models of the ARE paper (Sec. 3.2).

Birth-death N(t), marked Poisson arrivals and the Poisson mixture of eq. (1).
"""

from __future__ import annotations

__all__: list[str] = []

# --- Poisson mixture (eq. 1) ---
from are_stats.traffic._mixture import PoissonMixture  # noqa: E402

__all__ += ["PoissonMixture"]

# --- JAX's threefry key operations in NumPy (no XLA program per operation) ---
from are_stats.traffic._keys import (  # noqa: E402
    fold_in_key,
    key_bits,
    key_from_seed,
    key_uniform,
    split_key,
)

__all__ += ["fold_in_key", "key_bits", "key_from_seed", "key_uniform", "split_key"]

# --- marked Poisson process (life-cycle) ---
from are_stats.traffic._lifecycle import (  # noqa: E402
    LifecycleData,
    LifecyclePriors,
    LifecycleSummary,
    aot_compile,
    check_components,
    lifecycle_model,
    numpy_rng,
    prior_predictive,
    simulate_lifecycle,
    simulate_traffic_log,
)

__all__ += [
    "LifecycleData",
    "LifecyclePriors",
    "LifecycleSummary",
    "aot_compile",
    "check_components",
    "lifecycle_model",
    "numpy_rng",
    "prior_predictive",
    "simulate_lifecycle",
    "simulate_traffic_log",
]

# --- conjugate closed forms (life-cycle) ---
from are_stats.traffic._conjugate import (  # noqa: E402
    GammaPosterior,
    MixturePosterior,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    conjugate_mixture,
)

__all__ += [
    "GammaPosterior",
    "MixturePosterior",
    "conjugate_arrival_rate",
    "conjugate_leave_rate",
    "conjugate_mixture",
]

# --- birth-death process N(t) ---
from are_stats.traffic._birth_death import (  # noqa: E402
    BirthDeath,
    BirthDeathEvents,
    BirthDeathFit,
    birth_death_loglik,
    fit_birth_death,
    hac_bandwidth,
)

__all__ += [
    "BirthDeath",
    "BirthDeathEvents",
    "BirthDeathFit",
    "birth_death_loglik",
    "fit_birth_death",
    "hac_bandwidth",
]

# --- stay laws (exponential, gamma, weibull, lognormal) with censoring and truncation ---
from are_stats.traffic._stays import (  # noqa: E402
    STAY_LAWS,
    stay_cv,
    stay_log_excess,
    stay_logcdf,
    stay_loglik,
    stay_logpdf,
    stay_logsf,
    stay_sample,
    stay_sample_residual,
    stay_shape_from_cv,
)

__all__ += [
    "STAY_LAWS",
    "stay_cv",
    "stay_log_excess",
    "stay_logcdf",
    "stay_loglik",
    "stay_logpdf",
    "stay_logsf",
    "stay_sample",
    "stay_sample_residual",
    "stay_shape_from_cv",
]

# --- arrival laws (poisson, negbin, time-of-day, groups) ---
from are_stats.traffic._arrivals import (  # noqa: E402
    ARRIVAL_MODELS,
    DAY,
    ArrivalDraw,
    arrival_loglik,
    clock_offset,
    period_exposure,
    period_of,
    sample_arrivals,
    stationary_count_moments,
)

__all__ += [
    "ARRIVAL_MODELS",
    "DAY",
    "ArrivalDraw",
    "arrival_loglik",
    "clock_offset",
    "period_exposure",
    "period_of",
    "sample_arrivals",
    "stationary_count_moments",
]

# --- bursts within the window (MMPP, Hawkes) ---
from are_stats.traffic._bursts import (  # noqa: E402
    BurstSteps,
    burst_steps,
    group_count_dispersion,
    hawkes_count_dispersion,
    hawkes_step_loglik,
    mmpp_count_dispersion,
    mmpp_factors,
    mmpp_step_loglik,
    mmpp_transfer,
    sample_hawkes_times,
    sample_mmpp_times,
)

__all__ += [
    "BurstSteps",
    "burst_steps",
    "group_count_dispersion",
    "hawkes_count_dispersion",
    "hawkes_step_loglik",
    "mmpp_count_dispersion",
    "mmpp_factors",
    "mmpp_step_loglik",
    "mmpp_transfer",
    "sample_hawkes_times",
    "sample_mmpp_times",
]

# --- entry and exit positions (uniform, learned) ---
from are_stats.traffic._positions import (  # noqa: E402
    POSITION_MODELS,
    PositionDensity,
    boundary_distance,
    fit_position_density,
    uniform_position_density,
)

__all__ += [
    "POSITION_MODELS",
    "PositionDensity",
    "boundary_distance",
    "fit_position_density",
    "uniform_position_density",
]

# --- richer traffic models (numpyro, data-scaled) and the one sampler ---
from are_stats.traffic._models import (  # noqa: E402
    ARRIVAL_SPECS,
    ArrivalSpec,
    ArrivalUnits,
    StayUnits,
    arrival_model,
    arrival_unit_loglik,
    arrival_units,
    exponential_unit_loglik,
    poisson_unit_loglik,
    stay_model,
    stay_unit_loglik,
    stay_units,
)
from are_stats.traffic._sampler import TrafficLaws, sample_population  # noqa: E402
from are_stats.traffic._stays import stay_draws  # noqa: E402

__all__ += [
    "ARRIVAL_SPECS",
    "ArrivalSpec",
    "ArrivalUnits",
    "StayUnits",
    "TrafficLaws",
    "arrival_model",
    "arrival_unit_loglik",
    "arrival_units",
    "exponential_unit_loglik",
    "poisson_unit_loglik",
    "sample_population",
    "stay_draws",
    "stay_model",
    "stay_unit_loglik",
    "stay_units",
]
