"""``python -m beo_bench.bench.doctables FILE...``: rewrite the marked tables of the files."""

from beo_bench.bench.doctables.render import main

raise SystemExit(main())
