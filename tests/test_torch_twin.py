"""The PyTorch twin (fabricjax/bench/torch_twin.py) computes our model's function: equal weights, equal logits.

Skipped where torch is not installed (it is an optional extra used only by the benchmarks).
"""

import jax
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from fabricjax import catalog  # noqa: E402
from fabricjax.bench import synthetic, torch_twin  # noqa: E402
from fabricjax.config import Config  # noqa: E402
from fabricjax.model import make_predict  # noqa: E402
from fabricjax.sequences.inputs import feature_shapes  # noqa: E402
from fabricjax.training.placement import select  # noqa: E402
from fabricjax.training.trainer import make_trainer  # noqa: E402

SMALL = dict(
    preset="smoke", width=32, n_heads=4, n_layers=2, ffn=48, audio_hidden=(40, 24), proprio_hidden=(24, 16), seq_len=30
)


@pytest.mark.parametrize("modalities", [("internal", "external", "proprio"), ("proprio", "internal")])
def test_twin_logits_equal_ours_with_the_same_weights(modalities):
    cfg = Config(modalities=modalities, **SMALL)
    data = select(cfg, synthetic.data_set(cfg, 5, psd_bins=20))
    inputs = data["inputs"]
    # Huge inputs: the rescale maps them to [0, 1]; scaled positions give large attention logits.
    inputs = {k: v * 1e3 for k, v in inputs.items()}
    trainer = make_trainer(cfg, feature_shapes(inputs))
    params = trainer.init(jax.random.PRNGKey(3)).params
    # Every parameter moved off its initial value (LayerNorm scales off 1, biases off 0), so a
    # parameter the two models use differently cannot hide behind its initialisation.
    leaves, tree = jax.tree.flatten(params)
    keys = jax.random.split(jax.random.PRNGKey(4), len(leaves))
    params = jax.tree.unflatten(tree, [p + 0.2 * jax.random.normal(k, p.shape) for p, k in zip(leaves, keys)])
    params["position"] = params["position"] * 50.0
    ours = np.asarray(make_predict(trainer.graphdef)(params, inputs)["fabric"])

    twin = torch_twin.build(cfg, n_bins=20).eval()
    missing, unexpected = twin.load_state_dict(torch_twin.state_dict_from_params(params), strict=True)
    assert not missing and not unexpected
    with torch.inference_mode():
        theirs = twin({k: torch.from_numpy(np.array(v)) for k, v in inputs.items()}).numpy()
    assert theirs.shape == ours.shape == (5, catalog.N_CLASSES)
    np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-4)


def test_twin_initialisation_matches_ours_in_scale():
    cfg = Config(modalities=("internal", "proprio"), **SMALL)
    twin = torch_twin.build(cfg, n_bins=20)
    trainer = make_trainer(cfg, {"internal": (20,), "proprio": (18,)})
    ours = torch_twin.state_dict_from_params(trainer.init(jax.random.PRNGKey(0)).params)
    theirs = twin.state_dict()
    assert set(ours) == set(theirs)
    for name, value in ours.items():
        assert value.shape == theirs[name].shape, name
        # Same initialiser family: standard deviations agree within sampling noise.
        if value.numel() >= 256:
            np.testing.assert_allclose(float(theirs[name].std()), float(value.std()), rtol=0.25, err_msg=name)
        elif name.endswith("bias"):
            assert float(theirs[name].abs().max()) == float(value.abs().max()) == 0.0, name


def test_twin_training_step_runs():
    cfg = Config(modalities=("internal", "proprio"), **SMALL)
    run = torch_twin.train_step_runner(cfg, n_seeds=2, batch=4, n_bins=20, steps=1)
    assert run() > 0


def test_compiled_twin_computes_the_eager_twins_outputs():
    """torch.compile (the benchmarks' fastest twin variants) changes the speed, not the function.
    The first run compiles C++ (~40 s on 2 busy cores); later runs hit inductor's cache (seconds)."""
    cfg = Config(modalities=("internal", "proprio"), **SMALL)
    model = torch_twin.build(cfg, n_bins=20).eval()
    inputs, _ = torch_twin._batch(cfg, 3, 20)
    with torch.inference_mode():
        eager = model(inputs).numpy()
        compiled = torch_twin.compiled(model, torch_twin.COMPILE_MODES[0])(inputs).numpy()
    assert compiled.shape == eager.shape == (3, catalog.N_CLASSES)
    np.testing.assert_allclose(compiled, eager, rtol=1e-4, atol=1e-5)
    with pytest.raises(ValueError, match="compile_mode"):
        torch_twin.compiled(model, "fastest")


