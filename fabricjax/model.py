"""The paper's classifier (Fig. method_overview) in Flax NNX.

Per-step encoders (one MLP shared by both microphones, an MLP for the joints, small CNNs for
Minsight images and optical flow; joints, pixels and flow first standardised per channel with
fixed training-split statistics, Minsight frames measured from a reference frame and, in
training, rotated by the paper's augmentation) → concatenate → rescale every feature dimension to [0, 1] over
the sequence's time axis → Dense + learned position embedding → 3 pre-LayerNorm self-attention
blocks or a TCN → mean over time → two linear layers (fabric class) whose last layer is replaced
by one per property when property heads are on.

Inputs are a dict keyed by modality, every array with leading (batch, steps):
    internal / external  float (B, N, F)      log-PSD bins (same F: the encoder is shared)
    proprio              float (B, N, archive.N_PROPRIO): 6 joints x angle, velocity, current
    image                uint8 (B, N, H, W, 3)
    image_rows           uint8 (B, H*W, 3, N)  the same frames as pixel rows, instead of "image":
                                              how training holds its set (`inputs.training_layout`)
    flow                 float (B, N, 2, h, w)
Each CNN ends in a pool over its last layer's cells (`config.image_pool`, `config.flow_pool`): the
mean, with which any resolution works with the same weights, or "grid", every cell kept, which
fixes the resolution.
Only the encoders named in `config.modalities` are built.
"""

from __future__ import annotations

from typing import Any, Mapping

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from fabricjax import catalog
from fabricjax.config import AUDIO_MODALITIES, MODALITIES, Config
from fabricjax.sequences.inputs import STANDARDISED, channel_shape, scale_shape, shift_shape

RESCALE_EPS = 1e-6


def head_sizes(config: Config) -> dict[str, int]:
    """Output heads and their class counts: fabric (`config.n_classes`: the data's classes, the
    hand's 21 by default) and/or the three properties."""
    heads = {"fabric": config.n_classes} if config.fabric_head else {}
    if config.property_heads:
        heads.update(catalog.PROPERTY_LEVELS)
    return heads


def rescale_unit(x: jax.Array, axis: int = 1) -> jax.Array:
    """(x - min) / (max - min) over `axis`; a constant dimension maps to 0 instead of 0/0."""
    x = x.astype(jnp.float32)
    lo = x.min(axis=axis, keepdims=True)
    hi = x.max(axis=axis, keepdims=True)
    # A constant dimension also gets a zero gradient: through the eps alone its cotangent is 1/eps
    # times the upstream one, cancelling only in exact arithmetic (garbage in bfloat16, inf in float16).
    return jnp.where(hi > lo, (x - lo) / jnp.maximum(hi - lo, RESCALE_EPS), 0.0)


def matmul(x: jax.Array, w: jax.Array, dtype) -> jax.Array:
    """(..., K) @ (K, M) with both operands in the compute `dtype`, accumulated and returned in
    float32, forward and backward (`_low_matmul`); float32 is the plain product."""
    if jnp.dtype(dtype) == jnp.float32:
        return x.astype(jnp.float32) @ w.astype(jnp.float32)
    return _low_matmul(x.astype(dtype), w.astype(dtype))


@jax.custom_vjp
def _low_matmul(x: jax.Array, w: jax.Array) -> jax.Array:
    """`x @ w` of low-precision operands, float32 out. The VJP is written out so that the backward
    products take the cotangent in the operands' dtype too: autodiff's form would multiply the
    float32 cotangent with the operands converted to float32, the slow product again."""
    return jnp.matmul(x, w, preferred_element_type=jnp.float32)


def _low_matmul_fwd(x, w):
    return _low_matmul(x, w), (x, w)


