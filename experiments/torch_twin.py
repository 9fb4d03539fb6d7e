"""A PyTorch twin of the audio + proprioception FabricNet and its training step, for benchmarks only.

What a user would most likely write instead of us, made layer-for-layer equal to
`fabricjax.model.FabricNet` (GELU MLPs with the audio encoder shared by both microphones,
[0, 1] rescale over time, Dense + learned position, pre-LayerNorm attention blocks with fused QKV
and `scaled_dot_product_attention`, final LayerNorm, mean over time, ReLU hidden layer, linear
head) and to `fabricjax.train` (global-norm clip 1.0, AdamW decaying weight matrices only).
Optional: install with `pip install -e ".[compare]"`; nothing else imports torch.
"""

from __future__ import annotations

import time

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from fabricjax import catalog
from fabricjax.config import Config


class MLP(nn.Module):
    def __init__(self, sizes):
        super().__init__()
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(sizes[:-1], sizes[1:]))

    def forward(self, x):
        for layer in self.layers:
            x = F.gelu(layer(x))
        return x


class Block(nn.Module):
    def __init__(self, width, n_heads, ffn, dropout):
        super().__init__()
        self.n_heads = n_heads
        self.norm1, self.norm2 = nn.LayerNorm(width), nn.LayerNorm(width)
        self.qkv, self.proj = nn.Linear(width, 3 * width), nn.Linear(width, width)
        self.ff1, self.ff2 = nn.Linear(width, ffn), nn.Linear(ffn, width)
        self.drop = nn.Dropout(dropout)

    def forward(self, x):
        b, t, w = x.shape
        q, k, v = self.qkv(self.norm1(x)).view(b, t, 3, self.n_heads, w // self.n_heads).permute(2, 0, 3, 1, 4)
        a = F.scaled_dot_product_attention(q, k, v).transpose(1, 2).reshape(b, t, w)
        x = x + self.drop(self.proj(a))
        return x + self.drop(self.ff2(F.gelu(self.ff1(self.norm2(x)))))


class TorchFabricNet(nn.Module):
    def __init__(self, config: Config, n_bins: int):
        super().__init__()
        self.modalities = config.modalities
        self.audio = MLP((n_bins, *config.audio_hidden))
        self.proprio = MLP((18, *config.proprio_hidden))
        dims = sum(config.proprio_hidden[-1] if m == "proprio" else config.audio_hidden[-1] for m in config.modalities)
        self.embed = nn.Linear(dims, config.width)
        self.position = nn.Parameter(torch.randn(config.sequence_length, config.width) * 0.02)
        self.blocks = nn.ModuleList(
            Block(config.width, config.n_heads, config.ffn, config.dropout) for _ in range(config.n_layers)
        )
        self.norm = nn.LayerNorm(config.width)
        self.hidden = nn.Linear(config.width, config.width)
        self.head = nn.Linear(config.width, catalog.N_CLASSES)
        self.drop = nn.Dropout(config.dropout)

    def forward(self, inputs):
        parts = [self.proprio(inputs[m]) if m == "proprio" else self.audio(inputs[m]) for m in self.modalities]
        x = torch.cat(parts, -1)
        lo, hi = x.amin(1, keepdim=True), x.amax(1, keepdim=True)
        x = (x - lo) / (hi - lo).clamp_min(1e-6)
        x = self.drop(self.embed(x) + self.position[: x.shape[1]])
        for block in self.blocks:
            x = block(x)
        h = self.drop(F.relu(self.hidden(self.norm(x).mean(1))))
        return self.head(h)


def _optimizer(model: nn.Module, config: Config):
    decay = [p for p in model.parameters() if p.ndim > 1]
    rest = [p for p in model.parameters() if p.ndim <= 1]
    return torch.optim.AdamW(
        [{"params": decay, "weight_decay": config.weight_decay}, {"params": rest, "weight_decay": 0.0}],
        lr=config.learning_rate,
    )


def _batch(config: Config, batch: int, n_bins: int, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    n = config.sequence_length
    inputs = {m: torch.randn(batch, n, 18 if m == "proprio" else n_bins, generator=g) for m in config.modalities}
    return inputs, torch.randint(0, catalog.N_CLASSES, (batch,), generator=g)


def bench_train_step(config: Config, *, n_seeds: int = 1, batch: int = 32, n_bins: int = 320, steps: int = 10) -> dict:
    """Seconds per training step of `n_seeds` independent models trained one after another."""
    torch.manual_seed(0)
    models = [TorchFabricNet(config, n_bins).train() for _ in range(n_seeds)]
    opts = [_optimizer(m, config) for m in models]
    inputs, labels = _batch(config, batch, n_bins)

    def step():
        for model, opt in zip(models, opts):
            opt.zero_grad(set_to_none=True)
            F.cross_entropy(model(inputs), labels).backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()

    step()  # warm-up
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    s = float(np.median(times))
    return {"seconds_per_step": s, "sequences_per_second_per_seed": batch / (s / n_seeds), "n_seeds": n_seeds, "threads": torch.get_num_threads()}


def bench_inference(config: Config, *, n_bins: int = 320, repeats: int = 200) -> dict:
    """Latency of one sequence through the eval-mode model (p50 / p99 milliseconds)."""
    model = TorchFabricNet(config, n_bins).eval()
    inputs, _ = _batch(config, 1, n_bins)
    times = []
    with torch.inference_mode():
        for _ in range(10):
            model(inputs)
        for _ in range(repeats):
            t0 = time.perf_counter()
            model(inputs)
            times.append(time.perf_counter() - t0)
    ms = np.array(times) * 1e3
    return {"p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99))}
