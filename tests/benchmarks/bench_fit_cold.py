"""Benchmark: the first fit on a fresh machine (issue 29), ours side by side with PyMC.

Every run is a fresh process (``subprocess``) with an empty cache (a new
``$XDG_CACHE_HOME``: no JAX persistent cache, no traced programs, no stage record):

* ``are-stats fit courtyard_traffic --no-figures`` (the shipped 500-row log), **cold** then
  **repeated** on the cold run's cache, for the default comparison (``--compare laplace``:
  the candidates ranked by importance-sampled PSIS-LOO from their Laplace approximations,
  NUTS for the chosen model and the paper's) and for ``--compare nuts`` (every candidate
  sampled by NUTS, the only way before issue 29); the chosen models of both are printed
  (they must be the same);
* ``are-stats demo`` cold (the ``make demo`` goal without the venv's installation);
* ``are-stats fit`` of a 302-person tracks table with its map, cold (issue 29's "300-person
  tracks table with behaviour" goal): :mod:`tests.test_cli_tracks`'s seeded synthetic
  room and tracks (groups of 1-3 door to door at about 1.2 m/s, 2.5 Hz) over 1,700 s,
  12,112 rows; figures on, so the motion checks and held-out moves run as a user's fit
  runs them;
* ``are-stats fit`` of the independent crowd of :mod:`tests.crowd` (68 people round a
  pillar, groups abreast, 5 cm noise) with its map, cold, and the realism table and
  displacement errors ``are-stats report`` prints from it (issue 26; the same table,
  without the traffic fit, is ``python -m tests.benchmarks realism``);
* the peer: one NUTS fit of the gamma-stays model (:mod:`bench_traffic_nuts`'s synthetic
  log, the same model written in PyTensor) in a fresh process with an empty cache, ours and
  PyMC (when installed: ``pip install 'are-stats[bench]'``), ratio cold/cold.

Per stage (the NUTS fit of the paper's model, each candidate's Laplace approximation or
NUTS fit, the behaviour fit, ...) the times come from the CLI's own stage record
(:mod:`are_stats._stage_clock`, ``stage_times.json`` in the run's cache); compile and
sampling of the paper's NUTS fit from the fit file's ``sample_stats`` attributes. Also
printed: the load average before and after each run (the machine may be shared: read the
ratios, not the seconds), the CPU time of the child, and whether XLA's "Very slow
compile" banner reached stderr.

Run with ``python -m tests.benchmarks fit_cold`` (``--quick``: the cold and repeated
default fit only). Benchmarks never assert on time. Measured 2026-11-26 on the team's
shared 2-core machine (load average 10-15; the table is on the docs' "Choosing the traffic
models" page): cold CPU 111.6 s ranked vs 166.2 s all-NUTS (1.49x), the same choices, no
XLA banner; repeated 53.4 s vs 43.0 s CPU (noise of the load: the warm Laplace comparison
itself takes 3.8 s of CPU). The demo and peer parts did not run to the end
there (stopped to leave the cores to tests); PyMC was not installed.

With the paper's model drawn exactly (no NUTS program for it) and the prior predictive
drawn with NumPy, measured side by side with the previous main on one window (load 10-15):
cold CPU 68.9 s vs 92.3 s, repeated wall 46 s vs 61 s (a first round, noisier: cold CPU
107.5 vs 108.8 s, repeated wall 104 vs 190 s). The peer part with PyMC 5.28.5 installed
beside the environment (``pip install --target DIR pymc``, DIR on ``PYTHONPATH``): cold
gamma-stays NUTS process 77.7 s ours, 83.4 s PyMC (1.07x). The docs' table has the stages.

With the chosen models' posteriors importance-resampled from their Laplace draws (no NUTS
program in a default fit; 2026-11-27, main and the branch back to back at load 15-28, the
same command in fresh processes, timed by ``/usr/bin/time``, not by this script): cold CPU
29.0 s vs 108.0 s (wall 286 vs 891 s), repeated CPU 13.5 s vs 34.2 s (wall 86 vs 288 s;
again at load 7-9: 14.0 s vs 35.8 s, wall 32 vs 69 s),
XLA compilations in the cold run 38 vs 49 (9 vs 13 ahead-of-time programs), the same
choices. The script now also counts the XLA compilations and prints how the chosen
posteriors were drawn.

With the paper's candidates scored in NumPy, the Laplace starts unconstrained in NumPy, the
MMPP candidates' programs at XLA's default optimisation and the report's panels cut out of
one rendering (2026-11-27, main 4b99766 and the branch alternating at load 9-10, the full
``are-stats fit courtyard_traffic`` with figures, ``/usr/bin/time``): cold CPU 25.9 s vs
31.2 s (wall 46 vs 57 s), repeated CPU 12.3 and 13.5 s vs 16.0 and 17.1 s, XLA
compilations cold 21 vs 38, the same choices and printed tables. The stage names are
unchanged.

Without XLA's CPU fusion emitters for the Laplace programs, the fit's key operations in
NumPy (no one-operation programs) and the report's histograms as outlines (2026-11-27, main
cdb4212 and the branch alternating at load 5-12, the full ``are-stats fit
courtyard_traffic`` with figures, ``/usr/bin/time``, medians of 4 rounds): cold CPU 25.1 s
vs 31.9 s (wall 35.5 vs 51.1 s), repeated CPU 13.9 s vs 15.0 s (wall 21.5 vs 21.3 s; a run
varies by a third at this load); XLA compilations cold 9 (the Laplace programs) vs 21, the
same choices and printed tables.

With the Laplace candidates' latent-site layouts kept on disk (no model traced in a
repeated fit; 2026-11-27, main e3d94b9 and the branch alternating at load 10-12, the full
``are-stats fit courtyard_traffic`` with figures, ``/usr/bin/time``, 4 rounds): repeated
CPU median 12.1 s vs 12.4 s (0.97x; the nine candidates' starts 0.01 s instead of
0.25-0.33 s of thread CPU), the same printed tables, fit file and figures byte for byte.

The tracks part's command, timed by ``/usr/bin/time`` (2026-11-27, main 4b99766 and the
lockstep string pulling side by side at load 8-13): cold CPU 345 s vs 337 s, 31 min wall
each, the same choices and motion checks; of the 50 motion-check replicates' 150 s of CPU,
``separate_paths`` takes 110 s (the docs' "Choosing the traffic models" page has the
breakdown). Issue 29's 60 s is far off.

The tracks part after wt-tracks' second round (2026-11-27, main e3d94b9 and the branch side
by side in one window at load 12-15, the CLI's command with a stage logger around its
stage clock, ``/usr/bin/time``; CPU seconds, read the ratio): cold CPU 234.3 s main vs
198.5 s branch (1.18x; wall 1312 vs 1228 s at this load). Per stage, main vs branch: the
traffic fit up to the behaviour 43.7 vs 20.6 s (the groups arrivals' posterior by the
Laplace mode's Student-t, k 0.26, instead of NUTS after the Gaussian's k 0.71; posterior
means within 0.1 sd of NUTS's, sds within 3%), the motion checks 72.8 vs 57.2 s (their
routes about 29 vs 13.7 s: one table of track rows, no per-artefact masks in the exits,
segments tested in blocks of similar length; the social force's 67 windows, 43.5 s, are
now most of it), behaviour 24.0 vs 28.4 s, realism 24.0 vs 21.4 s, displacement errors
28.7 vs 28.2 s, the report's motion checks and held-out moves 36 vs 38 s (noise of the
load). Every printed table is the same except the PPC's "chosen" bands (other posterior
draws: the same flags) and ``r_hat`` of groups (no NUTS). Issue 29's 60 s is still far.

The tracks part with the criticism's move likelihoods in one program per shape bucket
(``track_log_likelihoods``) and a walk's windows without repulsion or of blocks padded to
its largest (2026-11-27, main d81aad3 and wt-tracks started together, load 17 -> 14; the
CLI's command in fresh processes with empty caches, CPU of the child by ``getrusage``):
cold CPU 158.0 s main vs 135.8 s branch (1.16x; wall 1,232 vs 1,138 s), again at load
11-12: 147.9 s vs 126.5 s (1.17x; wall 616 vs 581 s); XLA compilations 309 vs 64 (about
240 one-operation programs of the displacement errors' goal posteriors and the held-out
moves gone, ``_window`` 10 -> 5). All 17 criticism files and the fit file's behaviour and
posterior groups byte for byte the same, in both rounds. The stage record (times less
XLA compiling) shows the stages alike: the saving is compiling. Left: the behaviour
likelihood's Hessian program (``_second_derivative``, 113 s wall to compile at that load
against the gradient's 68 s). Issue 29's 60 s is still far.

The tracks part with the behaviour likelihood's Hessian from five-point differences of its
gradient program (the soft solve held at the epochs it stopped at; no ``_second_derivative``
program; 2026-11-28, main 9488233 and wt-tracks started together, load 17 -> 22, the
CLI's command in fresh processes with empty caches, CPU of the child by ``getrusage``):
cold CPU 129.0 s main vs 112.9 s branch (1.14x; wall 1,156 vs 1,064 s); again at load
19 -> 11: 130.5 s vs 115.0 s (1.13x; wall 710 vs 696 s); XLA compilations 64 (424 and 305
s of compile wall) vs 55 (298 and 251 s): the Hessian's program (114 and 85 s wall to
compile) and six one-operation programs of its loop gone. All 17 criticism files byte for
byte the same, in both rounds; the fit file identical except the behaviour group's
``beta_se`` 0.167445 -> 0.167425 and ``slip_se`` 0.0107430 -> 0.0107440 (float32
differences, 1e-4 relative; the branch's two runs identical). The stage record (wall less
compiling) shows the behaviour stage at 49.9 vs 33.0 s, then 32.6 vs 31.7 s (its 4n
gradient runs cost no more than the n(n + 1) / 2 second-derivative runs), the others
alike. The largest compiles left (round 1): the social force's five ``_window`` programs
(82 s wall), the nine Laplace ``call`` programs (74 s) and the gradient (54 s). Issue 29's
60 s is still far.

The tracks part with the realism stage's resampling from array slices (no table per track),
the displacement errors' soft policies solved once per goal set (not once per chunk of 25
windows) and walks without repulsion in a slot per person (no blocks per scenario: the
displacement errors' chunks 2,048 and 4,096 slots instead of 4,096 and 8,192) (2026-11-28,
main 0724dee and wt-tracks started together, load 20 -> 12; the CLI's command in fresh
processes with empty caches, CPU of the child by ``getrusage``): cold CPU 111.2 s main vs
102.4 s branch (0.92x; wall 735 vs 709 s); again at load 11 -> 7: 102.8 vs 94.4 s (0.92x;
wall 335 vs 327 s); at load 2-5, one after the other: 93.8 vs 89.1 s (0.95x; wall 106.5 vs
92.2 s, the stage record's realism stage 54.4 vs 40.1 s). XLA compilations 55 both
(``_window`` 5: 16, 32, 1,024 and the two chunk sizes). The fit file's every group
(``xarray`` ``identical``, attributes included) and all 17 criticism files byte for byte
the same, in all three rounds. The stage alone in-process (``fit_behaviour``,
``learn_interaction``, then the stage's own function, fresh cache, process CPU, main and
branch side by side at load 12-21): 76.8 vs 58.9 s and 75.1 vs 66.4 s (realism 18.4 -> 13.4
and 19.0 -> 13.3 s, displacement errors 33.0 -> 22.2 and 30.4 -> 25.3 s, the motion checks'
50 replicates alike, 21-25 s). Left in the stage (cProfile of main, process time): the
any-angle string pulling of the displacement errors' 32,000 continuations and the scenes'
routes (``string_pull_many``, about a fifth), the social force's walks and its five
``_window`` compilations, the scenes' route planning; issue 29's 60 s is still far.

The tracks part with string pulling's segment test answered by a summed table of blocked
cells where a segment's box of cells is free (only the others traced cell by cell), and
``walk_times`` and ``social_force_tracks``' per-path overheads cut (2026-11-28, main
1e277c1 and wt-tracks started together in fresh processes with empty caches, the CLI's
command, child CPU by ``getrusage``, ``JAX_LOG_COMPILES=1``): with the string pulling
alone, load 15 -> 25: cold CPU 116.4 s main vs 102.3 s branch (0.88x; wall 1,430 vs 1,222
s); with all three, load 19 -> 21: 127.7 vs 110.3 s (0.86x; wall 1,156 vs 1,102 s).
XLA compilations 55 both, the same programs (``_window`` 5: 16, 32, 1,024, 2,048 and
4,096 slots). The stage record's realism and displacement errors (wall less compiling,
at that load) 717 vs 475 s, then 423 vs 338 s. The fit file's every group (``xarray``
``identical``) and all 17 criticism files byte for byte the same, in both rounds. Where
main's CPU went (cProfile, ``time.process_time``, 182 s profiled): string pulling 17.8 s
(``_crossed_block`` 12.5 s; 3,000 door-to-door routes: 7.5 -> 0.24 s after), XLA
compiling 27.8 s (``_window`` five, the behaviour's gradient, the nine Laplace programs),
the imports 12.5 s, ``social_force_tracks`` 34 s (its programs' runs 8.3 s, compiling
13.7 s), ``walk_times`` 5.8 s (40,000 paths: 2.08 -> 0.43 s after), ``draw_exits`` 7.7 s
and ``continuous_paths``' 41,000 ``cell_to_world`` calls 1.7 s (``behaviour._model`` and
``_generate``, left alone). Tried and left: ``_window`` at XLA's optimisation level 0
(other bits, and its runs 3x slower); ``xla_llvm_disable_expensive_passes`` (no change).
The motion checks' 50 replicates stay: with a 5-95% band of R replicates an observed
value from the model's own law falls outside it 13.3% of the time at R = 50, 18.3% at
20, 24% at 10 (before the tolerances), so fewer replicates flag more. Issue 29's 60 s
is still far.

The tracks part with ``BehaviourFit.draw_exits`` given stays drawing every artefact's
uniforms and normals first (its draws are the same whatever they are) and checking and
weighing all tries at once, and ``continuous_paths`` turning the routes' cells to world
points in one call, dropping repeated points in one pass and timing the paths with
``walk_times_many`` (the AR(1) step by step for all paths of a length; libm's ``pow`` for
``rho ** 2``, as the scalar code) (2026-11-28, wt-int 2f1a8fd and wt-tracks2 started
together, the CLI's command in fresh processes with empty caches, child CPU by
``getrusage``): load 7 -> 6: cold CPU 118.9 s wt-int vs 110.6 s branch (0.93x; wall 464
vs 447 s; the stage record's realism and displacement errors 198.8 vs 163.8 s);
again, load 6 -> 8: 123.0 vs 116.1 s (0.94x; wall 524 vs 508 s; realism and
displacement errors 203.9 vs 164.9 s). XLA compilations 55 both, in both rounds. The fit
file's every group (``xarray`` ``identical``) and all 17 criticism files (CSVs and PNGs)
byte for byte the same, in both rounds. In-process CPU, wt-int and
branch alternated at load 5-9 (md5 of every output and the generator's state equal):
``draw_exits`` on the inputs of a generation from the tracks fit's behaviour (6,000
artefacts, 3 runs) 13.9 and 11.2 s -> 3.2 and 3.4 s; 20,000 artefacts of a door-to-door
room with stays 14.4 and 14.1 s -> 3.0 and 2.8 s (without stays, unchanged code: 4.8 and
4.8 vs 4.7 and 3.3 s); ``continuous_paths`` on that generation's 6,000 paths (6 runs)
9.16 -> 6.03 s, of it ``string_pull_many`` 7.12 -> 5.34 s and the rest (routes, timing)
2.04 -> 0.69 s. Not done: the ten one-shape random programs (padding the draws to
power-of-two buckets); left in ``draw_exits``: the generator calls (41 an artefact,
about a third), the rest not broken down (grouping the no-exit-within-reach artefacts'
nearest cells by entry and reach gave no measurable change and was left out). Issue 29's
60 s is still far.

The crowd part (2026-11-27, load 11): cold CPU 102 s (wall 336 s); realism weighted fitted
0.352, constant velocity 0.334, catalogue 0.316; ADE / FDE mean of 20 0.394 / 0.604 m
against constant velocity's 0.357 / 0.642 m (docs: "Realism on a crowd the package did not
simulate").

With the report's overview on a fixed grid (no ``tight_layout``, panels cut along the drawn
texts; 2026-11-28, main 9488233 and the branch started together in 3 pairs with figures and
2 without, each a cold fit then 3 repeated ones in fresh processes on one fresh cache, child
CPU by ``getrusage``, load 18-22: read the ratios): with figures cold CPU median 24.2 s vs
25.1 s (ratio 0.964-0.974 in the 3 pairs), repeated 12.2 s vs 12.7 s (0.956-0.965);
without figures (the change is not on that path) cold 1.00-1.01, repeated 1.02-1.03 (noise:
the runs span 9.2-10.7 s of CPU on the branch, 9.5-10.2 s on main). The fit file (every
variable bit for bit, every attribute), the CSVs, the printed tables and
``traffic_checks.png`` are the same; the overview and its panels differ in layout only.
Where the repeated fit's CPU goes (load 12-20, ``time.process_time`` around the parts):
imports 2.3-2.5 s to ``are_stats.fitting`` plus ArviZ 1.5 s in the InferenceData thread
(its largest part numba compiling ``arviz.stats.ecdf_utils._binom_pmf``, a ``vectorize`` with a
signature, at import); the nine Laplace programs read from the caches 0.7-1.1 s (XLA's
executable deserialisation itself, 0.05-0.14 s each: keeping the compiled executables by
``jax.experimental.serialize_executable`` instead was no faster, 0.14-0.18 s for gamma's),
their 79-140 batches each, 1.7 s in all (0.5-5 ms a batch), the mode searches and Hessians in
Python 0.2-0.3 s, PSIS-LOO 0.5 s, the NetCDF 0.6 s; the report 2.7 s (traffic checks 0.8 s,
overview 0.9 s, traffic-checks figure and PNG 0.6-0.8 s). Cold adds the nine programs'
trace, export and compile, about 10 s of CPU (XLA alone, measured apart: gamma's 2.3 s at
XLA's default optimisation, groups+mmpp 1.0 s, hawkes 0.3 s; a candidate's log-likelihood,
in its potential and again in its pointwise terms, is compiled once: leaving either out
saved nothing), traced one at a time under ``TRACE_LOCK``.

The Laplace calls of at least 32 points (``MIN_BATCH``; 2026-11-28, main 0724dee against
the branch alternated in 3 pairs, each a cold fit then 2 repeated with figures and 1
without on one fresh cache, a user's virtual environment without numba, load 16-22): child
CPU medians cold 20.3 s main / 20.9 s branch, repeated 10.3 / 10.4 s, without figures
7.9 / 7.6 s (branch/main per pair 0.92-1.13: no difference within the noise; in the
``bench`` environment, with numba, 3 pairs at load 10-18: cold 21.4 / 22.0 s, repeated
11.1 / 11.1 s, per pair 0.95-1.09); the nine
Laplace runs alone, serialised in a fresh process, 4.44-5.27 s on main, 4.31-4.36 s on the
branch; every output the same to the byte. In a repeated fit, loading a program (read the
export 0.01 s, lower it 0.07 s, JAX's cache key, read and load 0.09 s each, load 12) is
most of what a program per model family would save; an executable kept by
``jax.experimental.serialize_executable`` and loaded with ``deserialize_and_load`` fails
at its first call for these programs (``NOT_FOUND: Function broadcast_multiply_fusion not
found``): it is loaded without the compile options (fusion emitters off) that JAX's own
cache passes to ``deserialize_executable``. A first fit shows the Laplace stages' elapsed
seconds only (no record yet: "every stage over 2 s shows the time left" does not hold on a
machine's first fit, e.g. gamma's 17 s at load 18); no XLA or Warp banner reached the
terminal, first fit or repeated.

One Laplace program per model family (four ``lax.switch`` programs for the shipped log's
nine candidates, the candidate an index, the points padded with ignored columns) was
measured and not adopted (docs: "Choosing the traffic models"): compiled one after the
other in a fresh process 13.9-14.3 s of CPU against 10.1-10.9 s for the nine programs,
loaded from the caches 1.18 s against 0.75 s (2026-11-28, load 10-12); XLA compiles every
branch as it compiles the candidate's own program. Kept: a first fit's Laplace stages show
the candidates done and the time left at their measured rate. ``are-stats fit
courtyard_traffic --force`` with figures, main 1e277c1 and the branch alternated in 3 pairs
(fresh cache cold, then repeated on it; child CPU by ``getrusage``, load 20-27): cold CPU
22.6, 29.6, 29.0 s main against 23.4, 25.7, 25.8 s branch (wall 104-162 s against
78-138 s), repeated 12.8, 13.8, 16.1 s against 13.1, 12.7, 12.1 s; 9 XLA compilations in
every cold and repeated run, the same choices, the fit files' groups identical. A cold
tracks fit compiles ten one-shape random programs (``_normal`` 3, ``_uniform`` 3,
``_threefry_split`` 2, ``fold_in``, ``seed``; 18 s of wall at load 20): a draw of a shape
is, bit for bit, the prefix of a larger draw (``jax_threefry_partitionable``, checked for
1-3 dimensions, float32 and float64), so one padded program per dtype could serve them.

The report's traffic checks in one pass over the 400 replicated windows
(``_replicate_statistics``, every value ``window_statistics``' bit for bit) and the
overview's titles placed at y = 1 with its bands by ``np.quantile`` (2026-11-28, main
1e277c1 against the branch at load 15-28, the shared machine at its busiest: read the
parts). In-process CPU on the shipped fit, fresh processes alternated: ``traffic_checks``
0.70-0.85 s -> 0.57-0.66 s (the rest is ``generate_scenarios``), the overview and its
panels 0.96-1.14 -> 0.85-0.91 s, ``write_report`` as a whole 2.96, 3.36, 3.35 s -> 2.75,
2.72, 3.34 s. The full command, a cold fit then 3 repeated in fresh processes on one fresh
cache, main and branch alternated, 2 pairs (a third stopped for time), user environment
(no numba) and ``bench`` one side by side, main / branch: child CPU cold 24.4 / 21.8 s
and 22.1 / 28.1 s (user), 24.9 / 22.6 s and 27.6 / 28.8 s (bench); repeated medians
11.3 / 11.7 s and 13.9 / 14.0 s (user), 11.7 / 12.8 s and 16.5 / 14.9 s (bench), wall
80-110 s a run: one side's runs spread 10.3-18.2 s, so no difference is resolved end to
end. The fit file (every group ``xarray``-identical), the 13 criticism files byte for
byte, and the printed tables the same; no XLA or Warp banner.

The fit file written and read through one open file (``write_fit``: one ``h5netcdf.File``,
each group's ``Dataset.dump_to_store``; ``read_fit``: each group opened on the same handle
and loaded; ArviZ opened it once per group: 8 opens to write, 10 to read) and the traffic checks'
histograms as ``hist``'s polygons with their limits from the vertices, the legend one row in
the title band (no ``loc="best"`` search) (2026-11-28, wt-int 2f1a8fd against the branch,
load 6-12; the counts are exact, the seconds the machine's noise). h5py group lookups
8,524 -> 8,220 (write) and 2,972 -> 2,685 (read): they are h5netcdf's per-variable
dimension lookups, not the opens, so the saving is small. In-process CPU on the shipped
fit, 5 fresh processes alternated, with dask hidden as the CLI hides it, median of the
first call / of the least of 4 more: ``write_fit`` 0.84 / 0.68 s -> 0.74 / 0.55 s,
``read_fit`` (all groups loaded) 0.79 / 0.67 s -> 0.82 / 0.55 s, the figure and its PNG
0.94 / 0.81 s -> 0.82 / 0.76 s (cProfile: 597,560 -> 526,793 calls; what is left is
matplotlib's 10 axes and about 100 ticks, 0.3 s each profiled). ``are-stats fit
courtyard_traffic`` with figures, repeated on a warm cache, 4 pairs alternated, child CPU
(user + sys): the branch's first run recompiled after the source change (26.8 s, left
out); then 16.1 / 13.8, 14.7 / 13.9, 15.4 / 14.7 s wt-int / branch (wall 19-43 s a run
at this load): below the noise of a run. The fit file (every group ``xarray``-identical,
attributes and their types included), the 5 CSVs byte for byte, 7 of the 8 PNGs byte for
byte and the printed tables the same; ``traffic_checks.png`` differs in 2,569 pixels, all
at the legend's old and new places. The file is 3,122,191 bytes against 3,148,526 (less
HDF5 free space), the same bytes run to run; ``read_fit`` now returns the fit in memory
with the file closed. Issue 29's 5 s is still far: ``write_report``'s overview drawing is
its largest part, and ``import arviz`` compiles numba functions (``arviz.stats.ecdf_utils``)
where numba is installed.

What the repeated fit imports, by thread CPU per module
(:mod:`tests.benchmarks.bench_imports`; 2026-11-28, main 2f397d6, a user's virtual
environment without numba, bytecode written, load 17-18 where recorded, 3 repeated runs
with figures): import CPU 4.35, 5.12, 5.48 s of 13.0-15.1 s (main thread 2.7-3.3 s, ArviZ
in the InferenceData thread 1.6-2.2 s); by package scipy 1.24-1.67 s (stats 0.44-0.63,
signal 0.23-0.25), jax + jaxlib 0.85-1.04, matplotlib with its 3-D axes and pyparsing
0.7-0.9, pandas + pyarrow 0.4-0.5, numpy 0.18-0.24, xarray 0.15-0.19, numpyro 0.08-0.10,
typer's pydantic 0.06-0.08, our own modules 0.14-0.17. The 1.65 s that a profile charged to
``are_stats.export`` in the CLI's job module is JAX, the behaviours and the scenarios
imported there first: ``are_stats.fitting`` imports them too, and export on top of the
fit's imports is 6 modules and 8 ms. Every package above is one the fit or its report calls
(ArviZ brings scipy.stats, scipy.signal and ``matplotlib.pyplot``; the report draws with
pyplot, the position densities smooth with scipy.signal), so moving imports does not reach
issue 29's 1.8 s of import CPU. In one process (3 runs, load 19-22), on top of the fit's
other imports (4.3-4.4 s there): scipy.signal and scipy.stats 1.09-1.12 s (189 modules;
scipy 1.17 rewrites the docstring of every array-API function at import), then ArviZ
0.07-0.08 s (91 modules). Only a fit without ArviZ (its ``from_dict``, ``loo``, ``ess`` and
``summary``) and without scipy.signal and scipy.stats of its own would save that second.

The report's PNGs written from the rendered pixels as unfiltered RGB rows at zlib level 3
(Pillow tried all five PNG filters on every row), the traffic checks' empty y axes not drawn
(2026-11-28, main 2f397d6 and wt-report, the shipped log's saved fit, process CPU, load
15-26): the 8 PNGs' encoding 0.11 s against 0.24 s for Pillow's 7 overview images alone
(plus ``savefig``'s), 466 kB against 500 kB; every PNG the same pixels, every CSV
``cmp``-identical, the fit file byte for byte. ``write_report`` + ``write_fit`` stayed about
3.4 s of CPU: in the CLI's repeated fit, three alternated pairs, ``write_report`` 3.47,
2.70, 2.80 s main vs 2.38, 2.78, 3.35 s branch (repeated wall 51.7, 42.7, 41.3 vs 64.6,
43.0, 48.6 s; user 13.9, 12.1, 11.5 vs 18.0, 11.8, 13.1 s): the saving (about 0.2 s) is
below the noise of that load. A wrapper of each axis' locator that made ticks only inside
the view (186 -> 148 ticks, about 0.08 s, the same pixels) was not kept: 96 lines around
matplotlib's locator and formatter protocol for under a tenth of a second. Left (cProfile,
process time): the figures' axes and ticks (16 axes, each tick about 2 ms to make), text
drawing, ``generate_scenarios``' 200 chosen-model replicates one by one (about 0.5 s of
``traffic_checks``' 0.76 s) and h5netcdf's per-variable overhead in ``write_fit`` (0.6-0.9
s, 55 variables; compression's share not isolated: a fit read back keeps its variables'
compression encoding whatever ``write_fit`` asks).

The tracks part with the behaviour's eager key operations and float64 uniforms in NumPy
(``traffic.split_key``, ``fold_in_key``, ``key_from_seed`` and the new ``key_uniform``: the
walks, rollouts, realism scenes, assembly, motion checks and field fit) and
``preferred_speeds``' normals drawn in one shape up to 16,384 people (a draw is the prefix
of a longer one) (2026-11-28, main 2f397d6 and wt-tracks started together in fresh processes
with empty caches, the CLI's command, child CPU by ``getrusage``, ``JAX_LOG_COMPILES=1``):
load 18 -> 20: cold CPU 111.8 s main vs 109.2 s branch (wall 1,198 vs 1,199 s, a load of 20
on 2 cores); again, load 18 -> 10: 109.8 vs 107.5 s (0.98x; wall 882 vs 871 s; the random
programs' compile wall 30.6 vs 6.4 s); XLA compilations 55 vs 43 in both:
``_threefry_seed``, ``_threefry_fold_in``, two ``_threefry_split``, two ``unstack``, three
``_uniform``, one of the three ``_normal`` and two one-operation programs gone (their
compile wall 39.5 vs 12.5 s in the first round, the two normals left: float32 speeds and the
motion checks' float64 jitter). In a fresh process, the same draws (one of each shape the
fit makes) 4.64 and 4.26 s -> 2.17 and 1.60 s CPU, md5 of all draws equal. The fit file's
every group (``xarray`` ``identical``) and all 17 criticism files byte for byte the same, in
both rounds. Not done: ``_window``'s two displacement-error sizes (2,048 and 4,096 slots:
padding the five smaller walks to 4,096 doubles their runs, not measured against the compile
saved; smaller chunks draw otherwise) and the 16- and 32-slot windows (all pairs: their sums
over the slots keep their sizes).

The tracks part without one-operation programs (wt-tracks2; 2026-11-28, wt-int 1ef3373 and
the branch started together in fresh processes with empty caches, the CLI's command, child
CPU by ``getrusage``, ``JAX_LOG_COMPILES=1``): in JAX 0.10 ``jnp.asarray`` of a NumPy array
compiles a ``stage`` program per shape and dtype (a cast a ``convert_element_type`` one), and
a device array handed to a program split across the two devices two ``_multi_slice`` ones
(bool and float32 ``[8, 20, 40]``: the behaviour likelihood's goal-sharded arguments, not an
iteration). Found by a logging handler on the compilations with a traceback per
compilation: ten from the behaviour fit (its data, ``theta``, the solve's numbers), four from
``soft_policy``'s buckets (the assembly's goals), four per map from the social force's walls
(two maps), one from the window's ``jnp.int32`` counts. Now the likelihood's data stay NumPy
(the program places them), the others go by ``jax.device_put`` or as NumPy / Python numbers:
the same argument types, programs and bits. XLA compilations 43 -> 23 (the window's counts
still ``jnp.int32``), load 7.8 -> 10: cold CPU 104.5 vs 104.4 s (wall 414 vs 406 s); then
43 -> 22, load 9.4 -> 10.7: 98.3 vs 99.5 s (wall 441 vs 448 s): no CPU change above the
noise of a run at that load (20 such programs cost 0.49-0.52 s of CPU to make in a fresh
process, 0.03 s by ``device_put``; at idle about 0.05 s of wall each). The fit file's every
group and root (``xarray`` ``identical``) and all 17 criticism files byte for byte the same,
in both rounds. ``_window``'s displacement-error sizes: all eight walks at 4,096 slots
(instead of five at 2,048) keep the table's bits (md5 equal) and save the 2,048 program's
compile, but double the five walks: ``displacement_errors`` alone in a fresh process (the
fit's behaviour and interaction, 200 windows, process CPU, load 8-12, two rounds) cold 19.64
-> 18.02 and 14.93 -> 13.47 s, warm (second call) 7.36 -> 8.35 and 6.64 -> 7.42 s: 1.5 s
won cold, 0.8-1.0 s lost in every repeated fit (the compile is then read from the cache);
not kept. The variations' bootstrap (100 replicates) is 0.17 s of CPU on the 302-person
table (0.35 s with, 0.18 s without): left as it is. ``string_pull_many`` on a generation's
6,000 paths is now 1.28 s of ``continuous_paths``' 1.64 s (``_crossed_block`` 0.70 s):
left. The idle wall is about what wt-tracks estimated, less about a second (the programs'
compile wall at idle): roughly 61 s. Left, by compile wall at load 7 (one in-process cold
fit): the Laplace ``call`` programs, ``_window`` at 2,048, 1,024 and 4,096 slots, the
behaviour's gradient (about 9 s each at that load), the two ``_per_track_jit`` programs
(the displacement errors' 512 windows of 16 steps, the held-out moves' 128 whole tracks:
one program only by padding both ways, not tried), the motion checks' float64 jitter
``_normal`` (about 3 s).

The Laplace stage of a repeated fit, per candidate (2026-11-28, main 01ee85a and the branch
alternating, load 11-25; nine candidates one after another in a fresh process on a warm
cache, process CPU per phase): loading the programs 0.96-1.07 s, the mode searches 0.96-1.14
s, the Hessians 0.10 s, the 1,000 ranking draws 1.44-1.68 s, PSIS-LOO 0.32-0.37 s (the three
stay laws' 485 units 0.1 s each). groups+hawkes, the slowest (0.87-0.88 s: 13 ms a call of
32 points at the cheap XLA level), is now compiled at XLA's default optimisation: 0.32-0.50
s, the stage 3.79/4.37 -> 3.16/3.90 s, its compile 0.5-1.0 s longer; the chosen models and
draws unchanged, its ``loo_arrivals`` row moves in the 5th digit, the printed tables
identical. The whole command (``/usr/bin/time``, fresh caches, load 16-21, 3 alternated
pairs) does not resolve that: repeated CPU main 10.9, 14.4, 13.4 s vs branch 11.6, 10.9,
13.4 s (wall 35-42 s both), cold 23.4 vs 22.7 s CPU. Measured and not done: a mode-search
program sized to the stencil (``2d + 1`` points instead of ``MIN_BATCH`` = 32: 0.4-3.9 ms a
call at 5 points instead of 1.4-13.1 ms at 32) would save about 0.45 s of CPU a repeated fit
and cost a second program per candidate, 0.45-4.8 s of compile each (about 15 s cold); the
draws in calls of 5-16 points cost more than in 32. Thread CPU in the CLI's own run: each
candidate's thread 0.07-0.17 s of Python (its XLA work runs on XLA's threads), the
InferenceData thread 2.4-2.6 s. A busy Python thread (an import) beside a 10 ms XLA call
doubles the call's wall at that load whether Python's switch interval is 5 ms or 0.1 ms
(20.4 vs 20.8 ms), so what it takes is CPU, not a GIL hand-off; the hand-off costs about
0.17 ms on a call of 0.1 ms (about 0.1 s a fit).

The tracks part with a walk's tail (``social_force_tracks``' per-artefact ``np.interp``,
yaw and copies) and the displacement errors' 32,000 continuations (``_rollouts``: their
positions at the 12 predicted times and first headings) evaluated for all paths at once
(``_interp_runs``, NumPy's ``interp`` bit for bit; ``behaviour.positions_at``) (wt-tracks,
2026-11-28, main 01ee85a and the branch started together in fresh processes with empty
caches, the CLI's command, child CPU by ``getrusage``): load 18 -> 6.5: cold CPU 104.3 s
main vs 102.3 s branch (0.98x; wall 623 vs 619 s); load 4.5 -> 3.9: 95.8 vs 94.7 s
(0.99x; wall 187.2 vs 184.7 s); 22 XLA compilations each. The fit file's root and 9
groups (``xarray`` ``identical``) and all 17 criticism files byte for byte the same, in
both rounds. In-process CPU (load 15-24): the continuations' loop 0.79-1.15 s -> 0.19-0.29
s, a walk's tail on 4,000 people of small scenes 0.10-0.14 -> 0.03-0.04 s and on 15,100
(the motion checks') 0.46-0.59 -> 0.37-0.43 s (a search by ``lexsort`` was slower
there: 1.1 s). The idle wall, scaled from the roughly 61 s above by the CPU ratio: about
60 s, within the estimate's noise. Where main's CPU went (cProfile, ``time.process_time``,
in-process cold fit, 173 s profiled at load 10-15): XLA compiling in the main thread 31 s
(13 programs; of the 22 programs' 208 s of compile wall the behaviour's gradient 44.6 s,
``_window`` five 60.6 s, ``_capped_jit`` 10.1 s, the MDP ``body`` two 9.3 s,
``_per_track_jit`` two 8.6 s, ``_normal`` two 8.7 s) and the Laplace candidates' thread
awaited 20.8 s; ``social_force_tracks`` 39.9 s (its windows' runs 11.0 s), the realism
table 22.2 s, displacement errors 28.6 s, motion checks 28.9 s, ``learn_interaction``
12.2 s, the two ``fit_behaviour`` (the fit's and the report's held-out one) 27.7 s
(``_mle`` 18.6 s), the report 12.7 s. Measured and not kept: the behaviour gradient's
program without XLA's CPU fusion emitters (as the Laplace programs): ``fit_behaviour`` on
the 302 tracks in a fresh process 11.8 -> 8.6 s of CPU cold, 2.60 -> 2.43 s warm, but
other float32 bits (beta 1.89825845 -> 1.89825579, its se 0.16416075 -> 0.16415785): a
change of outputs for the lead to weigh (the criticism's draws would follow it).

The tracks part with the behaviour gradient and the social force's ``_window`` compiled
without XLA's CPU fusion emitters and ``discretise_tracks`` for all tracks at once (wt-tracks2,
2026-11-28, wt-int 81043a8 and the branch started together in fresh processes with empty
caches, the CLI's command, child CPU by ``getrusage``, load 12.4 -> 11-13): cold CPU 87.6 s
vs 75.8 s (0.87x; wall 371 vs 344 s), 22 XLA compilations each, their compile wall 186.9 vs
147.9 s. All 17 criticism files byte for byte the same; the fit file's root and groups
(``xarray`` ``identical``) the same but the behaviour group's ``beta``, ``beta_se``,
``slip``, ``slip_se`` and ``loglik`` (the gradient's float32 bits: beta 1.89825845 ->
1.89825579, its se 0.16416075 -> 0.16415785; adopted). In-process CPU: ``fit_behaviour``
on the 302 tracks in a fresh process 15.8 -> 10.9 s for the first call, 3.3 and 3.2 ->
3.5 and 3.1 s for the next; the golden social walks cold 19.8, 6.6, 14.1, 3.5 -> 14.2, 4.6,
9.6, 2.2 s, repeated alike, every digest kept; ``discretise_tracks`` 0.52 -> 0.014 s a call,
the same paths. On a warm cache (a second fresh process, load 9-12, wt-int then the branch):
``fit_behaviour``'s first call 4.98 -> 3.89 s, the golden walks 9.4, 1.0, 3.4, 0.9 -> 8.1,
1.0, 3.2, 0.8 s (cold on that round: 14.8 -> 10.4 s and 17.0, 5.4, 12.4, 3.2 -> 14.8, 4.4,
9.1, 1.9 s). ``_window``'s five programs, by a spy in a cold in-process fit: 16 slots (all
pairs, the learned interaction's rewalks on their own 49 x 119 grid, 66 windows), 32 (no
repulsion, the realism scenes, 132), 1,024 (the motion checks' replicates, 66 windows,
9.5 s of runs), 2,048 and 4,096 (the displacement errors' chunks, 5 and 3). Measured and
not kept: windows without repulsion walked in pieces of at most 1,024 slots (cut between
groups only): 22 -> 20 compilations and 121.5 -> 103.0 s of CPU cold (load 8 -> 18, with
the gradient and the emitters), every output of that fit the same, but a 4,096-slot window
of 700 small scenes at strength 0 walks to another digest whole, in pieces of 2,048 and in
pieces of 1,024 or fewer (those three agree): above 1,024 slots the program's size moves the
walk's bits, so pieces are not bit-safe. Left: the motion checks' 1,024-slot runs, the
Laplace ``call`` programs, ``_capped_jit``; issue 29's 60 s not shown met (idle wall,
scaled by the CPU ratio from about 60 s: about 52 s, not measured on idle cores).

Where a repeated ``are-stats fit courtyard_traffic`` (figures on) spends its CPU, and
``read_fit`` checking before it reads (wt-repeat29; 2026-11-28, main 8fc9593 and the branch
side by side, the bench environment: numba installed, so ``import arviz`` compiles
``ecdf_utils._binom_pmf``; load 10-32, the machine at its busiest: read the shares). Thread
and process CPU around the job's parts (one repeated run, load 17, process 15.6 s, main
thread 8.8 s): imports before the fit 3.6 s in the main thread (``are_stats.cli`` 0.12,
``_cli_jobs`` 2.39: JAX with its scan of every installed distribution's metadata for a ROCm
plugin, pandas + pyarrow, numpyro, scipy.sparse / linalg / optimize / special;
``are_stats.fitting`` 1.10); the log and the catalogue 0.10 s; ``fit_log`` 7.1 s of process
CPU with 0.3 s in the main thread: the InferenceData thread 2.9 s (ArviZ's import, most of
it numba compiling, 1.2-1.5 s, absent in a user's environment without numba; the groups
themselves about 0.3 s), the two Laplace run threads' Python 1.0 s, the PSIS-LOO thread 0.55
s and XLA's own threads about 2.3 s (the nine programs read from the persistent cache,
"Persistent compilation cache hit" nine times, 0.12-1.43 s of wall each at that load, the
mode searches and the ranking draws); ``write_fit`` 0.57 s; ``fit_summary`` 0.18 s;
``write_report`` 3.6 s (the overview 1.3, ``traffic_checks`` 1.06 with its 200
``generate_scenarios`` replicates about half, ``plot_traffic_checks`` 0.30, the predictive
checks 0.13, the PNGs 0.15, the traffic-checks figure's drawing and the CSVs the rest); the
collector 0.42-0.46 s in about 100 collections, spread over the parts; ``prune_cache`` 0.00
s. A cold run (fresh cache, same load class, process 28.0 s): imports 2.8 s, ``fit_log``
21.8 s (the Laplace threads' tracing and export 5.0 s of Python, the nine XLA compiles about
12 s, 3.0-16.4 s of wall each at load 24, the InferenceData thread 3.3 s), ``write_fit`` 0.7
s, the report 2.2 s; a fresh ``XDG_CACHE_HOME`` also rebuilds matplotlib's font list
(0.53-0.59 s of CPU against 0.29-0.31 s warm). The CLI's command, repeated on one warm cache
per tree, alternated main / branch in 3 rounds at load 27-32 (user + sys,
``/usr/bin/time``): main 13.66, 11.48, 12.07 s, branch 12.40, 13.31, 11.16 s (wall 36-71 s):
the branch does not touch the fit's path, and a run's spread at this load is 2 s; the fit
file's 8 groups (``xarray`` ``identical``), the 13 criticism files (``cmp``) and the printed
tables the same. ``read_fit`` now reads and checks the posterior, observed_data and
constant_data groups before it opens the others (opening a group's variables is most of a
read: h5netcdf's per-variable dimension lookups, 0.40 of 0.54 s opened lazily, 0.10 s for
the posterior alone): a newer-format refusal of the shipped fit 0.51-0.53 -> 0.12-0.13 s of
CPU (4 calls each; 0.27-0.28 s with the three groups read before the check, the posterior's
format is now checked before the other two), an accepted read unchanged (0.51-0.58 s) and
the same InferenceData. Measured and not kept: ``gc.freeze()`` after the fit's imports (the
collector 0.42-0.46 -> 0.31-0.36 s: about 0.1 s, below a run's noise, and it would freeze a
library caller's objects); ``write_fit`` on a thread beside ``write_report`` (h5netcdf and
matplotlib are both Python under the GIL: the same 3.1 s of process CPU, walls 19-25 s at
load 30 that resolve nothing). Left toward 5 s: every import above is used by the fit or its
report (numpyro's distributions define the traffic models' classes at import; ArviZ and
pyplot are the report's), so the import CPU (3.6 s in that run, 2.8 s in the cold one) goes
only with a fit that drops a library; the report's matplotlib axes and ticks (about 1 s);
the nine program loads (lowering each export to reach JAX's cache key); h5netcdf's
per-variable overhead in ``write_fit`` (0.6 s for 55 variables). Toward 15 s cold: the nine
XLA compiles (about 12 s of CPU) and their tracing (5 s).

The tracks part with the host loops of the interaction learner and of the walks' groups cut
(wt-tracks29, 2026-11-28): ``group_spacing`` in one k-d tree, every (scenario, group, time)
frame on its own stretch of a third axis (0.844 -> 0.045 s a call on the 302-person table),
``_on_one_step`` built from arrays (0.390 -> 0.014 s), ``formation`` without a loop over
the groups (15,100 artefacts: 0.310 -> 0.036 s), ``fit_behaviour``'s tracks from one
``lexsort`` (its second and third calls in a process 3.42 -> 2.66 s and 3.31 -> 2.49 s),
the realism's group labels read once per distinct label (``realism_features`` 0.213 ->
0.120 s); and ``behaviour.jit_with_options`` for the four jits that passed XLA options
straight to ``jax.jit`` (an option a later jaxlib does not know is left out; the same
programs today). Where main's CPU went before (8fc9593; cProfile, process time, an
in-process cold fit at load 10-14, 130.4 s profiled, 424 s wall): the traffic fit 26.7 s
(21.0 s of it while the main thread awaits the Laplace threads: their compiles' CPU),
``fit_behaviour`` 17.3 s (the gradient's compile 20.4 s wall), ``learn_interaction`` 11.7 s
(``repulsion_evidence`` 4.3, ``group_spacing`` 3.6, ``fit_social_force`` 2.1,
``_on_one_step`` 1.3), the realism table 18.1 s (the catalogue's ``walk_tracks`` 7.4 s: its
MDP solves 3.6 s and 1,248 one-path ``string_pull`` calls 2.0 s; the fitted scenes' soft
policies and paths 3.7 s, their social force 3.2 s), the displacement errors 15.7 s
(rollouts 5.7 s, string pulling 3.6 s of it; walks 7.3 s), the motion checks 17.5 s (walks
10.1 s, generation 4.6 s), the report 12.8 s (the held-out fit 3.9 s: its likelihood runs
the fit's gradient program, no compile of its own), imports 6.9 s; ``formation`` 1.6 s over
the walks. XLA compilations 22 (138 s of compile wall at that load: the nine Laplace
``call`` 73.5 s, the gradient 20.4 s, ``_window`` five 19.1 s, ``_capped_jit`` 8.3 s, the
MDP ``body`` two 7.0 s, ``_per_track_jit`` two 5.7 s, ``_normal`` two 3.8 s). The
benchmark's tracks part (``_bench_tracks``, fresh processes and caches, child CPU by
``getrusage``), main 8fc9593 against the branch (c9962eb in round 1, without ``formation``;
a6a9290 after): started together, load 25.4 -> 20.5: cold CPU 79.2 vs 77.1 s (0.97x; wall
764 vs 756 s); started together, load 14.5 -> 12.4: 68.8 vs 66.9 s (0.97x; wall 320.5 vs
312.1 s); one after the other, load 8.5 -> 7.9: 65.1 vs 62.3 s (0.96x; wall 119.9 vs 110.1
s); the branch first, load 8.6 -> 5.4: 71.4 vs 63.5 s (wall 73.8 vs 78.8 s); main first,
load 4.3 -> 6.2: 74.7 vs 78.7 s (wall 109.1 vs 166.3 s, the branch's compile wall 86 vs 37
s): one after the other the runs spread 62-79 s of CPU, so the saving (about 2 s) is
resolved only in the rounds started together. 22 XLA compilations each, every round. The
fit file's root and 9 groups (``xarray`` ``identical``, attributes included) and all 17
criticism files byte for byte the same, in every round; the social goldens' digests kept
(tests/behaviour/test_social_golden.py). Issue 29's 60 s wall on 2 idle cores is not shown:
at the lowest loads found (4-9) the walls were 74-166 s on 62-79 s of CPU; at idle the wall
is below the CPU (the Laplace programs compile in threads), by their overlap, not measured
here (the last estimate, about 52 s, scaled by 0.96: about 50 s; on 62-79 s of CPU the goal
needs that overlap). Left: the main thread's wait for the Laplace threads (the behaviour
stage does not need the traffic fit and could run beside them), and the realism table,
displacement errors and motion checks, which draw with their own keys, in threads (both in
``_field_fit``); the catalogue walk's one-path string pulling (``_walk._legs``);
``group_tracks``' loop over members (1.3 s profiled).

The tracks part with the fit's independent parts in threads (wt-tracks, 2026-11-28):
``fit_log`` fits the behaviour and the interaction (``_field_fit._fit_walkers``: the tracks
and the map alone) in a thread started before the traffic fit, whose cold run mostly waits
on XLA compiling the Laplace candidates; the displacement errors (and a labelled table's
motion checks) run in threads beside the realism table; ``write_motion_report``'s held-out
fit beside the motion checks; and the catalogue walk's legs of a round string-pulled
together (``_walk._pulled_legs``, ``string_pull_many``: the same paths as one by one,
tested; ``walk_tracks`` of 150 walkers over 300 s, warm, 25.1-25.9 -> 20.3-20.7 s of CPU a
call at load 17-19, the same tracks). Each part draws with its own key; the stage clock is
told the same steps in the same order. Only the behaviour's soft solves run a program with a
collective across the devices, so no two such programs are ever in flight together. Main
1662149 and the branch started together in fresh processes with empty caches (the CLI's
command, ``/usr/bin/time``, load 19.6 -> 18-20): **wall 944.7 s on main against 672.7 s
(0.71x), CPU (user + sys) 104.7 s against 105.8 s**; stage walls (main / branch): the
traffic stages 214 / 273 s, the main thread's wait for the behaviour 112.2 / 0.0 s and for
the interaction 64.0 / 0.0 s, realism and displacement errors 420.6 / 271.4 s, the
posterior-predictive checks 28.6 / 26.7 s, the motion checks 44.9 / 44.4 s. The fit file's 9
groups (``xarray`` ``identical``), the 17 criticism files (``cmp``) and the printed output
the same. Again with the relay's fix (4e2f9f8), started together at load 10.7 -> 8-9: wall
304.3 s on main against 279.1 s (0.92x), CPU 101.4 s against 102.3 s, maxrss 1.44 against
1.57 GB; stage walls: traffic 83.8 / 115.8 s, the waits for the behaviour and interaction
41.0 + 20.2 / 1.3 + 0.0 s, realism and displacement errors 126.7 / 115.0 s (the two threads
of that stage win little: most of it is Python under the GIL), the posterior-predictive
checks 4.9 / 7.0 s, the motion checks 6.4 / 11.3 s; every file and the printed output the
same again. An earlier pair (the behaviour thread alone, started 2 min apart, load 15-17):
wall 987.5 vs 968.2 s, CPU 104.5 vs 107.1 s, the behaviour and interaction waits 73.0 + 46.9
s vs 0.1 s. At these loads a process with two runnable threads also gets more of the machine
than one with one, so the wall ratio overstates what 2 idle cores give: there the saving is
the overlap itself, at most the behaviour and interaction (about 11 s of the idle run of
2026-11-27) and the shorter of the realism table and the displacement errors. Issue 29's 60
s on idle cores is still not shown (the CPU of a cold run here, 104-106 s at load 18-20, is
inflated by XLA's spinning threads; 62-79 s at load 4-9 before). Left: the traffic stage's
compiles (the nine Laplace programs, about half of its CPU), the realism table and
displacement errors' own work (45 s of CPU at load 18), ``_window``'s programs.

Where a user's 80-person tracks fit on the shipped courtyard goes (issue 29's qa tour:
324 s of CPU against about 76 s for the 302-person room; 2026-11-28, wt-int 4c33474, the
tour's ``people_tracks.csv``, two classes, 2.5 Hz, ``are-stats fit --method em`` with
figures, in-process cProfile by process time, a fresh cache, load 14-20): 372.6 s of
profiled CPU, maxrss 1.37 GB. Not the number of people: the behaviour's MDP grid, 60 x 80
cells on the courtyard (0.5 m) against 20 x 40 on the room, each soft solve iterating 186-318
epochs to its tolerance (one gradient evaluation about 1 s of CPU on 8 goals), run per
class and twice (the fit, then the report's held-out fit on 70% of the ids). Per part:
``fit_behaviour`` 153 s in 2 calls, 4 maximum likelihoods (the child's: L-BFGS-B 7
evaluations, then the Hessian's 8 gradient runs, about half), the fit's 53.4 s and the
report's held-out fit 99.6 s (plus 7.7 s scoring its moves): its person class's 16 tracks
end on more goal cells, padded to 16 goals instead of 8, twice the soft-solve work per
evaluation; ``fit_behaviour`` alone out of the profiler 41.3 s cold, 34.2 s on a warm
cache (child 16.7 s, person 16.6 s); the fit's motion tables 151 s
(displacement errors 66 s, motion checks' replicates 56 s, realism 28.6 s; string pulling's
``_crossed_block`` 23.3 s of own time); the traffic models 22 s. XLA: 33 compilations,
39.5 s of main-thread backend compile; ``_gradient_value_epochs`` four times (one per
class and fit: goals 8 or 16, tracks 8 or 16, steps 128 or 256: the child class, slower,
has longer paths and lands in the 256-step bucket), the catalogue walk's ``GridMDP`` solve
(``jit(body)``) four times (legs 8, 64, 256 at 64 or 128 epochs), ``_window`` six,
``_per_track_jit`` seven. No O(n^2) loop or runaway epoch count was found: the cost is
grid cells x epochs x classes x 2 fits. Not changed (no output-preserving fix found in the
time): a common step bucket across classes (one gradient program, about 3.5 s of CPU each
spared; the person class padded from 128 to 256 steps, warm cache, gave beta, slip, their
standard errors and the log-likelihood bit for bit, 18.0 s of CPU either way; it needs the
classes' paths before the first class is fitted, a change of ``fit_behaviour``'s class
loop), the held-out fit reusing the main fit's programs, and the memory (not broken
down). Issue 29's 60 s is far for a map of this size.
"""

