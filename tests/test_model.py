import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from fabricjax import catalog
from fabricjax.bench import synthetic
from fabricjax.config import CNN_POOLS, MODALITIES, Config
from fabricjax.model import (
    ConvEncoder,
    FabricNet,
    causal_conv,
    compile_predict_one,
    make_predict,
    patch_product,
    rescale_unit,
    self_attention,
)
from fabricjax.sequences.inputs import feature_shapes

TINY = dict(
    preset="smoke",
    width=16,
    n_heads=4,
    n_layers=1,
    ffn=32,
    audio_hidden=(16, 8),
    proprio_hidden=(16, 8),
    cnn_features=(4, 8),
    seq_len=10,
)
COMBOS = [c for r in range(1, len(MODALITIES) + 1) for c in itertools.combinations(MODALITIES, r)]


def build(cfg, inputs, seed=0):
    return FabricNet(cfg, feature_shapes(inputs), rngs=nnx.Rngs(seed))


@pytest.mark.parametrize("backbone", ["attention", "tcn"])
@pytest.mark.parametrize("modalities", COMBOS, ids="+".join)
def test_output_shapes_every_modality_combination(modalities, backbone):
    cfg = Config(modalities=modalities, backbone=backbone, property_heads=True, **TINY)
    inputs = synthetic.data_set(cfg, 3, seq_len=7)["inputs"]  # shorter than the model's N
    logits = jax.eval_shape(lambda: build(cfg, inputs)(inputs))
    assert {k: v.shape for k, v in logits.items()} == {
        "fabric": (3, catalog.N_CLASSES),
        **{k: (3, n) for k, n in catalog.PROPERTY_LEVELS.items()},
    }
    assert jax.eval_shape(lambda: build(cfg, inputs).latents(inputs)).shape == (3, 7, cfg.width)
    model = nnx.eval_shape(lambda: build(cfg, inputs))
    built = {k for k in ("audio", "proprio", "image", "flow") if getattr(model, k) is not None}
    expected = {"audio" if m in ("internal", "external") else m for m in modalities}
    assert built == expected  # a model builds only the encoders it uses


@pytest.mark.parametrize("backbone", ["attention", "tcn"])
def test_all_modalities_forward_is_finite_at_any_flow_resolution(backbone):
    for flow_hw in [(25, 34), (51, 68)]:
        cfg = Config(modalities=MODALITIES, backbone=backbone, **TINY)
        inputs = synthetic.data_set(cfg, 2, flow_hw=flow_hw, image_hw=(30, 40))["inputs"]
        inputs["flow"] = inputs["flow"].astype(np.float16)
        graphdef, params = nnx.split(build(cfg, inputs))
        logits = jax.jit(lambda p, x: nnx.merge(graphdef, p)(x, rngs=nnx.Rngs(dropout=1, augment=2)))(params, inputs)
        assert logits["fabric"].shape == (2, catalog.N_CLASSES)
        assert np.isfinite(logits["fabric"]).all()


def test_grid_pool_keeps_where_in_the_frame_a_response_sits():
    """The mean pool answers the same for a response moved by a whole cell; "grid" keeps each cell's
    features, so it answers where the response sits, and sizes the model's fusion by the cells."""
    rng = np.random.default_rng(0)
    blob = rng.normal(size=(10, 10, 3)).astype(np.float32)
    frames = np.zeros((2, 30, 40, 3), np.float32)
    frames[0, :10, :10], frames[1, 10:20, 20:30] = blob, blob  # the last layer's cells are 10 x 10 pixels
    encoders = {pool: ConvEncoder(3, (4, 8), dtype=jnp.float32, rngs=nnx.Rngs(0), pool=pool) for pool in CNN_POOLS}
    mean, grid = (np.asarray(encoders[p](jnp.asarray(frames))) for p in ("mean", "grid"))
    np.testing.assert_allclose(mean[0], mean[1], atol=1e-6)
    assert grid.shape == (2, 8 * 3 * 4) == (2, encoders["grid"].out_features(30, 40))
    assert not np.allclose(grid[0], grid[1], atol=1e-3)
    cfg = Config(modalities=("image", "flow"), image_pool="grid", flow_pool="grid", **TINY)
    inputs = synthetic.data_set(cfg, 2, flow_hw=(20, 27), image_hw=(30, 40))["inputs"]
    model = build(cfg, inputs)
    assert model.flow.out_features(20, 27) == 8 * 2 * 2  # 20 x 27 -> 4 x 5 cells -> 2 x 2
    assert model.embed.in_features == 8 * 3 * 4 + 8 * 2 * 2
    logits = model(inputs, rngs=nnx.Rngs(dropout=1, augment=2))["fabric"]
    assert logits.shape == (2, catalog.N_CLASSES) and np.isfinite(logits).all()


