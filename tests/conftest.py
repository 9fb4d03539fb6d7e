import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402

# Tests use tiny configs where XLA's compile time dominates the run time.
jax.config.update("jax_disable_most_optimizations", True)

from fabricjax import runtime  # noqa: E402

runtime.configure_jax()  # as every command does (fabricjax.cli.run)


import pytest  # noqa: E402

from fabricjax.store import workspace  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def default_workspace_outside_the_repository(tmp_path_factory):
    """What a test writes without naming a workdir (indexes of external folders, default results)
    goes to a temporary workspace, never into the repository's ./workspace."""
    os.environ[workspace.ENV_VAR] = str(tmp_path_factory.mktemp("default_workspace"))


SLOW_TIMEOUT_S = 1800  # an end-to-end test behind -m slow trains studies for minutes


def pytest_collection_modifyitems(items):
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))