from __future__ import annotations

import json
import os
import re
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from tests.benchmarks.bench_traffic_nuts import _env, _pymc_available, _run_worker, _spawn

LOG = "courtyard_traffic"
BANNER = re.compile(r"slow_operation_alarm|Very slow compile")
#: JAX's own line per XLA compilation (``JAX_LOG_COMPILES=1`` in the child).
COMPILED = re.compile(r"Finished XLA compilation of (.*) in ([0-9.eE+-]+) sec")


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(args: list[str], home: Path) -> dict[str, Any]:
    """One CLI run in a fresh process on the cache ``home``: wall, CPU, load, stages."""
    env = _env(home)
    env["JAX_LOG_COMPILES"] = "1"  # one line per XLA compilation: counted, then left out
    load0, cpu0 = os.getloadavg()[0], _children_cpu()
    proc, wall = _spawn([sys.executable, "-m", "are_stats", *args], env)
    if proc.returncode != 0:
        raise RuntimeError(f"are-stats {' '.join(args)} failed:\n{proc.stderr[-3000:]}")
    record = home / "are_stats" / "stage_times.json"
    stages = json.loads(record.read_text()) if record.is_file() else {}
    chosen = re.search(r"chosen models: (.*)", proc.stdout)
    compiled = [float(m.group(2)) for m in COMPILED.finditer(proc.stderr)]
    jax_log = re.compile(r"^(Finished|Compiling|Persistent compilation cache|Not writing)")
    stderr = [ln for ln in proc.stderr.splitlines() if ln.strip() and not jax_log.match(ln)]
    return {
        "wall": wall,
        "cpu": _children_cpu() - cpu0,
        "load": (load0, os.getloadavg()[0]),
        "stages": stages,
        "chosen": chosen.group(1).strip() if chosen else "",
        "banner": bool(BANNER.search(proc.stderr)),
        "stderr_lines": len(stderr),
        "compiles": (len(compiled), sum(compiled)),
    }


