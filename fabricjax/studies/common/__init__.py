"""What the studies share: loading (data), runner (rows -> trained seeds), documents (results files),
findings (the paper's claims as predicates)."""
