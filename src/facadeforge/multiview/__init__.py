"""Calibrated photo sets: dense stereo, the reconstruction frame, per-view appearance, labels."""
