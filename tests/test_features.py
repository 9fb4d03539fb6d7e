import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.signal

from fabricjax.features import extract, flow, images, welch
from fabricjax.store import archive
from tests import helpers
from tests.helpers import tiny_archive


def _words(samples):
    """Full-scale samples -> SPH0645 words (18 bits in 31..14, junk in the low bits)."""
    q = np.clip(np.round(samples * 2**17), -(2**17), 2**17 - 1).astype(np.int64)
    return ((q << 14) | 0x1234).astype(np.int32)


def _signal(kind, n_windows, rng):
    t = np.arange(archive.WINDOW) / archive.AUDIO_RATE
    noise = rng.normal(size=(n_windows, archive.WINDOW))
    if kind == "noise":
        x = 0.05 * noise
    elif kind == "dc_offset":  # the SPH0645's large DC offset on top of a quiet signal
        x = 0.4 + 0.002 * noise
    elif kind == "clipped":  # a loud tone plus noise, saturating the converter
        x = 3.0 * np.sin(2 * np.pi * 1000 * t + rng.uniform(0, 6, (n_windows, 1))) + 0.1 * noise
    return _words(x)


def _reference(words):
    x = (words >> 14).astype(np.float64) / 2**17
    return scipy.signal.welch(x, **welch.SCIPY_KWARGS)[1]


@pytest.mark.parametrize("n_windows", [1, 7, 64])
@pytest.mark.parametrize("kind", ["noise", "dc_offset", "clipped"])
def test_welch_matches_scipy_float32(kind, n_windows):
    """FFT rounding is relative to the window's energy, not to each bin, so in float32 "above the
    floor" means bins holding at least 1e-4 of the window's power (all but a few bins of noise,
    the harmonics of a clipped tone). The reference is scipy in float64."""
    words = _signal(kind, n_windows, np.random.default_rng(n_windows))
    ref = _reference(words)
    got = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0, log=False))
    assert got.dtype == np.float32 and got.shape == (n_windows, 512)
    above = ref >= 1e-4 * ref.sum(axis=-1, keepdims=True)
    assert above.sum(axis=-1).min() >= 8
    assert np.max(np.abs(got - ref)[above] / ref[above]) <= 1e-5


@pytest.mark.parametrize("n_windows", [1, 7, 64])
@pytest.mark.parametrize("kind", ["noise", "dc_offset", "clipped"])
def test_welch_matches_scipy_x64(kind, n_windows):
    words = _signal(kind, n_windows, np.random.default_rng(n_windows))
    ref = _reference(words)
    with jax.enable_x64(True):
        got = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0, log=False))
    assert got.dtype == np.float64
    above = ref > 1e-25  # everything but exact numerical zeros
    assert np.max(np.abs(got - ref)[above] / ref[above]) <= 1e-10


def test_log_psd_of_silence_is_the_floor():
    for words in (np.zeros((3, 2048), np.int32), np.full((3, 2048), 5 << 14, np.int32)):
        got = np.asarray(welch.welch_psd(words))
        assert np.all(np.isfinite(got))
        assert np.all(got <= np.log10(1e-18))  # at or near the floor, far below quantisation noise
    np.testing.assert_array_equal(np.asarray(welch.welch_psd(np.zeros((1, 2048), np.int32))), np.log10(welch.LOG_FLOOR))


def test_bandwidth_truncation_keeps_bins_up_to_the_bandwidth():
    assert [welch.n_bins(b) for b in (2.5, 10.0, 15.0, 24.0)] == [54, 213, 320, 512]
    assert welch.frequencies(15.0)[-1] <= 15000 < welch.frequencies(24.0)[320]
    words = _signal("noise", 4, np.random.default_rng(0))
    full = np.asarray(welch.welch_psd(words, bandwidth_khz=24.0))
    np.testing.assert_array_equal(np.asarray(welch.welch_psd(words)), full[:, :320])


def test_sph0645_words_to_full_scale():
    words = np.array([(-(2**17)) << 14, ((2**17 - 1) << 14) | 0x3FFF, 1 << 14, 0x3FFF], np.int32)
    np.testing.assert_array_equal(np.asarray(welch.to_full_scale(words)), [-1.0, 1 - 2**-17, 2**-17, 0.0])


