"""``python -m beo_bench.cli``: the ``beo-bench`` command."""

import sys

from beo_bench.cli import main

sys.exit(main())
