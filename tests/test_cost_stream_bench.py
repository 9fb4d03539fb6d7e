"""The cost study, live streaming and the benchmark suite on the smoke preset, with tiny settings.

Outputs are checked for shape and content; no time is asserted (timings are the benchmarks' job).
"""

import json

import jax
import numpy as np
import pytest

from acquisition.simulated_signals import bench_acquisition
from fabricjax import catalog, presets, sim
from fabricjax.bench import program_timing, sim_throughput
from fabricjax.bench import suite as bench
from fabricjax.config import Config
from fabricjax.features import welch
from fabricjax.features.extract import log_psd, mic_windows
from fabricjax.importers import example_rig
from fabricjax.inference import live
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import cost
from fabricjax.studies.diagnostics import stream as stream_command
from fabricjax.training import train

PNG = b"\x89PNG\r\n\x1a\n"
TINY = dict(width=16, n_heads=4, n_layers=1, ffn=32, audio_hidden=(32, 16), proprio_hidden=(16, 16))


@pytest.fixture(scope="session")
def smoke_workdir(tmp_path_factory):
    """The smoke dataset (audio + joints), generated once for every test here."""
    root = tmp_path_factory.mktemp("cost_stream_bench")
    sim.ensure_dataset("smoke", root, streams=("audio", "proprio"), progress=False)
    return root


def test_sweep_is_one_factor_at_a_time_with_the_paper_point_capped():
    base = Config.from_preset("smoke", modalities=("internal", "external"), seq_len=20)
    points, paper = cost.sweep_points(
        base,
        seq_lens=(10, 20, 200),
        backbones=("attention", "tcn"),
        widths=(8, 16),
        bandwidths=(2.5, 15.0),
        modality_sets=[("internal", "external"), ("internal",)],
        max_len=120,
    )
    names = [p.name for p in points]
    assert len(names) == len(set(names))
    assert all(p.config.seq_len <= 120 for p in points)  # N=200 skipped
    grid = [p for p in points if p.group == "N x backbone"]
    assert {(p.config.backbone, p.config.seq_len) for p in grid} == {
        (b, n) for b in ("attention", "tcn") for n in (10, 20)
    }
    # width 16 and 15 kHz and the first modality set are the base: no duplicate points
    assert sorted(p.group for p in points if p.group not in ("N x backbone",)) == [
        "bandwidth",
        "modalities",
        "paper",
        "width",
    ]
    paper_cfg = next(p.config for p in points if p.name == paper)
    assert (paper_cfg.seq_len, paper_cfg.width, paper_cfg.ffn, paper_cfg.backbone) == (120, 64, 128, "attention")
    assert paper_cfg.modalities == ("internal", "external") and paper_cfg.bandwidth_khz == 15.0


def test_a_width_point_at_the_base_width_but_another_ffn_has_its_own_name():
    # the default preset's FFN is not 2 x width, so its width's point (FFN 2 x width) is another model
    base = Config.from_preset("smoke", seq_len=20, width=16, ffn=16)
    points, _ = cost.sweep_points(
        base,
        seq_lens=(20,),
        backbones=("attention",),
        widths=(16,),
        bandwidths=(),
        modality_sets=[base.modalities],
        max_len=120,
    )
    names = [p.name for p in points]
    assert len(names) == len(set(names)) and "att N20 w16/32" in names


def test_pareto_front_keeps_only_undominated_points():
    pts = [
        {"name": "a", "touch_s": 0.5, "accuracy_mean": 60.0},
        {"name": "b", "touch_s": 1.0, "accuracy_mean": 55.0},  # slower and worse than a
        {"name": "c", "touch_s": 2.0, "accuracy_mean": 80.0},
        {"name": "d", "touch_s": 0.5, "accuracy_mean": 50.0},  # as fast as a, worse
    ]
    assert cost.pareto_front(pts, "touch_s") == ["a", "c"]