def _posterior_how(fit: Path) -> str:
    """How the chosen traffic models' posteriors were drawn (the fit's attributes)."""
    import xarray as xr

    try:
        attrs = xr.open_dataset(fit, group="posterior").attrs
    except (OSError, ValueError):
        return ""
    names = ("traffic_arrival_posterior", "traffic_lifetime_posterior")
    return "; ".join(f"{n[8:]}: {attrs[n]}" for n in names if n in attrs)


def _nuts_times(fit: Path) -> str:
    """Compile and sampling seconds of the paper's NUTS fit (from the fit file)."""
    import xarray as xr

    try:
        attrs = xr.open_dataset(fit, group="sample_stats").attrs
    except (OSError, ValueError):
        return ""
    parts = [f"{k[:-5]} {float(v):.1f} s" for k, v in attrs.items() if k.endswith("_time")]
    return ", ".join(parts)


def _print_run(label: str, r: dict[str, Any], previous: dict[str, Any] | None) -> None:
    print(
        f"{label}: wall {r['wall']:.1f} s, CPU {r['cpu']:.1f} s, load {r['load'][0]:.1f} -> "
        f"{r['load'][1]:.1f}; chosen: {r['chosen'] or '-'}; XLA banner on stderr: "
        f"{'YES' if r['banner'] else 'no'} ({r['stderr_lines']} other stderr lines); XLA "
        f"compilations {r['compiles'][0]} ({r['compiles'][1]:.1f} s)",
        flush=True,
    )
    if previous is None:  # the cold run: its stages
        for stage, secs in r["stages"].items():
            print(f"    {secs:7.1f} s  {stage}")


