"""The scene simulator: physically grounded trial archives, standing in for the paper's recorded dataset.

    scene = Scene(fabric_id=12, day=1, trial=0, condition="lab",
                  effects=EFFECTS, streams=("audio", "proprio"), cycles=50, seed=0)
    arch = simulate(scene)                 # fabricjax.store.archive.TrialArchive, images=None here
    path = ensure_dataset("default")       # every trial of a preset, resumable, indexed

Only what a scene calls for is computed: an effect missing from `scene.effects` is never
evaluated, and images are rendered only when "images" is in `scene.streams`. Each module's
docstring states what it models and where that comes from; every constant lives in
`fabricjax.sim.calibration` with its source tag ([paper], [ds], [minsight], [insight], [FACTS],
[cited], [law], [numerics], listed there) or as an estimate declared with its range in
`fabricjax.sim.estimates`. The time base and word format shared with recorded trials are
`fabricjax.store.archive`'s.
"""

from fabricjax.sim.dataset import ensure_dataset, scene_for
from fabricjax.sim.scene import EFFECTS, REQUIRED_STREAMS, STREAMS, Scene
from fabricjax.sim.trial import simulate

__all__ = ["EFFECTS", "REQUIRED_STREAMS", "STREAMS", "Scene", "ensure_dataset", "scene_for", "simulate"]
