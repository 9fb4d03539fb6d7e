import numpy as np

from fabricjax import catalog, plots


def test_confusion_matrix_counts():
    cm = plots.confusion_matrix([0, 1, 1, 2], [0, 1, 2, 2], 3)
    assert cm.tolist() == [[1, 0, 0], [0, 1, 1], [0, 0, 1]]


def test_confusion_classes_are_named_from_the_catalog():
    assert plots.class_label(0) == "0 no fabric" and plots.class_label(8) == "8 swimsuit"
    assert plots.class_label(12) == "12 real silk"


def test_figures_are_written(tmp_path):
    rng = np.random.default_rng(0)
    y = rng.integers(0, 21, 200)
    p1 = plots.plot_confusions(tmp_path / "cm.png", [("proprio", y, y), ("flow", y, rng.integers(0, 21, 200))])
    ids = list(range(1, 24))
    fabrics = {f: (catalog.fabric(f).name, catalog.fabric(f).properties) for f in ids}
    p2 = plots.plot_latents(tmp_path / "tsne.png", rng.normal(size=(len(ids), 2)), ids, fabrics, catalog.PROPERTY_HOLDOUTS)
    pts = [dict(name=f"N={n}", accuracy_mean=50 + n / 5, accuracy_sd=2.0, touch_s=n / 50, latency_ms=n / 100) for n in (25, 50, 100, 200)]
    p3 = plots.plot_pareto(tmp_path / "pareto.png", pts, [("touch_s", "touch time [s]"), ("latency_ms", "latency [ms]")], highlight="N=200")
    f = np.linspace(0, 24000, 512)
    p4 = plots.plot_psds(tmp_path / "psd.png", f, {"0": np.ones(512), "1": np.ones(512) * 2}, noise=np.ones(512) * 3)
    for p in (p1, p2, p3, p4):
        assert p.stat().st_size > 5000 and p.read_bytes()[:4] == b"\x89PNG"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["cm.png", "pareto.png", "psd.png", "tsne.png"]
