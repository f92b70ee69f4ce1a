"""slrig: everything that is not a device: patterns, geometry, scans, storage, service, CLI."""

__version__ = "0.1.0"
