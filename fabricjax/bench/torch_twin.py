"""A PyTorch twin of the audio + proprioception FabricNet and its training step, for benchmarks only.

What a user would most likely write instead of us, made to compute the same function as
`fabricjax.model.FabricNet` (GELU MLPs, tanh-approximated like `jax.nn.gelu`, with the audio
encoder shared by both microphones, [0, 1] rescale over time, Dense + learned position,
pre-LayerNorm attention blocks with fused QKV and `scaled_dot_product_attention`, final
LayerNorm (epsilon 1e-6 like Flax), mean over time, ReLU hidden layer, linear head), initialised
from the same distributions (LeCun-normal truncated kernels, zero biases, N(0, 0.02) positions),
and trained like `fabricjax.training.train` (global-norm clip 1.0, AdamW decaying weight matrices only; the
twin keeps a constant learning rate, which costs the same per step as our warm-up schedule).
`build(config, n_bins)` makes the twin; `state_dict_from_params` converts our parameter pytree to
its `state_dict`, so the two can be checked for equal logits (tests/test_torch_twin.py).
Optional: install with `pip install -e ".[compare]"`. Importing this module does not import
torch; every function that needs it imports it when called (ImportError without torch), so
`fabricjax.bench.program_timing.compare_with_torch` and the bench suite use it only where torch is installed.

The strongest PyTorch we know to write: the runners take `compile_mode` (None: eager; else a
`torch.compile` mode, `COMPILE_MODES`), the optimiser is the fastest AdamW implementation this
torch offers (`adamw_impl`: fused, else foreach), and several seeds train either one model after
another (`InSequence`) or as one `torch.vmap`ped ensemble (`Vmapped`, the peer of our `jax.vmap`
over seeds), so a ratio against the twin is not a ratio against a slow default.
"""

from __future__ import annotations

import functools
import math
import time
from types import SimpleNamespace
from typing import Any, Callable, Mapping

import numpy as np

from fabricjax import catalog
from fabricjax.config import MODALITIES, Config
from fabricjax.reporting import stats
from fabricjax.store import archive

LN_EPS = 1e-6  # flax.nnx.LayerNorm's default epsilon
SUPPORTED = ("internal", "external", "proprio")
# torch.compile modes the benchmarks time besides eager: the default and the slowest-to-compile
# one that works without a GPU (CUDA graphs are GPU-only).
COMPILE_MODES = ("default", "max-autotune-no-cudagraphs")
ADAMW_IMPLS = ("fused", "foreach")  # fastest first; `adamw_impl` picks the first this torch builds
MAX_GRAD_NORM = 1.0  # the global-norm clip of fabricjax.training.train