def _low_matmul_bwd(saved, dy):
    x, w = saved
    dy = dy.astype(x.dtype)
    dx = jnp.matmul(dy, w.T, preferred_element_type=jnp.float32)
    dw = jnp.matmul(x.reshape(-1, x.shape[-1]).T, dy.reshape(-1, dy.shape[-1]), preferred_element_type=jnp.float32)
    return dx.astype(x.dtype), dw.astype(w.dtype)


_low_matmul.defvjp(_low_matmul_fwd, _low_matmul_bwd)


class Dense(nnx.Linear):
    """`nnx.Linear` (float32 parameters) whose product takes its inputs in the layer's `dtype`
    (the compute dtype) and accumulates and returns float32 (`matmul`): bfloat16 halves the
    product's operand traffic and runs on the CPU's bfloat16 units where it has them, while the
    bias, activations and everything after the product stay float32."""

    def __call__(self, x: jax.Array) -> jax.Array:
        return matmul(x, self.kernel[...], self.dtype or jnp.float32) + self.bias[...]


def dense(a: int, b: int, *, dtype, rngs: nnx.Rngs) -> Dense:
    return Dense(a, b, dtype=dtype, rngs=rngs)


class Dropout(nnx.Module):
    """Dropout at `rate`, its mask drawn from 16-bit random words: an element is dropped where its
    word is below `round(rate * 2**16)`, a rate within 2**-17 of `rate`. The same regularisation as
    `nnx.Dropout` (whose mask compares a float32 uniform drawn from a 32-bit word per element) from
    half the random words: the generator's rounds are most of a CPU step's dropout cost."""

    BITS = 16

    def __init__(self, rate: float):
        self.rate = rate

    def __call__(self, x: jax.Array, *, deterministic: bool, rngs: nnx.Rngs | None) -> jax.Array:
        if deterministic or self.rate == 0.0:
            return x
        words = jax.random.bits(rngs.dropout(), x.shape, jnp.uint16)
        threshold = round(self.rate * 2**self.BITS)
        keep = 1.0 - threshold / 2**self.BITS
        return jnp.where(words >= threshold, x / keep, jnp.zeros_like(x))


class MLP(nnx.Module):
    """Linear layers with GELU between them and after the last (features feed the backbone).

    `input_norm` puts a LayerNorm over the input features first. The audio encoder needs it: log10
    PSD bins sit near -10, so without it the first layer's pre-activations have a spread of ~10,
    most GELU units start dead, and some seeds never leave chance. Normalising each step's
    spectrum keeps its shape (what identifies the fabric) and drops its overall level (which day-
    to-day gain drift changes anyway).
    """

    def __init__(self, sizes: tuple[int, ...], *, dtype, rngs: nnx.Rngs, input_norm: bool = False):
        self.input_norm = nnx.LayerNorm(sizes[0], rngs=rngs) if input_norm else None
        self.layers = nnx.List([dense(a, b, dtype=dtype, rngs=rngs) for a, b in zip(sizes[:-1], sizes[1:])])

    def __call__(self, x):
        layers = iter(self.layers)
        if self.input_norm is not None:
            x = jax.nn.gelu(self._normalize_and_project(x, next(layers)))
        for layer in layers:
            x = jax.nn.gelu(layer(x))
        return x

    def _normalize_and_project(self, x, layer: nnx.Linear):
        """`layer(input_norm(x))` with the norm's scale and shift folded into the layer's weights.

        The same function and parameters, computed as standardise(x) @ (scale * kernel) + (shift @
        kernel + bias): the standardised input is data (no parameter touches it), so the backward
        pass needs no input-sized gradient. Dropping that (steps x bins) gradient and its two
        reductions over steps cut the summed op time of a two-microphone training step by 11 %.
        """
        norm = self.input_norm
        x = x.astype(jnp.float32)
        mean = x.mean(-1, keepdims=True)
        var = jnp.maximum((x * x).mean(-1, keepdims=True) - mean * mean, 0.0)  # as nnx.LayerNorm
        x = (x - mean) * jax.lax.rsqrt(var + norm.epsilon)
        kernel, scale, shift = layer.kernel[...], norm.scale[...], norm.bias[...]
        return matmul(x, scale[:, None] * kernel, layer.dtype or jnp.float32) + (shift @ kernel + layer.bias[...])