@pytest.mark.slow
def test_cost_run_writes_table_json_and_pareto_png(smoke_workdir, tmp_path):
    doc = cost.run(
        n_seeds=2,
        preset="smoke",
        seq_lens=(20,),
        backbones=("attention",),
        widths=(),
        bandwidths=(),
        modality_sets=[("internal", "external")],
        latency_repeats=3,
        where=Location(workdir=smoke_workdir, results=tmp_path, command="test"),
    )
    assert [p["group"] for p in doc["points"]] == ["N x backbone", "paper"]
    assert doc["paper_point"] == doc["points"][1]["name"]
    saved = json.loads((tmp_path / "cost.json").read_text())
    for p in saved["points"]:
        assert {
            "accuracy",
            "accuracy_mean",
            "accuracy_sd",
            "touch_s",
            "train_s",
            "latency_p50_ms",
            "latency_p99_ms",
            "params",
        } <= set(p)
        assert len(p["accuracy"]) == 2 and p["params"] > 0 and p["latency_p99_ms"] >= p["latency_p50_ms"] > 0
        assert p["touch_s"] == p["seq_len"] / 50
    assert set(saved["pareto_front"]) == {"touch_s", "latency_p50_ms"} and "machine" in saved
    md = (tmp_path / "cost.md").read_text()
    assert f"**{doc['paper_point']}**" in md and "| point |" in md
    assert (tmp_path / "cost_pareto.png").read_bytes()[:8] == PNG


def _tiny_streamer(config, shapes=None, layout=live.HAND):
    shapes = shapes or {
        m: (18,) if m == "proprio" else (welch.n_bins(config.bandwidth_khz),) for m in config.modalities
    }
    trainer = train.make_trainer(config, shapes)
    return live.Streamer(trainer.graphdef, jax.jit(trainer.init)(jax.random.PRNGKey(0)).params, config, layout=layout)