def _bench_fit(tmp: Path, compare: str) -> dict[str, dict]:
    home = tmp / f"fit_{compare}"
    home.mkdir()
    out = {}
    for run in ("cold", "repeated"):
        fit = home / f"{run}.nc"
        args = ["fit", LOG, "--out", str(fit), "--no-figures", "--compare", compare]
        out[run] = _run(args, home)
        _print_run(f"  {run:8s}", out[run], out.get("cold") if run != "cold" else None)
        if run == "cold":
            times = _nuts_times(fit)
            if times:
                print(f"    paper's NUTS fit: {times}")
            how = _posterior_how(fit)
            if how:
                print(f"    {how}")
    return out


def _bench_peer(tmp: Path) -> None:
    """One NUTS fit of the gamma-stays model, cold, ours and PyMC (bench_traffic_nuts)."""
    impls = ["ours"] + (["pymc"] if _pymc_available() else [])
    opts = ["--warmup", "1000", "--samples", "1000", "--duration", "10800"]
    walls = {}
    for impl in impls:
        home = tmp / f"peer_{impl}"
        home.mkdir()
        result, wall = _run_worker(impl, "stays", 1, _env(home), opts)
        walls[impl] = (result, wall)
        print(f"  {impl:5s} cold gamma-stays NUTS fit: process {wall:.1f} s; call {result}")
    if "pymc" not in walls:
        print("  PyMC not installed in this environment: no peer ratio (pip install "
              "'are-stats[bench]')")  # fmt: skip
    else:
        print(f"  PyMC / ours, cold process wall: {walls['pymc'][1] / walls['ours'][1]:.2f}x")