class ConvEncoder(nnx.Module):
    """Non-overlapping strided convolutions (kernel = stride: 5x5, then 2x2 merges), ReLU, and a
    pool over the last layer's cells (`pool`, `config.CNN_POOLS`): their mean, resolution-independent
    per-frame features, or every cell's features side by side ("grid"), which keep where in the
    frame a response sits.

    Why kernel = stride: XLA's CPU convolutions with a handful of channels run far below its matrix
    product speed, and a non-overlapping convolution is a reshape plus one matrix product. Frames
    come 200 per sequence, so this encoder is what the camera rows' training time is made of.
    """

    PATCHES = (5, 2, 2, 2)

    def __init__(self, in_channels: int, features: tuple[int, ...], *, dtype, rngs: nnx.Rngs, pool: str = "mean"):
        if len(features) > len(self.PATCHES):
            raise ValueError(f"at most {len(self.PATCHES)} CNN layers, got {features}")
        sizes = (in_channels, *features)
        self.layers = nnx.List(
            [dense(p * p * a, b, dtype=dtype, rngs=rngs) for p, a, b in zip(self.PATCHES, sizes[:-1], sizes[1:])]
        )
        self.pool = pool

    def out_features(self, h: int, w: int) -> int:
        """Features per frame of an (h, w) input: the last layer's channels, times its cells under "grid"."""
        channels = self.layers[-1].out_features
        if self.pool == "mean":
            return channels
        for p in self.PATCHES[: len(self.layers)]:
            side = _patch_side(p, h, w)
            h, w = h // side, w // side
        return channels * h * w

    def __call__(self, x):  # (M, H, W, C)
        return self.after_first(jax.nn.relu(self.layers[0](_patches(x, self.first_patch(*x.shape[1:3])))))

    def first_patch(self, h: int, w: int) -> int:
        """The first layer's patch side on an (h, w) input."""
        return _patch_side(self.PATCHES[0], h, w)

    def from_rows(self, rows: jax.Array, grid: tuple[int, int]) -> jax.Array:
        """The same features from a batch of sequences given as patch rows: (B, cells, p*p*C, N),
        the pixels of each of the first layer's `grid` (rows, columns) of patches in their order
        (`features.images.patch_pixels`), every frame of the sequence side by side. -> (B * N, F).
        `patch_product` applies the first layer in this layout: the rotation hands its output over
        without the transpose into frames."""
        first = self.layers[0]
        dtype = first.dtype or jnp.float32
        y = patch_product(rows.astype(dtype), first.kernel[...].astype(dtype)) + first.bias[...][:, None]
        b, cells, f, n = y.shape
        return self.after_first(jax.nn.relu(jnp.moveaxis(y, 3, 1).reshape(b * n, *grid, f)))

    def after_first(self, x):
        """The layers after the first, on its (M, h, w, F) output, then the pool over the cells."""
        for p, layer in zip(self.PATCHES[1:], self.layers[1:]):
            x = jax.nn.relu(layer(_patches(x, _patch_side(p, *x.shape[1:3]))))
        return x.mean(axis=(1, 2)) if self.pool == "mean" else x.reshape(x.shape[0], -1)


def _patch_side(p: int, h: int, w: int) -> int:
    """A layer's patch side `p` on an (h, w) input: tiny inputs shrink it to what is there."""
    return max(1, min(p, h, w))


def _patches(x: jax.Array, p: int) -> jax.Array:
    """(M, H, W, C) -> (M, H // p, W // p, p * p * C): non-overlapping p x p patches of the
    top-left crop, each flattened row by row (the layout `ConvEncoder`'s layers read)."""
    m, h, w, c = x.shape
    h, w = h // p, w // p
    return x[:, : h * p, : w * p].reshape(m, h, p, w, p, c).transpose(0, 1, 3, 2, 4, 5).reshape(m, h, w, p * p * c)


