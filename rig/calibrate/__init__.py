"""Calibration: boards, views (from the simulated bench or a folder), OpenCV solvers, quality report,
and calibration files. A library API that the CLI (and later the REST service) calls."""
