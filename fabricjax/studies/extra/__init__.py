"""Studies beyond the paper's tables: probe, day_shift, decide, cost, sweep, palm."""
