"""Hypothesis profiles: ``HYPOTHESIS_PROFILE=fuzz`` (budget ``FUZZ_EXAMPLES``, default 2000) for a big fuzz run.

Commands' output is checked line by line, so the suite runs with a warm-up stamp of its own saying
every part is compiled: a command never announces a first compile here (tests compile in their own
process as they go); tests/test_warmup.py tests the cold path with a fresh stamp.
"""

import atexit
import os
import shutil
import tempfile

from hypothesis import HealthCheck, settings

settings.register_profile(
    "fuzz",
    max_examples=int(os.environ.get("FUZZ_EXAMPLES", "2000")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
if os.environ.get("HYPOTHESIS_PROFILE"):
    settings.load_profile(os.environ["HYPOTHESIS_PROFILE"])

os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="mrmt-test-cache-")
atexit.register(shutil.rmtree, os.environ["XDG_CACHE_HOME"], True)
from agents.warmup import PART_SECONDS, mark_warm  # noqa: E402

mark_warm(PART_SECONDS)
