"""The regression gate: runs against a baseline, item by item (``beo-bench gate``), and the
baseline file it reads (``beo-bench baseline``); docs/benchmark.md, "A regression gate".

**What is compared.** Each run is paired with the baseline run of the same suite label
(suite, track and, when it is not the suite's own, sensor: ``pose-1dof@class-free``,
``tabletop~ideal``). The two must have scored the same items the same way: the same suite,
suite version, seed, track, sensor, object library version and suite record (image size,
field of view, classes, dataset identity, sensor model version...; the record's ``size``,
``description`` and ``item_timeout_s`` change no score and are not compared), and exactly
the same items. Anything else is refused (:class:`GateUsageError`, exit status 2) with the
flag that fixes it. The baseline is a run directory, a directory of runs (``all --runs``), or
a baseline file: the per-view values of every pairable metric of one or more runs (format
:data:`BASELINE_FORMAT` version :data:`BASELINE_VERSION`, :func:`baseline_json`), small
enough to commit.

**The test.** A gate makes one test per metric and backend, **pooled over every suite** it
gates that measures the metric: per metric, the per-view values as the summary counts them
(failures at their worst case, :func:`beo_bench.bench.compare.view_values`), paired on the
views both runs scored and summed per **unit**, an item of a suite (:func:`pool`: the runs
of one suite's tracks or sensors score the same items, so their views of an item are one
unit, and the sign-flip test's units are independent). The statistic is the mean over the
pooled views of B - A (the baseline is A). A metric is a **regression** when the run is
worse than the baseline by more than the metric's **margin** (:data:`MARGINS`: 5 deg of
mean rotation error, 1 cm of mean translation error, 5 points of class accuracy, 10 of pick
success...; a difference a practitioner would call a regression), tested by a one-sided
paired **sign-flip permutation test** over units of the differences less the margin
(:func:`beo_bench.stats.sign_flip_p`): under "worse by exactly the margin" each unit's
shifted difference is as likely negated; exact over every sign pattern up to
:data:`~beo_bench.stats.EXACT_MAX_ITEMS` units that differ, else
:data:`~beo_bench.stats.DEFAULT_PERMUTATIONS` seeded random patterns. The p-values of every
test one gate makes are corrected together by **Holm's** step-down method
(:func:`beo_bench.stats.holm`), so a
gate over unchanged code fails with probability at most ``alpha`` however many metrics it
tests. The direction is the metric's (``MetricSpec.higher_is_better``,
:mod:`beo_bench.bench.columns`): an improvement never fails the gate. The report also gives
the difference's 95% paired bootstrap interval over units (the figure ``beo-bench compare``
prints for one run) and, per suite, its own difference (not tested: what a failure points
at).

By default the gate tests the declared primary metrics (:data:`PRIMARY_METRICS`), for each
thing a backend gets wrong: rotation (the mean rotation error and the > 15 deg rate),
translation (the mean translation error), class (the class accuracy) and pick (pick
success); a suite joins each test whose metric it measures. Five tests rather than one per
suite: pooled, the smoke set's 126 items that score a pose (166 a class) count together,
and Holm divides alpha by five at most, not by the number of runs (issue 47 saw a 90 deg
turn of every estimate pass, its p of 0.065 made 1 by 16 tests; docs/ci.md, "What the
default gate catches", has what the gate catches now).
``--metrics`` tests others instead, pooled the same way; a suite that does not measure one
is left out of that test and listed in the report as skipped.

The modules: :mod:`~beo_bench.bench.gate.spec` (metrics, margins, verdict words, errors),
:mod:`~beo_bench.bench.gate.baseline` (the runs read and the baseline file),
:mod:`~beo_bench.bench.gate.verdicts` (options, pooled units, verdicts),
:mod:`~beo_bench.bench.gate.report` (text, Markdown, JUnit, JSON) and
:mod:`~beo_bench.bench.gate.check` (:func:`~beo_bench.bench.gate.check.gate` itself).
"""
