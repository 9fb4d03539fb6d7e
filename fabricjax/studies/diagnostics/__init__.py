"""Our diagnostics beyond the paper's tables: what the inputs carry (probe, day_shift, palm), what the
simulator's estimates decide (sensitivity, calibrate, flow_budget, camera_frames, flow_agreement),
deciding and its cost on the robot (decide, cost, stream), recipes and variants (sweep, variant)."""
