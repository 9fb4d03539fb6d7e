"""Benchmarks: how fast the library runs, apart from what it computes (`python -m experiments.bench`).

    suite            every speed benchmark side by side (results/bench.json, the README's table)
    program_timing   the training step and inference timed, XLA's FLOP count, a matmul's peak
    torch_twin       the PyTorch model of the same function, for the comparison (optional torch)
    feature_timing   Welch PSDs and a trial's feature extraction against the reference routines
    sim_throughput   simulated seconds per wall second
    synthetic        random data of the model's input shapes (timing inputs, the tests' data)

The acquisition package's benchmark of its recording loop (`acquisition.simulated_signals.bench_acquisition`)
lives beside what it times and is passed in to `suite.run`, since the library does not import the
acquisition package; the batch import's (`fabricjax.importers.example_rig.bench_import`) lives beside
the importers.
"""