def test_fastest_adamw_is_named():
    # The compare extra asks torch >= 2.5, which has fused AdamW on CPU.
    assert torch_twin.adamw_impl() == "fused"


def test_twin_under_bfloat16_autocast_runs_and_stays_near_float32():
    """The twin's bfloat16 autocast (the benchmarks' peer of our bfloat16 compute) changes the
    arithmetic, not the function: logits within bfloat16's rounding of float32's; its runners run."""
    cfg = Config(modalities=("internal", "proprio"), **SMALL)
    model = torch_twin.build(cfg, n_bins=20).eval()
    inputs, _ = torch_twin._batch(cfg, 3, 20)
    with torch.inference_mode():
        full = model(inputs).numpy()
        with torch_twin.mixed_precision(True):
            low = model(inputs).float().numpy()
        with torch_twin.mixed_precision(False):
            np.testing.assert_array_equal(model(inputs).numpy(), full)
    np.testing.assert_allclose(low, full, atol=0.05 * float(np.abs(full).max()))
    assert torch_twin.train_step_runner(cfg, n_seeds=1, batch=4, n_bins=20, steps=1, autocast=True)() > 0
    assert torch_twin.inference_runner(cfg, n_bins=20, autocast=True)() > 0


def test_vmapped_ensemble_trains_each_seed_as_its_twin_alone():
    """The vmapped ensemble (the benchmarks' peer of our vmap over seeds) is n twins trained apart:
    over two steps, the same losses and the same clipped gradients going into AdamW (the second
    step's from the parameters the first AdamW step made), each seed on its own minibatch and
    clipped by its own global norm; weight decay on the same tensors. No dropout, so neither draws.
    Parameters are not compared: the key bias's gradient is zero but for rounding, and Adam
    scales rounding noise up to a full step."""
    cfg = Config(modalities=("internal", "proprio"), dropout=0.0, **SMALL)
    torch.manual_seed(0)
    models = [torch_twin.build(cfg, n_bins=20).train() for _ in range(3)]
    batches = torch_twin.batches(cfg, 3, batch=4, n_bins=20)
    # Every seed's global gradient norm is above the clip's and differs from the others': a clip by
    # one norm over all seeds, or none, would give other gradients.
    norms = []
    for model, (inputs, labels) in zip(models, batches):
        grads = torch.autograd.grad(torch_twin._loss(model, inputs, labels, autocast=False), list(model.parameters()))
        norms.append(float(torch.linalg.vector_norm(torch.stack([g.norm() for g in grads]))))
    assert min(norms) > 1.5 * torch_twin.MAX_GRAD_NORM and len({round(n, 3) for n in norms}) == 3
    vmapped = torch_twin.Vmapped(cfg, models, batches)  # copies the models' parameters before `alone` trains them
    alone = torch_twin.InSequence(cfg, models, batches)

    def groups(opt, seed_axes):
        return [(g["weight_decay"], [p.shape[seed_axes:] for p in g["params"]]) for g in opt.param_groups]

    assert groups(vmapped.opt, 1) == groups(alone.opts[0], 0)
    for _ in range(2):
        np.testing.assert_allclose(vmapped.step().numpy(), alone.step().numpy(), rtol=1e-5)
        for seed, model in enumerate(models):
            for name, p in model.named_parameters():
                np.testing.assert_allclose(
                    vmapped.params[name].grad[seed].numpy(), p.grad.numpy(), rtol=1e-4, atol=1e-7, err_msg=name
                )
    assert (
        torch_twin.train_step_runner(
            cfg, n_seeds=2, batch=4, n_bins=20, steps=1, autocast=True, ensemble=torch_twin.VMAPPED
        )()
        > 0
    )