def _bench_tracks(tmp: Path) -> dict[str, Any]:
    """One cold ``are-stats fit`` of the seeded 302-person tracks table with its map."""
    from tests.test_cli_tracks import _room, _tracks

    home = tmp / "tracks"
    home.mkdir()
    _room(home)
    log = _tracks(home, horizon=TRACKS_HORIZON)
    r = _run(["fit", str(log), "--out", str(home / "fit.nc")], home)
    _print_run("  cold", r, None)
    return r


def _bench_crowd(tmp: Path) -> dict[str, Any]:
    """``are-stats fit`` of the independent crowd (:mod:`tests.crowd`: door to door round a
    pillar, velocity-obstacle avoidance, groups abreast, 5 cm noise; 68 people over 300 s)
    with its map, cold, then ``are-stats report``: the realism table and the displacement
    errors the fit stored (issue 26: does the fitted motion beat the baselines on a crowd
    that is not constant velocity?)."""
    import pandas as pd

    from tests.crowd import write_crowd

    home = tmp / "crowd"
    home.mkdir()
    log = write_crowd(home)
    fit = home / "fit.nc"
    r = _run(["fit", str(log), "--out", str(fit), "--no-figures"], home)
    _print_run("  cold", r, None)
    proc, _ = _spawn(
        [sys.executable, "-m", "are_stats", "report", str(fit), "--out", str(home / "rep"),
         "--replicates", "20"], _env(home),
    )  # fmt: skip
    if proc.returncode != 0:
        raise RuntimeError(f"are-stats report failed:\n{proc.stderr[-3000:]}")
    with pd.option_context("display.width", 120, "display.float_format", "{:.3f}".format):
        print(pd.read_csv(home / "rep" / "realism.csv", index_col=0).to_string())
        print(pd.read_csv(home / "rep" / "displacement_errors.csv", index_col=0).to_string())
    return r