@jax.custom_vjp
def patch_product(rows: jax.Array, kernel: jax.Array) -> jax.Array:
    """(B, cells, J, N) patch rows times a (J, F) kernel -> (B, cells, F, N): each cell's (F, J) @
    (J, N) product, batched over (B, cells), accumulated and returned in float32 whatever the
    operands' (compute) dtype.

    Batched so that every product is a plain matrix product on XLA's CPU backend: the same
    contraction as one (B*cells*N, J) @ (J, F) product needs the rows transposed first. The VJP
    is written out for the same reason: the kernel's gradient as each cell's rows @ dy^T (with the
    small dy transposed) runs as plain products, where autodiff's form contracted both operands'
    minor axis and took most of the first layer's time."""
    kernel_t = jnp.broadcast_to(kernel.T, (*rows.shape[:2], *kernel.T.shape))
    return jnp.einsum("bckj,bcjn->bckn", kernel_t, rows, preferred_element_type=jnp.float32)


def _patch_product_fwd(rows, kernel):
    return patch_product(rows, kernel), (rows, kernel)


def _patch_product_bwd(saved, dy):
    rows, kernel = saved
    dy = dy.astype(kernel.dtype)  # the products' operands in the compute dtype, as forward
    kernel_t = jnp.broadcast_to(kernel.T, (*rows.shape[:2], *kernel.T.shape))
    d_rows = jnp.einsum("bckj,bckn->bcjn", kernel_t, dy, preferred_element_type=jnp.float32)
    d_kernel = jnp.einsum("bcjn,bcnk->bcjk", rows, jnp.swapaxes(dy, 2, 3), preferred_element_type=jnp.float32).sum(
        (0, 1)
    )
    return d_rows.astype(rows.dtype), d_kernel.astype(kernel.dtype)


patch_product.defvjp(_patch_product_fwd, _patch_product_bwd)


def self_attention(q: jax.Array, k: jax.Array, v: jax.Array) -> jax.Array:
    """Softmax attention of head-major (B, H, T, D) projections -> (B, H, T, D).

    Formulation chosen for XLA's CPU backend (timed with `fabricjax.bench.program_timing`): head-major
    einsums batch well under the seed `vmap`, where `jax.nn.dot_product_attention` cost more per
    seed; and normalising after the value product (divide the (B, H, T, D) output, not the
    (B, H, T, T) weights, with the max shift outside the gradient: softmax is shift-invariant)
    does less work per training step.
    """
    # q, k, v in the compute dtype; scores, softmax and output float32 (a float16 product would
    # overflow to inf above 65504)
    scores = jnp.einsum("bhtd,bhsd->bhts", q * q.shape[-1] ** -0.5, k, preferred_element_type=jnp.float32)
    e = jnp.exp(scores - jax.lax.stop_gradient(scores.max(axis=-1, keepdims=True)))
    return jnp.einsum("bhts,bhsd->bhtd", e.astype(v.dtype), v, preferred_element_type=jnp.float32) / e.sum(
        axis=-1, keepdims=True
    )


