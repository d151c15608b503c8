"""The generated tables of the README and the docs, one module per family of pages:
:mod:`~beo_bench.bench.doctables.render` marks and rewrites them (``python -m
beo_bench.bench.doctables FILE...``), each table reads the committed leaderboards through
:class:`~beo_bench.bench.doctables.boards.Boards`."""