@functools.cache
def _modules() -> SimpleNamespace:
    """The twin's torch modules, defined on first use (importing torch then, not with this module)."""
    import torch
    from torch import nn
    from torch.nn import functional as F

    def _gelu(x):
        return F.gelu(x, approximate="tanh")  # jax.nn.gelu's default

    class MLP(nn.Module):
        def __init__(self, sizes, input_norm: bool = False):
            super().__init__()
            self.input_norm = nn.LayerNorm(sizes[0], eps=LN_EPS) if input_norm else None
            self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(sizes[:-1], sizes[1:]))

        def forward(self, x):
            if self.input_norm is not None:
                x = self.input_norm(x)
            for layer in self.layers:
                x = _gelu(layer(x))
            return x

    class Block(nn.Module):
        def __init__(self, width, n_heads, ffn, dropout):
            super().__init__()
            self.n_heads = n_heads
            self.norm1, self.norm2 = nn.LayerNorm(width, eps=LN_EPS), nn.LayerNorm(width, eps=LN_EPS)
            self.qkv, self.proj = nn.Linear(width, 3 * width), nn.Linear(width, width)
            self.ff1, self.ff2 = nn.Linear(width, ffn), nn.Linear(ffn, width)
            self.drop = nn.Dropout(dropout)

        def forward(self, x):
            b, t, w = x.shape
            q, k, v = self.qkv(self.norm1(x)).view(b, t, 3, self.n_heads, w // self.n_heads).permute(2, 0, 3, 1, 4)
            a = F.scaled_dot_product_attention(q, k, v).transpose(1, 2).reshape(b, t, w)
            x = x + self.drop(self.proj(a))
            return x + self.drop(self.ff2(_gelu(self.ff1(self.norm2(x)))))

    class TorchFabricNet(nn.Module):
        def __init__(self, config: Config, n_bins: int):
            super().__init__()
            other = [m for m in config.modalities if m not in SUPPORTED]
            if other or config.backbone != "attention" or config.property_heads or not config.fabric_head:
                raise ValueError(
                    "the twin covers the attention model on audio + proprioception with the fabric head only"
                )
            # Our model's order (fabricjax.config.MODALITIES), whatever the config's order.
            self.modalities = tuple(m for m in MODALITIES if m in config.modalities)
            audio = [m for m in self.modalities if m != "proprio"]
            self.audio = MLP((n_bins, *config.audio_hidden), input_norm=True) if audio else None
            self.proprio = MLP((archive.N_PROPRIO, *config.proprio_hidden)) if "proprio" in self.modalities else None
            if self.proprio is not None:  # the model's fixed joint standardisation (see FabricNet)
                self.register_buffer("proprio_shift", torch.zeros(archive.N_PROPRIO))
                self.register_buffer("proprio_scale", torch.ones(archive.N_PROPRIO))
            dims = sum(
                config.proprio_hidden[-1] if m == "proprio" else config.audio_hidden[-1] for m in self.modalities
            )
            self.embed = nn.Linear(dims, config.width)
            self.position = nn.Parameter(torch.randn(config.seq_len, config.width) * 0.02)
            self.blocks = nn.ModuleList(
                Block(config.width, config.n_heads, config.ffn, config.dropout) for _ in range(config.n_layers)
            )
            self.norm = nn.LayerNorm(config.width, eps=LN_EPS)
            self.hidden = nn.Linear(config.width, config.width)
            self.head = nn.Linear(config.width, catalog.N_CLASSES)
            self.drop = nn.Dropout(config.dropout)
            self.reset_parameters()

        @torch.no_grad()
        def reset_parameters(self):
            """Flax's defaults: LeCun-normal (truncated at 2 sd) kernels, zero biases, unit LayerNorm scales."""
            for m in self.modules():
                if isinstance(m, nn.Linear):
                    std = math.sqrt(1.0 / m.in_features) / 0.87962566103423978  # sd of N(0,1) truncated at +-2
                    nn.init.trunc_normal_(m.weight, std=std, a=-2 * std, b=2 * std)
                    nn.init.zeros_(m.bias)
                elif isinstance(m, nn.LayerNorm):
                    nn.init.ones_(m.weight)
                    nn.init.zeros_(m.bias)
            nn.init.normal_(self.position, std=0.02)

        def forward(self, inputs):
            parts = [
                self.proprio((inputs[m] - self.proprio_shift) * self.proprio_scale)
                if m == "proprio"
                else self.audio(inputs[m])
                for m in self.modalities
            ]
            x = torch.cat(parts, -1)
            lo, hi = x.amin(1, keepdim=True), x.amax(1, keepdim=True)
            x = (x - lo) / (hi - lo).clamp_min(1e-6)
            x = self.drop(self.embed(x) + self.position[: x.shape[1]])
            for block in self.blocks:
                x = block(x)
            h = self.drop(F.relu(self.hidden(self.norm(x).mean(1))))
            return self.head(h)

    return SimpleNamespace(MLP=MLP, Block=Block, TorchFabricNet=TorchFabricNet)


def build(config: Config, n_bins: int):
    """The twin of `FabricNet(config, {modality: (n_bins,) or (archive.N_PROPRIO,)})`: a `torch.nn.Module` in
    training mode, initialised like ours (needs torch)."""
    return _modules().TorchFabricNet(config, n_bins)


def require():
    """The torch module; ImportError (with the reason) where torch is not installed."""
    import torch

    return torch


def state_dict_from_params(params: Mapping[str, Any]) -> dict[str, Any]:
    """Our parameter pytree (`nnx.to_pure_dict` of a FabricNet, one seed) as the twin's `state_dict`.

    Dense kernels (in, out) become Linear weights (out, in); LayerNorm scales become weights; the
    fused QKV kernel's output order (3, heads, head_dim) is the twin's `view(b, t, 3, H, D)`.
    """
    import torch

    t = lambda a: torch.from_numpy(np.array(a, dtype=np.float32))  # noqa: E731
    out: dict[str, Any] = {}

    def dense(prefix, p):
        out[f"{prefix}.weight"] = t(p["kernel"]).T.contiguous()
        out[f"{prefix}.bias"] = t(p["bias"])

    def norm(prefix, p):
        out[f"{prefix}.weight"] = t(p["scale"])
        out[f"{prefix}.bias"] = t(p["bias"])

    if "audio" in params and params["audio"].get("input_norm"):
        norm("audio.input_norm", params["audio"]["input_norm"])
    for enc in ("audio", "proprio"):
        if enc in params:
            for i, layer in sorted(params[enc]["layers"].items(), key=lambda kv: int(kv[0])):
                dense(f"{enc}.layers.{int(i)}", layer)
    for k in ("proprio_shift", "proprio_scale"):
        if k in params:
            out[k] = t(params[k])
    dense("embed", params["embed"])
    out["position"] = t(params["position"])
    for i, block in sorted(params["blocks"].items(), key=lambda kv: int(kv[0])):
        for name in ("qkv", "proj", "ff1", "ff2"):
            dense(f"blocks.{int(i)}.{name}", block[name])
        norm(f"blocks.{int(i)}.norm1", block["norm1"])
        norm(f"blocks.{int(i)}.norm2", block["norm2"])
    norm("norm", params["norm"])
    dense("hidden", params["hidden"])
    dense("head", params["heads"]["fabric"])
    return out


@functools.cache
def adamw_impl() -> str:
    """The first of `ADAMW_IMPLS` that this torch builds and steps on CPU parameters.

    Probed once on a throwaway parameter: fused AdamW on CPU arrived in torch 2.4, and a torch
    without it raises at construction or at the first step."""
    import torch

    for impl in ADAMW_IMPLS:
        try:
            p = torch.nn.Parameter(torch.ones(2, 2))
            p.grad = torch.ones(2, 2)
            torch.optim.AdamW([p], **{impl: True}).step()
            return impl
        except (RuntimeError, TypeError, ValueError):
            continue
    return "for-loop"


def _optimizer(config: Config, params, seed_axes: int = 0):
    """AdamW (`adamw_impl`) as ours: weight decay on weight matrices only. `seed_axes`: leading
    axes of `params` that stack seeds (1 for a vmapped ensemble's), so a stacked bias is no matrix."""
    import torch

    params = list(params)
    decay = [p for p in params if p.ndim - seed_axes > 1]
    rest = [p for p in params if p.ndim - seed_axes <= 1]
    groups = [{"params": decay, "weight_decay": config.weight_decay}, {"params": rest, "weight_decay": 0.0}]
    impl = adamw_impl()
    return torch.optim.AdamW(groups, lr=config.learning_rate, **({impl: True} if impl in ADAMW_IMPLS else {}))


def _clip_factor(grads):
    """optax.clip_by_global_norm(MAX_GRAD_NORM)'s factor for one model's gradients:
    MAX_GRAD_NORM / max(global norm, MAX_GRAD_NORM)."""
    import torch

    norm = torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(g) for g in grads]))
    return MAX_GRAD_NORM / torch.clamp(norm, min=MAX_GRAD_NORM)


