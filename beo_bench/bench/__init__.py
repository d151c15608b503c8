"""The benchmark: versioned suites, the evaluator that scores one item, the parallel and
resumable runner, run summaries and the leaderboards (docs/design.md "Benchmark runner and
leaderboards").

- :mod:`.suites`: the suite registry (``get_suite``, ``list_suites``);
- :mod:`.evaluate`: turns item ``i`` of a suite into scored result rows;
- :mod:`.runner`: ``beo-bench run`` (local processes or Ray, ``--resume``, one writer);
- :mod:`.rundir`: a run directory (its identity, lock, resume checks, rows, ``Summary``);
- :mod:`.pool`: the worker processes, with a deadline per item;
- :mod:`.campaign`: ``beo-bench all`` (every suite, track and backend);
- :mod:`.summary`: a run's metrics with bootstrap intervals;
- :mod:`.columns`: the metric specs every table reads (label, scale, direction);
- :mod:`.compare`: ``beo-bench compare`` (paired differences and verdicts);
- :mod:`.pages`: ``beo-bench leaderboard`` (Markdown, JSON, plots);
- :mod:`.doctables`: the documentation's generated tables;
- :mod:`.gate`: ``beo-bench gate`` and ``baseline``;
- :mod:`.recording`: ``beo-bench run --rerun`` recordings.
"""
