"""Device drivers for slrig: projectors, cameras, transports and the simulated bench.

This package knows nothing of scans: `rig` imports `drivers`, never the other way round.
"""
