import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402

# Tests use tiny configs where XLA's compile time dominates the run time.
jax.config.update("jax_disable_most_optimizations", True)
