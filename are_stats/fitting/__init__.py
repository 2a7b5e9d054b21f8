"""fitting: estimating the ARE models from field logs (EM, NUTS, model selection).

The Poisson mixture of eq. (1) is fitted by EM (``fit_mixture_em``) or by NUTS with the
class assignment marginalised (``fit_mixture_nuts``); ``select_n_components`` chooses the
number of components by BIC, WAIC and PSIS-LOO.
"""

from __future__ import annotations

__all__: list[str] = []

# --- Poisson mixture (eq. 1): EM, NUTS, model selection ---
from are_stats.fitting._em import (  # noqa: E402
    EMInfo,
    EMState,
    MarksHistogram,
    MixtureEMResult,
    em_init,
    em_step,
    fit_mixture_em,
    marks_histogram,
    squarem_step,
)
from are_stats.fitting._mixture_mcmc import fit_mixture_nuts, mixture_model  # noqa: E402
from are_stats.fitting._select import (  # noqa: E402
    InformationCriterion,
    mixture_loo,
    mixture_waic,
    select_n_components,
)

__all__ += [
    "EMInfo",
    "EMState",
    "MarksHistogram",
    "MixtureEMResult",
    "em_init",
    "em_step",
    "fit_mixture_em",
    "marks_histogram",
    "squarem_step",
    "fit_mixture_nuts",
    "mixture_model",
    "InformationCriterion",
    "mixture_waic",
    "mixture_loo",
    "select_n_components",
]

# --- life-cycle posterior by NUTS ---
from are_stats.fitting._lifecycle_mcmc import fit_lifecycle_nuts  # noqa: E402
from are_stats.fitting._nuts import chains_per_device, resolve_chain_method  # noqa: E402

__all__ += ["fit_lifecycle_nuts", "chains_per_device", "resolve_chain_method"]

# --- the typed fit: what a fit file holds, decoded once where it enters ---
from are_stats.fitting._fit import (  # noqa: E402
    PARAMETER_NAMES,
    TRAFFIC_NAMES,
    ClassShares,
    Fit,
    PosteriorMeans,
    as_fit,
    fit_class_labels,
    fit_from_idata,
    posterior_draws,
    traffic_draws,
)

__all__ += [
    "PARAMETER_NAMES",
    "TRAFFIC_NAMES",
    "ClassShares",
    "Fit",
    "PosteriorMeans",
    "as_fit",
    "fit_class_labels",
    "fit_from_idata",
    "posterior_draws",
    "traffic_draws",
]

# --- one field log in, the whole fit out (are-stats fit) ---
from are_stats.fitting._field_fit import fit_log, log_sha256  # noqa: E402

__all__ += ["fit_log", "log_sha256"]

# --- the motion criticism files of a fit from tracks ---
from are_stats.fitting._motion_report import (  # noqa: E402
    MotionReport,
    can_check_motion,
    variation_table,
    write_motion_report,
    write_motion_tables,
)

__all__ += [
    "MotionReport",
    "can_check_motion",
    "variation_table",
    "write_motion_report",
    "write_motion_tables",
]

# --- life-cycle posterior by exact draws (closed forms, no MCMC) ---
from are_stats.fitting._lifecycle_exact import (  # noqa: E402
    exact_lifecycle_draws,
    has_exact_posterior,
    sample_coupled_rates,
)

__all__ += ["exact_lifecycle_draws", "has_exact_posterior", "sample_coupled_rates"]

# --- field-log fits, criticism and richer alternatives (are-stats fit / report) ---
from are_stats.fitting._criticism import (  # noqa: E402
    DispersionTest,
    KaplanMeier,
    count_path,
    dispersion_index,
    hour_of_day_counts,
    kaplan_meier,
)
from are_stats.fitting._fit_log import (  # noqa: E402
    FIT_FORMAT_VERSION,
    FitFormatWarning,
    FitSettings,
    attach_behaviour,
    attach_traffic,
    check_fit_size,
    choose_n_components,
    fit_lifecycle_data,
    fit_loo,
    pointwise_log_likelihood,
    read_fit,
    write_fit,
)
from are_stats.fitting._laplace import (  # noqa: E402
    LaplaceRun,
    Resampled,
    importance_resample,
    laplace_loo,
    run_laplace,
)
from are_stats.fitting._nuts import (  # noqa: E402
    NutsPrefetch,
    NutsProgress,
    NutsRun,
    NutsSettings,
    clock_progress,
    nuts_warnings,
    run_nuts,
)
from are_stats.fitting._psis import psislw  # noqa: E402
from are_stats.fitting._report import (  # noqa: E402
    PredictiveChecks,
    check_report_outputs,
    check_report_size,
    fit_summary,
    plot_checks,
    predictive_checks,
    predictive_windows,
    read_traffic_checks,
    sampler_warnings,
    write_report,
)
from are_stats.fitting._traffic import (  # noqa: E402
    ARRIVAL_CHOICES,
    LIFETIME_CHOICES,
    POSITION_CHOICES,
    TrafficFit,
    choose_simplest,
    fit_traffic,
    loo_pointwise,
)
from are_stats.fitting._traffic_checks import (  # noqa: E402
    CROWDING_STATISTICS,
    TRAFFIC_STATISTICS,
    burst_statistics,
    crowding_statistics,
    plot_traffic_checks,
    traffic_checks,
    window_statistics,
)

