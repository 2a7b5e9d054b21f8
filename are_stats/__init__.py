"""are_stats: the ARE paper (Augmented Reality Environment for mobile robots) as software.

The public surface is re-exported here; implementation lives in private ``_module.py``
files inside one subpackage per concept of the paper (traffic, fitting, logs, scenarios,
environment, builder, behaviour, perception, experiments).

Importing ``are_stats`` enables 64-bit floats in JAX (``jax_enable_x64``): the exact
likelihoods of the life-cycle models need double precision. Kernels that are faster in
single precision (behaviours, perception) ask for ``float32`` explicitly.
"""

from __future__ import annotations

import jax as _jax

_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"

__all__ = ["__version__"]

# --- traffic: birth-death N(t), marked Poisson arrivals, Poisson mixture (eq. 1) ---

# --- fitting: EM, NUTS, model criticism ---

# --- logs: field-log formats ---

# --- scenarios: posterior-predictive scenario generation ---

# --- environment: occupancy grid, voxel map, meshes, frames, catalogue ---

# --- builder: registration, collisions ---

# --- behaviour: finite-horizon MDP ---

# --- perception: camera, Warp kernels, perceived set A_f ---

# --- experiments: robot, planners, metrics ---
