"""The paper's published numbers, as data, so every results table can print ours beside theirs.

Accuracies in percent, mean and SD over seeds, transcribed from the paper's tables. Row
modalities use fabricjax.config.MODALITIES names ("image" = Minsight image, "flow" = optical
flow, "internal" = Minsound, "external" = palm microphone, "proprio" = proprioception).
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class AblationRow:
    name: str
    backbone: str
    modalities: tuple[str, ...]
    paper_mean: float
    paper_sd: float


ABLATION = (
    AblationRow("image", "attention", ("image",), 41.15, 5.74),
    AblationRow("flow", "attention", ("flow",), 47.16, 5.12),
    AblationRow("internal", "attention", ("internal",), 95.06, 1.85),
    AblationRow("external", "attention", ("external",), 59.22, 2.43),
    AblationRow("proprio", "attention", ("proprio",), 47.10, 3.72),
    AblationRow("image+internal", "attention", ("image", "internal"), 73.94, 5.73),
    AblationRow("image+internal+external+proprio", "attention", ("image", "internal", "external", "proprio"), 85.59, 3.87),
    AblationRow("flow+internal", "attention", ("flow", "internal"), 87.44, 5.88),
    AblationRow("flow+internal+external+proprio", "attention", ("flow", "internal", "external", "proprio"), 91.34, 2.47),
    AblationRow("internal+proprio", "attention", ("internal", "proprio"), 94.63, 2.78),
    AblationRow("internal+external+proprio", "attention", ("internal", "external", "proprio"), 96.10, 1.26),
    AblationRow("internal+external", "attention", ("internal", "external"), 97.75, 1.27),
    AblationRow("tcn:internal+external+proprio", "tcn", ("internal", "external", "proprio"), 75.41, 11.2),
)
# The paper's Wilcoxon test: internal+external against internal alone, p = 0.0254.
ABLATION_WILCOXON_P = 0.0254

# Bandwidth [kHz] -> (validation mean, SD, test mean, SD)
BANDWIDTH = {2.5: (92.43, 1.13, 89.87, 3.31), 10.0: (97.45, 1.17, 93.07, 3.33), 15.0: (97.75, 1.62, 95.06, 1.85), 24.0: (98.20, 1.39, 91.94, 2.68)}

# Cafe-noise test set, 10 seeds; p against the preceding row.
NOISE = (
    (("internal",), 67.51, 5.05, None),
    (("internal", "proprio"), 87.51, 2.66, "< 0.0001"),
    (("internal", "proprio", "external"), 90.30, 2.18, "0.0098"),
)

# Property perception, 5 seeds, mean accuracy: property -> (chance, train Minsound, train
# Minsound+Minsight, holdout Minsound, holdout Minsound+Minsight). Proprioception always on.
PROPERTIES = {
    "stretchiness": (50.00, 97.40, 85.99, 76.15, 82.95),
    "roughness": (20.00, 97.47, 82.38, 40.23, 33.94),
    "thickness": (33.33, 97.59, 90.43, 70.56, 90.47),
}
