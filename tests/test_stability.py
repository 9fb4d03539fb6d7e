"""Hard cases stay numerically stable, through the real code paths (issue 9).

Signals (welch.welch_psd, extract.mic_windows / log_psd, data.load_sequences), the model and one
optimiser step (trainer.Trainer), statistics, faults (a training process killed mid-epoch), and the
study commands under `jax_debug_nans`. Bad input (archives, index, checkpoints) is in
tests/test_bad_input.py. Cases already covered elsewhere are not repeated here:

    silence / DC / clipped tone vs scipy          test_features.py
    constant features, rescale_unit               test_model.py
    Wilcoxon all-zero and ties, mean +- SD of one test_stats.py
    t-SNE of identical latents                    test_studies.py
    dataset generation killed mid-trial           test_sim.py
    acquisition interrupted / device failure      test_acquisition.py
"""

import dataclasses
import functools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy import stats as sps
from threadpoolctl import threadpool_limits

from fabricjax import catalog, sim
from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.features import extract, welch
from fabricjax.model import self_attention
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.store import archive
from fabricjax.studies.paper import latents
from fabricjax.training import placement, train
from fabricjax.training.trainer import make_trainer, masked_accuracy, masked_cross_entropy
from tests.helpers import tiny_archive

ROOT = Path(__file__).resolve().parents[1]
INT32_MIN, INT32_MAX = np.iinfo(np.int32).min, np.iinfo(np.int32).max
TOP = (2**17 - 1) << 14  # the largest valid 18-bit sample, low 14 bits zero
FLOOR = np.float32(np.log10(welch.LOG_FLOOR))


def finite(tree) -> bool:
    return all(bool(np.isfinite(np.asarray(x, np.float32)).all()) for x in jax.tree.leaves(tree))


# ---------------------------------------------------------------------------------------------
# Signals


def _scipy_psd(words):
    x = (np.asarray(words, np.int64) >> 14).astype(np.float64) / 2**17
    return scipy.signal.welch(x, **welch.SCIPY_KWARGS)[1]


def _window(kind):
    w = np.zeros(archive.WINDOW, np.int64)
    if kind == "silent":
        pass
    elif kind == "stuck_at_full_scale":  # a saturated converter: the largest word, junk in the low bits
        w[:] = INT32_MAX
    elif kind == "stuck_at_minus_full_scale":
        w[:] = INT32_MIN
    elif kind == "dc":
        w[:] = 77_777 << 14
    elif kind == "impulse":
        w[1000] = TOP
    elif kind == "alternating_extremes":  # +-full scale every sample: all power at Nyquist
        w[0::2], w[1::2] = INT32_MIN, TOP
    elif kind == "clipped_square":  # a 1 kHz tone driven far past full scale
        t = np.arange(archive.WINDOW) / archive.AUDIO_RATE
        w[:] = np.where(np.sin(2 * np.pi * 1000 * t) >= 0, TOP, INT32_MIN)
    return w.astype(np.int32)


CONSTANT = ["silent", "stuck_at_full_scale", "stuck_at_minus_full_scale", "dc"]
VARYING = ["impulse", "alternating_extremes", "clipped_square"]


@pytest.mark.parametrize("kind", CONSTANT)
def test_constant_microphones_give_exactly_the_log_floor(kind):
    """Digital silence, a stuck (saturated) microphone and pure DC have no power once detrended:
    the exact integer detrend gives 0, and the log floor turns that into a finite value."""
    words = np.stack([_window(kind)] * 3)
    np.testing.assert_array_equal(np.asarray(welch.welch_psd(words, bandwidth_khz=24.0, log=False)), 0.0)
    np.testing.assert_array_equal(np.asarray(welch.welch_psd(words, bandwidth_khz=24.0)), FLOOR)
    np.testing.assert_array_equal(extract.log_psd(words), FLOOR)


@pytest.mark.parametrize("kind", VARYING)
def test_impulse_and_extreme_words_match_scipy(kind):
    words = np.stack([_window(kind), np.roll(_window(kind), 37)])
    ref = _scipy_psd(words)
    got = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0, log=False))
    assert got.dtype == np.float32 and np.isfinite(got).all()
    above = ref >= 1e-4 * ref.sum(axis=-1, keepdims=True)
    assert above.any(axis=-1).all()
    assert np.max(np.abs(got - ref)[above] / ref[above]) <= 1e-5
    logged = extract.log_psd(words)
    assert np.isfinite(logged).all() and logged.min() >= FLOOR
    np.testing.assert_allclose(logged[above], np.log10(ref[above]), atol=1e-5)