def _loss(forward, inputs, labels, autocast: bool):
    """The training loss of one model (`forward`) on one minibatch, under `mixed_precision(autocast)`."""
    from torch.nn import functional as F

    with mixed_precision(autocast):
        return F.cross_entropy(forward(inputs), labels, ignore_index=-1)


def _batch(config: Config, batch: int, n_bins: int, seed: int = 0):
    import torch

    g = torch.Generator().manual_seed(seed)
    n = config.seq_len
    inputs = {
        m: torch.randn(batch, n, archive.N_PROPRIO if m == "proprio" else n_bins, generator=g)
        for m in config.modalities
    }
    return inputs, torch.randint(0, catalog.N_CLASSES, (batch,), generator=g)


def batches(config: Config, n_seeds: int, batch: int, n_bins: int) -> list:
    """One synthetic minibatch (inputs, labels) per seed: each seed trains on its own samples, as
    ours, whose seeds each draw their own minibatches."""
    return [_batch(config, batch, n_bins, seed=s) for s in range(n_seeds)]


def compiled(fn, compile_mode: str | None):
    """`fn` (a module or a function) itself (eager) or `torch.compile(fn, mode=compile_mode)`; compilation
    happens at the first call, so the runners' warm-up call is where a mode fails or spends its compile time."""
    import torch

    if compile_mode is None:
        return fn
    if compile_mode not in COMPILE_MODES:
        raise ValueError(f"compile_mode must be None or one of {COMPILE_MODES}, got {compile_mode!r}")
    return torch.compile(fn, mode=compile_mode)