def test_streaming_psd_of_the_newest_step_equals_the_batch_feature(smoke_workdir):
    folder = smoke_workdir / "datasets" / "smoke"
    trial = archive.read_archive(stream_command.first_test_trial(folder), images=False)
    config = Config(
        preset="smoke", modalities=("internal", "external", "proprio"), seq_len=8, bandwidth_khz=10.0, **TINY
    )
    s = _tiny_streamer(config)
    extra = 3
    probs = [
        s.update(live.step_windows(trial, t, s.mics, s.windows), trial.joints[t]) for t in range(config.seq_len + extra)
    ]
    assert all(p is None for p in probs[: config.seq_len - 1])
    assert all(p.shape == (21,) and np.isclose(p.sum(), 1, atol=1e-5) for p in probs[config.seq_len - 1 :])
    k = welch.n_bins(10.0)
    steps = slice(extra, extra + config.seq_len)
    for m, mic in (("internal", 0), ("external", 1)):
        batch = log_psd(mic_windows(trial, mic))[steps, :k]
        np.testing.assert_allclose(np.asarray(s.window[m]), batch, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(np.asarray(s.window["proprio"]), trial.joints[steps].reshape(config.seq_len, 18))


def test_streaming_a_rig_uses_the_window_by_duration_at_its_mics_rate():
    """A rig's 2.2 kHz vibration microphone and 7 x 3 joints, a 0.3 s step window: each step's PSD is
    the batch feature's (the loader's window, `data.window_of`), the joints its 21 values, and the
    classes the trial's label map."""
    from fabricjax.features import extract
    from fabricjax.sequences import data
    from tests.test_rig_archive import rig_archive

    trial = rig_archive(n_steps=12)
    lay = archive.layout(trial.meta)
    config = Config(
        preset="smoke", modalities=("internal", "proprio"), seq_len=4, mic_window_s=0.3, n_classes=3, **TINY
    )
    window = data.window_of(config, 2200)
    assert window == 660
    s = _tiny_streamer(config, {"internal": (welch.full_bins(window),), "proprio": (21,)}, lay)
    assert s.windows == (window,) and s.mics == [0]
    probs = [s.update(live.step_windows(trial, t, s.mics, s.windows), trial.joints[t]) for t in range(6)]
    assert probs[-1].shape == (3,)
    batch = extract.feature_for("internal", window=window).compute(trial)[2:6]
    np.testing.assert_allclose(
        np.asarray(s.window["internal"]),
        batch[:, : welch.n_bins(config.bandwidth_khz, 2200, window)],
        rtol=0,
        atol=1e-5,
    )
    np.testing.assert_array_equal(np.asarray(s.window["proprio"]), trial.joints[2:6].reshape(4, 21))
    assert live.class_name(2, trial.meta) == "felt" and live.class_name(2) == catalog.fabric(2).name


def test_streamer_rejects_camera_models():
    with pytest.raises(ValueError, match="streaming supports"):
        live.Streamer(None, None, Config(preset="smoke", modalities=("internal", "flow")))


def test_stream_run_trains_a_quick_model_then_restores_it(smoke_workdir, tmp_path):
    lines = []
    doc = stream_command.run(
        preset="smoke",
        realtime=False,
        print_every=5,
        where=Location(workdir=smoke_workdir, results=tmp_path),
        out=lines.append,
    )
    assert doc["decided_steps"] == doc["steps"] - doc["window_steps"] + 1 > 0
    assert doc["latency_p99_ms"] >= doc["latency_p50_ms"] > 0 and doc["late_steps"] is None
    assert any("p=" in line and "ms" in line for line in lines) and lines[-1].startswith("first correct decision")
    assert json.loads((tmp_path / "stream.json").read_text())["archive"] == doc["archive"]
    again = stream_command.run(
        checkpoint_dir=doc["checkpoint"],
        realtime=False,
        print_every=0,
        where=Location(workdir=smoke_workdir, results=tmp_path),
        out=lines.append,
    )
    assert again["config"] == doc["config"]
    assert again["accuracy_over_decided_steps"] == doc["accuracy_over_decided_steps"]


@pytest.mark.slow  # ~30-55 s on 2 cores: run with -m slow
def test_bench_runs_every_benchmark_and_writes_json(smoke_workdir, tmp_path, monkeypatch):
    workload = bench.Workload(
        Config(preset="smoke", modalities=("internal", "external", "proprio"), seq_len=12, **TINY), batch=8, bins=24
    )
    lines = []
    full = example_rig.bench_import
    monkeypatch.setattr(example_rig, "bench_import", lambda trials: full(trials=20, seconds=(2.0, 3.0)))
    doc = bench.run(
        quick=True,
        workload=workload,
        where=Location(workdir=smoke_workdir, results=tmp_path, command="test"),
        out=lines.append,
        acquisition=bench_acquisition,
    )
    saved = json.loads((tmp_path / "bench.json").read_text())
    assert set(saved["benchmarks"]) == set(bench.BENCHMARKS) and saved["machine"]["cores"] > 0
    b = saved["benchmarks"]
    assert set(b["training"]["ours_5_seed"]) == set(b["inference"]["ours"]) == set(program_timing.DTYPES)
    assert b["training"]["ours_5_seed"]["bfloat16"]["n_seeds"] == 5 and b["welch"]["speedup_vs_scipy"] > 0
    assert b["streaming"]["decided_steps"] > 0 and b["extraction"]["peak_rss_mb"] > 0
    assert b["import"]["trials"] == 20 and b["import"]["wall_s"] > 0
    camera = b["camera"]["rows"]
    rotation = camera["camera"]["s_per_step"] / camera["camera_unrotated"]["s_per_step"]
    assert b["camera"]["rotation_ratio"] == pytest.approx(rotation) and "with the paper's rotation" in lines[-1]
    assert set(b["frame_scale"]["sizes"]) == {"60x80", "77x103"} and "camera data at 77x103" in lines[-1]
    assert "missed_deadlines" in b["acquisition"] and b["simulator"]["realtime_factor"] > 0
    assert all(saved["matmul_peak"][d]["gflop_per_s"] > 0 for d in program_timing.DTYPES)
    for d in program_timing.DTYPES:
        assert (
            b["training"]["ours_5_seed"][d]["xla"]["flops_per_step"]
            > b["training"]["ours_1_seed"][d]["xla"]["flops_per_step"]
            > 0
        )
        assert set(b["inference"]["ours"][d]["xla"]["fraction_of_peak"]) == set(program_timing.DTYPES)
        assert f"{d} (batch 8, N=12)" in lines[-1] and f"sequence, {d}, p50" in lines[-1]
    if doc["torch"] is not None:
        assert all(
            "ratio" in b["training"]["ours_1_seed"][d] and "ratio_p50" in b["inference"]["ours"][d]
            for d in program_timing.DTYPES
        )
        assert (
            b["training"]["torch_1_seed"]["variant"]
            in b["training"]["interleaved"]["training"]["1_seed"]["torch_variants"]
        )
        assert "eager +bf16 autocast" in b["training"]["interleaved"]["training"]["1_seed"]["torch_variants"]
    else:
        assert "skipped" in doc["torch_note"]
    assert "| benchmark |" in lines[-1] and (tmp_path / "bench.md").exists()


def test_xla_flops_utilisation_and_matmul_peak_are_positive():
    f = jax.jit(lambda a, b: jax.numpy.tanh(a @ b))
    a, b = jax.numpy.ones((32, 16)), jax.numpy.ones((16, 8))
    flops = program_timing.xla_flops(f, a, b)
    assert np.isfinite(flops) and flops >= 2 * 32 * 16 * 8  # at least the matmul's multiply-adds
    peaks = {d: program_timing.matmul_peak(n=128, repeats=2, dtype=d) for d in program_timing.DTYPES}
    for d, peak in peaks.items():
        # Rows split over every device: the per-device counts add up to the whole matmul's.
        assert (
            peak["flops"] == pytest.approx(2 * 128**3, rel=0.01)
            and peak["devices"] == len(jax.devices())
            and peak["dtype"] == d
        )
        assert np.isfinite(peak["gflop_per_s"]) and peak["gflop_per_s"] > 0
    use = program_timing.utilisation(flops, 1e-4, {d: p["gflop_per_s"] for d, p in peaks.items()})
    assert np.isfinite(use["gflop_per_s"]) and use["gflop_per_s"] > 0
    for d, p in peaks.items():
        assert use["fraction_of_peak"][d] == pytest.approx(use["gflop_per_s"] / p["gflop_per_s"])


def test_bench_table_names_the_fastest_variant_and_a_failed_compile():
    xla = {"flops_per_step": 2e9, "gflop_per_s": 20.0, "fraction_of_peak": {"float32": 0.25, "bfloat16": 0.125}}
    failed = {"error": "BackendCompilerFailed: no C++ compiler"}
    eager = {"build_and_warmup_s": 1.0, "s_per_step": 0.2, "ratio": {"float32": 0.5, "bfloat16": 0.4}}
    training = {"1_seed": {"torch_variants": {"eager": eager, "compiled:default": failed}}}
    peak = {"n": 2048, "devices": 2}
    doc = {
        "command": "test",
        "quick": False,
        "torch": "2.13.0",
        "machine": {"cpu": "cpu", "cores": 2, "jax": "0.10"},
        "matmul_peak": {"float32": {**peak, "gflop_per_s": 80.0}, "bfloat16": {**peak, "gflop_per_s": 160.0}},
        "benchmarks": {
            "training": {
                "workload": {"batch": 32, "seq_len": 200},
                "ours_1_seed": {
                    "float32": {"seconds_per_step": 0.1, "ratio": 0.5, "xla": xla},
                    "bfloat16": {"seconds_per_step": 0.08, "ratio": 0.4, "xla": xla},
                },
                "torch_1_seed": {"variant": "eager", "seconds_per_step": 0.2},
                "interleaved": {"torch_adamw": "fused", "training": training},
            },
            "inference": {
                "workload": {"seq_len": 200},
                "ours": {"float32": {"p50_ms": 3.0, "p99_ms": 9.0, "xla": xla}},
            },
        },
    }
    table = bench.markdown(doc)
    assert (
        "| training step, 1 seed, float32 (batch 32, N=200) | 100 ms | eager 200 ms | 0.50 | 2 | 20 (25 % / 12 %) |"
        in table
    )
    assert "| training step, 1 seed, bfloat16 (batch 32, N=200) | 80 ms | eager 200 ms | 0.40 |" in table
    assert (
        "float32 operands (80.0 GFLOP/s) and bfloat16 operands (160.0 GFLOP/s)" in table
        and "on the same 2 devices" in table
    )
    assert "| training, 1 seed | eager | 200 ms | float32 0.50, bfloat16 0.40 | 1.0 s |" in table
    assert "| inference, one 200-step sequence, float32, p50 / p99 | 3.00 / 9.00 ms | n/a |" in table
    assert "| training, 1 seed | compiled:default | n/a |  | failed: BackendCompilerFailed: no C++ compiler |" in table
    assert "AdamW fused" in table


def test_bench_rejects_unknown_names(tmp_path):
    with pytest.raises(ValueError, match="unknown benchmarks"):
        bench.run(only=["nope"], where=Location(results=tmp_path))
    with pytest.raises(ValueError, match="acquisition benchmark needs its function"):
        bench.run(only=["acquisition"], where=Location(results=tmp_path))


@pytest.mark.slow  # ~20 s on 2 cores: the benchmark suite's comparison
def test_comparison_times_every_dtype_against_every_twin_variant(monkeypatch):
    """`compare_with_torch`'s bookkeeping with a stand-in twin (torch is optional): ours in each
    compute dtype against eager and compiled variants, each in float32 and under autocast; a
    variant that fails to build is recorded, the fastest one is the reference of every ratio; several
    seeds come in sequence and vmapped, one seed alone."""
    from fabricjax.bench import torch_twin

    seconds = {(None, False): 0.4, (None, True): 0.2, ("default", False): 0.3, ("default", True): 0.25}

    def runner(*args, compile_mode=None, autocast=False, ensemble=torch_twin.IN_SEQUENCE, **kw):
        if compile_mode == "broken":
            raise RuntimeError("no C++ compiler\nmore")
        return lambda: seconds[(compile_mode, autocast)] / (2 if ensemble == torch_twin.VMAPPED else 1)

    monkeypatch.setattr(torch_twin, "require", lambda: type("T", (), {"get_num_threads": staticmethod(lambda: 2)}))
    monkeypatch.setattr(torch_twin, "adamw_impl", lambda: "fused")
    monkeypatch.setattr(torch_twin, "train_step_runner", runner)
    monkeypatch.setattr(torch_twin, "inference_runner", runner)
    cfg = Config(preset="smoke", modalities=("internal", "proprio"), seq_len=6, **TINY)
    out = program_timing.compare_with_torch(
        cfg,
        seeds=(1, 2),
        batch=4,
        seq_len=6,
        psd_bins=8,
        steps=1,
        rounds=2,
        inference_rounds=1,
        inference_calls=2,
        pause_s=0.0,
        compile_modes=("default", "broken"),
    )
    for t, fastest, s, ensembles in (
        (out["training"]["1_seed"], "eager +bf16 autocast", 0.2, [""]),
        (out["training"]["2_seed"], "eager +bf16 autocast, vmapped", 0.1, [", in sequence", ", vmapped"]),
    ):
        assert t["torch_variant"] == fastest and t["torch_s_per_step"] == s
        assert set(t["ours"]) == set(program_timing.DTYPES)
        assert all(v["ratio"] == pytest.approx(v["s_per_step"] / s, rel=1e-6) for v in t["ours"].values())
        assert len(t["torch_variants"]) == 3 * 2 * len(ensembles)
        for e in ensembles:
            assert "error" in t["torch_variants"]["compiled:broken +bf16 autocast" + e]
            assert set(t["torch_variants"]["compiled:default" + e]["ratio"]) == set(program_timing.DTYPES)
    assert "per_seed_vs_1_seed" in out["training"]["2_seed"]["ours"]["bfloat16"]
    i = out["inference"]
    assert i["torch_variant"] == "eager +bf16 autocast" and set(i["ours"]) == set(program_timing.DTYPES)
    assert i["ours"]["float32"]["ratio_p50"] == pytest.approx(i["ours"]["float32"]["p50_ms"] / 200.0)


def test_bench_and_studies_do_not_import_each_other():
    """What the benchmarks and the studies share lies beneath both (`fabricjax.timing`,
    `fabricjax.reporting.results_files`): no module of one imports the other."""
    import ast
    from pathlib import Path

    package = Path(archive.__file__).parent
    for here, other in (("bench", "fabricjax.studies"), ("studies", "fabricjax.bench")):
        for path in (package / here).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.module:
                    names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
                elif isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                else:
                    continue
                assert not any(n == other or n.startswith(other + ".") for n in names), (path, names)


def test_the_frame_scale_bench_scales_one_trial_to_the_preset():
    """Frames at twice the side hold four times the bytes; the preset's time is its trials' on its cores."""
    out = sim_throughput.bench_frame_scale("smoke", sizes=((16, 20), (32, 40)), cycles=1, cores=2)
    small, big = out["sizes"]["16x20"], out["sizes"]["32x40"]
    assert big["frame_mb_per_trial"] == pytest.approx(4 * small["frame_mb_per_trial"])
    assert out["trials"] == len(presets.get("smoke").dataset.trials()) and out["frames_per_trial"] > 0
    for v in (small, big):
        per_trial = v["render_s_per_trial"] + v["flow_s_per_trial"]
        assert v["flow_s_per_trial"] > 0 and v["preset_s"] == pytest.approx(per_trial * out["trials"] / 2)
