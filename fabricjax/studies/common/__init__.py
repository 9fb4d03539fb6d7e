"""What the studies share: rows (a study's rows), loading (data), runner (a training study),
row_training (rows -> trained seeds), documents (results files), findings (the paper's claims as
predicates); `fabricjax.studies` lists every module."""