def mixed_precision(autocast: bool):
    """`torch.autocast` to bfloat16 on the CPU when `autocast` (PyTorch's own mixed precision:
    matrix products and convolutions in bfloat16, float32 parameters), else a no-op context."""
    import torch

    return torch.autocast("cpu", dtype=torch.bfloat16, enabled=autocast)


class InSequence:
    """`models` trained one after another, each on its own minibatch of `batches` (see `batches`):
    every step runs each model's forward and backward, the clip and its AdamW step in turn. With
    `compile_mode` each model's forward (and with it, through AOTAutograd, its backward) is
    `torch.compile`d; with `autocast` the forward and loss run under `mixed_precision`; clipping
    and the AdamW step (`adamw_impl`) stay eager and float32, as fused kernels already. The
    models are trained in place."""

    def __init__(self, config: Config, models, batches, compile_mode: str | None = None, autocast: bool = False):
        self.models, self.batches, self.autocast = models, batches, autocast
        self.opts = [_optimizer(config, m.parameters()) for m in models]
        self.forwards = [compiled(m, compile_mode) for m in models]

    def step(self):
        """One training step of every model; their losses, (n_seeds,)."""
        import torch

        losses = []
        for model, forward, opt, (inputs, labels) in zip(self.models, self.forwards, self.opts, self.batches):
            opt.zero_grad(set_to_none=True)
            loss = _loss(forward, inputs, labels, self.autocast)
            loss.backward()
            grads = [p.grad for p in model.parameters()]
            torch._foreach_mul_(grads, _clip_factor(grads))
            opt.step()
            losses.append(loss.detach())
        return torch.stack(losses)


class Vmapped:
    """`models` trained as one vmapped ensemble, PyTorch's peer of our `jax.vmap` over seeds: their
    parameters and buffers stacked over a leading seed axis (`torch.func.stack_module_state`, a
    copy: `models` stay as they were), one `torch.vmap` over a function that runs one model
    (`torch.func.functional_call`) on its own minibatch of `batches` (stacked likewise) and returns
    its loss and its gradients (`torch.func.grad_and_value`) clipped by its own global norm, as
    our vmapped optax clips each seed's; dropout draws a different mask for every seed
    (`randomness="different"`); one AdamW (`adamw_impl`) steps the stacked parameters, which is
    every seed's AdamW at once (its arithmetic is elementwise; decay on the seeds' weight
    matrices only). With `compile_mode` that vmapped function (forward, backward and clip) is
    `torch.compile`d; with `autocast` the forward and loss run under `mixed_precision`.

    This torch has no batching rule for its CPU attention kernel (nor its backward): vmap runs
    `scaled_dot_product_attention` seed by seed (with a warning) and batches the rest."""

    def __init__(self, config: Config, models, batches, compile_mode: str | None = None, autocast: bool = False):
        import copy

        import torch
        from torch import func

        self.params, self.buffers = func.stack_module_state(models)
        self.inputs = {m: torch.stack([inputs[m] for inputs, _ in batches]) for m in batches[0][0]}
        self.labels = torch.stack([labels for _, labels in batches])
        self.opt = _optimizer(config, self.params.values(), seed_axes=1)
        base = copy.deepcopy(models[0]).to("meta")  # the architecture only: functional_call brings each seed's tensors

        def one_seed(params, buffers, inputs, labels):
            def loss(p):
                return _loss(functools.partial(func.functional_call, base, (p, buffers)), inputs, labels, autocast)

            grads, value = func.grad_and_value(loss)(params)
            factor = _clip_factor(list(grads.values()))
            return {k: g * factor for k, g in grads.items()}, value

        self.grads_and_loss = compiled(torch.vmap(one_seed, randomness="different"), compile_mode)

    def step(self):
        """One training step of every seed; their losses, (n_seeds,)."""
        import torch

        with torch.no_grad():  # gradients come from func.grad alone; no autograd graph of the stacked parameters
            grads, losses = self.grads_and_loss(self.params, self.buffers, self.inputs, self.labels)
        for k, p in self.params.items():
            p.grad = grads[k]
        self.opt.step()
        return losses


