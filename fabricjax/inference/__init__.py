"""A trained model in use: temperature calibration, the stopping rule, the streaming classifier, the viewer."""
