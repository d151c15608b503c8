"""The benchmark: versioned suites, the evaluator that scores one item, the parallel and
resumable runner, run summaries and the leaderboards (DESIGN.md "Benchmark runner and
leaderboards").

- :mod:`.suites`: the suite registry (``get_suite``, ``list_suites``);
- :mod:`.evaluate`: turns item ``i`` of a suite into scored result rows;
- :mod:`.runner`: ``beo-bench run`` (local processes or Ray, ``--resume``);
- :mod:`.summary`: a run's metrics with bootstrap intervals;
- :mod:`.leaderboard`: ``beo-bench leaderboard`` (Markdown, JSON, plots);
- :mod:`.recording`: ``beo-bench run --rerun`` recordings.
"""