words_strategy = hnp.arrays(
    np.int32,
    (2, archive.WINDOW),
    elements=st.one_of(st.sampled_from([INT32_MIN, INT32_MAX, TOP, 0, -1, 1 << 14]), st.integers(INT32_MIN, INT32_MAX)),
    fill=st.sampled_from([0, INT32_MAX, INT32_MIN]),
)


@settings(max_examples=25, deadline=None)
@given(words_strategy)
def test_any_int32_words_give_a_finite_psd_matching_scipy(words):
    """Any int32 word is valid input (the low 14 bits are ignored): finite, at or above the floor,
    and equal to scipy in float64 up to FFT rounding relative to the window's power."""
    logged = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0))
    assert np.isfinite(logged).all() and logged.min() >= FLOOR
    ref = _scipy_psd(words)
    with jax.enable_x64(True):
        got = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0, log=False))
    assert np.all(np.abs(got - ref) <= 1e-9 * ref.sum(axis=-1, keepdims=True) + 1e-30)


def test_windows_at_index_zero_are_silent_padding():
    """window_end 0 (the step's window lies wholly before the recording) gives a zero window and
    the floor PSD; a partly covered window holds exactly the samples recorded so far."""
    a = tiny_archive(n_steps=6, images=None)
    we = np.array([0, 0, 1, 700, 2048, 3000], np.int64)
    a = dataclasses.replace(a, window_end=np.stack([we, we], 1))
    archive.validate(a)
    w = extract.mic_windows(a, 0)
    assert w.shape == (6, 2048) and w.dtype == np.int32
    assert not w[:2].any()
    np.testing.assert_array_equal(w[2, -1:], a.audio[0, :1])
    np.testing.assert_array_equal(w[3, -700:], a.audio[0, :700])
    assert not w[3, :-700].any()
    np.testing.assert_array_equal(w[5], a.audio[0, 3000 - 2048 : 3000])
    psd = extract.log_psd(w)
    # window_end 1: the one recorded sample is among the 4 that Welch's three segments leave unused
    np.testing.assert_array_equal(psd[:3], FLOOR)
    assert np.isfinite(psd).all() and (psd[3:] > FLOOR).any(axis=1).all()


N = 8
SIGNAL_TRIALS = [(4, 1, 0, "lab"), (4, 1, 1, "lab"), (4, 3, 0, "lab")]  # train, val, test


def _hard_signal_archive(fabric_id, day, trial, condition, seed):
    """Internal mic silent, palm mic stuck at full scale, windows from index 0, the test-day
    trial holding fewer samples than one window."""
    a = tiny_archive(24, fabric_id=fabric_id, day=day, trial=trial, condition=condition, images=None, seed=seed)
    n_samples = 600 if day == 3 else 960 * 24
    ends = np.minimum(960 * np.arange(24), n_samples).astype(np.int64)
    audio = np.stack([np.zeros(n_samples, np.int32), np.full(n_samples, INT32_MAX, np.int32)])
    return dataclasses.replace(a, audio=audio, window_end=np.stack([ends, ends], 1))


TINY = Config(
    preset="smoke",
    modalities=("internal", "external", "proprio"),
    width=16,
    n_heads=4,
    n_layers=1,
    ffn=32,
    audio_hidden=(16, 8),
    proprio_hidden=(16, 8),
    cnn_features=(16, 32, 64),
    seq_len=N,
    batch_size=6,
    property_heads=True,
    epochs=40,
    learning_rate=1e-3,
    warmup_steps=0,  # one optimiser step must move the parameters (a warm-up starts at rate 0)
)


@functools.lru_cache(maxsize=None)
def _stepper(config: Config, shapes: tuple):
    """Jitted (loss, grads, params after one optimiser step) through the real `Trainer` pieces."""
    trainer = make_trainer(config, dict(shapes))

    def step(params, opt_state, batch, key):  # the body of `Trainer.train_epoch`'s scan
        (loss, _), grads = jax.value_and_grad(trainer.loss, has_aux=True)(params, batch, key)
        updates, _ = trainer.tx.update(grads, opt_state, params)
        return loss, grads, optax.apply_updates(params, updates)

    return trainer, jax.jit(step), jax.jit(trainer.logits)


