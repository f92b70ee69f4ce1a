"""Calibration: boards, views (placed by the rig where it can, or read from a folder), OpenCV
solvers, quality report, calibration files, and the projector response."""
