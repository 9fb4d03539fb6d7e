"""The release tooling: reproduce (every study of the plan in order, one report), what of a results
folder is stale, REPORT.md and README's results block, and the soak of the install check."""
