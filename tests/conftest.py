import os

import jax

# Hermetic tests: the command line's persistent compilation cache stays off here (it would
# write under ~/.cache and make a test's compile depend on an earlier run); tests/test_cache.py
# turns it on in processes of its own.
os.environ["TOLERAX_CACHE"] = "off"

jax.config.update("jax_enable_x64", True)