def one_step(config: Config, ds, params=None):
    batch = placement.select(config, ds)
    shapes = tuple(sorted((k, tuple(v.shape[2:])) for k, v in batch["inputs"].items()))
    n = jax.tree.leaves(batch["labels"])[0].shape[0]
    trainer, step, logits = _stepper(dataclasses.replace(config, batch_size=n), shapes)
    state = trainer.init(jax.random.PRNGKey(0))
    params = state.params if params is None else params
    loss, grads, new = step(params, state.opt_state, batch, jax.random.PRNGKey(1))
    return {"loss": loss, "grads": grads, "params": params, "new": new, "logits": logits(params, batch["inputs"])}


def check_step(out):
    assert np.isfinite(out["loss"]), out["loss"]
    assert finite(out["logits"]) and finite(out["grads"]) and finite(out["new"])
    assert any(not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(out["params"]), jax.tree.leaves(out["new"])))


def test_silent_and_saturated_microphones_through_load_sequences_and_training(tmp_path):
    ds = tmp_path / "ds"
    for i, t in enumerate(SIGNAL_TRIALS):
        a = _hard_signal_archive(*t, seed=i)
        archive.write_archive(ds / archive.trial_filename(a.meta), a)
    sets = data.load_sequences(TINY, ds, workdir=tmp_path / "ws", progress=False, workers=1)
    assert [len(sets[s]) for s in ("train", "val", "test")] == [3, 3, 3]
    for s in ("train", "val", "test"):
        for mic in ("internal", "external"):
            assert sets[s].inputs[mic].shape == (3, N, 320) and np.isfinite(sets[s].inputs[mic]).all()
        np.testing.assert_array_equal(sets[s].inputs["internal"], FLOOR)  # silence: the floor everywhere
    # the stuck microphone's full windows (window_end >= 2048: from step 3) are the floor too; the
    # first windows are zero-padded before the recording, so they see a step from 0 to full scale
    external = sets["train"].inputs["external"].reshape(3 * N, 320)
    np.testing.assert_array_equal(external[3:], FLOOR)
    np.testing.assert_array_equal(external[0], FLOOR)  # window_end 0: all padding
    assert (external[1:3] > FLOOR).any(axis=1).all()
    for dtype in ("float32", "bfloat16"):
        check_step(one_step(dataclasses.replace(TINY, compute_dtype=dtype), sets["train"]))


def _variants(n=6):
    """Feature sets over which the model must stay finite, with their labels."""
    base = synthetic.data_set(TINY, n, psd_bins=320, seed=0)  # 15 kHz: the compiled step of the load test
    x = base["inputs"]
    const_time = {k: np.repeat(v[:, :1], N, axis=1) for k, v in x.items()}  # every dimension constant in time
    half = {k: v.copy() for k, v in x.items()}
    half["internal"][..., ::2] = 0.25  # half the bins constant, half varying
    equal_psd = {**x, "internal": np.broadcast_to(x["internal"][:1, :1], x["internal"].shape).copy()}
    equal_psd["external"] = equal_psd["internal"].copy()
    floor = {**x, "internal": np.full_like(x["internal"], FLOOR), "external": np.full_like(x["external"], FLOOR)}
    big = {k: v * 1e4 for k, v in x.items()}
    return {
        "random": x,
        "constant_over_time": const_time,
        "half_constant_dims": half,
        "all_equal_psds": equal_psd,
        "floor_psds": floor,
        "huge_inputs": big,
    }, base["labels"]


CASES = ["random", "constant_over_time", "half_constant_dims", "all_equal_psds", "floor_psds", "huge_inputs"]


@pytest.mark.parametrize("dtype", ["float32", "bfloat16"])
@pytest.mark.parametrize("case", CASES)
def test_hard_features_give_finite_loss_gradients_and_step(case, dtype):
    inputs, labels = _variants()
    out = one_step(dataclasses.replace(TINY, compute_dtype=dtype), {"inputs": inputs[case], "labels": labels})
    check_step(out)
    if case in ("constant_over_time", "all_equal_psds", "floor_psds"):
        # features constant over the sequence rescale to 0 and teach the encoder nothing
        assert not np.asarray(out["grads"]["audio"]["layers"][0]["kernel"]).any()


def _qkv_scaled(params, factor):
    params = jax.tree.map(lambda a: a, params)
    params["blocks"][0]["qkv"]["kernel"] = params["blocks"][0]["qkv"]["kernel"] * factor
    return params


