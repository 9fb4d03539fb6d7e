"""What every study is built of: rows (a study's rows), loading (data), runner (a training study),
row_training (rows -> trained seeds), documents (results files), findings (the paper's claims as
predicates), and each measurement two studies share; `fabricjax.studies` lists every module."""
