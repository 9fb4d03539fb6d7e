"""One training loop over vmapped seeds: placement, sharding, checkpoints, curves."""