def test_mic_windows_end_at_window_end_and_pad_the_start():
    a = tiny_archive(n_steps=5)
    we = a.window_end.copy()
    we[0] = 100  # a window that starts before the recording
    a = type(a)(**{**a.__dict__, "window_end": we})
    w = extract.mic_windows(a, 1)
    np.testing.assert_array_equal(w[3], a.audio[1, we[3, 1] - 2048 : we[3, 1]])
    np.testing.assert_array_equal(w[0, -100:], a.audio[1, :100])
    assert not w[0, :-100].any()


def test_proprio_is_joint_major():
    a = tiny_archive(n_steps=4)
    p = extract.feature_for("proprio").compute(a)
    assert p.shape == (4, 18) and p.dtype == np.float32
    np.testing.assert_array_equal(p[2, 3:6], a.joints[2, 1])


def _numpy_pool(dense, drop_top=False):
    """Plain reference: top ceil(0.1 %) magnitudes per frame (or all but them), then means of 3x3
    patches (rows floor(H / 3), columns ceil(W / 3), the last column patch over the pixels it has)."""
    t, h, w, _ = dense.shape
    ph, pw = h // 3, -(-w // 3)
    out = np.zeros((t, 2, ph, pw))
    for f in range(t):
        mag = np.hypot(dense[f, ..., 0], dense[f, ..., 1])
        kth = np.sort(mag.ravel())[-int(np.ceil(0.001 * h * w))]
        kept = np.where(((mag >= kth) != drop_top)[..., None], dense[f], 0.0)
        for i in range(ph):
            for j in range(pw):
                out[f, :, i, j] = kept[3 * i : 3 * i + 3, 3 * j : 3 * j + 3].reshape(-1, 2).mean(axis=0)
    return out


@pytest.mark.parametrize("shape", [(20, 26), (77, 103), (31, 45)])
def test_flow_pooling_matches_numpy(shape):
    dense = np.random.default_rng(1).normal(size=(3, *shape, 2)).astype(np.float32)
    dense[1] = 0.0  # no motion: nothing survives but zeros
    got = np.asarray(flow.sparsify_and_pool(dense))
    assert got.shape == (3, 2, *flow.pooled_shape(*shape))
    np.testing.assert_allclose(got, _numpy_pool(dense), rtol=1e-6, atol=1e-7)
    assert (got[0] != 0).sum() <= 2 * np.ceil(0.001 * shape[0] * shape[1])