__all__ += [
    "CROWDING_STATISTICS",
    "TRAFFIC_STATISTICS",
    "burst_statistics",
    "crowding_statistics",
    "plot_traffic_checks",
    "traffic_checks",
    "window_statistics",
    "ARRIVAL_CHOICES",
    "LIFETIME_CHOICES",
    "POSITION_CHOICES",
    "NutsPrefetch",
    "NutsProgress",
    "LaplaceRun",
    "Resampled",
    "importance_resample",
    "laplace_loo",
    "run_laplace",
    "psislw",
    "NutsRun",
    "NutsSettings",
    "TrafficFit",
    "attach_behaviour",
    "attach_traffic",
    "choose_simplest",
    "fit_traffic",
    "loo_pointwise",
    "nuts_warnings",
    "clock_progress",
    "run_nuts",
    "DispersionTest",
    "KaplanMeier",
    "count_path",
    "dispersion_index",
    "hour_of_day_counts",
    "kaplan_meier",
    "FitSettings",
    "check_fit_size",
    "choose_n_components",
    "fit_lifecycle_data",
    "fit_loo",
    "pointwise_log_likelihood",
    "FIT_FORMAT_VERSION",
    "FitFormatWarning",
    "read_fit",
    "write_fit",
    "PredictiveChecks",
    "check_report_outputs",
    "check_report_size",
    "fit_summary",
    "sampler_warnings",
    "plot_checks",
    "predictive_checks",
    "predictive_windows",
    "read_traffic_checks",
    "write_report",
]

# --- count panel against the life-cycle fit (issue 14, count panels) ---
from are_stats.fitting._panel import PanelComparison, compare_panel, panel_estimates  # noqa: E402

__all__ += ["PanelComparison", "compare_panel", "panel_estimates"]
# --- behaviour fitted from tracks (issue 16) ---
from are_stats.fitting._behaviour import (  # noqa: E402
    BEHAVIOUR_FEATURES,
    NoWalkersError,
    behaviour_log_likelihood,
    discretise_tracks,
    fit_behaviour,
    open_area_grid,
)

__all__ += [
    "BEHAVIOUR_FEATURES",
    "NoWalkersError",
    "behaviour_log_likelihood",
    "discretise_tracks",
    "fit_behaviour",
    "open_area_grid",
]
# --- criticism for motion (issue 16) ---
from are_stats.fitting._motion_checks import (  # noqa: E402
    MOTION_STATISTICS,
    MOTION_TOLERANCE,
    band_flags,
    heldout_log_likelihood,
    motion_checks,
    plot_motion_checks,
    score_moves,
    track_statistics,
    tracker_noise,
)
from are_stats.fitting._prediction import constant_velocity, displacement_errors  # noqa: E402

__all__ += [
    "MOTION_STATISTICS",
    "MOTION_TOLERANCE",
    "band_flags",
    "constant_velocity",
    "displacement_errors",
    "heldout_log_likelihood",
    "motion_checks",
    "plot_motion_checks",
    "score_moves",
    "track_statistics",
    "tracker_noise",
]

from are_stats.fitting._interaction import (  # noqa: E402
    fit_group_spacing,
    fit_interaction,
    interaction_attrs,
    interaction_evidence,
    interaction_from_attrs,
    learn_interaction,
)

__all__ += [
    "fit_group_spacing",
    "fit_interaction",
    "interaction_attrs",
    "interaction_evidence",
    "interaction_from_attrs",
    "learn_interaction",
]

from are_stats.fitting._motion_store import (  # noqa: E402
    MOTION_TABLES,
    motion_attrs,
    motion_tables,
)

__all__ += ["MOTION_TABLES", "motion_attrs", "motion_tables"]

from are_stats.fitting._classes import (  # noqa: E402
    CLASS_MOTION_STATISTICS,
    CLASS_STATISTICS,
    CLASS_STAY_MODELS,
    ClassFit,
    attach_classes,
    class_checks,
    class_motion_checks,
    fit_classes,
)

__all__ += [
    "CLASS_MOTION_STATISTICS",
    "CLASS_STATISTICS",
    "CLASS_STAY_MODELS",
    "ClassFit",
    "attach_classes",
    "class_checks",
    "class_motion_checks",
    "fit_classes",
]

from are_stats.fitting._class_traffic import (  # noqa: E402
    CLASS_POSITION_MODELS,
    CLASS_SHARE_MODELS,
    MIN_CLASS_POINTS,
    N_SHARE_PERIODS,
    ClassPositions,
    ClassShareClock,
    attach_class_positions,
    attach_class_shares_by_time,
    class_position_densities,
    fit_class_positions,
    fit_class_shares_by_time,
)

__all__ += [
    "CLASS_POSITION_MODELS",
    "CLASS_SHARE_MODELS",
    "MIN_CLASS_POINTS",
    "N_SHARE_PERIODS",
    "ClassPositions",
    "ClassShareClock",
    "attach_class_positions",
    "attach_class_shares_by_time",
    "class_position_densities",
    "fit_class_positions",
    "fit_class_shares_by_time",
]

from are_stats.fitting._class_report import (  # noqa: E402
    class_share_checks,
    plot_class_checks,
    plot_class_entries,
    plot_class_shares_by_hour,
)

__all__ += [
    "class_share_checks",
    "plot_class_checks",
    "plot_class_entries",
    "plot_class_shares_by_hour",
]
