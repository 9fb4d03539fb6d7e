"""Trials to training sets: features to N-step sequences per split, their standardisation and layout."""
