"""Accuracy against ground truth: every pair of a scan, and a merged cloud, measured on a rig
that has ground truth (the simulated bench)."""
