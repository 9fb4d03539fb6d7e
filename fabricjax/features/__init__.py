"""Model inputs computed from trial archives: Welch PSD (welch), optical flow (flow), Minsight
frames (images), the per-trial feature table (extract) and its on-disk cache (cache)."""
