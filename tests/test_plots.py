import numpy as np

from fabricjax import catalog
from fabricjax.reporting import plots, stats


def test_confusion_matrix_counts():
    cm = stats.confusion_matrix([0, 1, 1, 2], [0, 1, 2, 2], 3)
    assert cm.tolist() == [[1, 0, 0], [0, 1, 1], [0, 0, 1]]


def test_confusion_classes_are_named_from_the_catalog():
    assert plots.class_label(0) == "0 no fabric" and plots.class_label(8) == "8 swimsuit"
    assert plots.class_label(12) == "12 real silk"


def test_figures_are_written(tmp_path):
    rng = np.random.default_rng(0)
    y = rng.integers(0, 21, 200)
    panels = [
        ("proprio", stats.confusion_matrix(y, y, 21)),
        ("flow", stats.confusion_matrix(y, rng.integers(0, 21, 200), 21)),
    ]
    p1 = plots.plot_confusions(tmp_path / "cm.png", panels)
    ids = list(range(1, 24))
    fabrics = {f: (catalog.fabric(f).name, catalog.fabric(f).properties) for f in ids}
    p2 = plots.plot_latents(
        tmp_path / "tsne.png", rng.normal(size=(len(ids), 2)), ids, fabrics, catalog.PROPERTY_HOLDOUTS
    )
    pts = [
        dict(name=f"N={n}", accuracy_mean=50 + n / 5, accuracy_sd=2.0, touch_s=n / 50, latency_ms=n / 100)
        for n in (25, 50, 100, 200)
    ]
    p3 = plots.plot_pareto(
        tmp_path / "pareto.png", pts, [("touch_s", "touch time [s]"), ("latency_ms", "latency [ms]")], highlight="N=200"
    )
    f = np.linspace(0, 24000, 512)
    p4 = plots.plot_psds(tmp_path / "psd.png", f, {"0": np.ones(512), "1": np.ones(512) * 2}, noise=np.ones(512) * 3)
    for p in (p1, p2, p3, p4):
        assert p.stat().st_size > 5000 and p.read_bytes()[:4] == b"\x89PNG"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["cm.png", "pareto.png", "psd.png", "tsne.png"]


def test_accuracy_error_bars_stop_at_0_and_100_percent():
    below, above = plots.clipped_errors(np.array([3.0, 50.0, 99.0]), np.array([5.0, 5.0, 5.0]))
    assert below.tolist() == [3.0, 5.0, 5.0] and above.tolist() == [5.0, 5.0, 1.0]


def test_the_paper_tick_is_named_with_its_split(monkeypatch, tmp_path):
    """The noise figure's paper means are the cafe test's: the legend says so."""
    drawn = []
    monkeypatch.setattr(
        plots, "_save", lambda fig, path: drawn.append([t.get_text() for t in fig.axes[0].get_legend().get_texts()])
    )
    plots.plot_seed_bars(
        tmp_path / "x.png",
        ["a", "b"],
        {"test": ([np.ones(2), np.ones(2)], [None, None]), "cafe": ([np.ones(2), np.ones(2)], [40.0, None])},
        "title",
    )
    assert "cafe test, paper (mean)" in drawn[0] and not any(t.startswith("paper") for t in drawn[0])
