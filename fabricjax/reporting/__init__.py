"""What a results file records: its header and fingerprint, statistics and figures."""
