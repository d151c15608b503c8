"""The leaderboard pages (``beo-bench leaderboard``, :mod:`beo_bench.bench.pages.leaderboard`):
``leaderboards/`` regenerated from run summaries.

Per suite: ``<suite>.md``, ``<suite>.json`` (the summaries behind the tables, with their
provenance), ``<suite>_paired.json`` (the paired verdicts), and the plots
(``<suite>[_<track>]_rot_cdf.png``, ``..._confusion_<backend>.png``,
``..._error_vs_samples.png``); ``README.md`` indexes them.

Only runs scored under the same rules share a table:

- a suite with tracks (``Suite.class_hint``: the pose suites) gets a part per track,
  ``class-given`` then ``class-free``; a backend that cannot use the class hint is run in
  ``class-free`` only and listed in the ``class-given`` table too, marked *(hint not
  used)*: it would score the same there;
- within a track, one section per (seed, items): the suite's own seed and the largest run
  first. A section of fewer items than the suite's size says *partial*, and a row with
  fewer views than its section's others says so too;
- only the newest suite version is tabulated (older versions' scores are not comparable;
  the page says how many runs were left out);
- a row is a backend with its options (``icp (starts=48)``) and its model's digest (8 hex
  digits; ``-`` for none); one row per backend and options in a section.

The first section of each track also gets the per-category tables (on the ModelNet10
suites also Tables 3.1/4.1's form, the most frequent confusions and each backend's
confusion matrix in counts), the plots, and the paired verdicts: each method against the
baselines (:data:`BASELINES`), B - A on mean rotation error and the > 15 deg rate over the
items both runs scored, with a bootstrap interval over items and a verdict
(:mod:`beo_bench.bench.compare`).

Runs under a depth sensor other than the suite's own (``--sensor``; the tabletop suite's
own is ``kinect-v1``, the others' ``ideal``) are tabulated the same way in the page's part
for that sensor (``## sensor d435``), after the suite's own; a page with runs under more
than one sensor gets a robustness table (:func:`robustness`): per backend and headline
metric (:data:`~beo_bench.bench.columns.ROBUSTNESS_KEYS`) its value under each sensor,
``ideal -> kinect-v1 -> d435``, each paired with the first on the same items (item ``i``
is the same scene under every sensor), written into ``<suite>_paired.json`` with
``"pairing": "sensor"``. A page whose runs are all at the suite's own sensor is as it was
before sensors existed.

A pick page (:func:`is_pick_suite`) also holds every run's episodes in its JSON, one short
record each (:func:`attach_episodes`, :data:`EPISODE_FIELDS`), pairs each method with
``hbeo`` and the MDN's two modes with each other episode by episode (:func:`pick_comparisons`:
an interval, an exact McNemar p and a verdict, ``"pairing": "method"`` in its
``_paired.json``), and counts its successes per category (:func:`pick_category_table`).
"""
