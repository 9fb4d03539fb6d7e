"""Tools over the studies: reproduce (every study in order, one report) and stream (live classification)."""