#: Seconds of :func:`tests.test_cli_tracks._tracks` that make 302 people (12,112 rows).
TRACKS_HORIZON = 1700.0


def main(quick: bool = False) -> None:
    """The goals of issue 29 in fresh processes with empty caches."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_fit_cold_"))
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the start")
    try:
        results = {}
        for compare in ("laplace",) if quick else ("laplace", "nuts"):
            print(f"\nare-stats fit {LOG} --no-figures --compare {compare}", flush=True)
            results[compare] = _bench_fit(tmp, compare)
        if "nuts" in results:
            a, b = results["laplace"], results["nuts"]
            same = a["cold"]["chosen"] == b["cold"]["chosen"]
            ratio = b["cold"]["wall"] / a["cold"]["wall"]
            print(
                f"\ncold fit: --compare nuts / --compare laplace {ratio:.2f}x "
                f"wall, {b['cold']['cpu'] / a['cold']['cpu']:.2f}x CPU; repeated "
                f"{b['repeated']['wall'] / a['repeated']['wall']:.2f}x wall; same choices: {same}"
            )
        if quick:
            return
        print("\nare-stats demo (cold: fresh cache; not the venv's installation)", flush=True)
        home = tmp / "demo"
        home.mkdir()
        tic = time.perf_counter()
        r = _run(["demo", "--out", str(home / "out"), "--force"], home)
        _print_run("  cold", r, None)
        print(f"  ({time.perf_counter() - tic:.1f} s)")
        print("\nare-stats fit of a 302-person tracks table with its map (cold)", flush=True)
        _bench_tracks(tmp)
        print("\nare-stats fit of the independent crowd (tests.crowd) with its map (cold), "
              "then its realism table", flush=True)  # fmt: skip
        _bench_crowd(tmp)
        print("\npeer: one cold NUTS fit of the same gamma-stays model and data", flush=True)
        _bench_peer(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