def test_shared_audio_encoder_is_one_set_of_weights():
    one = Config(modalities=("internal",), **TINY)
    two = Config(modalities=("internal", "external"), **TINY)
    m1 = build(one, synthetic.data_set(one, 1)["inputs"])
    m2 = build(two, synthetic.data_set(two, 1)["inputs"])
    count = lambda tree: sum(x.size for x in jax.tree.leaves(tree))  # noqa: E731
    s1, s2 = nnx.state(m1), nnx.state(m2)
    assert count(s1["audio"]) == count(s2["audio"])
    # The second microphone adds only its 8 features to the embedding's input.
    assert count(s2) - count(s1) == two.audio_hidden[-1] * two.width
    # The same weights encode both streams: equal inputs give equal features.
    x = np.random.default_rng(0).normal(size=(1, 10, 24)).astype(np.float32)
    feats = m2.features({"internal": x, "external": x})
    np.testing.assert_array_equal(feats[..., :8], feats[..., 8:])


def test_rescale_is_unit_range_and_finite_on_constant_input():
    x = jnp.asarray(np.random.default_rng(0).normal(size=(2, 9, 5)) * 1e3, jnp.float32)
    y = rescale_unit(x)
    np.testing.assert_allclose(y.min(axis=1), 0)
    np.testing.assert_allclose(y.max(axis=1), 1, rtol=1e-6)
    const = jnp.full((2, 9, 5), 3.0)
    assert (rescale_unit(const) == 0).all()
    g = jax.grad(lambda c: rescale_unit(c).sum())(const)
    assert np.isfinite(g).all()


def test_constant_inputs_give_finite_logits_and_gradients():
    cfg = Config(modalities=("internal", "proprio"), **TINY)
    inputs = {"internal": jnp.zeros((2, 10, 24)), "proprio": jnp.ones((2, 10, 18))}
    graphdef, params = nnx.split(build(cfg, inputs))
    loss = lambda p: nnx.merge(graphdef, p)(inputs)["fabric"].sum()  # noqa: E731
    value, grads = jax.jit(jax.value_and_grad(loss))(params)
    assert np.isfinite(value)
    assert all(np.isfinite(g).all() for g in jax.tree.leaves(grads))