IN_SEQUENCE, VMAPPED = "in sequence", "vmapped"
ENSEMBLES = {IN_SEQUENCE: InSequence, VMAPPED: Vmapped}  # how the runners train several seeds, by name


def train_step_runner(
    config: Config,
    *,
    n_seeds: int = 1,
    batch: int = 32,
    n_bins: int = 320,
    steps: int = 4,
    compile_mode: str | None = None,
    autocast: bool = False,
    ensemble: str = IN_SEQUENCE,
) -> Callable[[], float]:
    """A warmed-up callable that runs `steps` training steps of `n_seeds` models, each on its own
    minibatch, trained as `ensemble` says (a key of `ENSEMBLES`: `InSequence`, `Vmapped`; with
    `compile_mode` and `autocast` as there) and returns seconds per step."""
    import torch

    torch.manual_seed(0)
    models = [build(config, n_bins).train() for _ in range(n_seeds)]
    trainer = ENSEMBLES[ensemble](config, models, batches(config, n_seeds, batch, n_bins), compile_mode, autocast)
    trainer.step()  # warm-up

    def run() -> float:
        t0 = time.perf_counter()
        for _ in range(steps):
            trainer.step()
        return (time.perf_counter() - t0) / steps

    return run


def bench_train_step(config: Config, *, n_seeds: int = 1, batch: int = 32, n_bins: int = 320, steps: int = 10) -> dict:
    """Seconds per training step (median over `steps`) of `n_seeds` independent models trained one after another."""
    torch = require()
    run = train_step_runner(config, n_seeds=n_seeds, batch=batch, n_bins=n_bins, steps=1)
    s = float(np.median([run() for _ in range(steps)]))
    return {
        "seconds_per_step": s,
        "sequences_per_second_per_seed": batch / (s / n_seeds),
        "n_seeds": n_seeds,
        "threads": torch.get_num_threads(),
    }


def inference_runner(
    config: Config, *, n_bins: int = 320, compile_mode: str | None = None, autocast: bool = False
) -> Callable[[], float]:
    """A warmed-up callable returning the seconds of one eval-mode forward pass on one sequence
    (`compile_mode` and `autocast` as in `train_step_runner`)."""
    import torch

    model = compiled(build(config, n_bins).eval(), compile_mode)
    inputs, _ = _batch(config, 1, n_bins)

    def run() -> float:
        with torch.inference_mode(), mixed_precision(autocast):
            t0 = time.perf_counter()
            model(inputs)
            return time.perf_counter() - t0

    for _ in range(10):
        run()
    return run


def bench_inference(config: Config, *, n_bins: int = 320, repeats: int = 200) -> dict:
    """Latency of one sequence through the eval-mode model (p50 / p99 milliseconds)."""
    run = inference_runner(config, n_bins=n_bins)
    return stats.percentiles_ms([run() for _ in range(repeats)])
