"""Calibrated photo sets: dense multi-view stereo, the reconstruction frame, appearance and labels seen from each view."""