@pytest.mark.parametrize("compute_dtype", ["float32", "bfloat16"])
def test_compiled_predict_one_matches_the_models_apply(compute_dtype):
    cfg = Config(modalities=("internal", "proprio"), compute_dtype=compute_dtype, **TINY)
    inputs = synthetic.data_set(cfg, 3)["inputs"]
    graphdef, params = nnx.split(build(cfg, inputs))
    params = nnx.to_pure_dict(params)
    applied = nnx.merge(graphdef, params)(inputs)
    batch = make_predict(graphdef)(params, inputs)
    one = {k: v[1] for k, v in inputs.items()}
    predict_one = compile_predict_one(graphdef, params, one)
    for head, logits in applied.items():
        np.testing.assert_allclose(predict_one(one)[head], logits[1], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(batch[head][1], logits[1], rtol=1e-5, atol=1e-6)
    with pytest.raises(TypeError):  # compiled for one sequence's shapes
        predict_one({k: v[:, :-1] for k, v in inputs.items()})


def test_mismatched_audio_bins_and_missing_modalities_are_clear_errors():
    cfg = Config(modalities=("internal", "external"), **TINY)
    with pytest.raises(ValueError, match="shared audio encoder"):
        FabricNet(cfg, {"internal": (24,), "external": (32,)}, rngs=nnx.Rngs(0))
    with pytest.raises(ValueError, match="external"):
        FabricNet(cfg, {"internal": (24,)}, rngs=nnx.Rngs(0))


def test_self_attention_and_its_gradient_match_jax_reference():
    q, k, v = 4 * jax.random.normal(jax.random.PRNGKey(0), (3, 2, 4, 7, 8))  # each (B, H, T, D)
    w = jax.random.normal(jax.random.PRNGKey(1), (2, 4, 7, 8))

    # jax.nn.dot_product_attention takes (B, T, H, D)
    def ref(q, k, v):
        return jnp.swapaxes(jax.nn.dot_product_attention(*(jnp.swapaxes(a, 1, 2) for a in (q, k, v))), 1, 2)

    np.testing.assert_allclose(self_attention(q, k, v), ref(q, k, v), rtol=1e-5, atol=1e-5)
    grad = lambda f: jax.grad(lambda *a: (f(*a) * w).sum(), argnums=(0, 1, 2))(q, k, v)  # noqa: E731
    for ours, theirs in zip(grad(self_attention), grad(ref)):
        np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("dilation", [1, 2, 4])
def test_tcn_convolution_as_a_product_equals_the_causal_convolution(dilation):
    conv = nnx.Conv(6, 5, (3,), kernel_dilation=dilation, padding="CAUSAL", rngs=nnx.Rngs(0))
    conv.bias[...] = jnp.arange(5.0)
    x = jax.random.normal(jax.random.PRNGKey(dilation), (3, 2, 12, 6))  # (seeds, batch, steps, channels)
    np.testing.assert_allclose(causal_conv(conv, x), conv(x), atol=1e-5)
    # Step t sees steps t, t - d, t - 2d only: changing a later step leaves earlier outputs alone.
    later = x.at[:, :, 7:].add(1.0)
    np.testing.assert_array_equal(causal_conv(conv, later)[:, :, :7], causal_conv(conv, x)[:, :, :7])


def test_patch_product_and_its_written_out_gradient_are_the_plain_product():
    """`patch_product` writes its VJP out for speed: both cotangents equal autodiff's of the plain
    (cells x N, J) @ (J, F) product it computes."""
    rng = np.random.default_rng(0)
    rows = jnp.asarray(rng.normal(size=(3, 4, 12, 5)).astype(np.float32))
    kernel = jnp.asarray(rng.normal(size=(12, 2)).astype(np.float32))
    plain = lambda r, k: jnp.moveaxis(jnp.moveaxis(r, 3, 2) @ k, 3, 2)  # noqa: E731
    np.testing.assert_allclose(patch_product(rows, kernel), plain(rows, kernel), rtol=1e-5, atol=1e-5)
    dy = jnp.asarray(rng.normal(size=(3, 4, 2, 5)).astype(np.float32))
    for got, want in zip(jax.vjp(patch_product, rows, kernel)[1](dy), jax.vjp(plain, rows, kernel)[1](dy)):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def _dot_dtypes(jaxpr) -> list[tuple[tuple[str, ...], str]]:
    """(operand dtypes, output dtype) of every dot_general in a jaxpr, nested ones included."""
    found = []
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "dot_general":
            found.append((tuple(str(v.aval.dtype) for v in eqn.invars), str(eqn.outvars[0].aval.dtype)))
        for sub in jax.core.jaxprs_in_params(eqn.params):
            found += _dot_dtypes(sub)
    return found


@pytest.mark.parametrize("backbone", ["attention", "tcn"])
def test_bfloat16_compute_multiplies_in_bfloat16_and_accumulates_in_float32(backbone):
    """Under compute_dtype="bfloat16" the encoders', backbone's and hidden layer's products (forward
    and backward, image rows and frames) take bfloat16 operands and return float32; parameters and
    logits stay float32. The float32 heads, the folded LayerNorm shift and the attention's backward
    products multiply in float32."""
    cfg = Config(modalities=MODALITIES, backbone=backbone, compute_dtype="bfloat16", **TINY)
    inputs = synthetic.data_set(cfg, 2, image_hw=(30, 40))["inputs"]
    graphdef, params = nnx.split(build(cfg, inputs))
    assert {str(x.dtype) for x in jax.tree.leaves(params)} == {"float32"}

    def loss(p, x):
        logits = nnx.merge(graphdef, p)(x, rngs=nnx.Rngs(dropout=1, augment=2))
        return sum(v.sum() for v in logits.values()), logits

    jaxpr = jax.make_jaxpr(jax.grad(loss, has_aux=True))(params, inputs).jaxpr
    dots = _dot_dtypes(jaxpr) + _dot_dtypes(
        jax.make_jaxpr(lambda p, x: nnx.merge(graphdef, p)(x))(params, inputs).jaxpr
    )
    assert all(out == "float32" for _, out in dots)
    low = [d for d, _ in dots if d == ("bfloat16", "bfloat16")]
    assert len(low) >= 0.75 * len(dots), dots
    logits = nnx.merge(graphdef, params)(inputs)
    assert all(v.dtype == jnp.float32 and np.isfinite(v).all() for v in logits.values())


@pytest.mark.parametrize("activation", ["relu", "gelu"])
def test_a_head_whose_units_are_all_off_passes_a_gradient_only_under_gelu(activation):
    """The collapse of the paper's image row: every unit of the head's hidden layer off for every
    sequence. Under ReLU nothing below the head learns again; GELU's negative side keeps a gradient."""
    cfg = Config(modalities=("internal",), head_activation=activation, **TINY)
    inputs = {"internal": jnp.asarray(np.random.default_rng(0).normal(size=(3, 10, 24)), jnp.float32)}
    model = build(cfg, inputs)
    model.hidden.bias[...] = jnp.full_like(model.hidden.bias[...], -3.0)
    graphdef, params = nnx.split(model)
    labels = jnp.array([0, 1, 2])
    loss = lambda p: -jax.nn.log_softmax(nnx.merge(graphdef, p)(inputs)["fabric"])[jnp.arange(3), labels].mean()  # noqa: E731
    grads = jax.grad(loss)(params)
    below = np.abs(np.asarray(grads["embed"]["kernel"])).max()
    assert (below > 1e-6) == (activation == "gelu"), below
