"""Training over two processes (`jax.distributed`, JAX's CPU collectives over Gloo) equals one
process with as many devices, up to the order of float summation."""

import json
import os
import socket
import subprocess
import sys

import numpy as np
import pytest

# One process of a run: trains two seeds of tests/test_train.py's tiny config over every device of
# the run (the mesh spans the processes' devices), with a checkpoint and training curves, restores
# the checkpoint, and writes what it read back (metrics, a seed's parameters) to <out>.<process>.npz.
WORKER = """
import json, sys
import jax
jax.config.update("jax_disable_most_optimizations", True)
from fabricjax import runtime
runtime.configure_jax(distributed=json.loads(sys.argv[1]))
from fabricjax.reporting import results_files
from fabricjax.studies.machinery import documents
import numpy as np
sys.path.insert(0, {tests!r})
from test_train import TINY, data_sets
from fabricjax.training.train import train_and_evaluate
out, folder = sys.argv[2], sys.argv[3]
saves = []
res = train_and_evaluate(
    TINY, data_sets(TINY), seeds=[3, 4], workdir=folder + "/ckpt", save_every=2, on_save=saves.append,
    log_dir=folder + "/logs",
)
again = train_and_evaluate(TINY, data_sets(TINY), seeds=[3, 4], workdir=folder + "/ckpt")  # restored, not retrained
results_files.write_text(f"{{folder}}/written_by_{{jax.process_index()}}", "")
test = res.metrics["eval"]["test"]
leaves = jax.tree_util.tree_leaves_with_path(jax.device_get(res.params(1)))
np.savez(
    f"{{out}}.{{jax.process_index()}}.npz", devices=jax.device_count(), saves=saves,
    train_loss=res.metrics["train_loss"],
    accuracy=test["accuracy"]["fabric"], predictions=test["predictions"]["fabric"],
    restored=again.metrics["eval"]["test"]["predictions"]["fabric"],
    **{{jax.tree_util.keystr(k): v for k, v in leaves}},
)
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def start(tmp_path, name: str, cpu_devices: int, distributed=None) -> subprocess.Popen:
    """A worker writing <tmp_path>/out/<name>.<process>.npz; the processes of a run share the
    folder <tmp_path>/<name> (checkpoints, curves), as on a cluster's shared file system."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env.update(JAX_PLATFORMS="cpu", JAX_NUM_CPU_DEVICES=str(cpu_devices))
    folder = tmp_path / name
    folder.mkdir(exist_ok=True)
    code = WORKER.format(tests=os.path.dirname(__file__))
    args = [sys.executable, "-c", code, json.dumps(distributed), str(tmp_path / "out" / name), str(folder)]
    return subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@pytest.mark.slow  # ~85 s on 2 loaded cores (three processes compiling): run with -m slow
def test_two_processes_train_as_one_process_with_two_devices(tmp_path):
    (tmp_path / "out").mkdir()
    address = f"localhost:{free_port()}"
    procs = [start(tmp_path, "one", 2)]
    procs += [
        start(tmp_path, "two", 1, dict(coordinator_address=address, num_processes=2, process_id=i)) for i in range(2)
    ]
    for p in procs:
        log = p.communicate(timeout=300)[0]
        assert p.returncode == 0, log[-3000:]
    one = np.load(tmp_path / "out" / "one.0.npz")
    two = [np.load(tmp_path / "out" / f"two.{i}.npz") for i in range(2)]
    assert int(one["devices"]) == int(two[0]["devices"]) == 2  # the same mesh: minibatch samples over 2 devices
    for got in two:  # every process reads the whole result
        assert list(got["saves"]) == [2, 3]
        np.testing.assert_allclose(got["train_loss"], one["train_loss"], rtol=1e-5)
        np.testing.assert_allclose(got["accuracy"], one["accuracy"], rtol=1e-6)
        np.testing.assert_array_equal(got["predictions"], one["predictions"])
        np.testing.assert_array_equal(got["restored"], got["predictions"])
        for k in one.files:
            if k not in ("devices", "saves", "train_loss", "accuracy", "predictions", "restored"):
                np.testing.assert_allclose(got[k], one[k], rtol=1e-4, atol=1e-6, err_msg=k)
    assert sorted(p.name for p in (tmp_path / "two").glob("written_by_*")) == [
        "written_by_0"
    ]  # only process 0 writes results