class AttentionBlock(nnx.Module):
    """Pre-LayerNorm multi-head self-attention + FFN.

    The QKV projection is one parameter (W, 3W), applied as three (W, W) products: each output
    then goes to the head-major layout with a 4-D transpose, where splitting one fused (B, T, 3,
    H, D) output takes a 5-D one that XLA's CPU backend runs far slower under the seed vmap, in the
    forward pass and again in the backward pass.
    """

    def __init__(self, width: int, n_heads: int, ffn: int, dropout: float, *, dtype, rngs: nnx.Rngs):
        if width % n_heads:
            raise ValueError(f"width {width} is not divisible by n_heads {n_heads}")
        self.n_heads = n_heads
        self.norm1 = nnx.LayerNorm(width, rngs=rngs)
        self.qkv = dense(width, 3 * width, dtype=dtype, rngs=rngs)
        self.proj = dense(width, width, dtype=dtype, rngs=rngs)
        self.norm2 = nnx.LayerNorm(width, rngs=rngs)
        self.ff1 = dense(width, ffn, dtype=dtype, rngs=rngs)
        self.ff2 = dense(ffn, width, dtype=dtype, rngs=rngs)
        self.dropout = Dropout(dropout)

    def __call__(self, x, rngs):
        b, t, w = x.shape
        h = self.norm1(x)
        dtype = self.qkv.dtype or jnp.float32
        kernel, bias = self.qkv.kernel[...], self.qkv.bias[...]
        heads = (  # noqa: E731
            lambda i: jnp.swapaxes(
                (matmul(h, kernel[:, i * w : (i + 1) * w], dtype) + bias[i * w : (i + 1) * w])
                .astype(dtype)
                .reshape(b, t, self.n_heads, -1),
                1,
                2,
            )
        )
        a = jnp.swapaxes(self_attention(heads(0), heads(1), heads(2)), 1, 2).reshape(b, t, w)
        x = x + self.dropout(self.proj(a), deterministic=rngs is None, rngs=rngs)
        h = self.ff2(jax.nn.gelu(self.ff1(self.norm2(x))))
        return x + self.dropout(h, deterministic=rngs is None, rngs=rngs)


class TCNBlock(nnx.Module):
    """Two dilated causal 1-D convolutions (kernel 3) with a residual connection (Bai et al. 2018)."""

    def __init__(self, width: int, dilation: int, dropout: float, *, dtype, rngs: nnx.Rngs):
        conv = lambda: nnx.Conv(  # noqa: E731
            width, width, (3,), kernel_dilation=dilation, padding="CAUSAL", dtype=dtype, rngs=rngs
        )
        self.conv1, self.conv2 = conv(), conv()
        self.dropout = Dropout(dropout)

    def __call__(self, x, rngs):
        h = self.dropout(jax.nn.relu(causal_conv(self.conv1, x)), deterministic=rngs is None, rngs=rngs)
        h = self.dropout(jax.nn.relu(causal_conv(self.conv2, h)), deterministic=rngs is None, rngs=rngs)
        return jax.nn.relu(x + h)


def causal_conv(conv: nnx.Conv, x: jax.Array) -> jax.Array:
    """`conv(x)` (a causal, dilated 1-D `nnx.Conv`) as one product of the kernel with its shifted inputs.

    Same function and parameters, but vmapped over seeds a convolution becomes a grouped one, which
    XLA:CPU runs as a slow loop; the product runs on its matrix kernels."""
    kernel = conv.kernel[...]  # (taps, in, out)
    (dilation,) = np.atleast_1d(conv.kernel_dilation)
    taps, steps = kernel.shape[0], x.shape[-2]
    padded = jnp.pad(x, [(0, 0)] * (x.ndim - 2) + [((taps - 1) * dilation, 0), (0, 0)])
    shifted = jnp.concatenate([padded[..., j * dilation : j * dilation + steps, :] for j in range(taps)], axis=-1)
    return matmul(shifted, kernel.reshape(-1, kernel.shape[-1]), conv.dtype or jnp.float32) + conv.bias[...]