def test_the_two_flow_readings_split_the_field_between_them():
    """keep_top keeps the strongest 0.1 % of vectors (5 of 4800 at 60x80), drop_top zeros exactly
    those: each matches the NumPy reference, and the two add up to the pooled dense flow."""
    dense = np.random.default_rng(2).normal(size=(2, 60, 80, 2)).astype(np.float32)
    keep, drop = (np.asarray(flow.sparsify_and_pool(dense, mode)) for mode in ("keep_top", "drop_top"))
    np.testing.assert_allclose(keep, _numpy_pool(dense), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(drop, _numpy_pool(dense, drop_top=True), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(
        keep + drop, _numpy_pool(dense, drop_top=True) + _numpy_pool(dense), rtol=1e-5, atol=1e-6
    )
    assert (keep != 0).mean() < 0.02 and (drop != 0).mean() > 0.99
    with pytest.raises(ValueError, match="sparsification"):
        flow.sparsify_and_pool(dense, "keep_all")
    assert {extract.feature_for("flow", flow_sparsify=m).name for m in flow.SPARSIFY} == {"flow", "flow_drop_top"}
    assert extract.feature_named("flow_drop_top").params["sparsify"] == "drop_top"


def test_flow_shape_at_paper_and_preset_sizes():
    assert flow.pooled_shape(308, 410) == (102, 137)
    assert flow.pooled_shape(154, 205) == (51, 69)
    assert np.asarray(flow.sparsify_and_pool(np.zeros((1, 308, 410, 2), np.float32))).shape == (1, 2, 102, 137)


def test_trial_flow_sees_motion_and_chunks_agree():
    import cv2

    rng = np.random.default_rng(0)
    scene = cv2.GaussianBlur(rng.integers(0, 255, (60, 80, 3), dtype=np.uint8), (0, 0), 2)
    frames = np.stack([scene[10:40, 10 - s : 50 - s] for s in range(0, 10, 2)])  # moves +2 px/step in x
    a = flow.trial_flow(frames, chunk=2)
    b = flow.trial_flow(frames, chunk=8)
    assert a.shape == (5, 2, 10, 14) and a.dtype == np.float16
    np.testing.assert_array_equal(a, b)
    assert not a[0].any()  # step 0 has no predecessor
    moving = a[1:, 0] != 0
    assert moving.any() and np.all(a[1:, 0][moving] > 0)  # x-flow points along the motion
    assert np.abs(a[1:, 1]).sum() < 0.2 * np.abs(a[1:, 0]).sum()


def _rotate_frames(frames, degrees, interpolation="bilinear", fill=0.0):
    """(N, H, W, C) frames turned by the library's rows rotation, back as frames."""
    n, h, w, c = frames.shape
    rows = images.rotate_rows(images.to_rows(jnp.asarray(frames)), degrees, h, w, np.arange(h * w), interpolation, fill)
    return np.asarray(jnp.moveaxis(rows, -1, 0).reshape(n, h, w, c))


@pytest.mark.parametrize("interpolation", ["bilinear", "nearest"])
def test_rotation_geometry(interpolation):
    f = np.random.default_rng(0).integers(0, 255, (1, 9, 9, 1)).astype(np.float32)
    np.testing.assert_allclose(_rotate_frames(f, 0.0, interpolation), f)
    np.testing.assert_allclose(_rotate_frames(f, 90.0, interpolation), np.rot90(f, -1, axes=(1, 2)), atol=1e-3)


def test_nearest_rotation_keeps_every_value_whole():
    f = np.random.default_rng(2).integers(0, 255, (2, 12, 16, 3)).astype(np.float32)
    turned = _rotate_frames(f, 33.0, "nearest")
    assert np.isin(turned, np.append(f, 0.0)).all()
    assert not np.isin(_rotate_frames(f, 33.0), np.append(f, 0.0)).all()  # bilinear blends


@pytest.mark.parametrize("interpolation", ["bilinear", "nearest"])
def test_the_fill_is_what_the_turn_brings_in(interpolation):
    """A frame of the fill value turns into itself at every angle, edges and corners included;
    with the default fill (0) its corners go dark."""
    c = np.array([1.5, -2.0, 0.25], np.float32)
    f = np.broadcast_to(c, (2, 12, 16, 3)).astype(np.float32)
    for degrees in (-90.0, -41.0, 17.0, 90.0):
        np.testing.assert_allclose(_rotate_frames(f, degrees, interpolation, c[:, None]), f, atol=1e-5)
    assert (_rotate_frames(f, 45.0, interpolation)[:, 0, 0] == 0).all()


@pytest.mark.parametrize("hw", [(12, 16), (30, 40), (7, 5)])
def test_rotated_rows_equal_the_frame_rotation_they_replaced(hw):
    """Same angles, same bilinear interpolation: the rows path computes the rotation of the
    frames the model used to apply (kept in tests/helpers.py), in any pixel order asked for."""
    h, w = hw
    frames = np.random.default_rng(1).normal(size=(3, h, w, 3)).astype(np.float32)
    order = images.patch_pixels(h, w, min(5, h, w))
    for degrees in (-90.0, -33.3, 0.0, 12.5, 61.0, 90.0):
        want = np.asarray(helpers.reference_rotate(frames, degrees)).reshape(3, h * w, 3)
        rows = np.asarray(images.rotate_rows(images.to_rows(jnp.asarray(frames)), degrees, h, w, order))
        np.testing.assert_allclose(np.moveaxis(rows, -1, 0), want[:, order], atol=2e-5)


def test_patch_pixels_are_the_first_layers_patches():
    frame = np.arange(7 * 11).reshape(7, 11)
    p = 3
    order = images.patch_pixels(7, 11, p)
    assert order.shape == (2 * 3 * p * p,) and len(set(order)) == len(order)
    patches = frame[:6, :9].reshape(2, p, 3, p).transpose(0, 2, 1, 3).reshape(-1)
    np.testing.assert_array_equal(frame.reshape(-1)[order], patches)


def test_one_angle_per_sequence():
    angles = np.asarray(images.random_angles(jax.random.key(3), 64))
    assert angles.shape == (64,) and len(set(angles.tolist())) == 64
    assert np.all(np.abs(angles) <= images.MAX_DEGREES) and angles.min() < -45 and angles.max() > 45
    np.testing.assert_array_equal(angles, np.asarray(images.random_angles(jax.random.key(3), 64)))
    frames = np.random.default_rng(0).normal(size=(4, 12, 16, 3)).astype(np.float32)
    turned = _rotate_frames(frames, float(angles[0]))
    for i in range(len(frames)):  # each frame turned exactly as it would be alone
        np.testing.assert_allclose(turned[i], _rotate_frames(frames[i : i + 1], float(angles[0]))[0], atol=1e-5)


def test_downsample_to_60x80():
    frames = np.full((2, 308, 410, 3), 77, np.uint8)
    small = images.downsample(frames)
    assert small.shape == (2, 60, 80, 3) and small.dtype == np.uint8
    assert np.all(small == 77)


def test_the_papers_window_by_duration_is_todays_feature_bit_for_bit():
    """The default step window (42.67 ms) at the hand's 48 kHz is 2048 samples: the same feature
    name and cache key as the paper's fixed window, so cached features stay valid, and the same
    numbers as slicing the 2048 samples before each window end directly."""
    from fabricjax.config import Config
    from fabricjax.sequences import data

    cfg = Config.from_preset("smoke")
    assert data.window_of(cfg, archive.AUDIO_RATE) == archive.WINDOW
    f = extract.feature_for("internal", window=data.window_of(cfg, archive.AUDIO_RATE))
    assert f.name == "psd_internal"
    assert f.params == {"mic": "internal", **welch.SCIPY_KWARGS, "log10_floor": welch.LOG_FLOOR}
    a = tiny_archive(fabric_id=3, n_steps=12)
    k = extract.mic_index(a, "internal")
    direct = np.stack([a.audio[k, e - archive.WINDOW : e] for e in a.window_end[:, k]])
    np.testing.assert_array_equal(f.compute(a), extract.log_psd(direct))
    assert f.compute(a).shape == (12, welch.N_BINS)


def test_another_window_is_another_feature_with_the_segment_following_it():
    w = welch.window_samples(0.1, archive.AUDIO_RATE)  # 4800 samples: hop 1197, segments of 2394
    f = extract.feature_for("internal", window=w)
    assert f.name == "psd_internal_w4800" and f.params["nperseg"] == 2394 and f.params["noverlap"] == 1197
    assert extract.feature_named(f.name).params == f.params
    a = tiny_archive(fabric_id=3, n_steps=12)
    psd = f.compute(a)
    assert psd.shape == (12, welch.full_bins(w)) == (12, 1198)
    x = extract.mic_windows(a, extract.mic_index(a, "internal"), w)
    ref = scipy.signal.welch((x >> 14).astype(np.float64) / 2**17, **welch.scipy_kwargs(w))[1]
    np.testing.assert_allclose(psd, np.log10(np.maximum(ref, welch.LOG_FLOOR)), atol=2e-3)


def test_rows_on_the_host_equal_the_device_layout():
    """`to_rows` of NumPy frames (blocks of sequences on the host) is the jnp transpose, over
    several blocks and leading axes."""
    frames = np.random.default_rng(0).integers(0, 256, (2, 70, 5, 3, 4, 3), np.uint8)
    host = images.to_rows(frames)
    assert isinstance(host, np.ndarray) and len(frames.reshape(-1, 5, 3, 4, 3)) > images.HOST_BLOCK
    np.testing.assert_array_equal(host, np.asarray(images.to_rows(jnp.asarray(frames))))
