"""The studies' pages and figures, drawn from what a study measured (`machinery.results`) and
nothing else.

The code fingerprint leaves this package out (`source.VIEWS`): an edit here draws the pages
again and stales no number, while the study that measures keeps its own fingerprint.
"""
