"""``python -m benchmarks``: run the benchmark scenarios (see :mod:`benchmarks.main`)."""
import sys

from benchmarks.main import main

sys.exit(main())
