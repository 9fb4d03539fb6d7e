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


@pytest.fixture(autouse=True)
def plans_time_rows_at_a_fixed_cost(monkeypatch):
    """A study's plan times each row's compiled step on this host (`program_timing.row_cost`), which
    compiles every row twice more: in tests, whose studies train tiny rows, a fixed cost stands in.
    tests/test_plan.py times the real programs of a row."""
    from fabricjax.bench import program_timing
    from fabricjax.studies.machinery import plan

    cost = program_timing.RowCost(
        s_per_step=0.01, s_per_eval_batch=0.003, flops_per_step=1e8, flops_per_eval_batch=3e7, compile_s=1.0
    )
    monkeypatch.setattr(program_timing, "row_cost", lambda config, n_seeds, arrays, **kw: cost)
    monkeypatch.setattr(plan, "host_peak_flops", lambda: 100e9)