class FabricNet(nnx.Module):
    """The classifier. `shapes` are the per-step input shapes (see `inputs.feature_shapes`)."""

    def __init__(self, config: Config, shapes: Mapping[str, tuple[int, ...]], *, rngs: nnx.Rngs):
        missing = [m for m in config.modalities if m not in shapes]
        if missing:
            raise ValueError(f"inputs lack the configured modalities {missing}; got {sorted(shapes)}")
        dtype = jnp.dtype(config.compute_dtype)
        self.modalities = tuple(m for m in MODALITIES if m in config.modalities)
        self.dtype = dtype
        width = config.width
        audio = [m for m in self.modalities if m in AUDIO_MODALITIES]
        bins = {shapes[m][-1] for m in audio}
        if len(bins) > 1:
            raise ValueError(f"the shared audio encoder needs equal PSD bins for {audio}, got {bins}")
        cnn = config.cnn_features
        self.audio = MLP((*bins, *config.audio_hidden), dtype=dtype, rngs=rngs, input_norm=True) if audio else None
        self.proprio = (
            MLP((shapes["proprio"][-1], *config.proprio_hidden), dtype=dtype, rngs=rngs)
            if "proprio" in self.modalities
            else None
        )
        # Fixed input standardisation (no gradient, no decay), set from the training split by
        # `inputs.with_input_statistics`: joint values span four orders of magnitude (currents ~1e-3 A
        # apart, velocities ~1 rad/s) and their absolute levels carry the load; camera pixels (0-255)
        # and sparse flow (mostly exact zeros) must be centred and scaled before a handful of ReLU
        # channels, or most units start on one side of zero for every input and the rows never
        # leave chance. One (shift, scale) per joint value, colour channel or flow component (per
        # pixel and colour under `config.image_standardisation`). Minsight frames are read as the
        # difference to a reference frame (`config.image_reference`: the session's no-contact frame,
        # or the training split's mean): without it the LEDs' fixed colour field dominates every
        # frame, and under the paper's rotation it turns with the angle, a nuisance far larger than
        # the deformation that tells fabrics apart.
        for m in STANDARDISED:
            if m in self.modalities:
                setattr(self, f"{m}_shift", nnx.Param(jnp.zeros(shift_shape(config, m, shapes[m]), jnp.float32)))
                setattr(self, f"{m}_scale", nnx.Param(jnp.ones(scale_shape(config, m, shapes[m]), jnp.float32)))
        self.rotate_images = "image" in self.modalities and config.augment_rotation
        self.rotation_interpolation, self.rotation_fill = config.rotation_interpolation, config.rotation_fill
        self.image = (
            ConvEncoder(3, cnn, dtype=dtype, rngs=rngs, pool=config.image_pool) if "image" in self.modalities else None
        )
        self.image_hw = tuple(shapes["image"][:2]) if "image" in self.modalities else None  # (H, W) of its frames
        self.flow = (
            ConvEncoder(2, cnn, dtype=dtype, rngs=rngs, pool=config.flow_pool) if "flow" in self.modalities else None
        )
        out = {"proprio": config.proprio_hidden[-1]}
        if self.image is not None:
            out["image"] = self.image.out_features(*self.image_hw)
        if self.flow is not None:
            out["flow"] = self.flow.out_features(*shapes["flow"][1:])
        dims = sum(out.get(m, config.audio_hidden[-1]) for m in self.modalities)
        # Fusion normalisation (config.FUSION_NORMS): the paper's [0, 1] rescale over each sequence
        # discards every feature's steady level (a palm microphone's loudness, a joint's load),
        # so our variant normalises each step's concatenated features instead (LayerNorm).
        self.fusion_norm = nnx.LayerNorm(dims, rngs=rngs) if config.fusion_norm == "step_layernorm" else None
        self.embed = dense(dims, width, dtype=dtype, rngs=rngs)
        self.position = nnx.Param(nnx.initializers.normal(0.02)(rngs.params(), (config.seq_len, width)))
        if config.backbone == "attention":
            blocks = [
                AttentionBlock(width, config.n_heads, config.ffn, config.dropout, dtype=dtype, rngs=rngs)
                for _ in range(config.n_layers)
            ]
        else:
            blocks = [TCNBlock(width, 2**i, config.dropout, dtype=dtype, rngs=rngs) for i in range(config.n_layers)]
        self.blocks = nnx.List(blocks)
        self.norm = nnx.LayerNorm(width, rngs=rngs)
        self.hidden = dense(width, width, dtype=dtype, rngs=rngs)
        self.head_activation = {"relu": jax.nn.relu, "gelu": jax.nn.gelu}[config.head_activation]
        self.heads = nnx.Dict({k: nnx.Linear(width, n, rngs=rngs) for k, n in head_sizes(config).items()})
        self.dropout = Dropout(config.dropout)

    def features(self, inputs: Mapping[str, jax.Array], rngs: nnx.Rngs | None = None) -> jax.Array:
        """Per-step concatenated encoder outputs, normalised (config.fusion_norm): (B, N, D).
        In training (`rngs` given) image sequences are rotated by the paper's augmentation, one
        angle per sequence from the "augment" stream, after standardisation: what turns is the
        frame minus the reference, and 0 (no deformation) fills what the turn brings in."""
        parts = []
        for m in self.modalities:
            if m == "image":
                parts.append(self.image_features(inputs, rngs))
                continue
            x = inputs[m]
            b, n = x.shape[:2]
            x = x.reshape(b * n, *x.shape[2:])
            if m in STANDARDISED:
                x = self.standardise(m, x)
            if m == "flow":
                x = self.flow(jnp.moveaxis(x, 1, -1))
            elif m == "proprio":
                x = self.proprio(x)
            else:
                x = self.audio(
                    x
                )  # standardised in float32 first: log-PSD levels near -10 lose their detail in bfloat16
            parts.append(x.reshape(b, n, -1))
        fused = jnp.concatenate(parts, axis=-1)
        return rescale_unit(fused) if self.fusion_norm is None else self.fusion_norm(fused.astype(jnp.float32))

    def image_features(self, inputs: Mapping[str, jax.Array], rngs: nnx.Rngs | None) -> jax.Array:
        """Per-step image features (B, N, F). Evaluation on frames ("image"): standardise, then the
        CNN. Training (`rngs` given), or frames already as rows ("image_rows", how training holds
        its set: `inputs.training_layout`): standardise the rows, turn each sequence by its angle
        (`features.images.rotate_rows`, when `rotate_images`), taking the rotated frame's pixels
        in the first layer's patch order, and feed those rows to the CNN (`ConvEncoder.from_rows`):
        the same function as rotating the frames and running the CNN on them."""
        from fabricjax.features import images  # traced only for image rows

        if "image_rows" not in inputs and rngs is None:
            x = inputs["image"]
            b, n = x.shape[:2]
            return self.image(self.standardise("image", x.reshape(b * n, *x.shape[2:]))).reshape(b, n, -1)
        rows = inputs["image_rows"] if "image_rows" in inputs else images.to_rows(inputs["image"])
        b, _, c, n = rows.shape
        (h, w), p = self.image_hw, self.image.first_patch(*self.image_hw)
        pixels = images.patch_pixels(h, w, p)
        shift, scale = jax.lax.stop_gradient((self.image_shift[...], self.image_scale[...]))
        # each a frame, or one value per colour
        reference, scale = (jnp.broadcast_to(v, (h, w, c)).reshape(h * w, c, 1) for v in (shift, scale))
        rows = (rows.astype(jnp.float32) - reference) * scale
        if self.rotate_images and rngs is not None:
            degrees = images.random_angles(rngs.augment(), b)
            # the standardised value of the input's 0 (`config.rotation_fill`), at each output pixel
            fill = (-reference * scale)[pixels] if self.rotation_fill == "no_contact" else 0.0
            rows = jax.vmap(lambda r, d: images.rotate_rows(r, d, h, w, pixels, self.rotation_interpolation, fill))(
                rows, degrees
            )
        else:
            rows = rows[:, pixels]
        grid = (h // p, w // p)
        return self.image.from_rows(rows.reshape(b, grid[0] * grid[1], p * p * c, n), grid).reshape(b, n, -1)

    def standardise(self, modality: str, x: jax.Array) -> jax.Array:
        """(x - shift) * scale per channel with the fixed training-split statistics, in the compute dtype."""
        shift, scale = jax.lax.stop_gradient(
            (getattr(self, f"{modality}_shift")[...], getattr(self, f"{modality}_scale")[...])
        )
        shape = channel_shape(modality, x.ndim - 1)
        # a frame of shifts or scales (one per pixel and colour) broadcasts as it is
        shift, scale = (v.reshape(shape) if v.ndim == 1 else v for v in (shift, scale))
        return ((x.astype(jnp.float32) - shift) * scale).astype(self.dtype)

    def latents(self, inputs: Mapping[str, jax.Array], rngs: nnx.Rngs | None = None) -> jax.Array:
        """Backbone output per step (B, N, width): the representation the t-SNE analysis plots."""
        x = self.features(inputs, rngs)
        n = x.shape[1]
        if n > self.position.shape[0]:
            raise ValueError(f"sequence of {n} steps exceeds the model's {self.position.shape[0]}")
        x = self.embed(x) + self.position[:n]
        x = self.dropout(x, deterministic=rngs is None, rngs=rngs)
        for block in self.blocks:
            x = block(x, rngs)
        return self.norm(x)

    def __call__(self, inputs: Mapping[str, jax.Array], rngs: nnx.Rngs | None = None) -> dict[str, jax.Array]:
        """Logits per head (float32). Dropout and the image rotation are on exactly when `rngs` (streams
        "dropout" and "augment") is given: training."""
        h = self.head_activation(self.hidden(self.latents(inputs, rngs).mean(axis=1)))
        h = self.dropout(h, deterministic=rngs is None, rngs=rngs)
        return {k: head(h).astype(jnp.float32) for k, head in self.heads.items()}


def make_predict(graphdef: nnx.GraphDef):
    """`predict(params, inputs)`: logits per head for a batch (B, N, ...) of sequences, jitted;
    `params` a plain pytree (`nnx.to_pure_dict`). Make it once per model and keep it: the jitted
    function closes over `graphdef`, so a call hashes no graphdef (a static `GraphDef` argument
    is hashed on every call, a cost of the order of a single-sequence forward pass)."""

    def predict(params, inputs: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
        return nnx.merge(graphdef, params)(inputs)

    return jax.jit(predict)


def compile_predict_one(
    graphdef: nnx.GraphDef, params, example: Mapping[str, Any], device: jax.Device | None = None
) -> jax.stages.Compiled:
    """`predict_one(inputs)`: logits per head for one sequence {modality: (N, ...)} of `example`'s
    shapes and dtypes, e.g. live on the robot; the production single-sequence path.

    Compiled ahead of time (`jax.jit(...).lower(...).compile()`) for one `device` (default: the
    first) with `params` (a plain pytree, `nnx.to_pure_dict`) closed over: a call dispatches only
    the inputs, never the parameter pytree, checks no cache and hashes no graphdef, and XLA
    compiles against the fixed weights. Same function as `nnx.merge(graphdef, params)` on a batch
    of one. A call with other shapes or dtypes than `example`'s is a TypeError (compile again)."""
    device = device or jax.devices()[0]
    params = jax.device_put(params, device)

    def predict_one(inputs: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
        logits = nnx.merge(graphdef, params)(jax.tree.map(lambda a: a[None], inputs))
        return jax.tree.map(lambda a: a[0], logits)

    placed = jax.sharding.SingleDeviceSharding(device)
    shapes = {
        m: jax.ShapeDtypeStruct(np.shape(a), jax.dtypes.canonicalize_dtype(a.dtype), sharding=placed)
        for m, a in example.items()
    }
    return jax.jit(predict_one).lower(shapes).compile()