def _max_logit(config, params, inputs):
    """Largest |q.k| / sqrt(D) of the first attention block (recomputed outside the model)."""
    from flax import nnx

    trainer = make_trainer(config, {k: v.shape[2:] for k, v in inputs.items()})
    model = nnx.merge(trainer.graphdef, params)
    x = model.embed(model.features(inputs)) + model.position[: inputs["proprio"].shape[1]]
    b, t, w = x.shape
    qkv = model.blocks[0].qkv(model.blocks[0].norm1(x)).reshape(b, t, 3, config.n_heads, w // config.n_heads)
    s = jnp.einsum("bthd,bshd->bhts", qkv[:, :, 0].astype(jnp.float32), qkv[:, :, 1].astype(jnp.float32))
    return float(jnp.abs(s).max() / np.sqrt(w // config.n_heads))


def test_self_attention_with_logits_of_1e4_matches_float64():
    rng = np.random.default_rng(0)
    qkv = rng.normal(size=(2, 7, 3, 4, 8))
    qkv[:, :, :2] *= 60  # q.k / sqrt(8) up to ~1e4
    q, k, v = (np.moveaxis(qkv[:, :, i], 1, 2) for i in range(3))  # (B, H, T, D)
    s = np.einsum("bhtd,bhsd->bhts", q, k) / np.sqrt(8)
    assert np.abs(s).max() > 1e4
    p = np.exp(s - s.max(-1, keepdims=True))
    ref = np.swapaxes((p / p.sum(-1, keepdims=True)) @ v, 1, 2)
    x = [jnp.asarray(a, jnp.float32) for a in (q, k, v)]
    np.testing.assert_allclose(jnp.swapaxes(self_attention(*x), 1, 2), ref, atol=1e-4)
    g = jax.grad(lambda *a: (self_attention(*a) ** 2).sum(), argnums=(0, 1, 2))(*x)
    assert finite(g)


@pytest.mark.parametrize("dtype", ["float32", "bfloat16", "float16"])
def test_huge_attention_logits_in_the_model_stay_finite(dtype):
    """The QKV kernel scaled by 300 drives q.k / sqrt(D) to ~1e5 (past float16's range)."""
    cfg = dataclasses.replace(TINY, compute_dtype=dtype)
    inputs, labels = _variants()
    ds = {"inputs": inputs["random"], "labels": labels}
    params = _qkv_scaled(one_step(cfg, ds)["params"], 300.0)
    assert _max_logit(cfg, params, placement.select(cfg, ds)["inputs"]) > 1e4
    check_step(one_step(cfg, ds, params))


@pytest.mark.parametrize("dtype, tol", [("bfloat16", 0.05), ("float16", 0.01)])
def test_low_precision_compute_is_close_to_float32(dtype, tol):
    """Same float32 parameters, bfloat16 / float16 arithmetic: logits, loss and gradient norms
    close to float32 on every hard case (float16 but for inputs of 1e4, past its range in the
    first layer's sums)."""
    inputs, labels = _variants()
    for case in CASES[:-1] if dtype == "float16" else CASES:
        ds = {"inputs": inputs[case], "labels": labels}
        ref = one_step(TINY, ds)
        low = one_step(dataclasses.replace(TINY, compute_dtype=dtype), ds)
        check_step(low)
        for a, b in zip(jax.tree.leaves(ref["params"]), jax.tree.leaves(low["params"])):
            np.testing.assert_array_equal(a, b)  # the same float32 parameters
        for h in ref["logits"]:
            scale = float(np.abs(ref["logits"][h]).max())
            np.testing.assert_allclose(low["logits"][h], ref["logits"][h], atol=tol * scale, err_msg=f"{case} {h}")
        assert abs(float(low["loss"]) - float(ref["loss"])) <= tol * float(ref["loss"])
        norm = float(optax.global_norm(ref["grads"]))
        assert abs(float(optax.global_norm(low["grads"])) - norm) <= 4 * tol * norm, case


def test_a_batch_of_one_class_without_properties():
    """Every sequence fabric 0 (the no-fabric class: every property unknown, -1): the fabric loss is
    the plain mean cross-entropy, the property heads get exactly zero loss and gradient."""
    inputs, labels = _variants()
    labels = {"fabric": np.zeros(6, np.int32), **{p: np.full(6, -1, np.int32) for p in catalog.PROPERTY_LEVELS}}
    out = one_step(TINY, {"inputs": inputs["random"], "labels": labels})
    check_step(out)
    logits = out["logits"]
    expected = -jax.nn.log_softmax(logits["fabric"])[:, 0].mean()
    trainer = _stepper(
        dataclasses.replace(TINY, batch_size=6), tuple(sorted((k, v.shape[2:]) for k, v in inputs["random"].items()))
    )[0]
    loss, _ = trainer.loss(out["params"], placement.select(TINY, {"inputs": inputs["random"], "labels": labels}), None)
    assert float(loss) == pytest.approx(float(expected), rel=1e-5)
    for p in catalog.PROPERTY_LEVELS:
        assert not np.asarray(out["grads"]["heads"][p]["kernel"]).any()
        np.testing.assert_array_equal(out["new"]["heads"][p]["bias"], out["params"]["heads"][p]["bias"])
    assert float(masked_accuracy(jnp.zeros(6, jnp.int32), labels["roughness"])) == 0.0


def test_a_batch_of_one_known_class():
    logits = jnp.asarray(np.random.default_rng(0).normal(size=(5, 21)) * 30, jnp.float32)
    labels = jnp.full(5, 7, jnp.int32)
    ce = masked_cross_entropy(logits, labels)
    assert float(ce) == pytest.approx(float(-jax.nn.log_softmax(logits)[:, 7].mean()), rel=1e-5)
    assert finite(jax.grad(masked_cross_entropy)(logits, labels))


# ---------------------------------------------------------------------------------------------
# Statistics


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.sampled_from([0.0, 0.01, -0.01, 0.02, 0.05, -0.05, 0.1]), min_size=1, max_size=80),
    st.integers(0, 10**6),
)
def test_wilcoxon_with_ties_and_zeros_is_valid_and_its_floor_holds(diffs, seed):
    """Ties and zero differences everywhere: p in [0, 1], never below the reported smallest
    attainable p; the normal approximation (many pairs) equals scipy's."""
    b = np.random.default_rng(seed).uniform(size=len(diffs)).round(2)
    a = b + np.asarray(diffs)
    r = stats.wilcoxon(a, b, pairing="x")
    assert 0.0 <= r.p_value <= 1.0 and np.isfinite(r.statistic) and 0 < r.min_attainable_p <= 1
    assert r.min_attainable_p <= r.p_value * (1 + 1e-9)
    if r.method == stats.APPROX:
        ref = sps.wilcoxon(a, b, zero_method="wilcox", method="approx")
        assert r.p_value == pytest.approx(ref.pvalue)


def test_statistics_of_non_finite_values_are_errors():
    with pytest.raises(ValueError, match="non-finite"):
        stats.mean_sd([0.9, np.nan])
    with pytest.raises(ValueError, match="non-finite"):
        stats.wilcoxon([0.9, np.inf], [0.8, 0.7], pairing="per seed")
    assert stats.format_mean_sd([0.5]) == "50.00 ± 0.00"


@pytest.mark.parametrize(
    "points",
    [
        np.ones((6, 8)) + 1e-9 * np.random.default_rng(0).normal(size=(6, 8)),  # identical up to rounding
        np.full((7, 8), 1e6),  # identical, far from the origin
        np.repeat(np.random.default_rng(1).normal(size=(2, 8)), 4, axis=0),  # two groups of identical points
        np.vstack([np.zeros((6, 8)), np.ones((1, 8))]),  # all but one identical
    ],
    ids=["near_identical", "identical_offset", "duplicates", "one_outlier"],
)
def test_tsne_of_degenerate_latents_is_finite(points):
    with threadpool_limits(1):  # same numbers; OpenMP threads crawl on a loaded 2-core machine
        xy, perplexity = latents.tsne(points)
    assert xy.shape == (len(points), 2) and np.isfinite(xy).all()
    assert perplexity is None or 1 <= perplexity <= 30


# ---------------------------------------------------------------------------------------------
# Faults: a training process killed mid-epoch resumes from its last checkpoint

RESUME = dataclasses.replace(TINY, modalities=("internal",), property_heads=False, epochs=5, batch_size=4, seq_len=8)


def resume_sets():
    return {
        k: synthetic.data_set(RESUME, n, seed=i) for i, (k, n) in enumerate([("train", 12), ("val", 8), ("test", 8)])
    }


_KILLED_TRAINER = """
import sys, time, jax
jax.config.update("jax_disable_most_optimizations", True)
sys.path.insert(0, {root!r})
from fabricjax import runtime
runtime.configure_jax()
from tests.test_stability import RESUME, resume_sets
from fabricjax.training import train, trainer

loss = trainer.Trainer.loss

def slow_loss(self, params, batch, key):  # the same loss, but every minibatch takes 0.3 s: a kill lands inside an epoch
    jax.debug.callback(lambda: time.sleep(0.3))
    return loss(self, params, batch, key)

trainer.Trainer.loss = slow_loss
train.train_and_evaluate(RESUME, resume_sets(), [0, 1], workdir={workdir!r}, save_every=1,
                   on_save=lambda e: print("saved", e, flush=True))
"""


# a fresh process compiles the run: ~15-35 s; the on_save interruption in test_checkpoint.py runs always
@pytest.mark.slow
def test_training_killed_mid_epoch_resumes_from_its_last_checkpoint(tmp_path):
    workdir = tmp_path / "ckpt"
    code = _KILLED_TRAINER.format(root=str(ROOT), workdir=str(workdir))
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        for line in proc.stdout:
            if line.strip() == "saved 2":
                break
        else:
            pytest.fail(f"trainer exited (rc {proc.wait()}) before its second save")
        time.sleep(0.5)  # inside epoch 3: its three minibatches take >= 0.9 s
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    from fabricjax.training import checkpoint

    assert checkpoint.manager(workdir).latest_step() == 2  # epoch 3 was never saved
    saved = []
    resumed = train.train_and_evaluate(
        RESUME, resume_sets(), [0, 1], workdir=workdir, save_every=1, on_save=saved.append
    )
    assert saved == [3, 4, 5]  # continued after epoch 2, did not start over
    full = train.train_and_evaluate(RESUME, resume_sets(), [0, 1], save_every=1)  # the same compiled chunks

    def outcome(m):  # not the curves (NaN before the resume) nor the wall times
        return {k: v for k, v in m.items() if k not in ("epochs", "time")}

    for a, b in zip(jax.tree.leaves(outcome(resumed.metrics)), jax.tree.leaves(outcome(full.metrics))):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    assert finite(resumed.state.params)


# ---------------------------------------------------------------------------------------------
# The study commands with jax_debug_nans on the smoke preset


@pytest.fixture(scope="session")
def smoke_workdir(tmp_path_factory):
    """The smoke dataset without frames, generated once per session."""
    root = tmp_path_factory.mktemp("debug_nans")
    sim.ensure_dataset("smoke", root, streams=("audio", "proprio"), progress=False)
    return root


def _command(module, *args, results):
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_DEBUG_NANS": "True", "JAX_DISABLE_MOST_OPTIMIZATIONS": "1"}
    out = subprocess.run(
        [sys.executable, "-m", module, *args, f"--results={results}"],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-4000:]
    assert "FloatingPointError" not in out.stderr
    return out


def test_debug_nans_is_read_from_the_environment():
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_DEBUG_NANS": "True"}
    code = (
        "import jax, jax.numpy as jnp\nassert jax.config.jax_debug_nans\ntry:\n jnp.log(jnp.float32(-1))\nexcept "
        "FloatingPointError:\n print('caught')"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert out.stdout.strip().endswith("caught"), out.stderr[-2000:]


@pytest.mark.slow  # ~17 s on 2 cores: a command under debug-NaNs
def test_ablation_command_under_debug_nans(smoke_workdir, tmp_path):
    _command(
        "experiments.ablation",
        "--preset=smoke",
        "--seeds=1",
        "--set=epochs=1",
        "--rows=internal+proprio",
        f"--workdir={smoke_workdir}",
        results=tmp_path,
    )
    doc = json.loads((tmp_path / "ablation.json").read_text())
    (row,) = doc["rows"]
    assert np.isfinite(row["accuracy"]["test"]["fabric"]).all()


@pytest.mark.slow  # ~30-55 s on 2 cores: run with -m slow
def test_properties_and_latents_commands_under_debug_nans(smoke_workdir, tmp_path):
    _command(
        "experiments.properties",
        "--preset=smoke",
        "--seeds=1",
        "--set=epochs=1",
        "--rows=internal+proprio",
        f"--workdir={smoke_workdir}",
        results=tmp_path,
    )
    (row,) = json.loads((tmp_path / "properties.json").read_text())["rows"]
    assert all(np.isfinite(v).all() for split in row["accuracy"].values() for v in split.values())
    _command("experiments.latents", f"--checkpoint={row['checkpoint']}", f"--workdir={smoke_workdir}", results=tmp_path)
    points = json.loads((tmp_path / "latents.json").read_text())["points"]
    assert points and np.isfinite([p["xy"] for p in points]).all()
